"""A server-sent-event parser (the WHATWG event-stream format) over lines of text."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Iterable, Iterator, Optional, Union


@dataclass(frozen=True)
class Event:
    """One event: `event` is `progress`, `status` or `done`; `data` the raw text (JSON here)."""

    event: str
    data: str
    id: Optional[str] = None
    retry: Optional[int] = None
    _parsed: list = field(default_factory=list, repr=False, compare=False)

    def json(self) -> Any:
        """`data` parsed as JSON (the progress, the status, or the Job for `done`)."""
        if not self._parsed:
            self._parsed.append(json.loads(self.data))
        return self._parsed[0]


class KeepAlive:
    """A comment line (the server's keep-alive); yielded so a waiting caller may look at the clock."""

    __slots__ = ("text",)

    def __init__(self, text: str):
        self.text = text


def parse(lines: Iterable[str]) -> Iterator[Union[Event, KeepAlive]]:
    """Events from the lines of a stream (without their line ends), as a browser's EventSource
    reads them: `field: value` lines, a blank line ends an event, `:` starts a comment, an event
    with no `data` is not dispatched, and an unfinished event at the end is dropped."""
    data: list[str] = []
    event = ""
    event_id: Optional[str] = None
    retry: Optional[int] = None
    for line in lines:
        if line == "":
            if data:
                yield Event(event=event or "message", data="\n".join(data), id=event_id, retry=retry)
            data, event, retry = [], "", None
            continue
        if line.startswith(":"):
            yield KeepAlive(line[1:].lstrip())
            continue
        name, sep, value = line.partition(":")
        if sep and value.startswith(" "):
            value = value[1:]
        if name == "data":
            data.append(value)
        elif name == "event":
            event = value
        elif name == "id":
            if "\0" not in value:
                event_id = value
        elif name == "retry":
            if value.isdigit():
                retry = int(value)
        # Other fields are ignored, as the format says.
