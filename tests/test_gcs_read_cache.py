"""The read side's cache of encoded documents (gcs.missions.read_cache) and the routes it serves.

- The cache itself: a document is built once per version, rebuilt when the version moves, evicted least
  recently used first.
- GET /missions/{id} and GET /missions answer the same JSON as the response models describe, and never a stale
  one: a write by another storage object on the same database (as a second service instance would write) shows
  at the next request, on SQLite and on PostgreSQL.
"""

from __future__ import annotations

import asyncio

import pytest
from fastapi.testclient import TestClient

from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.domain.planning import FlightParams, make_plan
from gcs.domain.records import MissionProgress
from gcs.domain.schemas import MissionOut, MissionSummary
from gcs.domain.status import MissionStatus
from gcs.missions.read_cache import VersionedCache
from gcs.settings import Settings
from gcs.storage import open_storage
from planner.scenario import reference_scenario


# ----- the cache
def test_a_document_is_built_once_per_version():
    cache, builds = VersionedCache(), []

    def build(text: str):
        async def built() -> bytes:
            builds.append(text)
            return text.encode()

        return built

    def get(version: int, text: str) -> bytes:
        return asyncio.run(cache.get("a", version, build(text)))

    assert get(1, "one") == b"one"
    assert get(1, "again") == b"one"  # same version: the cached bytes
    assert get(2, "two") == b"two"  # the version moved: built again
    assert get(1, "old") == b"old"  # any other version is a miss, older ones too
    assert builds == ["one", "two", "old"]
    assert (cache.hits, cache.misses) == (1, 3)


def test_requests_missing_together_build_the_document_once_and_share_a_failure():
    async def scenario() -> None:
        cache, builds, gate = VersionedCache(), [], asyncio.Event()

        async def build() -> bytes:
            builds.append(1)
            await gate.wait()  # still building while the others ask
            return b"doc"

        waiting = [asyncio.ensure_future(cache.get("m", 7, build)) for _ in range(50)]
        await asyncio.sleep(0)
        gate.set()
        assert await asyncio.gather(*waiting) == [b"doc"] * 50
        assert len(builds) == 1 and cache.lookup("m", 7) == b"doc"

        async def broken() -> bytes:
            builds.append(1)
            await asyncio.sleep(0)
            raise LookupError("no such mission")

        failing = [asyncio.ensure_future(cache.get("m", 8, broken)) for _ in range(3)]
        outcomes = await asyncio.gather(*failing, return_exceptions=True)
        assert all(isinstance(outcome, LookupError) for outcome in outcomes) and len(builds) == 2
        assert await cache.get("m", 8, build) == b"doc"  # nothing left behind: the next request builds again

    asyncio.run(scenario())


def test_least_recently_used_documents_go_first():
    cache = VersionedCache(max_entries=2)
    cache.store("a", 1, b"a")
    cache.store("b", 1, b"b")
    assert cache.lookup("a", 1) == b"a"  # a is now the most recently used
    cache.store("c", 1, b"c")
    assert cache.lookup("b", 1) is None
    assert cache.lookup("a", 1) == b"a" and cache.lookup("c", 1) == b"c"
    assert len(cache) == 2


def test_the_byte_budget_bounds_the_memory_and_keeps_the_newest():
    cache = VersionedCache(max_bytes=100)
    for key in "abcd":
        cache.store(key, 1, bytes(40))
    assert cache.size_bytes <= 100 and len(cache) == 2
    assert cache.lookup("d", 1) is not None and cache.lookup("a", 1) is None
    cache.store("d", 2, bytes(10))  # a new version replaces the old body in the count
    assert cache.size_bytes == 50
    cache.store("huge", 1, bytes(500))  # larger than the budget alone: kept (it was just asked for), the rest go
    assert len(cache) == 1 and cache.lookup("huge", 1) is not None


# ----- the routes, with a second storage object on the same database writing behind the service's back
def store_mission(storage) -> int:
    scenario = reference_scenario(1)
    buoys = [(float(lat), float(lon)) for lat, lon in scenario.buoys_lat_lon]
    plan = make_plan(scenario.home[:2], buoys, [f"B{i + 1}" for i in range(len(buoys))], "exact")
    return storage.create_mission(FlightParams(5.0, 10.0, 1.0, 2.0), plan)


def check_reads_follow_another_writer(client: TestClient, other) -> None:
    mission_id = store_mission(other)
    first = client.get(f"/missions/{mission_id}")
    assert first.status_code == 200 and first.headers["content-type"] == "application/json"
    document = first.json()
    assert MissionOut.model_validate(document).model_dump(mode="json") == document  # the response model's shape
    assert document["status"] == "planned" and document["progress"]["current_seq"] is None  # defaults filled in
    assert client.get(f"/missions/{mission_id}").content == first.content
    listed = client.get("/missions?limit=5").json()
    assert [m["id"] for m in listed] == [mission_id]
    assert MissionSummary.model_validate(listed[0]).model_dump(mode="json") == listed[0]

    other.set_status(mission_id, MissionStatus.FAILED, "written by another instance")
    changed = client.get(f"/missions/{mission_id}").json()
    assert (changed["status"], changed["reason"]) == ("failed", "written by another instance")
    assert [e["status"] for e in changed["events"]] == ["planned", "failed"]
    assert client.get("/missions?limit=5").json()[0]["status"] == "failed"

    other.set_progress(mission_id, MissionProgress(visited=3, buoys=13, reached_at={4: 12.5}))
    changed = client.get(f"/missions/{mission_id}").json()
    assert changed["progress"]["visited"] == 3
    assert changed["buoy_results"][4]["arrival_s"] == 12.5

    second = store_mission(other)
    assert [m["id"] for m in client.get("/missions?limit=5").json()] == [second, mission_id]
    assert [m["id"] for m in client.get("/missions?limit=1").json()] == [second]
    assert client.get(f"/missions/{second + 1}").status_code == 404


def test_reads_follow_another_writer_on_sqlite(tmp_path):
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    with TestClient(create_app(settings)) as client:
        other = open_storage(settings.database)
        try:
            check_reads_follow_another_writer(client, other)
        finally:
            other.close()


@pytest.mark.integration
def test_reads_follow_another_writer_on_postgresql(tmp_path, postgres_url):
    settings = Settings(db=postgres_url, data_dir=tmp_path, vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    with TestClient(create_app(settings)) as client:
        other = open_storage(postgres_url)
        try:
            check_reads_follow_another_writer(client, other)
        finally:
            other.close()


def test_an_unchanged_mission_is_encoded_once(tmp_path):
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    with TestClient(create_app(settings)) as client:
        other = open_storage(settings.database)
        mission_id = store_mission(other)
        other.close()
        documents = client.app.state.service.documents
        before = documents.misses
        bodies = {client.get(f"/missions/{mission_id}").content for _ in range(5)}
        assert len(bodies) == 1 and documents.misses == before + 1
