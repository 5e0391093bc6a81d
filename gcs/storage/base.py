"""The storage's SQL, written once for both databases; the dialects (`sqlite`, `postgres`) supply the rest.

`Storage` holds every query the service runs, with `?` placeholders and names for every selected column. A
dialect subclass says how to reach its database: a connection for reads (`_reading`), a transaction for writes
(`_begin`), how to serialise migrations and version numbers across service instances, and which driver errors
mean a broken constraint.
"""

from __future__ import annotations

import json
from abc import ABC, abstractmethod
from collections.abc import Iterable, Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from typing import Any, ClassVar, Protocol

from gcs.domain.inspection import InspectionRecord, StoredFrame
from gcs.domain.planning import FlightParams, Plan
from gcs.domain.records import MissionProgress, MissionResults
from gcs.domain.schemas import StatusEvent
from gcs.domain.status import UNFINISHED, MissionKind, MissionStatus
from gcs.storage.migrations import MIGRATIONS, TRACK_COLUMNS

# The next version, taken inside the write's transaction, after the dialect's `_serialise_versions`: writers take
# it one at a time and commit in that order, so a reader that saw latest_version() == N never later sees a
# mission appear with a version <= N.
NEXT_VERSION = "(SELECT COALESCE(MAX(version), 0) + 1 FROM missions)"


class StorageError(RuntimeError):
    """The database cannot be opened, is from a newer version of the service, or refused a write."""


class FramesFullError(StorageError):
    """A mission's frames would pass the size limit: the frame was not stored."""


class ConstraintError(StorageError):
    """A write broke one of the schema's rules (an unknown mission, a status that does not exist): nothing of
    the transaction was written."""


class Cursor(Protocol):
    @property  # read-only: the drivers' cursors (sqlite3's, psycopg's) do not let it be set
    def rowcount(self) -> int: ...

    def fetchone(self) -> Any: ...

    def fetchall(self) -> list[Any]: ...


class Connection(Protocol):
    """What `transaction()` yields: sqlite3.Connection's execute/executemany (`?` placeholders). Rows are read
    by column name. Positional-only arguments, as sqlite3's take them."""

    def execute(self, sql: str, parameters: Sequence[Any] = ..., /) -> Cursor: ...

    def executemany(self, sql: str, rows: Iterable[Sequence[Any]], /) -> Any: ...


@dataclass
class MissionRecord:
    id: int
    created_at: str
    updated_at: str
    status: MissionStatus
    reason: str | None
    flight: FlightParams
    plan: Plan
    progress: MissionProgress
    results: MissionResults | None
    events: list[StatusEvent] = field(default_factory=list)  # get_mission's; empty from the other reads
    vehicle_sysid: int | None = None  # the vehicle it flies on (None: the service's one vehicle)
    # the column grouping a fleet mission with its parts: a part's fleet mission, and a fleet mission's own id (so
    # one index finds the group); outside storage, ask `kind` and `part_of`
    fleet_id: int | None = None

    @property
    def is_fleet(self) -> bool:
        """A fleet mission (flown by its parts, never by a vehicle itself)."""
        return self.fleet_id == self.id

    @property
    def part_of(self) -> int | None:
        """The fleet mission this one is a part of (None: not a part)."""
        return None if self.is_fleet else self.fleet_id

    @property
    def kind(self) -> MissionKind:
        if self.is_fleet:
            return MissionKind.FLEET
        return MissionKind.SINGLE if self.fleet_id is None else MissionKind.FLEET_PART


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def _json(value: Any) -> str:
    # allow_nan=False: a NaN would make the stored document unreadable by strict JSON clients
    return json.dumps(value, allow_nan=False, separators=(",", ":"))


def _record(row: Any, events: list[StatusEvent]) -> MissionRecord:
    return MissionRecord(
        id=int(row["id"]),
        created_at=row["created_at"],
        updated_at=row["updated_at"],
        status=MissionStatus(row["status"]),
        reason=row["reason"],
        flight=FlightParams(**json.loads(row["flight"])),
        plan=Plan.from_dict(json.loads(row["plan"])),
        progress=MissionProgress.model_validate_json(row["progress"]),
        results=MissionResults.model_validate_json(row["results"]) if row["results"] else None,
        events=events,
        vehicle_sysid=None if row["vehicle_sysid"] is None else int(row["vehicle_sysid"]),
        fleet_id=None if row["fleet_id"] is None else int(row["fleet_id"]),
    )


class Storage(ABC):
    """Missions, their status history and their telemetry. Safe to share between threads. Open one with
    `gcs.storage.open_storage`."""

    dialect: ClassVar[str]  # which SQL of each migration applies: "sqlite" or "postgresql"
    location: str  # the database for messages: a file name, or a URL without its password
    constraint_errors: ClassVar[tuple[type[Exception], ...]]  # the driver's errors for a broken constraint

    # ----- what a dialect supplies
    @abstractmethod
    def _reading(self) -> AbstractContextManager[Connection]:
        """A connection for reads (no transaction needed)."""

    @abstractmethod
    def _begin(self) -> AbstractContextManager[Connection]:
        """A transaction holding the database's write lock where it has one; commits at the end of the block,
        rolls back on an error."""

    @abstractmethod
    def _serialise_migrations(self, db: Connection) -> None:
        """Called first in the migration's transaction: another instance migrating waits until it commits."""

    @abstractmethod
    def _serialise_versions(self, db: Connection) -> None:
        """Called first in every mission write: writers take NEXT_VERSION one at a time, in commit order."""

    @abstractmethod
    def close(self) -> None: ...

    # ----- plumbing
    @contextmanager
    def transaction(self) -> Iterator[Connection]:
        """All statements inside commit together or not at all."""
        try:
            with self._begin() as db:
                yield db
        except self.constraint_errors as error:
            raise ConstraintError(f"{self.location}: {error}") from error

    def schema_version(self) -> int:
        with self._reading() as db:
            return self._schema_version(db)

    @staticmethod
    def _schema_version(db: Connection) -> int:
        return int(
            db.execute("SELECT COALESCE(MAX(version), 0) AS version FROM schema_migrations").fetchone()["version"]
        )

    def _migrate(self) -> None:
        """Bring the schema to the newest version, in one transaction: all the missing migrations or none."""
        with self.transaction() as db:
            self._serialise_migrations(db)
            db.execute(
                "CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL)"
            )
            current = self._schema_version(db)
            if current > len(MIGRATIONS):
                raise StorageError(
                    f"{self.location}: schema version {current} is newer than this service ({len(MIGRATIONS)})"
                )
            for version in range(current + 1, len(MIGRATIONS) + 1):
                migration = MIGRATIONS[version - 1]
                for statement in migration.statements(self.dialect):
                    db.execute(statement)
                if self.dialect == "sqlite" and migration.sqlite_steps is not None:
                    migration.sqlite_steps(db)
                db.execute("INSERT INTO schema_migrations (version, applied_at) VALUES (?, ?)", (version, _now()))

    @contextmanager
    def _mission_write(self) -> Iterator[Connection]:
        with self.transaction() as db:
            self._serialise_versions(db)
            yield db

    # ----- missions
    def create_mission(
        self,
        flight: FlightParams,
        plan: Plan,
        status: MissionStatus = MissionStatus.PLANNED,
        vehicle_sysid: int | None = None,
        fleet_id: int | None = None,
    ) -> int:
        """A new mission, on a vehicle of the fleet (`vehicle_sysid`; None: the service's one vehicle) and, as a
        part of a fleet mission, under it (`fleet_id`)."""
        with self._mission_write() as db:
            return self._insert_mission(db, flight, plan, status, vehicle_sysid, fleet_id)

    def create_fleet_mission(
        self, flight: FlightParams, plan: Plan, parts: list[tuple[FlightParams, Plan, int]]
    ) -> tuple[int, list[int]]:
        """A fleet mission (its fleet_id its own id) and its parts, each (flight, plan, vehicle_sysid), in one
        transaction: all of them or none. Returns (the fleet mission's id, the parts' ids)."""
        with self._mission_write() as db:
            fleet_id = self._insert_mission(db, flight, plan, MissionStatus.PLANNED, None, None)
            db.execute("UPDATE missions SET fleet_id = id WHERE id = ?", (fleet_id,))
            ids = [
                self._insert_mission(db, part_flight, part_plan, MissionStatus.PLANNED, sysid, fleet_id)
                for part_flight, part_plan, sysid in parts
            ]
        return fleet_id, ids

    @staticmethod
    def _insert_mission(
        db: Connection,
        flight: FlightParams,
        plan: Plan,
        status: MissionStatus,
        vehicle_sysid: int | None,
        fleet_id: int | None,
    ) -> int:
        now = _now()
        mission_id = int(
            db.execute(
                f"INSERT INTO missions (created_at, updated_at, status, flight, plan, vehicle_sysid, fleet_id,"
                f" version) VALUES (?, ?, ?, ?, ?, ?, ?, {NEXT_VERSION}) RETURNING id",
                (now, now, status, _json(asdict(flight)), _json(plan.to_dict()), vehicle_sysid, fleet_id),
            ).fetchone()["id"]
        )
        db.execute("INSERT INTO mission_events (mission_id, at, status) VALUES (?, ?, ?)", (mission_id, now, status))
        return mission_id

    def set_status(self, mission_id: int, status: MissionStatus, reason: str | None = None) -> None:
        now = _now()
        with self._mission_write() as db:
            cursor = db.execute(
                f"UPDATE missions SET status = ?, reason = ?, updated_at = ?, version = {NEXT_VERSION} WHERE id = ?",
                (status, reason, now, mission_id),
            )
            if cursor.rowcount != 1:
                raise KeyError(f"no mission {mission_id}")
            db.execute(
                "INSERT INTO mission_events (mission_id, at, status, reason) VALUES (?, ?, ?, ?)",
                (mission_id, now, status, reason),
            )

    def set_progress(self, mission_id: int, progress: MissionProgress) -> None:
        self._set_document(mission_id, "progress", progress.model_dump(mode="json"))

    def set_plan(self, mission_id: int, plan: Plan) -> None:
        """A mission re-planned in flight (a fleet's share grown by a lost vehicle's buoys)."""
        self._set_document(mission_id, "plan", plan.to_dict())

    def set_results(self, mission_id: int, results: MissionResults) -> None:
        self._set_document(mission_id, "results", results.model_dump(mode="json"))

    def _set_document(self, mission_id: int, column: str, document: dict[str, Any]) -> None:
        with self._mission_write() as db:
            db.execute(
                f"UPDATE missions SET {column} = ?, updated_at = ?, version = {NEXT_VERSION} WHERE id = ?",
                (_json(document), _now(), mission_id),
            )

    def unfinished_missions(self, vehicle_sysid: int | None = None) -> list[int]:
        """Ids of missions a previous run of the service left uploading, uploaded or flying, oldest first: those
        of vehicle `vehicle_sysid` (None: of the service's one vehicle, missions stored without a vehicle)."""
        if vehicle_sysid is None:
            return self._unfinished("vehicle_sysid IS NULL AND (fleet_id IS NULL OR fleet_id <> id)")
        return self._unfinished("vehicle_sysid = ? AND (fleet_id IS NULL OR fleet_id <> id)", (vehicle_sysid,))

    def unfinished_fleets(self) -> list[int]:
        """Ids of fleet missions a previous run left flying (their parts re-attach by vehicle), oldest first."""
        return self._unfinished("fleet_id = id")

    def _unfinished(self, condition: str, parameters: tuple[Any, ...] = ()) -> list[int]:
        """Ids of the missions left uploading, uploaded or flying that meet `condition`, oldest first."""
        with self._reading() as db:
            rows = db.execute(
                f"SELECT id FROM missions WHERE status IN ({', '.join('?' * len(UNFINISHED))}) AND {condition}"
                " ORDER BY id",
                (*UNFINISHED, *parameters),
            ).fetchall()
        return [int(row["id"]) for row in rows]

    def fleet_parts(self, fleet_id: int) -> list[MissionRecord]:
        """A fleet mission's parts (one mission per vehicle, and those re-planned in flight), oldest first."""
        with self._reading() as db:
            rows = db.execute(
                "SELECT * FROM missions WHERE fleet_id = ? AND id <> ? ORDER BY id", (fleet_id, fleet_id)
            ).fetchall()
        return [_record(row, []) for row in rows]

    def get_mission(self, mission_id: int) -> MissionRecord | None:
        with self._reading() as db:
            row = db.execute("SELECT * FROM missions WHERE id = ?", (mission_id,)).fetchone()
            if row is None:
                return None
            events = db.execute(
                "SELECT at, status, reason FROM mission_events WHERE mission_id = ? ORDER BY id", (mission_id,)
            ).fetchall()
        return _record(row, [StatusEvent.model_validate(dict(event)) for event in events])

    def mission_version(self, mission_id: int) -> int | None:
        """The mission's change counter (None: no such mission): it grows at every write to the mission."""
        with self._reading() as db:
            row = db.execute("SELECT version FROM missions WHERE id = ?", (mission_id,)).fetchone()
        return None if row is None else int(row["version"])

    def latest_version(self) -> int:
        """The highest change counter of all missions: it grows whenever any mission is created or changes."""
        with self._reading() as db:
            row = db.execute("SELECT COALESCE(MAX(version), 0) AS version FROM missions").fetchone()
        return int(row["version"])

    def list_missions(self, limit: int = 100) -> list[MissionRecord]:
        """The latest missions, newest first: a fleet mission, not its parts (`fleet_parts`)."""
        with self._reading() as db:
            rows = db.execute(
                "SELECT * FROM missions WHERE fleet_id IS NULL OR fleet_id = id ORDER BY id DESC LIMIT ?", (limit,)
            ).fetchall()
        return [_record(row, []) for row in rows]

    # ----- telemetry
    def add_telemetry(self, mission_id: int, samples: list[dict[str, Any]]) -> None:
        """Store samples (each with a `t_s` key) in one transaction: all of them or none. A sample whose instant
        is already stored for the mission is skipped (a stand-by taking over may record it again)."""
        if not samples:
            return
        # in time order: two instances recording the same instants lock them in the same order, never a deadlock
        rows = [
            (mission_id, float(s["t_s"]), _json(s), *(s.get(c) for c in TRACK_COLUMNS))
            for s in sorted(samples, key=lambda s: float(s["t_s"]))
        ]
        with self.transaction() as db:
            db.executemany(
                f"INSERT INTO telemetry (mission_id, t_s, sample, {', '.join(TRACK_COLUMNS)})"
                f" VALUES (?, ?, ?, {', '.join('?' * len(TRACK_COLUMNS))}) ON CONFLICT (mission_id, t_s) DO NOTHING",
                rows,
            )

    def telemetry(self, mission_id: int, limit: int | None = None) -> list[dict[str, Any]]:
        """The mission's samples in time order (the vehicle's clock), the first `limit` of them."""
        query = "SELECT sample FROM telemetry WHERE mission_id = ? ORDER BY t_s"
        with self._reading() as db:
            if limit is None:
                rows = db.execute(query, (mission_id,)).fetchall()
            else:
                rows = db.execute(f"{query} LIMIT ?", (mission_id, limit)).fetchall()
        return [json.loads(row["sample"]) for row in rows]

    def track_columns(self, mission_id: int) -> list[tuple[float, float | None, float | None, float | None]]:
        """(t_s, lat, lon, cross_track_m) of every sample in time order: what a display track needs, read
        without decoding the samples' documents."""
        with self._reading() as db:
            rows = db.execute(
                f"SELECT t_s, {', '.join(TRACK_COLUMNS)} FROM telemetry WHERE mission_id = ? ORDER BY t_s",
                (mission_id,),
            ).fetchall()
        return [(row["t_s"], *(row[column] for column in TRACK_COLUMNS)) for row in rows]

    def telemetry_at(self, mission_id: int, times_s: list[float]) -> list[dict[str, Any]]:
        """The samples recorded at these instants (each a t_s of `track_columns`), in time order."""
        samples: list[dict[str, Any]] = []
        with self._reading() as db:
            for start in range(0, len(times_s), 500):  # a bounded IN list per query
                chunk = times_s[start : start + 500]
                rows = db.execute(
                    f"SELECT sample FROM telemetry WHERE mission_id = ? AND t_s IN ({', '.join('?' * len(chunk))})"
                    " ORDER BY t_s",
                    (mission_id, *chunk),
                ).fetchall()
                samples += [json.loads(row["sample"]) for row in rows]
        return samples

    def telemetry_count(self, mission_id: int) -> int:
        with self._reading() as db:
            row = db.execute("SELECT COUNT(*) AS samples FROM telemetry WHERE mission_id = ?", (mission_id,)).fetchone()
        return int(row["samples"])

    # ----- inspections: camera frames and each buoy's record
    def add_frame(self, mission_id: int, frame: StoredFrame, data: bytes, max_mission_bytes: int) -> int:
        """Store a frame's bytes and record; returns its id. Raises FramesFullError (nothing stored) when the
        mission's frames would pass max_mission_bytes."""
        with self.transaction() as db:
            row = db.execute("SELECT COALESCE(SUM(size), 0) AS size FROM frames WHERE mission_id = ?", (mission_id,))
            stored = int(row.fetchone()["size"])
            if stored + len(data) > max_mission_bytes:
                raise FramesFullError(
                    f"the mission's frames would pass {max_mission_bytes} bytes ({stored} stored, {len(data)} more)"
                )
            record = _json(frame.model_dump(mode="json", exclude={"id"}))
            return int(
                db.execute(
                    "INSERT INTO frames (mission_id, buoy, captured, size, data) VALUES (?, ?, ?, ?, ?) RETURNING id",
                    (mission_id, frame.buoy, record, len(data), data),
                ).fetchone()["id"]
            )

    def frames(self, mission_id: int) -> list[StoredFrame]:
        """The mission's frames' records (not their bytes), by buoy, in the order they were stored."""
        with self._reading() as db:
            rows = db.execute(
                "SELECT id, captured FROM frames WHERE mission_id = ? ORDER BY buoy, id", (mission_id,)
            ).fetchall()
        return [StoredFrame.model_validate(json.loads(row["captured"]) | {"id": row["id"]}) for row in rows]

    def frame_data(self, mission_id: int, frame_id: int) -> bytes | None:
        """A frame's bytes (None: no such frame of this mission)."""
        with self._reading() as db:
            row = db.execute(
                "SELECT data FROM frames WHERE mission_id = ? AND id = ?", (mission_id, frame_id)
            ).fetchone()
        return None if row is None else bytes(row["data"])

    def set_inspection(self, mission_id: int, record: InspectionRecord) -> None:
        """Store (or replace) one buoy's inspection record; the mission's version rises (its views change)."""
        document = _json(record.model_dump(mode="json"))
        with self._mission_write() as db:
            db.execute(
                "INSERT INTO inspections (mission_id, buoy, record) VALUES (?, ?, ?)"
                " ON CONFLICT (mission_id, buoy) DO UPDATE SET record = excluded.record",
                (mission_id, record.buoy, document),
            )
            db.execute(
                f"UPDATE missions SET updated_at = ?, version = {NEXT_VERSION} WHERE id = ?", (_now(), mission_id)
            )

    def inspections(self, mission_id: int) -> list[InspectionRecord]:
        """The mission's inspection records by buoy input index."""
        with self._reading() as db:
            rows = db.execute("SELECT record FROM inspections WHERE mission_id = ? ORDER BY buoy", (mission_id,))
            return [InspectionRecord.model_validate_json(row["record"]) for row in rows.fetchall()]

    # ----- removal
    def delete_mission(self, mission_id: int) -> bool:
        """Remove a mission and everything of it (a fleet mission: its parts too): events, telemetry, frames and
        inspections, in one transaction. False when there is no such mission."""
        with self._mission_write() as db:
            rows = db.execute(
                "SELECT id FROM missions WHERE id = ? OR (fleet_id = ? AND fleet_id <> id)", (mission_id, mission_id)
            ).fetchall()
            ids = sorted((int(row["id"]) for row in rows), reverse=True)  # parts (higher ids) before their fleet
            for table in ("frames", "inspections", "telemetry", "mission_events"):
                db.executemany(f"DELETE FROM {table} WHERE mission_id = ?", [(i,) for i in ids])
            db.executemany("DELETE FROM missions WHERE id = ?", [(i,) for i in ids])
        return bool(ids)
