"""Storage: migrations, transitions with history, telemetry, restart, and all-or-nothing writes."""

import sqlite3

import pytest

from gcs.storage import MIGRATIONS, ConstraintError, StorageError
from gcs.storage import SqliteStorage as Storage

PLAN = {"order": [1, 0], "length_m": 10.0}
FLIGHT = {"altitude_m": 5.0}


def test_fresh_database_is_migrated_and_in_wal_mode(tmp_path):
    storage = Storage(tmp_path / "sub" / "gcs.sqlite")
    assert storage.schema_version() == len(MIGRATIONS)
    with storage.transaction() as db:
        assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    storage.close()


def test_transitions_are_recorded_in_order_with_reasons(tmp_path):
    storage = Storage(tmp_path / "gcs.sqlite")
    mission_id = storage.create_mission(FLIGHT, PLAN)
    for status in ("uploading", "uploaded", "flying"):
        storage.set_status(mission_id, status)
    storage.set_status(mission_id, "failed", "link lost")
    record = storage.get_mission(mission_id)
    assert (record.status, record.reason) == ("failed", "link lost")
    assert [e["status"] for e in record.events] == ["planned", "uploading", "uploaded", "flying", "failed"]
    assert record.events[-1]["reason"] == "link lost"
    with pytest.raises(KeyError):
        storage.set_status(999, "flying")
    storage.close()


def test_history_and_telemetry_survive_a_restart(tmp_path):
    path = tmp_path / "gcs.sqlite"
    storage = Storage(path)
    mission_id = storage.create_mission(FLIGHT, PLAN)
    storage.add_telemetry(mission_id, [{"t_s": 0.1 * i, "lat": 1.0} for i in range(25)])
    storage.set_progress(mission_id, {"visited": 2})
    storage.set_results(mission_id, {"tracking": {"rms_cross_track_m": 0.5}})
    storage.set_status(mission_id, "completed")
    storage.close()

    reopened = Storage(path)
    record = reopened.get_mission(mission_id)
    assert record.status == "completed"
    assert record.plan == PLAN and record.flight == FLIGHT
    assert record.progress == {"visited": 2}
    assert record.results["tracking"]["rms_cross_track_m"] == 0.5
    assert reopened.telemetry_count(mission_id) == 25
    assert [s["t_s"] for s in reopened.telemetry(mission_id, limit=3)] == pytest.approx([0.0, 0.1, 0.2])
    assert [m.id for m in reopened.list_missions()] == [mission_id]
    reopened.close()


def test_failed_transaction_leaves_nothing(tmp_path):
    storage = Storage(tmp_path / "gcs.sqlite")
    with pytest.raises(RuntimeError), storage.transaction() as db:
        db.execute(
            "INSERT INTO missions (created_at, updated_at, status, flight, plan) VALUES ('a','a','planned','{}','{}')"
        )
        raise RuntimeError("crash mid-write")
    assert storage.list_missions() == []


def test_telemetry_batch_is_all_or_nothing(tmp_path):
    storage = Storage(tmp_path / "gcs.sqlite")
    mission_id = storage.create_mission(FLIGHT, PLAN)
    with pytest.raises(ValueError):  # NaN cannot be stored as strict JSON: the whole batch is refused
        storage.add_telemetry(mission_id, [{"t_s": 0.0}, {"t_s": 0.1}, {"t_s": 0.2, "x": float("nan")}])
    assert storage.telemetry_count(mission_id) == 0
    with pytest.raises(ConstraintError):  # unknown mission: foreign key
        storage.add_telemetry(12345, [{"t_s": 0.0}])
    assert storage.telemetry_count(12345) == 0


def test_invalid_status_is_refused_by_the_schema(tmp_path):
    storage = Storage(tmp_path / "gcs.sqlite")
    mission_id = storage.create_mission(FLIGHT, PLAN)
    with pytest.raises(ConstraintError):
        storage.set_status(mission_id, "exploded")
    record = storage.get_mission(mission_id)
    assert record.status == "planned" and len(record.events) == 1


def test_unfinished_missions_are_the_ones_left_mid_flight_oldest_first(tmp_path):
    storage = Storage(tmp_path / "gcs.sqlite")
    flying = storage.create_mission(FLIGHT, PLAN)
    storage.set_status(flying, "flying")
    done = storage.create_mission(FLIGHT, PLAN)
    storage.set_status(done, "completed")
    uploading = storage.create_mission(FLIGHT, PLAN)
    storage.set_status(uploading, "uploading")
    storage.create_mission(FLIGHT, PLAN)  # planned: never started, so not unfinished
    assert storage.unfinished_missions() == [flying, uploading]


def test_database_from_a_newer_service_is_refused(tmp_path):
    path = tmp_path / "gcs.sqlite"
    Storage(path).close()
    db = sqlite3.connect(path)
    db.execute("INSERT INTO schema_migrations VALUES (99, 'later')")
    db.commit()
    db.close()
    with pytest.raises(StorageError, match="newer"):
        Storage(path)


def test_every_write_to_a_mission_raises_its_version_above_all_others(tmp_path):
    storage = Storage(tmp_path / "gcs.sqlite")
    assert storage.latest_version() == 0
    first, second = storage.create_mission(FLIGHT, PLAN), storage.create_mission(FLIGHT, PLAN)
    assert storage.mission_version(first) < storage.mission_version(second) == storage.latest_version()
    seen = storage.latest_version()
    for write in (
        lambda: storage.set_status(first, "uploading"),
        lambda: storage.set_progress(first, {"current_seq": 2}),
        lambda: storage.set_results(first, {"buoys": []}),
    ):
        write()
        assert storage.mission_version(first) == storage.latest_version() > seen
        seen = storage.latest_version()
    assert storage.mission_version(999) is None
    storage.close()
