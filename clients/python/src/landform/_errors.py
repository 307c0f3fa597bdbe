"""Errors: problem+json answers, and jobs that ended without succeeding."""

from __future__ import annotations

import json
from typing import Any, Optional

import httpx

# Members of a problem that have attributes of their own; the rest go to `extra`.
_KNOWN = ("type", "title", "status", "detail", "errors", "instance")


class LandformError(Exception):
    """Every error this package raises on purpose."""


class LandformProblem(LandformError):
    """An `application/problem+json` answer (RFC 9457) from the server.

    `errors` lists the bad fields of a validation problem (422) as the server sends them,
    `[{"field": "operations[0].pass.blade.width_m", "message": "..."}]`; `fields` is their JSON
    paths alone. Members beyond the standard ones (`memory_estimate_bytes`,
    `memory_budget_bytes`, `work_estimate_seconds`, `time_limit_seconds`, …) are in `extra`.
    """

    def __init__(
        self,
        status: int,
        title: str,
        detail: str = "",
        type: str = "about:blank",
        errors: Optional[list] = None,
        *,
        instance: Optional[str] = None,
        extra: Optional[dict] = None,
        headers: Optional[httpx.Headers] = None,
    ):
        self.status = status
        self.title = title
        self.detail = detail
        self.type = type
        self.errors: list[dict[str, Any]] = list(errors or [])
        self.instance = instance
        self.extra: dict[str, Any] = dict(extra or {})
        self.headers = headers if headers is not None else httpx.Headers()
        super().__init__(str(self))

    @property
    def fields(self) -> list[str]:
        """The JSON path of each bad field (validation problems), e.g. `terrain.fractal.size`."""
        return [str(e.get("field", "")) for e in self.errors if isinstance(e, dict)]

    @property
    def retry_after(self) -> Optional[int]:
        """Seconds to wait before trying again (429, 503), when the server said."""
        value = self.headers.get("retry-after")
        return int(value) if value and value.isdigit() else None

    @property
    def problem(self) -> dict[str, Any]:
        """The problem as the server sent it."""
        doc: dict[str, Any] = {"type": self.type, "title": self.title, "status": self.status, "detail": self.detail}
        if self.errors:
            doc["errors"] = self.errors
        if self.instance is not None:
            doc["instance"] = self.instance
        doc.update(self.extra)
        return doc

    def __str__(self) -> str:
        text = f"{self.status} {self.title}"
        if self.detail:
            text += f": {self.detail}"
        for e in self.errors[:5]:
            if isinstance(e, dict):
                text += f"\n  {e.get('field', '?')}: {e.get('message', '')}"
        if len(self.errors) > 5:
            text += f"\n  … and {len(self.errors) - 5} more"
        return text

    def __repr__(self) -> str:
        return f"LandformProblem(status={self.status!r}, title={self.title!r}, fields={self.fields!r})"

    @classmethod
    def from_dict(cls, doc: dict, *, status: Optional[int] = None, headers: Optional[httpx.Headers] = None) -> "LandformProblem":
        return cls(
            status=int(doc.get("status") or status or 0),
            title=str(doc.get("title") or ""),
            detail=str(doc.get("detail") or ""),
            type=str(doc.get("type") or "about:blank"),
            errors=doc.get("errors") if isinstance(doc.get("errors"), list) else None,
            instance=doc.get("instance"),
            extra={k: v for k, v in doc.items() if k not in _KNOWN},
            headers=headers,
        )

    @classmethod
    def from_response(cls, response: httpx.Response) -> "LandformProblem":
        """The problem a response carries; a plain error answer (not problem+json) as one too."""
        try:
            doc = json.loads(response.content)
        except ValueError:
            doc = None
        if isinstance(doc, dict) and ("title" in doc or "type" in doc):
            return cls.from_dict(doc, status=response.status_code, headers=response.headers)
        text = response.text.strip()[:200]
        return cls(
            status=response.status_code,
            title=response.reason_phrase or "HTTP error",
            detail=text,
            headers=response.headers,
        )


class JobError(LandformError):
    """A job that ended without succeeding; `job` is its document, `problem` its `error`."""

    def __init__(self, job: dict):
        self.job = job
        self.problem: Optional[dict] = job.get("error") if isinstance(job.get("error"), dict) else None
        detail = (self.problem or {}).get("detail") or (self.problem or {}).get("title") or ""
        super().__init__(f"job {job.get('id')} {job.get('status')}" + (f": {detail}" if detail else ""))

    @property
    def status(self) -> str:
        return str(self.job.get("status"))


class JobFailed(JobError):
    """The job failed (`status: failed`)."""


class JobCancelled(JobError):
    """The job was cancelled (`status: cancelled`), by a client or its time limit."""
