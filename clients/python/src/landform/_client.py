"""The client: `Client` for the service, `Job` for one job."""

from __future__ import annotations

import hashlib
import os
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Mapping, Optional, Union, cast
from urllib.parse import quote

import httpx

from . import _types
from ._errors import JobCancelled, JobFailed, LandformError, LandformProblem
from ._sse import Event, KeepAlive, parse

JobDocument = _types.Job
JobPage = _types.JobPage

# Every route the client calls: name -> (method, path template). `{kind}` is one of the kinds'
# own paths (`/v1/jobs/bulldoze`, …); the tests check each against openapi.yaml.
ROUTES: dict[str, tuple[str, str]] = {
    "submit": ("POST", "/v1/jobs/{kind}"),
    "list": ("GET", "/v1/jobs"),
    "get": ("GET", "/v1/jobs/{id}"),
    "delete": ("DELETE", "/v1/jobs/{id}"),
    "events": ("GET", "/v1/jobs/{id}/events"),
    "artifact": ("GET", "/v1/jobs/{id}/artifacts/{name}"),
    "live": ("GET", "/v1/jobs/{id}/live.png"),
    "sequence": ("GET", "/v1/jobs/{id}/sequence"),
    "replay": ("POST", "/v1/jobs/{id}/replay"),
    "cancel": ("POST", "/v1/jobs/{id}/cancel"),
    "presets": ("GET", "/v1/presets"),
    "healthz": ("GET", "/healthz"),
}

TERMINAL = ("succeeded", "failed", "cancelled")

# Statuses an event stream's reconnection waits out rather than ends on: rate limits and a busy
# or restarting server or proxy.
_PASSING = (429, 502, 503, 504)

# The server sends a keep-alive comment every 15 s on an idle event stream.
_STREAM_READ_TIMEOUT = 60.0


class Client:
    """A Landform server.

        client = Client("http://127.0.0.1:8080", api_key="…")
        job = client.submit("bulldoze", body)
        job.wait()
        job.artifact("mesh.glb", "out/mesh.glb")

    `api_key` is sent as `Authorization: Bearer KEY` (servers started with `--api-keys`).
    `timeout` (seconds) bounds each request; event streams wait at least a minute between reads.
    """

    def __init__(
        self,
        base_url: str,
        api_key: Optional[str] = None,
        timeout: float = 30.0,
        *,
        headers: Optional[Mapping[str, str]] = None,
        transport: Optional[httpx.BaseTransport] = None,
    ):
        all_headers = {"user-agent": "landform-python", "accept": "application/json, application/problem+json"}
        all_headers.update(headers or {})
        if api_key:
            all_headers["authorization"] = f"Bearer {api_key}"
        self.base_url = base_url.rstrip("/")
        self.timeout = timeout
        self._http = httpx.Client(base_url=self.base_url, headers=all_headers, timeout=timeout, transport=transport)
        # (method, path template) of every request made, kinds' paths written out.
        self.calls: set[tuple[str, str]] = set()

    # -- plumbing -----------------------------------------------------------------------------

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _url(self, route: str, params: Mapping[str, str]) -> tuple[str, str]:
        method, template = ROUTES[route]
        if "kind" in params:
            template = template.replace("{kind}", params["kind"])
        self.calls.add((method, template))
        path = template
        for name, value in params.items():
            # Artifact names may hold folders (`tiles/0/1_2.glb`): their slashes stay.
            path = path.replace("{" + name + "}", quote(str(value), safe="/" if name == "name" else ""))
        return method, path

    def _request(
        self,
        route: str,
        params: Optional[Mapping[str, str]] = None,
        *,
        json: Any = None,
        content: Optional[bytes] = None,
        headers: Optional[Mapping[str, str]] = None,
        query: Optional[Mapping[str, Any]] = None,
        timeout: Optional[float] = None,
    ) -> httpx.Response:
        method, path = self._url(route, params or {})
        kwargs: dict[str, Any] = {}
        if json is not None:
            kwargs["json"] = json
        elif content is not None:
            kwargs["content"] = content
        response = self._http.request(
            method,
            path,
            headers=headers,
            params={k: v for k, v in (query or {}).items() if v is not None},
            timeout=timeout if timeout is not None else httpx.USE_CLIENT_DEFAULT,
            **kwargs,
        )
        if response.status_code >= 400:
            raise LandformProblem.from_response(response)
        return response

    @contextmanager
    def _stream(
        self, route: str, params: Mapping[str, str], *, headers: Optional[Mapping[str, str]] = None, read_timeout: Optional[float] = None
    ) -> Iterator[httpx.Response]:
        method, path = self._url(route, params)
        timeout = httpx.Timeout(self.timeout, read=max(self.timeout, read_timeout or 0.0))
        with self._http.stream(method, path, headers=headers, timeout=timeout) as response:
            if response.status_code >= 400:
                response.read()
                raise LandformProblem.from_response(response)
            yield response

    # -- the service --------------------------------------------------------------------------

    def submit(
        self,
        kind: str,
        body: Mapping[str, Any],
        idempotency_key: Optional[str] = None,
        *,
        wait: Optional[int] = None,
    ) -> "Job":
        """Submit a job of `kind` (one of `landform.KINDS`) with its parameters.

        `idempotency_key`: the same key with the same body returns the job made the first time
        (with another body the server answers 409). `wait` (seconds, at most 60) asks the
        server to hold the answer until the job ends or that time passes (`Prefer: wait=N`).
        """
        headers = {}
        if idempotency_key is not None:
            headers["Idempotency-Key"] = idempotency_key
        if wait is not None:
            headers["Prefer"] = f"wait={int(wait)}"
        response = self._request(
            "submit",
            {"kind": kind},
            json=dict(body),
            headers=headers,
            timeout=self.timeout + wait if wait is not None else None,
        )
        return Job(self, response.json())

    def job(self, id: str) -> "Job":
        """The job with this id (fetched: an unknown id raises a 404 `LandformProblem`)."""
        return Job(self, self._request("get", {"id": id}).json())

    def jobs(
        self,
        kind: Optional[str] = None,
        status: Optional[str] = None,
        limit: Optional[int] = None,
        cursor: Optional[str] = None,
        replays: Optional[bool] = None,
    ) -> JobPage:
        """One page of jobs, newest first: `{"items": [...], "next_cursor": id or None}`;
        `replays=False` leaves replays out (filtered by the server)."""
        query = {"kind": kind, "status": status, "limit": limit, "cursor": cursor}
        if replays is not None:
            query["replays"] = "true" if replays else "false"
        return cast(JobPage, self._request("list", query=query).json())

    def iter_jobs(self, kind: Optional[str] = None, status: Optional[str] = None, page_size: int = 100) -> Iterator["Job"]:
        """Every job (of a kind, in a status), newest first, following the pages' cursors."""
        cursor = None
        while True:
            page = self.jobs(kind=kind, status=status, limit=page_size, cursor=cursor)
            for item in page["items"]:
                yield Job(self, item)
            cursor = page.get("next_cursor")
            if not cursor:
                return

    def presets(self, kind: Optional[str] = None) -> list[dict[str, Any]]:
        """The server's example requests (`{"kind", "name", "label", "body"}`), of one kind or all."""
        return list(self._request("presets", query={"kind": kind}).json()["items"])

    def preset(self, kind: str, name: str) -> dict[str, Any]:
        """The body of the example `name` of `kind`, ready for `submit(kind, body)`."""
        for p in self.presets(kind):
            if p["name"] == name:
                return dict(p["body"])
        raise LandformError(f"the server has no {kind} preset {name!r}")

    def healthy(self) -> bool:
        """Whether the server answers its health check."""
        try:
            return self._request("healthz").status_code == 200
        except (httpx.HTTPError, LandformProblem):
            return False


class Job:
    """One job on the server. `document` is its last-seen job document (see `status()`)."""

    def __init__(self, client: Client, document: Mapping[str, Any]):
        self.client = client
        self.document: JobDocument = cast(JobDocument, dict(document))
        self.id: str = str(document["id"])

    def __repr__(self) -> str:
        return f"Job({self.id!r}, kind={self.document.get('kind')!r}, status={self.document.get('status')!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Job) and other.id == self.id

    def __hash__(self) -> int:
        return hash(self.id)

    def status(self) -> JobDocument:
        """GET the job: its document (`status`, `progress`, `request`, `result`, `artifacts`, …)."""
        self.document = cast(JobDocument, self.client._request("get", {"id": self.id}).json())
        return self.document

    refresh = status

    def wait(self, progress: Union[bool, Mapping[str, Any]] = True, timeout: Optional[float] = None) -> JobDocument:
        """Follow the job to its end and return its final document.

        Shows a tqdm progress bar (to stderr) from the progress the server reports when
        `progress` is true (a mapping: keyword arguments for `tqdm`). Raises `JobFailed` or
        `JobCancelled` when the job did not succeed, `TimeoutError` after `timeout` seconds.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        bar = None
        if progress:
            from tqdm.auto import tqdm

            options: dict[str, Any] = {"total": 100, "unit": "%", "desc": self.document.get("kind", "job"), "leave": True,
                                       "bar_format": "{desc}: {percentage:3.0f}%|{bar}| {elapsed}{postfix}"}
            if isinstance(progress, Mapping):
                options.update(progress)
            bar = tqdm(**options)
        try:
            for item in self._follow(self.document.get("status") not in TERMINAL):
                if deadline is not None and time.monotonic() > deadline:
                    raise TimeoutError(f"job {self.id} did not end within {timeout} s")
                if isinstance(item, KeepAlive):
                    continue
                data = _json_or_none(item)
                if bar is not None and item.event == "progress" and isinstance(data, dict):
                    fraction = data.get("fraction")
                    if isinstance(fraction, (int, float)):
                        bar.n = max(0.0, min(100.0, round(100.0 * fraction, 1)))
                    stage, message = data.get("stage"), data.get("message")
                    kind = self.document.get("kind", "job")
                    if stage:
                        # A kind's first stage is often named for the kind: not twice.
                        bar.set_description_str(kind if stage == kind else f"{kind} {stage}", refresh=False)
                    bar.set_postfix_str(str(message or "")[:60], refresh=False)
                    bar.refresh()
                elif bar is not None and item.event == "status" and isinstance(data, dict):
                    bar.set_postfix_str(str(data.get("status", "")), refresh=True)
                if item.event == "done":
                    break
            final = self.status()
            if final["status"] not in TERMINAL:  # the stream ended early: poll to the end
                while final["status"] not in TERMINAL:
                    if deadline is not None and time.monotonic() > deadline:
                        raise TimeoutError(f"job {self.id} did not end within {timeout} s")
                    time.sleep(0.5)
                    final = self.status()
            if bar is not None and final["status"] == "succeeded":
                bar.n = 100
                bar.set_postfix_str("succeeded", refresh=True)
        finally:
            if bar is not None:
                bar.close()
        if final["status"] == "failed":
            raise JobFailed(dict(final))
        if final["status"] == "cancelled":
            raise JobCancelled(dict(final))
        return final

    def events(
        self,
        last_event_id: Optional[Union[str, int]] = None,
        *,
        reconnect: bool = True,
        max_reconnects: int = 5,
    ) -> Iterator[Event]:
        """The job's server-sent events: `progress`, `status` on each change, and a final `done`
        carrying the job, after which the stream (and this generator) ends.

        `last_event_id` resumes after that event (`Last-Event-ID`): only later events come.
        When the connection drops before `done`, it is opened again with the id of the last
        event received (up to `max_reconnects` times in a row without a new event).
        """
        for item in self._events(last_event_id, reconnect=reconnect, max_reconnects=max_reconnects):
            if isinstance(item, Event):
                yield item

    def _follow(self, live: bool) -> Iterator[Union[Event, KeepAlive]]:
        if not live:
            return iter(())
        return self._events(None, reconnect=True, max_reconnects=5)

    def _events(self, last_event_id: Optional[Union[str, int]], *, reconnect: bool, max_reconnects: int) -> Iterator[Union[Event, KeepAlive]]:
        last = None if last_event_id is None else str(last_event_id)
        failures = 0
        delay = 0.25
        while True:
            headers = {"accept": "text/event-stream", "cache-control": "no-cache"}
            if last is not None:
                headers["Last-Event-ID"] = last
            error: Optional[BaseException] = None
            wait_for: Optional[float] = None
            try:
                with self.client._stream("events", {"id": self.id}, headers=headers, read_timeout=_STREAM_READ_TIMEOUT) as response:
                    for item in parse(response.iter_lines()):
                        if isinstance(item, Event):
                            if item.id is not None:
                                last = item.id
                            if item.retry is not None:
                                delay = item.retry / 1000.0
                            failures = 0
                            if item.event == "done":
                                _update_from_done(self, item)
                                yield item
                                return
                        yield item
            except httpx.TransportError as e:  # dropped, refused, timed out: resume
                error = e
            except LandformProblem as e:  # busy, or a proxy between: wait it out and resume
                if e.status not in _PASSING:
                    raise
                error = e
                if e.retry_after is not None:
                    wait_for = float(min(e.retry_after, 60))
            if not reconnect or failures >= max_reconnects:
                if error is not None:
                    raise error
                raise LandformError(f"the event stream of job {self.id} ended before its `done` event")
            failures += 1
            time.sleep(wait_for if wait_for is not None else min(delay * failures, 5.0))

    def artifact(self, name: str, path: Union[str, "os.PathLike[str]", None] = None, *, verify: bool = True) -> Union[bytes, Path]:
        """Download an artifact (`mesh.glb`, `heightmap.png`, `tiles/0/0_0.glb`, …), streamed.

        With `path`, the bytes go to that file (or into that folder under the artifact's base
        name) and the path is returned; else the bytes are. With `verify`, the bytes' sha256
        is checked against the ETag the server sends.
        """
        with self.client._stream("artifact", {"id": self.id, "name": name}, read_timeout=self.client.timeout) as response:
            digest = hashlib.sha256()
            etag = response.headers.get("etag", "").strip('"')
            if path is None:
                chunks = []
                for chunk in response.iter_bytes():
                    digest.update(chunk)
                    chunks.append(chunk)
                data: Union[bytes, Path] = b"".join(chunks)
            else:
                target = Path(path)
                if target.is_dir():
                    target = target / Path(name).name
                partial = target.with_name(target.name + ".part")
                try:
                    with open(partial, "wb") as f:
                        for chunk in response.iter_bytes():
                            digest.update(chunk)
                            f.write(chunk)
                    os.replace(partial, target)
                finally:
                    if partial.exists():
                        partial.unlink()
                data = target
        if verify and len(etag) == 64 and digest.hexdigest() != etag:
            raise LandformError(f"artifact {name} of job {self.id}: sha256 {digest.hexdigest()} is not the ETag {etag}")
        return data

    def sequence(self) -> dict:
        """The recorded operation sequence (`sequence.json`)."""
        return cast(dict, self.client._request("sequence", {"id": self.id}).json())

    def live_png(self) -> bytes:
        """The latest live snapshot while the job runs (its preview once it has succeeded)."""
        return self.client._request("live", {"id": self.id}).content

    def replay(self, until_step: Optional[int] = None, *, wait: Optional[int] = None) -> "Job":
        """A new job rebuilding this one's result from its recorded sequence, whole or up to
        `until_step` (at most `result.sequence_steps`)."""
        headers = {"Prefer": f"wait={int(wait)}"} if wait is not None else None
        body = {"until_step": until_step} if until_step is not None else {}
        response = self.client._request(
            "replay",
            {"id": self.id},
            json=body,
            headers=headers,
            timeout=self.client.timeout + wait if wait is not None else None,
        )
        return Job(self.client, response.json())

    def cancel(self) -> JobDocument:
        """Stop the job (queued or running; a running job stops at its next step): its document."""
        self.document = cast(JobDocument, self.client._request("cancel", {"id": self.id}).json())
        return self.document

    def delete(self) -> None:
        """Remove the job and its artifacts (cancelling it first if it runs)."""
        self.client._request("delete", {"id": self.id})


def _json_or_none(event: Event) -> Any:
    try:
        return event.json()
    except ValueError:
        return None


def _update_from_done(job: Job, event: Event) -> None:
    data = _json_or_none(event)
    if isinstance(data, dict) and data.get("id") == job.id and not data.get("request_omitted"):
        job.document = cast(JobDocument, data)
