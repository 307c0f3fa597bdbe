#!/usr/bin/env python3
"""The API's peak resident memory around one large submission (issue 28: a 63 MB body peaked
at 3.5 GB in the API). Starts `BINARY serve --role api` (no worker: the job stays queued) on
127.0.0.1 with a fresh SQLite file, posts one bulldoze body of about MB megabytes (a pass along
a path of decimal points), and prints the API's VmRSS before and VmHWM after.

    python3 loadtests/submission_peak.py target/release/landform 8
"""
import json
import subprocess
import sys
import tempfile
import time
import urllib.request

binary = sys.argv[1]
megabytes = float(sys.argv[2]) if len(sys.argv) > 2 else 8.0
folder = tempfile.mkdtemp()
server = subprocess.Popen(
    [binary, "serve", "--addr", "127.0.0.1:0", "--database", folder + "/landform.db",
     "--max-body-bytes", "100000000", "--max-operations", "10000000", "--role", "api"],
    stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
try:
    base = server.stdout.readline().strip().split("listening on ")[1]

    def status(field):
        with open(f"/proc/{server.pid}/status") as f:
            for line in f:
                if line.startswith(field):
                    return int(line.split()[1]) * 1024
        raise SystemExit(f"no {field}")

    points = int(megabytes * 1_000_000 / 28)
    path = [{"x": ((i * 2654435761) % 12700) / 100 + 0.05,
             "z": (((i * 2654435761) // 12700) % 12700) / 100 + 0.05} for i in range(points)]
    body = json.dumps({"terrain": {"fractal": {"size": 129}},
                       "operations": [{"pass": {"path": path, "blade": {"width_m": 2.5}, "operator": "replace"}}]}).encode()
    time.sleep(0.3)
    with open(f"/proc/{server.pid}/clear_refs", "w") as f:
        f.write("5")
    before = status("VmRSS")
    request = urllib.request.Request(base + "/v1/jobs/bulldoze", data=body, headers={"content-type": "application/json"})
    with urllib.request.urlopen(request, timeout=120) as reply:
        answer = reply.read()
        code = reply.status
    peak = status("VmHWM")
    print(f"a {len(body) / 1e6:.1f} MB body: {code}, answer {len(answer)} bytes; "
          f"API resident {before / 1e6:.0f} MB before, peak {peak / 1e6:.0f} MB ({peak / len(body):.0f} x the body)")
    if code != 202:
        raise SystemExit("the submission was not accepted")
finally:
    server.kill()
