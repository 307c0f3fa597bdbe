# Landform's HTTP API for the add-on, on the Python standard library alone (Blender's Python
# has no httpx or requests, and an add-on should not pip-install into it). Nothing here imports
# bpy: a `Run` works in a thread of its own while Blender's UI stays responsive, and the panel
# reads its state from a `bpy.app.timers` callback.
import copy
import json
import os
import tempfile
import threading
import time
import urllib.error
import urllib.parse
import urllib.request

DEFAULT_URL = "http://127.0.0.1:8080"
TIMEOUT = 30  # seconds for one request (the server answers polls at once)
POLL = 0.25  # seconds between polls of a running job
USER_AGENT = "landform-blender/0.2"


class ApiError(Exception):
    """A problem+json answer (RFC 9457), or a server that could not be reached.

    `str()` is what the panel shows: the title, the detail and each bad field by its JSON path.
    """

    def __init__(self, status, problem):
        self.status = status
        self.problem = problem if isinstance(problem, dict) else {"title": str(problem)}
        super().__init__(self.message())

    @property
    def fields(self):
        return [e.get("field", "") for e in self.problem.get("errors") or [] if isinstance(e, dict)]

    def message(self):
        p = self.problem
        title = p.get("title") or (f"HTTP {self.status}" if self.status else "Error")
        text = title
        detail = p.get("detail")
        if detail and detail != title:
            text += f": {detail}"
        errors = [e for e in p.get("errors") or [] if isinstance(e, dict)]
        # The detail usually repeats a single field's message; name every field anyway.
        named = [f"{e.get('field', '?')}: {e.get('message', '')}" for e in errors]
        missing = [n for n in named if not detail or n not in detail]
        if missing:
            text += " (" + "; ".join(missing) + ")"
        elif errors:
            text += " [field " + ", ".join(e.get("field", "?") for e in errors) + "]"
        return text


class Client:
    """The routes the add-on calls. `url` is the server's base URL; `api_key`, if any, goes in
    `Authorization: Bearer` (servers run with `--api-keys`)."""

    def __init__(self, url=DEFAULT_URL, api_key="", timeout=TIMEOUT):
        self.url = (url or DEFAULT_URL).strip().rstrip("/")
        if "://" not in self.url:
            self.url = "http://" + self.url
        self.api_key = (api_key or "").strip()
        self.timeout = timeout

    def _headers(self, extra=None):
        headers = {"Accept": "application/json, application/problem+json", "User-Agent": USER_AGENT}
        if self.api_key:
            headers["Authorization"] = f"Bearer {self.api_key}"
        headers.update(extra or {})
        return headers

    def absolute(self, href):
        return urllib.parse.urljoin(self.url + "/", href)

    def _open(self, method, path, body=None, headers=None):
        data = None
        extra = dict(headers or {})
        if body is not None:
            data = json.dumps(body, separators=(",", ":")).encode("utf-8")
            extra["Content-Type"] = "application/json"
        request = urllib.request.Request(self.absolute(path), data=data, method=method, headers=self._headers(extra))
        try:
            return urllib.request.urlopen(request, timeout=self.timeout)
        except urllib.error.HTTPError as error:
            raw = error.read()
            try:
                problem = json.loads(raw.decode("utf-8"))
            except ValueError:
                problem = {"title": f"HTTP {error.code} {error.reason}", "detail": raw.decode("utf-8", "replace")[:300]}
            raise ApiError(error.code, problem) from None
        except (urllib.error.URLError, OSError) as error:
            reason = getattr(error, "reason", error)
            raise ApiError(0, {"title": "Cannot reach the server", "detail": f"{self.url}: {reason}"}) from None

    def _json(self, method, path, body=None, headers=None):
        with self._open(method, path, body, headers) as response:
            raw = response.read()
        return json.loads(raw.decode("utf-8")) if raw else None

    def presets(self, kind=None):
        """`GET /v1/presets[?kind=]`: `[{"kind", "name", "label", "body"}]`, by kind then name."""
        query = "?" + urllib.parse.urlencode({"kind": kind}) if kind else ""
        return self._json("GET", "/v1/presets" + query).get("items", [])

    def submit(self, kind, body):
        """`POST /v1/jobs/{kind}`: the Job (202, queued)."""
        return self._json("POST", "/v1/jobs/" + urllib.parse.quote(kind, safe=""), body)

    def job(self, job_id):
        return self._json("GET", "/v1/jobs/" + urllib.parse.quote(job_id, safe=""))

    def cancel(self, job_id):
        return self._json("POST", "/v1/jobs/" + urllib.parse.quote(job_id, safe="") + "/cancel")

    def download(self, href, path, chunk=1 << 16):
        """Streams an artifact (`artifacts[].href`) to `path`; returns its size."""
        size = 0
        with self._open("GET", href, headers={"Accept": "*/*"}) as response, open(path, "wb") as out:
            while True:
                block = response.read(chunk)
                if not block:
                    break
                out.write(block)
                size += len(block)
        return size


# --- Request bodies -----------------------------------------------------------------------------


def deep_merge(base, override):
    """`override` over `base` as a JSON merge patch (RFC 7396): objects merge member by member,
    a `null` member removes the member (`{"terrain": {"fractal": null, "heightmap": {...}}}`
    swaps a terrain source), anything else replaces (a list too). Neither argument is changed."""
    if not isinstance(override, dict):
        return copy.deepcopy(override)
    merged = copy.deepcopy(base) if isinstance(base, dict) else {}
    for key, value in override.items():
        if value is None:
            merged.pop(key, None)
        else:
            merged[key] = deep_merge(merged.get(key), value)
    return merged


def fractal_of(body):
    """The body's `terrain.fractal` object, or None (a heightmap or job terrain, or no terrain)."""
    terrain = body.get("terrain") if isinstance(body, dict) else None
    fractal = terrain.get("fractal") if isinstance(terrain, dict) else None
    return fractal if isinstance(fractal, dict) else None


def build_body(preset_body, fields, override=None):
    """The body to post: the preset's, then the panel's fields (`seed`; `lods` off → `[]`; the
    fractal terrain's `size`, `cell_size`, `relief` and `seed` as `terrain_seed`, only where the
    preset has a fractal terrain), then the raw JSON override merged over both (`deep_merge`)."""
    body = copy.deepcopy(preset_body or {})
    if fields.get("seed") is not None:
        body["seed"] = int(fields["seed"])
    if fields.get("lods") is False:
        body["lods"] = []
    fractal = fractal_of(body)
    if fractal is not None:
        for name, key in (("size", "size"), ("cell_size", "cell_size"), ("relief", "relief"), ("terrain_seed", "seed")):
            value = fields.get(name)
            if value is not None:
                fractal[key] = value
    if override:
        if not isinstance(override, dict):
            raise ValueError("the JSON override must be an object")
        body = deep_merge(body, override)
    return body


def parse_override(text):
    """A text block's JSON: an object, or None when the text is empty."""
    text = (text or "").strip()
    if not text:
        return None
    try:
        value = json.loads(text)
    except ValueError as error:
        raise ValueError(f"the JSON override is not JSON: {error}") from None
    if not isinstance(value, dict):
        raise ValueError("the JSON override must be a JSON object")
    return value


# --- A run: submit, follow, download ---------------------------------------------------------------

TERMINAL = ("succeeded", "failed", "cancelled")


class Run:
    """One job from submit to downloaded artifacts, its state readable from any thread.

    `start()` runs it in a daemon thread; `run()` runs it in the caller's (the blocking
    operator). The importing is left to the caller, in Blender's main thread: `files` maps
    artifact names to downloaded paths once `state == "downloaded"`.
    """

    # The artifacts a run downloads, when the job made them.
    WANTED = ("mesh.glb", "heightmap.png")

    def __init__(self, client, kind, body, timeout=None):
        self.client = client
        self.kind = kind
        self.body = body
        self.timeout = timeout
        self._lock = threading.Lock()
        self.state = "submitting"  # → running → downloading → downloaded | failed | cancelled | error
        self.job_id = None
        self.job = None
        self.fraction = 0.0
        self.stage = "submitting"
        self.message = ""
        self.error = None  # an ApiError or a message
        self.files = {}
        self.dir = None
        self._cancel = threading.Event()
        self._thread = None

    def snapshot(self):
        with self._lock:
            return {
                "state": self.state,
                "job_id": self.job_id,
                "fraction": self.fraction,
                "stage": self.stage,
                "message": self.message,
                "error": self.error,
            }

    def _set(self, **values):
        with self._lock:
            for key, value in values.items():
                setattr(self, key, value)

    @property
    def finished(self):
        return self.state in ("downloaded", "failed", "cancelled", "error")

    def start(self):
        self._thread = threading.Thread(target=self._guarded, name="landform-run", daemon=True)
        self._thread.start()
        return self

    def join(self, timeout=None):
        if self._thread is not None:
            self._thread.join(timeout)

    def cancel(self):
        """Asks the server to cancel (`POST /v1/jobs/{id}/cancel`); the run then ends `cancelled`."""
        self._cancel.set()
        job_id = self.job_id
        if job_id:
            self.client.cancel(job_id)

    def run(self):
        self._guarded()
        return self

    def _guarded(self):
        try:
            self._run()
        except ApiError as error:
            self._set(state="error", error=error, message=str(error))
        except Exception as error:  # a bug or a broken download: shown, never a dead thread
            self._set(state="error", error=error, message=f"{type(error).__name__}: {error}")

    def _run(self):
        job = self.client.submit(self.kind, self.body)
        self._set(job_id=job["id"], job=job, state="running")
        if self._cancel.is_set():
            self.client.cancel(job["id"])
        started = time.monotonic()
        while job["status"] not in TERMINAL:
            self._progress(job)
            if self.timeout is not None and time.monotonic() - started > self.timeout:
                raise ApiError(0, {"title": "Timed out", "detail": f"job {job['id']} still {job['status']}"})
            time.sleep(POLL)
            job = self.client.job(job["id"])
        self._progress(job)
        self._set(job=job)
        if job["status"] != "succeeded":
            problem = job.get("error") or {"title": f"Job {job['status']}"}
            self._set(state=job["status"], error=ApiError(problem.get("status", 0), problem))
            self._set(message=str(self.error))
            return
        self._set(state="downloading", stage="downloading", message="mesh.glb")
        self.dir = tempfile.mkdtemp(prefix="landform-")
        files = {}
        for artifact in job.get("artifacts", []):
            if artifact.get("name") in self.WANTED and artifact.get("href"):
                path = os.path.join(self.dir, job["id"] + "-" + artifact["name"])
                self.client.download(artifact["href"], path)
                files[artifact["name"]] = path
        if "mesh.glb" not in files:
            raise ApiError(0, {"title": "No mesh", "detail": f"job {job['id']} has no mesh.glb artifact"})
        self._set(files=files, state="downloaded", fraction=1.0, stage="done", message="downloaded")

    def _progress(self, job):
        progress = job.get("progress") or {}
        stage = progress.get("stage") or job.get("status", "")
        message = progress.get("message") or ""
        steps = progress.get("steps") or 0
        if steps:
            message = f"{message} ({progress.get('step', 0)}/{steps})".strip()
        fraction = float(progress.get("fraction") or 0.0)
        self._set(fraction=max(0.0, min(1.0, fraction)), stage=stage, message=message)

    def cleanup(self):
        """Removes the downloaded files (after importing: the heightmap image is packed)."""
        if self.dir and os.path.isdir(self.dir):
            for name in os.listdir(self.dir):
                try:
                    os.remove(os.path.join(self.dir, name))
                except OSError:
                    pass
            try:
                os.rmdir(self.dir)
            except OSError:
                pass
