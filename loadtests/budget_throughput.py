#!/usr/bin/env python3
"""Throughput of many small jobs: admission by memory budget against one job at a time.

Starts the given landform binary twice on 127.0.0.1 (a fresh store each time), submits the
same N small bulldoze jobs from a few client threads, waits until every one has ended, and
prints jobs per second for each setup and their ratio. Bounded: N jobs, one run each, a
timeout per request; traffic only to the servers it starts.

    python3 loadtests/budget_throughput.py target/release/landform [N]
"""

import json
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

BODY = {
    "terrain": {"fractal": {"size": 129, "relief": 40.0, "seed": 3}},
    "operations": [
        {"primitive": {"shape": {"mound": {"center": {"x": 64, "z": 64}, "radius_m": 30, "height_m": 15}},
                       "operator": "add"}},
        {"primitive": {"shape": {"box": {"center": {"x": 40, "z": 90}, "size_x_m": 20, "size_z_m": 10,
                                         "height_m": 5}}, "operator": "subtract"}},
        {"pass": {"path": [{"x": 10, "z": 10}, {"x": 60, "z": 20, "height": 12.0}, {"x": 110, "z": 60},
                           {"x": 120, "z": 120}],
                  "blade": {"width_m": 8, "profile": [[-1, 0.5], [-0.5, 0], [0.5, 0], [1, 0.5]]},
                  "operator": "replace"}},
    ],
}
CLIENTS = 8


def request(base, method, path, body=None, headers=None):
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(base + path, data=data, method=method, headers=headers or {})
    if data is not None:
        req.add_header("content-type", "application/json")
    with urllib.request.urlopen(req, timeout=120) as res:
        return res.status, json.loads(res.read() or b"null")


def run(binary, n, extra):
    with tempfile.TemporaryDirectory() as tmp:
        server = subprocess.Popen(
            [binary, "serve", "--addr", "127.0.0.1:0", "--database", f"{tmp}/landform.db",
             "--queue-capacity", str(n + 16)] + extra,
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            base = server.stdout.readline().strip().removeprefix("listening on ")
            ids, lock = [], threading.Lock()
            per_client = [n // CLIENTS + (1 if i < n % CLIENTS else 0) for i in range(CLIENTS)]

            def client(count, seed0):
                for k in range(count):
                    body = dict(BODY, seed=seed0 + k)
                    status, job = request(base, "POST", "/v1/jobs/bulldoze", body)
                    assert status == 202, job
                    with lock:
                        ids.append(job["id"])

            started = time.monotonic()
            threads = [threading.Thread(target=client, args=(c, 1000 * i)) for i, c in enumerate(per_client)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            for job_id in ids:
                while True:
                    _, job = request(base, "GET", f"/v1/jobs/{job_id}", headers={"prefer": "wait=60"})
                    if job["status"] in ("succeeded", "failed", "cancelled"):
                        assert job["status"] == "succeeded", job
                        break
                    time.sleep(0.01)
            elapsed = time.monotonic() - started
            return n / elapsed, elapsed
        finally:
            server.terminate()
            server.wait(timeout=30)


def main():
    binary = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 200
    one, one_s = run(binary, n, ["--concurrent-jobs", "1"])
    budget, budget_s = run(binary, n, [])
    print(f"{n} small bulldoze jobs, {CLIENTS} clients")
    print(f"  --concurrent-jobs 1:        {one:7.1f} jobs/s  ({one_s:.2f} s)")
    print(f"  admission by memory budget: {budget:7.1f} jobs/s  ({budget_s:.2f} s)")
    print(f"  ratio: {budget / one:.2f}")


if __name__ == "__main__":
    main()
