"""Storage: migrations, transitions with history, telemetry, restart, all-or-nothing writes, and the change
counter, on both backends (SQLite and a real PostgreSQL server); then what only one of them has."""

from __future__ import annotations

import dataclasses
import json
import sqlite3
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import psycopg
import pytest
from stored_missions import FLIGHT, PLAN

from gcs.domain.fleet_coordination import Reshare
from gcs.domain.inspection import InspectionRecord, StoredFrame
from gcs.domain.records import MissionProgress, MissionResults
from gcs.domain.schemas import SeparationOut, TrackingFigures
from gcs.missions.inspector import not_inspected
from gcs.storage import MIGRATIONS, ConstraintError, FramesFullError, Storage, StorageError, open_storage
from gcs.storage.postgres import VERSION_LOCK

TRACKING = TrackingFigures(
    legs=[], rms_cross_track_m=0.5, max_cross_track_m=0.9, distance_flown_m=120.0, planned_length_m=118.0,
    flight_time_s=14.0,
)  # fmt: skip
THREAD_DEADLINE_S = 120.0  # generous: the machine may be loaded; a correct run takes a second or two


@pytest.fixture
def open_db(database: str | Path) -> Iterator[Callable[[], Storage]]:
    """Opens the test's database (as many times as a test asks); closes them all at the end."""
    opened: list[Storage] = []

    def open_it() -> Storage:
        opened.append(open_storage(database))
        return opened[-1]

    yield open_it
    for storage in opened:
        storage.close()


@pytest.fixture
def storage(open_db: Callable[[], Storage]) -> Storage:
    return open_db()


def raw_connection(database: str | Path) -> sqlite3.Connection | psycopg.Connection:
    """The driver's own connection, in autocommit mode, for setting a database up as another version left it."""
    if isinstance(database, Path):
        return sqlite3.connect(database, isolation_level=None)
    return psycopg.connect(database, autocommit=True)


def database_at_version(database: str | Path, schema_version: int) -> sqlite3.Connection | psycopg.Connection:
    """The database as a service of `schema_version` left it, with one flying mission (id 1): a raw connection."""
    connection = raw_connection(database)
    dialect = "sqlite" if isinstance(database, Path) else "postgresql"
    connection.execute("CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL)")
    for version in range(1, schema_version + 1):
        for statement in MIGRATIONS[version - 1].statements(dialect):
            connection.execute(statement)
        connection.execute(f"INSERT INTO schema_migrations VALUES ({version}, 'then')")
    flight, plan = json.dumps(dataclasses.asdict(FLIGHT)), json.dumps(PLAN.to_dict())
    connection.execute(
        "INSERT INTO missions (created_at, updated_at, status, flight, plan) VALUES ('a','a','flying',"
        f"'{flight}','{plan}')"
    )
    return connection


# ----- both backends
def test_fresh_database_is_migrated(storage):
    assert storage.schema_version() == len(MIGRATIONS)


def test_transitions_are_recorded_in_order_with_reasons(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    for status in ("uploading", "uploaded", "flying"):
        storage.set_status(mission_id, status)
    storage.set_status(mission_id, "failed", "link lost")
    record = storage.get_mission(mission_id)
    assert (record.status, record.reason) == ("failed", "link lost")
    assert [e.status for e in record.events] == ["planned", "uploading", "uploaded", "flying", "failed"]
    assert record.events[-1].reason == "link lost"
    with pytest.raises(KeyError):
        storage.set_status(999, "flying")


def test_history_and_telemetry_survive_a_restart(open_db):
    storage = open_db()
    mission_id = storage.create_mission(FLIGHT, PLAN)
    storage.add_telemetry(mission_id, [{"t_s": 0.1 * i, "lat": 1.0} for i in range(25)])
    storage.set_progress(mission_id, MissionProgress(visited=2, reached_at={1: 3.5}))
    storage.set_results(mission_id, MissionResults(tracking=TRACKING))
    storage.set_status(mission_id, "completed")
    storage.close()

    reopened = open_db()
    record = reopened.get_mission(mission_id)
    assert record.status == "completed"
    assert record.plan == PLAN and record.flight == FLIGHT
    assert record.progress == MissionProgress(visited=2, reached_at={1: 3.5})
    assert record.results == MissionResults(tracking=TRACKING)
    assert reopened.telemetry_count(mission_id) == 25
    assert [s["t_s"] for s in reopened.telemetry(mission_id, limit=3)] == pytest.approx([0.0, 0.1, 0.2])
    assert [m.id for m in reopened.list_missions()] == [mission_id]


def test_documents_an_earlier_version_stored_are_read_with_defaults_and_unknown_keys_ignored(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    with storage.transaction() as db:  # as a service of two releases ago wrote them: fewer keys, one since removed
        db.execute(
            "UPDATE missions SET progress = ?, results = ? WHERE id = ?",
            ('{"visited": 1, "reached_at": {"1": 2.5}, "retired": true}', '{"buoys": []}', mission_id),
        )
    record = storage.get_mission(mission_id)
    assert record.progress == MissionProgress(visited=1, reached_at={1: 2.5})
    assert record.results == MissionResults(buoys=[])


def test_failed_transaction_leaves_nothing(storage):
    with pytest.raises(RuntimeError), storage.transaction() as db:
        db.execute(
            "INSERT INTO missions (created_at, updated_at, status, flight, plan) VALUES ('a','a','planned','{}','{}')"
        )
        raise RuntimeError("crash mid-write")
    assert storage.list_missions() == []


def test_telemetry_batch_is_all_or_nothing(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    with pytest.raises(ValueError):  # NaN cannot be stored as strict JSON: the whole batch is refused
        storage.add_telemetry(mission_id, [{"t_s": 0.0}, {"t_s": 0.1}, {"t_s": 0.2, "x": float("nan")}])
    assert storage.telemetry_count(mission_id) == 0
    with pytest.raises(ConstraintError):  # unknown mission: foreign key
        storage.add_telemetry(12345, [{"t_s": 0.0}])
    assert storage.telemetry_count(12345) == 0


def test_a_sample_recorded_again_is_skipped_and_samples_come_in_time_order(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    storage.add_telemetry(mission_id, [{"t_s": 0.2, "by": "owner"}, {"t_s": 0.3, "by": "owner"}])
    # a stand-by taking over records the owner's last instant again, in the same batch as new ones
    storage.add_telemetry(
        mission_id, [{"t_s": 0.4, "by": "stand-by"}, {"t_s": 0.3, "by": "stand-by"}, {"t_s": 0.4, "by": "again"}]
    )
    storage.add_telemetry(mission_id, [{"t_s": 0.1, "by": "late"}])
    assert storage.telemetry(mission_id) == [
        {"t_s": 0.1, "by": "late"},
        {"t_s": 0.2, "by": "owner"},
        {"t_s": 0.3, "by": "owner"},
        {"t_s": 0.4, "by": "stand-by"},
    ]
    assert storage.telemetry_count(mission_id) == 4


def test_migration_3_removes_duplicate_samples_keeping_the_first(database):
    connection = database_at_version(database, 2)
    for t_s, sample in ((0.1, "first"), (0.2, "first"), (0.1, "second"), (0.3, "first"), (0.2, "second")):
        connection.execute(f"""INSERT INTO telemetry VALUES (1, {t_s}, '{{"t_s": {t_s}, "is": "{sample}"}}')""")
    connection.close()

    storage = open_storage(database)
    try:
        assert storage.schema_version() == len(MIGRATIONS)
        assert [(s["t_s"], s["is"]) for s in storage.telemetry(1)] == [(0.1, "first"), (0.2, "first"), (0.3, "first")]
    finally:
        storage.close()


def test_migration_4_copies_each_stored_samples_position_into_the_track_columns(database):
    connection = database_at_version(database, 3)
    connection.execute("""INSERT INTO telemetry VALUES (1, 0.1, '{"t_s": 0.1, "lat": 55.5, "lon": 12.25}')""")
    connection.execute(
        """INSERT INTO telemetry VALUES (1, 0.2, '{"t_s": 0.2, "lat": null, "lon": null, "cross_track_m": 0.75}')"""
    )
    connection.close()

    storage = open_storage(database)
    try:
        assert storage.schema_version() == len(MIGRATIONS)
        assert storage.track_columns(1) == [(0.1, 55.5, 12.25, None), (0.2, None, None, 0.75)]
    finally:
        storage.close()


def test_migration_6_admits_waiting_for_battery_and_still_refuses_an_unknown_status(database):
    connection = database_at_version(database, 5)
    with pytest.raises((sqlite3.IntegrityError, psycopg.errors.CheckViolation)):  # version 5 knows no such status
        connection.execute("UPDATE missions SET status = 'waiting_for_battery' WHERE id = 1")
    connection.close()

    storage = open_storage(database)
    try:
        assert storage.schema_version() == len(MIGRATIONS)
        storage.set_status(1, "waiting_for_battery", "sortie 2 needs 64 %")
        assert storage.get_mission(1).status == "waiting_for_battery"
        assert storage.unfinished_missions(None) == [1]  # a restart re-attaches a mission waiting between sorties
        with pytest.raises(ConstraintError):
            storage.set_status(1, "exploded")
    finally:
        storage.close()
    reopened = open_storage(database)  # another connection reads the rewritten definition
    try:
        with pytest.raises(ConstraintError):
            reopened.set_status(1, "exploded")
        reopened.set_status(1, "flying")
    finally:
        reopened.close()


def test_track_columns_and_samples_at_instants_read_what_add_telemetry_stored(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    samples = [
        {"t_s": round(0.1 * k, 1), "lat": 55.0 + k * 1e-5, "lon": None if k == 3 else 12.0, "cross_track_m": k / 10}
        for k in range(1200)
    ]
    storage.add_telemetry(mission_id, samples[::-1])
    expected = [(s["t_s"], s["lat"], s["lon"], s["cross_track_m"]) for s in samples]
    assert storage.track_columns(mission_id) == expected  # doubles both ways: exact
    wanted = [samples[k]["t_s"] for k in (0, 3, 501, 1000, 1199)]  # more than one IN-list chunk apart
    assert storage.telemetry_at(mission_id, wanted) == [samples[k] for k in (0, 3, 501, 1000, 1199)]
    assert storage.track_columns(999) == [] and storage.telemetry_at(999, wanted) == []


def test_invalid_status_is_refused_by_the_schema(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    with pytest.raises(ConstraintError):
        storage.set_status(mission_id, "exploded")
    record = storage.get_mission(mission_id)
    assert record.status == "planned" and len(record.events) == 1


def test_unfinished_missions_are_the_ones_left_mid_flight_oldest_first(storage):
    flying = storage.create_mission(FLIGHT, PLAN)
    storage.set_status(flying, "flying")
    done = storage.create_mission(FLIGHT, PLAN)
    storage.set_status(done, "completed")
    uploading = storage.create_mission(FLIGHT, PLAN)
    storage.set_status(uploading, "uploading")
    storage.create_mission(FLIGHT, PLAN)  # planned: never started, so not unfinished
    assert storage.unfinished_missions() == [flying, uploading]


def test_missions_of_a_fleet_keep_their_vehicle_and_fleet_and_restart_per_vehicle(storage):
    fleet, (first, second) = storage.create_fleet_mission(FLIGHT, PLAN, [(FLIGHT, PLAN, 1), (FLIGHT, PLAN, 2)])
    alone = storage.create_mission(FLIGHT, PLAN)  # the one vehicle of a service without a fleet
    for mission_id in (fleet, first, second, alone):
        storage.set_status(mission_id, "flying")
    record = storage.get_mission(second)
    assert (record.vehicle_sysid, record.fleet_id, record.is_fleet) == (2, fleet, False)
    assert storage.get_mission(fleet).is_fleet and storage.unfinished_fleets() == [fleet]
    assert (storage.get_mission(alone).vehicle_sysid, storage.get_mission(alone).fleet_id) == (None, None)
    assert [part.id for part in storage.fleet_parts(fleet)] == [first, second]
    assert [m.id for m in storage.list_missions()] == [alone, fleet]  # the fleet mission, not its parts
    assert storage.unfinished_missions(vehicle_sysid=2) == [second]  # each vehicle re-attaches its own
    lone = storage.create_mission(FLIGHT, PLAN, vehicle_sysid=3)
    assert (storage.get_mission(lone).vehicle_sysid, storage.get_mission(lone).fleet_id) == (3, None)
    assert storage.unfinished_missions() == [alone]  # a fleet mission is flown by its parts, never re-attached


def test_a_fleet_mission_and_its_parts_are_stored_together_or_not_at_all(storage):
    before = storage.latest_version()
    with pytest.raises(ValueError):  # the second part's plan cannot be stored (NaN is not JSON)
        storage.create_fleet_mission(
            FLIGHT, PLAN, [(FLIGHT, PLAN, 1), (FLIGHT, dataclasses.replace(PLAN, length_m=float("nan")), 2)]
        )
    assert storage.list_missions() == [] and storage.latest_version() == before


def _reshare(part_id: int, at: str = "2026-01-01T00:00:00.000000+00:00") -> Reshare:
    return Reshare(part_id=part_id, sysid=2, reason="link lost", handed_over={"1": [3]}, orders={"1": [2, 1]}, at=at)


def test_a_fleet_missions_coordinator_state_is_claimed_kept_and_read_back_by_another_instance(open_db):
    storage = open_db()
    fleet, (first, second) = storage.create_fleet_mission(FLIGHT, PLAN, [(FLIGHT, PLAN, 1), (FLIGHT, PLAN, 2)])
    assert storage.fleet_coordination(fleet) is None  # nobody followed it yet
    state = storage.claim_fleet(fleet, "gcs-a")
    assert (state.coordinator, state.reshares, state.separation.min_distance_m) == ("gcs-a", [], None)
    separation = SeparationOut(min_horizontal_m=3.0, min_vertical_m=0.5, min_distance_m=3.2)
    storage.set_fleet_separation(fleet, separation)
    grown = dataclasses.replace(PLAN, length_m=PLAN.length_m + 10.0)
    storage.record_reshare(fleet, grown, _reshare(second), "vehicle 2 lost (link lost): B4 to vehicle 1")
    storage.record_reshare(fleet, grown, _reshare(first), "vehicle 1 lost")
    taken_over = open_db().claim_fleet(fleet, "gcs-b")  # another instance, as a stand-by taking over
    assert taken_over.coordinator == "gcs-b" and taken_over.separation == separation
    assert taken_over.reshares == [_reshare(second), _reshare(first)] and taken_over.handled() == {first, second}
    record = storage.get_mission(fleet)
    assert record.plan.length_m == grown.length_m and record.status == "flying"
    assert [(e.status, e.reason) for e in record.events][-2:] == [
        ("flying", "vehicle 2 lost (link lost): B4 to vehicle 1"),
        ("flying", "vehicle 1 lost"),
    ]
    assert storage.delete_mission(fleet) and storage.fleet_coordination(fleet) is None


def test_a_reshare_is_stored_with_its_plan_and_event_or_not_at_all(storage):
    fleet, (_, second) = storage.create_fleet_mission(FLIGHT, PLAN, [(FLIGHT, PLAN, 1), (FLIGHT, PLAN, 2)])
    storage.claim_fleet(fleet, "gcs-a")
    before, version = storage.get_mission(fleet), storage.latest_version()
    with pytest.raises(ValueError):  # the plan cannot be stored (NaN is not JSON): nothing of the re-share is
        storage.record_reshare(fleet, dataclasses.replace(PLAN, length_m=float("nan")), _reshare(second), "lost")
    with pytest.raises(KeyError):  # no such fleet mission: its state is not written either
        storage.record_reshare(fleet + 100, PLAN, _reshare(second), "lost")
    after = storage.get_mission(fleet)
    assert (after.plan, after.events, storage.latest_version()) == (before.plan, before.events, version)
    assert storage.fleet_coordination(fleet).reshares == [] and storage.fleet_coordination(fleet + 100) is None


def test_migration_5_leaves_every_stored_mission_on_the_one_vehicle(database):
    database_at_version(database, 4).close()
    storage = open_storage(database)
    try:
        (mission_id,) = storage.unfinished_missions()
        record = storage.get_mission(mission_id)
        assert (record.vehicle_sysid, record.fleet_id) == (None, None) and record.status == "flying"
    finally:
        storage.close()


# ----- inspections: frames and records
def stored_frame(buoy: int, image_index: int) -> StoredFrame:
    return StoredFrame(buoy=buoy, image_index=image_index, t_s=10.0 + image_index, lat=38.9, lon=121.6, height_m=5.0,
                       q=(1.0, 0.0, 0.0, 0.0), file_url=f"mftp://[;comp=100]/IMG_{image_index:06d}.jpg", found=True,
                       light_on=image_index % 2 == 0, note="found")  # fmt: skip


def inspection_record(buoy: int, frame_ids: list[int]) -> InspectionRecord:
    record = not_inspected(PLAN, buoy, "no frames")
    return record.model_copy(update={"frame_ids": frame_ids, "best_frame": frame_ids[0] if frame_ids else None})


def test_frames_and_inspections_are_stored_read_back_and_replaced_per_buoy(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    other = storage.create_mission(FLIGHT, PLAN)
    ids = [
        storage.add_frame(mission_id, stored_frame(1, k), b"\xff\xd8\xff" + bytes([k]) * 100, 10_000) for k in range(3)
    ]
    storage.add_frame(other, stored_frame(0, 9), b"other", 10_000)
    assert [f.id for f in storage.frames(mission_id)] == ids
    assert storage.frames(mission_id)[1] == stored_frame(1, 1).model_copy(update={"id": ids[1]})
    assert storage.frame_data(mission_id, ids[2]) == b"\xff\xd8\xff" + bytes([2]) * 100
    assert storage.frame_data(other, ids[0]) is None  # a frame is read through its own mission only
    version = storage.mission_version(mission_id)
    storage.set_inspection(mission_id, inspection_record(1, ids))
    assert storage.mission_version(mission_id) > version  # the mission's views change with its verdicts
    storage.set_inspection(mission_id, inspection_record(1, ids[:1]))  # judged again: replaced, not added
    storage.set_inspection(mission_id, inspection_record(0, []))
    assert storage.inspections(mission_id) == [inspection_record(0, []), inspection_record(1, ids[:1])]
    assert storage.inspections(other) == []


def test_a_frame_beyond_the_missions_frame_limit_is_refused_and_nothing_of_it_stored(storage):
    mission_id = storage.create_mission(FLIGHT, PLAN)
    storage.add_frame(mission_id, stored_frame(0, 0), b"x" * 600, 1000)
    with pytest.raises(FramesFullError, match="600 stored, 500 more"):
        storage.add_frame(mission_id, stored_frame(0, 1), b"y" * 500, 1000)
    assert len(storage.frames(mission_id)) == 1
    with pytest.raises(ConstraintError):  # unknown mission: foreign key
        storage.add_frame(12345, stored_frame(0, 0), b"z", 1000)


def test_deleting_a_mission_removes_everything_of_it_and_of_its_parts_and_nothing_else(storage):
    fleet, (first, second) = storage.create_fleet_mission(FLIGHT, PLAN, [(FLIGHT, PLAN, 1), (FLIGHT, PLAN, 2)])
    kept = storage.create_mission(FLIGHT, PLAN)
    for mission_id in (first, kept):
        frame_id = storage.add_frame(mission_id, stored_frame(0, 0), b"jpeg", 1000)
        storage.set_inspection(mission_id, inspection_record(0, [frame_id]))
        storage.add_telemetry(mission_id, [{"t_s": 0.0, "lat": 1.0}])
    assert storage.delete_mission(fleet)
    for mission_id in (fleet, first, second):
        assert storage.get_mission(mission_id) is None
        assert (storage.frames(mission_id), storage.inspections(mission_id)) == ([], [])
        assert storage.telemetry_count(mission_id) == 0
    assert [m.id for m in storage.list_missions()] == [kept]
    assert len(storage.frames(kept)) == 1 and len(storage.inspections(kept)) == 1 and storage.telemetry_count(kept)
    assert not storage.delete_mission(fleet)  # gone already


def test_database_from_a_newer_service_is_refused(open_db):
    storage = open_db()
    with storage.transaction() as db:
        db.execute("INSERT INTO schema_migrations VALUES (99, 'later')")
    storage.close()
    with pytest.raises(StorageError, match="schema version 99 is newer than this service"):
        open_db()


def test_every_write_to_a_mission_raises_its_version_above_all_others(storage):
    assert storage.latest_version() == 0
    first, second = storage.create_mission(FLIGHT, PLAN), storage.create_mission(FLIGHT, PLAN)
    assert storage.mission_version(first) < storage.mission_version(second) == storage.latest_version()
    seen = storage.latest_version()
    for write in (
        lambda: storage.set_status(first, "uploading"),
        lambda: storage.set_progress(first, MissionProgress(current_seq=2)),
        lambda: storage.set_results(first, MissionResults(buoys=[])),
    ):
        write()
        assert storage.mission_version(first) == storage.latest_version() > seen
        seen = storage.latest_version()
    assert storage.mission_version(999) is None
    # a delete moves the counter too (the list changed), and a number is never given twice: deleting the latest
    # mission and writing another must not come back to a counter a reader saw before
    storage.delete_mission(first)  # not the latest written
    assert storage.latest_version() > seen
    seen = storage.latest_version()
    storage.delete_mission(second)  # the latest written
    assert storage.latest_version() > seen
    seen = storage.latest_version()
    third = storage.create_mission(FLIGHT, PLAN)
    assert storage.mission_version(third) == storage.latest_version() > seen


# ----- SQLite only
def test_sqlite_database_is_in_wal_mode(tmp_path):
    storage = open_storage(tmp_path / "sub" / "gcs.sqlite")
    with storage.transaction() as db:
        assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    storage.close()


# ----- PostgreSQL only: several service instances on one database
@pytest.fixture
def two_instances(postgres_url: str) -> Iterator[list[Storage]]:
    """Two services' storages on one database."""
    instances = [open_storage(postgres_url), open_storage(postgres_url)]
    yield instances
    for storage in instances:
        storage.close()


def _in_threads(*jobs: Callable[[], object]) -> list[object]:
    """Run the jobs at once, each in its own thread; their results (a job's exception is raised here)."""
    with ThreadPoolExecutor(max_workers=len(jobs)) as pool:
        futures = [pool.submit(job) for job in jobs]
        return [future.result(timeout=THREAD_DEADLINE_S) for future in futures]


@pytest.mark.integration
def test_concurrent_writers_on_one_database_keep_versions_unique_and_visible_in_order(two_instances):
    writers_done = threading.Event()

    def write_missions(storage: Storage) -> list[int]:
        """Each write's version, read back at once (only this thread writes these missions)."""
        versions = []
        for _ in range(8):
            mission_id = storage.create_mission(FLIGHT, PLAN)
            versions.append(storage.mission_version(mission_id))
            for step in range(4):
                storage.set_progress(mission_id, MissionProgress(current_seq=step))
                versions.append(storage.mission_version(mission_id))
        return versions

    def watch(storage: Storage) -> int:
        """A reader (a cache, a stand-by): once it saw latest_version() == N, no mission with a version <= N may
        appear later that it did not see then."""
        observations, previous = 0, None
        while not writers_done.is_set() or observations < 2:
            latest = storage.latest_version()
            with storage.transaction() as db:
                rows = db.execute("SELECT id, version FROM missions").fetchall()
            seen = {(row["id"], row["version"]) for row in rows}
            if previous is not None:
                previous_latest, previous_seen = previous
                appeared = {pair for pair in seen if pair[1] <= previous_latest} - previous_seen
                assert not appeared, f"after latest_version() == {previous_latest}, {appeared} appeared"
            previous, observations = (latest, seen), observations + 1
        return observations

    watcher = ThreadPoolExecutor(max_workers=1).submit(watch, two_instances[1])
    try:  # two writing threads per instance, as the lifecycle's worker threads write
        written = _in_threads(*(lambda s=s: write_missions(s) for s in two_instances for _ in range(2)))
    finally:
        writers_done.set()
    assert watcher.result(timeout=THREAD_DEADLINE_S) >= 2
    for versions in written:
        assert versions == sorted(versions)  # each mission's version grows at each write
    every_version = [version for versions in written for version in versions]
    assert len(set(every_version)) == len(every_version) == 4 * 8 * 5
    assert two_instances[0].latest_version() == max(every_version)


@pytest.mark.integration
def test_two_instances_recording_the_same_flight_store_each_sample_once(two_instances):
    owner, stand_by = two_instances
    mission_id = owner.create_mission(FLIGHT, PLAN)

    def record(storage: Storage, first_t: int) -> None:  # overlapping batches of ten samples
        for start in range(first_t, 200, 10):
            storage.add_telemetry(mission_id, [{"t_s": t / 10} for t in range(start, min(start + 10, 200))])

    _in_threads(lambda: record(owner, 0), lambda: record(stand_by, 5))
    assert [s["t_s"] for s in stand_by.telemetry(mission_id)] == [t / 10 for t in range(200)]
    assert owner.telemetry_count(mission_id) == 200


@pytest.mark.integration
def test_instances_starting_at_once_migrate_once(postgres_url):
    start = threading.Barrier(4, timeout=THREAD_DEADLINE_S)

    def start_service() -> Storage:
        start.wait()
        return open_storage(postgres_url)

    instances = _in_threads(*([start_service] * 4))
    try:
        assert all(storage.schema_version() == len(MIGRATIONS) for storage in instances)
        with psycopg.connect(postgres_url) as db:
            versions = [row[0] for row in db.execute("SELECT version FROM schema_migrations ORDER BY version")]
        assert versions == list(range(1, len(MIGRATIONS) + 1))
    finally:
        for storage in instances:
            storage.close()


@pytest.mark.integration
def test_a_read_does_not_wait_for_an_open_write(postgres_url):
    storage = open_storage(postgres_url)
    try:
        mission_id = storage.create_mission(FLIGHT, PLAN)
        with storage.transaction() as db:  # a long write holding the version lock, not yet committed
            db.execute("SELECT pg_advisory_xact_lock(?)", (VERSION_LOCK,))
            db.execute("UPDATE missions SET progress = '{\"current_seq\": 9}' WHERE id = ?", (mission_id,))
            (record,) = _in_threads(lambda: storage.get_mission(mission_id))  # another thread reads meanwhile
            assert record.progress == MissionProgress()  # it read the committed state, without waiting for this write
        assert storage.get_mission(mission_id).progress == MissionProgress(current_seq=9)
    finally:
        storage.close()


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("postgresql://nobody@127.0.0.1:1/x", "cannot connect to postgresql://nobody@127.0.0.1:1/x: connection failed"),
        ("postgresql://nobody:secret@127.0.0.1:1/x", "cannot connect to postgresql://nobody:***@127.0.0.1:1/x"),
        ("postgresql://nobody@127.0.0.1:notaport/x", "cannot connect to postgresql://nobody@127.0.0.1:notaport/x"),
    ],
)
def test_an_unreachable_or_bad_url_is_a_storage_error_naming_it(url, message):
    with pytest.raises(StorageError) as error:
        open_storage(url)
    assert message in str(error.value) and "secret" not in str(error.value)
