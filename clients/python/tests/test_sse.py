"""The event-stream parser on its own."""

from landform._sse import Event, KeepAlive, parse


def test_parse_fields_comments_and_multiline_data() -> None:
    lines = [
        ": keep-alive",
        "id: 7",
        "event: progress",
        'data: {"fraction": 0.5,',
        'data:  "stage": "x"}',
        "retry: 1500",
        "",
        "",  # a blank line with no event pending dispatches nothing
        "id: 8",
        "event: done",
        "data: {}",
        "unknown: field",
        "",
        "id: 9",
        "data: cut off before its blank line",
    ]
    items = list(parse(lines))
    assert isinstance(items[0], KeepAlive) and items[0].text == "keep-alive"
    first, second = items[1], items[2]
    assert isinstance(first, Event) and isinstance(second, Event)
    assert (first.id, first.event, first.retry) == ("7", "progress", 1500)
    assert first.json() == {"fraction": 0.5, "stage": "x"}
    assert (second.id, second.event, second.data) == ("8", "done", "{}")
    assert len(items) == 3


def test_event_without_a_name_is_a_message() -> None:
    (event,) = parse(["data:plain", ""])
    assert event.event == "message" and event.data == "plain" and event.id is None
