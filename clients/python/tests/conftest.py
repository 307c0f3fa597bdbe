"""A real `landform serve` on 127.0.0.1 for the tests, on a temporary SQLite database.

The binary is `LANDFORM_BIN` (default: the repository's target/debug/landform).
"""

from __future__ import annotations

import json
import os
import queue
import secrets
import signal
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Iterator, Optional

import pytest

from landform import Client

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("LANDFORM_BIN") or REPO / "target" / "debug" / "landform")
SPEC = REPO / "openapi.yaml"
API = REPO / "api"

# Every client the fixtures made, so test_spec.py can check the routes they called.
CLIENTS: list[Client] = []


class Server:
    """`landform serve --addr 127.0.0.1:0`; `url` is the address it printed."""

    def __init__(self, *extra: str):
        if not BIN.is_file():
            raise RuntimeError(f"no landform binary at {BIN} (set LANDFORM_BIN)")
        self.dir = tempfile.TemporaryDirectory(prefix="landform-py-")
        self.stderr = open(Path(self.dir.name) / "stderr.log", "w+b")
        # The server's own settings come from its flags alone, not from this shell.
        env = {k: v for k, v in os.environ.items() if not k.startswith("LANDFORM_") and k != "DATABASE_URL"}
        env.setdefault("RUST_LOG", "warn")
        args = [
            str(BIN), "serve",
            "--addr", "127.0.0.1:0",
            "--database", str(Path(self.dir.name) / "landform.db"),
            "--job-timeout-secs", "120",
            "--shutdown-deadline-secs", "1",
            "--memory-budget", str(1 << 30),
            *extra,
        ]
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=self.stderr, env=env, cwd=self.dir.name)
        lines: "queue.Queue[Optional[str]]" = queue.Queue()

        def read() -> None:
            assert self.proc.stdout is not None
            for raw in self.proc.stdout:
                lines.put(raw.decode("utf-8", "replace").strip())
            lines.put(None)

        threading.Thread(target=read, daemon=True).start()
        deadline = time.monotonic() + 60
        self.url = ""
        while time.monotonic() < deadline:
            try:
                line = lines.get(timeout=0.5)
            except queue.Empty:
                continue
            if line is None:
                break
            if line.startswith("listening on "):
                self.url = line[len("listening on "):].strip()
                break
        if not self.url:
            self.stop()
            raise RuntimeError(f"landform serve did not start:\n{self.log()}")

    def log(self) -> str:
        self.stderr.flush()
        self.stderr.seek(0)
        return self.stderr.read().decode("utf-8", "replace")[-4000:]

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.stderr.close()
        self.dir.cleanup()


def make_client(url: str, api_key: Optional[str] = None) -> Client:
    client = Client(url, api_key=api_key, timeout=30)
    CLIENTS.append(client)
    return client


@pytest.fixture(scope="session")
def server() -> Iterator[Server]:
    s = Server()
    yield s
    s.stop()


@pytest.fixture(scope="session")
def client(server: Server) -> Iterator[Client]:
    c = make_client(server.url)
    yield c
    c.close()


@pytest.fixture(scope="session")
def api_keys() -> tuple[str, str]:
    return ("py-" + secrets.token_hex(12), "py-" + secrets.token_hex(12))


@pytest.fixture(scope="session")
def keyed_server(api_keys: tuple[str, str]) -> Iterator[Server]:
    with tempfile.NamedTemporaryFile("w", suffix=".keys", delete=False) as f:
        f.write(f"alice {api_keys[0]}\nbob {api_keys[1]}\n")
    s = Server("--api-keys", f.name)
    yield s
    s.stop()
    os.unlink(f.name)


def example(kind: str, name: str) -> dict:
    with open(API / kind / f"{name}.json", encoding="utf-8") as f:
        return json.load(f)


@pytest.fixture
def small_body() -> dict:
    """api/bulldoze/mound-box-add.json (a 65 × 65 grid): done in a moment."""
    return example("bulldoze", "mound-box-add")


@pytest.fixture
def long_body() -> dict:
    return long_erode_body()


def long_erode_body() -> dict:
    """An erode job that runs a couple of seconds with a progress event every 50 ms or so:
    api/erode/scree-slopes.json (129 × 129) with 1 000 iterations and no levels of detail."""
    body = example("erode", "scree-slopes")
    body["iterations"] = 1000
    body["lods"] = []
    return body


@pytest.fixture(scope="session")
def finished_job(client: Client):
    """One small bulldoze job run to success, shared by the tests that only read it."""
    job = client.submit("bulldoze", example("bulldoze", "mound-box-add"))
    job.wait(progress=False, timeout=120)
    return job
