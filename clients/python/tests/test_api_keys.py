"""A server started with `--api-keys`: the key goes as `Authorization: Bearer`."""

from __future__ import annotations

import pytest

from landform import LandformProblem

from conftest import make_client


def test_without_a_key_is_401(keyed_server, small_body: dict) -> None:
    anonymous = make_client(keyed_server.url)
    with pytest.raises(LandformProblem) as e:
        anonymous.submit("bulldoze", small_body)
    assert e.value.status == 401
    assert e.value.headers.get("www-authenticate", "").lower().startswith("bearer")
    with pytest.raises(LandformProblem) as e:
        anonymous.jobs()
    assert e.value.status == 401
    wrong = make_client(keyed_server.url, api_key="not-a-key-of-this-server")
    with pytest.raises(LandformProblem) as e:
        wrong.jobs()
    assert e.value.status == 401


def test_with_a_key(keyed_server, api_keys, small_body: dict) -> None:
    alice = make_client(keyed_server.url, api_key=api_keys[0])
    job = alice.submit("bulldoze", small_body, idempotency_key="same")
    doc = job.wait(progress=False, timeout=120)
    assert doc["status"] == "succeeded"
    assert job.artifact("mesh.glb")[:4] == b"glTF"
    assert [e.event for e in job.events()] == ["done"]
    assert job.id in {j["id"] for j in alice.jobs()["items"]}

    # Another key neither sees the job nor shares its idempotency keys.
    bob = make_client(keyed_server.url, api_key=api_keys[1])
    with pytest.raises(LandformProblem) as e:
        bob.job(job.id)
    assert e.value.status == 404
    assert bob.submit("bulldoze", small_body, idempotency_key="same").id != job.id
