"""The client against a real server: submit, wait, events, download, replay, cancel, errors."""

from __future__ import annotations

import socket
import struct
import threading
import time
import uuid

import httpx
import pytest

from landform import Client, Job, JobCancelled, LandformProblem, types

from conftest import make_client


def glb_header(data: bytes) -> tuple[bytes, int, int]:
    magic, version, length = struct.unpack("<4sII", data[:12])
    return magic, version, length


def test_submit_wait_download(client: Client, small_body: dict, tmp_path) -> None:
    job = client.submit("bulldoze", small_body)
    assert isinstance(job, Job) and job.document["status"] in ("queued", "running", "succeeded")
    doc = job.wait(progress=True, timeout=120)
    assert doc["status"] == "succeeded"
    assert doc["progress"]["fraction"] == pytest.approx(1.0)
    names = {a["name"] for a in doc["artifacts"]}
    assert {"mesh.glb", "heightmap.png", "sequence.json"} <= names

    data = job.artifact("mesh.glb")
    assert isinstance(data, bytes)
    magic, version, length = glb_header(data)
    assert (magic, version, length) == (b"glTF", 2, len(data))

    saved = job.artifact("mesh.glb", tmp_path / "mesh.glb")
    assert saved.read_bytes() == data
    into_folder = job.artifact("heightmap.png", tmp_path)
    assert into_folder == tmp_path / "heightmap.png"
    assert into_folder.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    assert client.job(job.id).document["status"] == "succeeded"
    assert job.sequence()["generator"]["kind"] == "bulldoze"


def test_submit_with_prefer_wait(client: Client, small_body: dict) -> None:
    job = client.submit("bulldoze", small_body, wait=50)
    assert job.document["status"] == "succeeded"


def test_events_progress_done_and_resume(client: Client, long_body: dict) -> None:
    job = client.submit("erode", long_body)
    first = []
    for event in job.events():
        first.append(event)
        if len(first) == 3 or event.event == "done":
            break
    assert first[0].event in ("progress", "status"), first
    resume_after = first[-1].id
    assert resume_after is not None and resume_after.isdigit()

    rest = list(job.events(last_event_id=resume_after))
    assert rest, "the resumed stream sent nothing"
    assert rest[-1].event == "done"
    assert rest[-1].json()["id"] == job.id
    assert rest[-1].json()["status"] == "succeeded"
    assert all(int(e.id) > int(resume_after) for e in rest), [e.id for e in rest]
    ids = [int(e.id) for e in first + rest]
    assert ids == sorted(ids) and len(set(ids)) == len(ids)
    progress = [e.json() for e in first + rest if e.event == "progress"]
    assert progress, "no progress event"
    assert all(0.0 <= p["fraction"] <= 1.0 and "stage" in p for p in progress)

    # A finished job's stream is its `done` alone.
    again = list(job.events())
    assert [e.event for e in again] == ["done"]


class CuttingProxy:
    """A TCP proxy on 127.0.0.1 that cuts its first connection after `cut_after` bytes of the
    server's answer, and records each request's head."""

    def __init__(self, upstream: str, cut_after: int):
        host, port = upstream.removeprefix("http://").rsplit(":", 1)
        self.upstream = (host, int(port))
        self.cut_after = cut_after
        self.requests: list[str] = []
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self.listener.getsockname()[1]}"
        threading.Thread(target=self.accept, daemon=True).start()

    def accept(self) -> None:
        while True:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                return
            first = not self.requests
            self.requests.append("")
            threading.Thread(target=self.serve, args=(conn, len(self.requests) - 1, first), daemon=True).start()

    def serve(self, conn: socket.socket, index: int, cut: bool) -> None:
        up = socket.create_connection(self.upstream)

        def upward() -> None:
            try:
                while data := conn.recv(65536):
                    self.requests[index] += data.decode("latin-1")
                    up.sendall(data)
            except OSError:
                pass

        threading.Thread(target=upward, daemon=True).start()
        sent = 0
        try:
            while data := up.recv(65536):
                if cut and sent + len(data) >= self.cut_after:
                    conn.sendall(data[: max(0, self.cut_after - sent)])
                    break
                conn.sendall(data)
                sent += len(data)
        except OSError:
            pass
        finally:
            # shutdown, not only close: the other thread's recv must end, and the client see EOF.
            for sock in (conn, up):
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                sock.close()

    def close(self) -> None:
        self.listener.close()


def test_events_resume_after_dropped_connection(server, long_body: dict) -> None:
    direct = make_client(server.url)
    job = direct.submit("erode", long_body)
    proxy = CuttingProxy(server.url, cut_after=900)
    try:
        through = make_client(proxy.url)
        events = list(Job(through, job.document).events())
    finally:
        proxy.close()
    assert events[-1].event == "done" and events[-1].json()["status"] == "succeeded"
    ids = [int(e.id) for e in events]
    assert ids == sorted(ids) and len(set(ids)) == len(ids), ids
    assert len(proxy.requests) >= 2, "the stream was not opened again"
    resumed = proxy.requests[1].lower()
    assert "last-event-id: " in resumed
    resumed_from = int(resumed.split("last-event-id: ")[1].split("\r\n")[0])
    assert resumed_from in ids and resumed_from < ids[-1]


def test_replay(client: Client, finished_job: Job) -> None:
    doc = finished_job.status()
    steps = doc["result"]["sequence_steps"]
    assert steps >= 1
    partial = finished_job.replay(until_step=1)
    assert partial.id != finished_job.id
    pdoc = partial.wait(progress=False, timeout=120)
    assert pdoc["replay_of"] == finished_job.id
    assert pdoc["replay_until_step"] == 1

    whole = finished_job.replay()
    wdoc = whole.wait(progress=False, timeout=120)
    original = {a["name"]: a["sha256"] for a in doc["artifacts"]}
    replayed = {a["name"]: a["sha256"] for a in wdoc["artifacts"]}
    assert replayed["mesh.glb"] == original["mesh.glb"]

    with pytest.raises(LandformProblem) as e:
        finished_job.replay(until_step=steps + 1)
    assert e.value.status == 422 and "until_step" in e.value.fields


def test_cancel_running_job(client: Client, long_body: dict) -> None:
    job = client.submit("erode", long_body)
    deadline = time.monotonic() + 60
    while job.status()["status"] == "queued" and time.monotonic() < deadline:
        time.sleep(0.05)
    assert job.document["status"] == "running", job.document["status"]
    after = job.cancel()
    assert after["id"] == job.id
    with pytest.raises(JobCancelled) as e:
        job.wait(progress=False, timeout=60)
    assert e.value.job["status"] == "cancelled"
    assert job.status()["status"] == "cancelled"
    with pytest.raises(LandformProblem) as again:
        job.cancel()
    assert again.value.status == 409


def test_invalid_field_is_a_problem(client: Client, small_body: dict) -> None:
    small_body["terrain"]["fractal"]["size"] = 1
    with pytest.raises(LandformProblem) as e:
        client.submit("bulldoze", small_body)
    problem = e.value
    assert problem.status == 422
    assert problem.title and problem.type and problem.detail
    assert "terrain.fractal.size" in problem.fields, problem.errors
    assert all("message" in err for err in problem.errors)
    assert "terrain.fractal.size" in str(problem)


def test_unknown_job_and_kind(server, client: Client, small_body: dict) -> None:
    with pytest.raises(LandformProblem) as e:
        client.job(str(uuid.uuid4()))
    assert e.value.status == 404
    # A client of its own: the route it calls is not one of the spec's (see test_spec.py).
    with Client(server.url) as other, pytest.raises(LandformProblem) as e:
        other.submit("no-such-kind", small_body)
    assert e.value.status == 404


def test_idempotency_key(client: Client, small_body: dict) -> None:
    key = f"py-{uuid.uuid4()}"
    first = client.submit("bulldoze", small_body, idempotency_key=key)
    second = client.submit("bulldoze", small_body, idempotency_key=key)
    assert second.id == first.id
    other = dict(small_body, label="another body")
    with pytest.raises(LandformProblem) as e:
        client.submit("bulldoze", other, idempotency_key=key)
    assert e.value.status == 409
    third = client.submit("bulldoze", small_body, idempotency_key=key + "-b")
    assert third.id != first.id


def test_list_jobs(client: Client, finished_job: Job) -> None:
    page = client.jobs(kind="bulldoze", status="succeeded", limit=1)
    assert len(page["items"]) == 1
    assert page["items"][0]["kind"] == "bulldoze"
    everything = list(client.iter_jobs(kind="bulldoze", page_size=2))
    assert finished_job.id in {j.id for j in everything}
    ids = [j.id for j in everything]
    assert ids == sorted(ids, reverse=True)
    assert client.healthy()


def test_presets_and_replays_left_out(client: Client, finished_job: Job) -> None:
    presets = client.presets("bulldoze")
    assert len(presets) >= 5 and all(p["kind"] == "bulldoze" for p in presets)
    assert {p["name"] for p in presets} >= {"ziggurat"}
    body = client.preset("bulldoze", "ziggurat")
    assert "operations" in body
    every = client.presets()
    assert {p["kind"] for p in every} == set(types.KINDS)
    with pytest.raises(LandformProblem) as e:
        client.presets("nope")
    assert e.value.status == 422 and e.value.fields == ["kind"]
    replay = finished_job.replay(until_step=0)
    replay.wait(progress=False)
    originals = client.jobs(replays=False, limit=100)["items"]
    assert originals and all(j.get("replay_of") is None for j in originals)
    assert replay.id in {j["id"] for j in client.jobs(limit=100)["items"]}


def test_events_wait_out_a_busy_server_while_reconnecting() -> None:
    # A stand-in server: the event stream is refused twice (503 with Retry-After: 0, then a
    # proxy's 502 page), then sent; the client waits both out and resumes after the last id.
    seen: list = []

    def handler(request: httpx.Request) -> httpx.Response:
        seen.append((request.url.path, request.headers.get("last-event-id")))
        if request.url.path.endswith("/events"):
            n = sum(1 for p, _ in seen if p.endswith("/events"))
            if n == 1:
                return httpx.Response(200, headers={"content-type": "text/event-stream"}, content=b"id: 4\nevent: progress\ndata: {}\n\n")
            if n == 2:
                return httpx.Response(503, headers={"retry-after": "0", "content-type": "application/problem+json"}, json={"type": "about:blank", "title": "Busy", "status": 503, "detail": "busy"})
            if n == 3:
                return httpx.Response(502, headers={"content-type": "text/html"}, content=b"<html>bad gateway</html>")
            return httpx.Response(200, headers={"content-type": "text/event-stream"}, content=b'id: 5\nevent: done\ndata: {"id": "j", "status": "succeeded"}\n\n')
        return httpx.Response(404, json={"type": "about:blank", "title": "Not found", "status": 404, "detail": "no"})

    client = Client("http://stand-in", transport=httpx.MockTransport(handler))
    job = Job(client, {"id": "j", "kind": "bulldoze", "status": "running"})
    events = [e for e in job.events() if hasattr(e, "event")]
    assert [(e.event, e.id) for e in events] == [("progress", "4"), ("done", "5")]
    assert [h for p, h in seen if p.endswith("/events")] == [None, "4", "4", "4"]
    # Anything else is the caller's to see at once.
    def refusing(request: httpx.Request) -> httpx.Response:
        return httpx.Response(404, json={"type": "about:blank", "title": "Not found", "status": 404, "detail": "no"})
    gone = Job(Client("http://stand-in", transport=httpx.MockTransport(refusing)), {"id": "j", "status": "running"})
    with pytest.raises(LandformProblem):
        list(gone.events())
