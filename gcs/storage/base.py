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

from gcs.domain.fleet_coordination import FleetCoordination, Reshare
from gcs.domain.inspection import InspectionRecord, StoredFrame
from gcs.domain.listing import MissionFilter, PageKey, stored_time
from gcs.domain.planning import FlightParams, Plan
from gcs.domain.records import MissionProgress, MissionResults
from gcs.domain.register import (
    UNCLOSED,
    BuoyEvent,
    BuoyFilter,
    Defect,
    DefectState,
    RegisterBuoy,
    StoredBuoy,
    defect_findings,
)
from gcs.domain.schemas import SeparationOut, StatusEvent
from gcs.domain.status import UNFINISHED, MissionKind, MissionStatus
from gcs.storage.migrations import MIGRATIONS, TRACK_COLUMNS


def next_version(db: Connection) -> int:
    """The next change counter, taken inside a mission write's transaction after the dialect's
    `_serialise_versions`: writers take it one at a time and commit in that order, so a reader that saw
    latest_version() == N never later sees a mission appear with a version <= N. The counter has a table of its
    own (migration 11) rather than being the missions' highest version: a delete moves it too, and a number is
    never given twice (the highest, derived, fell back when the latest mission was deleted, and the next write
    took its number again: a list cached under it was served with the deleted mission in it)."""
    return int(db.execute("UPDATE mission_changes SET version = version + 1 RETURNING version").fetchone()["version"])


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


@dataclass(frozen=True)
class StoredFlightLog:
    """A mission's flight log as the service fetched it: its size and id on the vehicle (its bytes: `flight_log_data`),
    or, when the download failed, only a `note` saying why (size None)."""

    downloaded_at: str
    size_bytes: int | None = None
    vehicle_log_id: int | None = None
    note: str | None = None


def _now() -> str:
    return stored_time(datetime.now(UTC))  # one width for every time: GET /missions compares them as text


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


_BUOY_COLUMNS = "id, name, lat, lon, kind, light, swing_radius_m, charted, source"
# A register buoy with its last inspection that gave a verdict and its count of open or confirmed defects
_STORED_BUOYS = f"""SELECT {_BUOY_COLUMNS}, mmsi, created_at, updated_at,
    (SELECT MAX(at) FROM buoy_events AS e WHERE e.buoy_id = b.id AND e.kind = 'inspection'
     AND e.verdict IN ('ok', 'defect')) AS last_inspected_at,
    (SELECT COUNT(*) FROM buoy_defects AS d WHERE d.buoy_id = b.id AND d.state IN ('open', 'confirmed'))
     AS unclosed_defects
    FROM buoys AS b"""


def _coordination(row: Any) -> FleetCoordination:
    separation = SeparationOut(
        min_horizontal_m=row["min_horizontal_m"],
        min_vertical_m=row["min_vertical_m"],
        min_distance_m=row["min_distance_m"],
    )
    return FleetCoordination(
        fleet_id=row["fleet_id"],
        coordinator=row["coordinator"],
        separation=separation,
        reshares=[Reshare.model_validate(item) for item in json.loads(row["reshares"])],
        updated_at=row["updated_at"],
    )


def _charted_values(buoy: RegisterBuoy) -> tuple[Any, ...]:
    """The buoy's values in _BUOY_COLUMNS' order, without its source."""
    return (buoy.id, buoy.name, buoy.lat, buoy.lon, buoy.kind, buoy.light, buoy.swing_radius_m, _json(buoy.charted))


def _register_buoy(row: Any) -> RegisterBuoy:
    return RegisterBuoy(id=row["id"], lat=float(row["lat"]), lon=float(row["lon"]), name=row["name"],
                        kind=row["kind"], light=row["light"], swing_radius_m=float(row["swing_radius_m"]),
                        charted=json.loads(row["charted"]), source=row["source"])  # fmt: skip


def _stored_buoy(row: Any) -> StoredBuoy:
    return StoredBuoy(buoy=_register_buoy(row), mmsi=None if row["mmsi"] is None else int(row["mmsi"]),
                      created_at=row["created_at"], updated_at=row["updated_at"],
                      last_inspected_at=row["last_inspected_at"],
                      unclosed_defects=int(row["unclosed_defects"]))  # fmt: skip


def _event(row: Any) -> BuoyEvent:
    return BuoyEvent(id=int(row["id"]), buoy_id=row["buoy_id"], at=row["at"], kind=row["kind"],
                     mission_id=_optional_int(row["mission_id"]), defect_id=_optional_int(row["defect_id"]),
                     verdict=row["verdict"], detail=json.loads(row["detail"]), note=row["note"])  # fmt: skip


def _defect(row: Any) -> Defect:
    return Defect(id=int(row["id"]), buoy_id=row["buoy_id"], code=row["code"], state=row["state"],
                  mission_id=int(row["mission_id"]), finding=json.loads(row["finding"]), opened_at=row["opened_at"],
                  updated_at=row["updated_at"], note=row["note"])  # fmt: skip


def _optional_int(value: Any) -> int | None:
    return None if value is None else int(value)


def _buoy_conditions(where: BuoyFilter) -> tuple[list[str], list[Any]]:
    """GET /buoys' filters as SQL conditions on _STORED_BUOYS' columns, and their parameters."""
    conditions: list[str] = []
    parameters: list[Any] = []
    if where.bbox is not None:
        west, south, east, north = where.bbox
        conditions.append("lat BETWEEN ? AND ? AND lon BETWEEN ? AND ?")
        parameters += [south, north, west, east]  # west < east: gcs.domain.areas.parse_bbox
    if where.kind is not None:
        conditions.append("kind = ?")
        parameters.append(where.kind)
    if where.inspected_before is not None:
        conditions.append("(last_inspected_at IS NULL OR last_inspected_at < ?)")
        parameters.append(where.inspected_before)
    if where.open_defects is not None:
        conditions.append("unclosed_defects > 0" if where.open_defects else "unclosed_defects = 0")
    return conditions, parameters


def _mission_conditions(where: MissionFilter) -> tuple[list[str], list[Any]]:
    """GET /missions' filters as SQL conditions on `missions AS m`, and their parameters: missions listed (single
    and fleet missions, not the parts) that pass."""
    conditions = ["(m.fleet_id IS NULL OR m.fleet_id = m.id)"]
    parameters: list[Any] = []
    if where.statuses:
        conditions.append(f"m.status IN ({', '.join('?' * len(where.statuses))})")
        parameters += where.statuses
    if where.vehicle is not None:
        # a single mission stored for the vehicle, or a fleet mission one of whose parts was (missions_by_fleet)
        conditions.append(
            "(m.vehicle_sysid = ? OR (m.fleet_id = m.id AND EXISTS (SELECT 1 FROM missions AS part"
            " WHERE part.fleet_id = m.id AND part.id <> m.id AND part.vehicle_sysid = ?)))"
        )
        parameters += [where.vehicle, where.vehicle]
    for column_test, bound in (("m.created_at >= ?", where.since), ("m.created_at < ?", where.until)):
        if bound is not None:
            conditions.append(column_test)
            parameters.append(bound)
    return conditions, parameters


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
        now, version = _now(), next_version(db)
        mission_id = int(
            db.execute(
                "INSERT INTO missions (created_at, updated_at, status, flight, plan, vehicle_sysid, fleet_id,"
                " version) VALUES (?, ?, ?, ?, ?, ?, ?, ?) RETURNING id",
                (now, now, status, _json(asdict(flight)), _json(plan.to_dict()), vehicle_sysid, fleet_id, version),
            ).fetchone()["id"]
        )
        db.execute("INSERT INTO mission_events (mission_id, at, status) VALUES (?, ?, ?)", (mission_id, now, status))
        return mission_id

    def set_status(self, mission_id: int, status: MissionStatus, reason: str | None = None) -> None:
        now = _now()
        with self._mission_write() as db:
            cursor = db.execute(
                "UPDATE missions SET status = ?, reason = ?, updated_at = ?, version = ? WHERE id = ?",
                (status, reason, now, next_version(db), mission_id),
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
                f"UPDATE missions SET {column} = ?, updated_at = ?, version = ? WHERE id = ?",
                (_json(document), _now(), next_version(db), mission_id),
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

    # ----- a fleet mission's coordinator state (gcs.domain.fleet_coordination), so another instance can carry it on
    def fleet_coordination(self, fleet_id: int) -> FleetCoordination | None:
        """The fleet mission's coordinator state, None before anyone followed it."""
        with self._reading() as db:
            row = db.execute("SELECT * FROM fleet_coordination WHERE fleet_id = ?", (fleet_id,)).fetchone()
        return None if row is None else _coordination(row)

    def claim_fleet(self, fleet_id: int, coordinator: str) -> FleetCoordination:
        """Record that instance `coordinator` follows the fleet mission from now (the caller holds the leases of
        its vehicles: gcs.missions.ownership); returns its state as stored (empty the first time)."""
        with self.transaction() as db:
            db.execute(
                "INSERT INTO fleet_coordination (fleet_id, coordinator, updated_at) VALUES (?, ?, ?)"
                " ON CONFLICT (fleet_id) DO UPDATE SET coordinator = excluded.coordinator,"
                " updated_at = excluded.updated_at",
                (fleet_id, coordinator, _now()),
            )
            row = db.execute("SELECT * FROM fleet_coordination WHERE fleet_id = ?", (fleet_id,)).fetchone()
        return _coordination(row)

    def set_fleet_separation(self, fleet_id: int, separation: SeparationOut) -> None:
        """The closest approach so far of the fleet mission's vehicles (its row made by `claim_fleet`)."""
        with self.transaction() as db:
            db.execute(
                "UPDATE fleet_coordination SET min_horizontal_m = ?, min_vertical_m = ?, min_distance_m = ?,"
                " updated_at = ? WHERE fleet_id = ?",
                (separation.min_horizontal_m, separation.min_vertical_m, separation.min_distance_m, _now(), fleet_id),
            )

    def record_reshare(self, fleet_id: int, plan: Plan, reshare: Reshare, reason: str) -> None:
        """A lost part's buoys re-shared, in one transaction: the fleet mission's plan (the lost share marked, the
        receiving shares grown), its event (still flying, `reason`) and the re-share added to its coordinator
        state. Nothing of it is stored if any of it fails."""
        now = _now()
        with self._mission_write() as db:
            cursor = db.execute(
                "UPDATE missions SET plan = ?, status = ?, reason = ?, updated_at = ?, version = ? WHERE id = ?",
                (_json(plan.to_dict()), MissionStatus.FLYING, reason, now, next_version(db), fleet_id),
            )
            if cursor.rowcount != 1:
                raise KeyError(f"no mission {fleet_id}")
            db.execute(
                "INSERT INTO mission_events (mission_id, at, status, reason) VALUES (?, ?, ?, ?)",
                (fleet_id, now, MissionStatus.FLYING, reason),
            )
            row = db.execute("SELECT reshares FROM fleet_coordination WHERE fleet_id = ?", (fleet_id,)).fetchone()
            reshares = [*(json.loads(row["reshares"]) if row is not None else []), reshare.model_dump(mode="json")]
            db.execute(
                "INSERT INTO fleet_coordination (fleet_id, reshares, updated_at) VALUES (?, ?, ?)"
                " ON CONFLICT (fleet_id) DO UPDATE SET reshares = excluded.reshares, updated_at = excluded.updated_at",
                (fleet_id, _json(reshares), now),
            )

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
        """The change counter (`next_version`): it grows whenever any mission is created, changes or is deleted."""
        with self._reading() as db:
            return int(db.execute("SELECT version FROM mission_changes").fetchone()["version"])

    def list_missions(
        self, limit: int = 100, where: MissionFilter | None = None, after: PageKey | None = None
    ) -> list[MissionRecord]:
        """The latest missions that pass `where`, newest first by (created_at, id), the first `limit` of those
        created before `after` (a page's last mission: gcs.domain.listing): a fleet mission, not its parts
        (`fleet_parts`). Filtered and paged in SQL along the index on (created_at, id)."""
        conditions, parameters = _mission_conditions(where or MissionFilter())
        if after is not None:
            conditions.append("(m.created_at, m.id) < (?, ?)")  # keyset: where the previous page ended
            parameters += [after.created_at, after.id]
        with self._reading() as db:
            rows = db.execute(
                f"SELECT m.* FROM missions AS m WHERE {' AND '.join(conditions)}"
                " ORDER BY m.created_at DESC, m.id DESC LIMIT ?",
                (*parameters, limit),
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
                "UPDATE missions SET updated_at = ?, version = ? WHERE id = ?", (_now(), next_version(db), mission_id)
            )
            self._add_to_register(db, mission_id, record)

    def inspections(self, mission_id: int) -> list[InspectionRecord]:
        """The mission's inspection records by buoy input index."""
        with self._reading() as db:
            rows = db.execute("SELECT record FROM inspections WHERE mission_id = ? ORDER BY buoy", (mission_id,))
            return [InspectionRecord.model_validate_json(row["record"]) for row in rows.fetchall()]

    # ----- the buoy register (gcs.domain.register)
    def store_basemap(self, cell: str, edition: str | None, update: str | None, features: str) -> None:
        """A chart cell's base map features (a JSON list), replacing what an earlier import of the cell stored."""
        with self.transaction() as db:
            db.execute(
                "INSERT INTO chart_basemaps (cell, edition, update_number, imported_at, features)"
                " VALUES (?, ?, ?, ?, ?) ON CONFLICT (cell) DO UPDATE SET edition = excluded.edition,"
                " update_number = excluded.update_number, imported_at = excluded.imported_at,"
                " features = excluded.features",
                (cell, edition, update, _now(), features),
            )

    def basemaps(self) -> list[str]:
        """Every stored cell's base map features (each a JSON list), by cell name."""
        with self._reading() as db:
            rows = db.execute("SELECT features FROM chart_basemaps ORDER BY cell").fetchall()
        return [str(row["features"]) for row in rows]

    def upsert_buoys(self, buoys: Sequence[RegisterBuoy]) -> tuple[list[str], list[str], int]:
        """Register buoys by id, in one transaction: a new one is inserted, a known one whose charted attributes
        changed is updated (its history, MMSI and defects kept, the change an event), an unchanged one takes the new
        source. Returns (created ids, updated ids, how many were unchanged)."""
        created, updated, unchanged = [], [], 0
        now = _now()
        with self.transaction() as db:
            for buoy in buoys:
                row = db.execute(f"SELECT {_BUOY_COLUMNS} FROM buoys WHERE id = ?", (buoy.id,)).fetchone()
                if row is None:
                    db.execute(
                        "INSERT INTO buoys (id, name, lat, lon, kind, light, swing_radius_m, charted, source,"
                        " created_at, updated_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                        (*_charted_values(buoy), buoy.source, now, now),
                    )
                    self._add_event(db, buoy.id, now, "registered", detail={"source": buoy.source})
                    created.append(buoy.id)
                elif changes := buoy.changes_from(_register_buoy(row)):
                    db.execute(
                        "UPDATE buoys SET name = ?, lat = ?, lon = ?, kind = ?, light = ?, swing_radius_m = ?,"
                        " charted = ?, source = ?, updated_at = ? WHERE id = ?",
                        (*_charted_values(buoy)[1:], buoy.source, now, buoy.id),
                    )
                    self._add_event(db, buoy.id, now, "charted", detail={"source": buoy.source, "changes": changes})
                    updated.append(buoy.id)
                else:
                    # the same as charted: the source names the latest import that gave it, no history entry
                    db.execute("UPDATE buoys SET source = ? WHERE id = ?", (buoy.source, buoy.id))
                    unchanged += 1
        return created, updated, unchanged

    def set_buoy_mmsi(self, buoy_id: str, mmsi: int | None) -> bool:
        """Give a register buoy the MMSI of its AIS transmitter (None: it has none). False: no such buoy."""
        with self.transaction() as db:
            cursor = db.execute("UPDATE buoys SET mmsi = ?, updated_at = ? WHERE id = ?", (mmsi, _now(), buoy_id))
            return cursor.rowcount == 1

    def known_buoys(self, ids: Iterable[str]) -> set[str]:
        """Those of `ids` that are register ids."""
        wanted = sorted(set(ids))
        known: set[str] = set()
        with self._reading() as db:
            for start in range(0, len(wanted), 500):  # a bounded IN list per query
                chunk = wanted[start : start + 500]
                rows = db.execute(f"SELECT id FROM buoys WHERE id IN ({', '.join('?' * len(chunk))})", chunk)
                known.update(row["id"] for row in rows.fetchall())
        return known

    def buoys(self, where: BuoyFilter | None = None) -> list[StoredBuoy]:
        """The register's buoys that pass the filter, by id."""
        conditions, parameters = _buoy_conditions(where or BuoyFilter())
        with self._reading() as db:
            rows = db.execute(
                f"SELECT * FROM ({_STORED_BUOYS}) AS buoy WHERE {' AND '.join(conditions) or 'TRUE'} ORDER BY id",
                parameters,
            ).fetchall()
        return [_stored_buoy(row) for row in rows]

    def buoy(self, buoy_id: str) -> StoredBuoy | None:
        with self._reading() as db:
            row = db.execute(f"SELECT * FROM ({_STORED_BUOYS}) AS buoy WHERE id = ?", (buoy_id,)).fetchone()
        return None if row is None else _stored_buoy(row)

    def buoy_events(self, buoy_id: str) -> list[BuoyEvent]:
        """A register buoy's history, oldest first."""
        with self._reading() as db:
            rows = db.execute("SELECT * FROM buoy_events WHERE buoy_id = ? ORDER BY id", (buoy_id,)).fetchall()
        return [_event(row) for row in rows]

    def defects(self, buoy_id: str | None = None, code: str | None = None, unclosed: bool = True) -> list[Defect]:
        """Defects (open or confirmed only, unless `unclosed` is False), of one buoy and of one code when given."""
        conditions = ["state IN (?, ?)"] if unclosed else []
        parameters: list[Any] = list(UNCLOSED) if unclosed else []
        for column, value in (("buoy_id", buoy_id), ("code", code)):
            if value is not None:
                conditions.append(f"{column} = ?")
                parameters.append(value)
        with self._reading() as db:
            rows = db.execute(
                f"SELECT * FROM buoy_defects WHERE {' AND '.join(conditions) or 'TRUE'} ORDER BY id", parameters
            ).fetchall()
        return [_defect(row) for row in rows]

    def set_defect_state(self, buoy_id: str, defect_id: int, state: DefectState, note: str) -> Defect | None:
        """An operator's change of a defect's state, with a note, in its buoy's history. None: the buoy has no
        such defect."""
        now = _now()
        with self.transaction() as db:
            row = db.execute("SELECT * FROM buoy_defects WHERE id = ? AND buoy_id = ?", (defect_id, buoy_id)).fetchone()
            if row is None:
                return None
            db.execute(
                "UPDATE buoy_defects SET state = ?, note = ?, updated_at = ? WHERE id = ?",
                (state, note, now, defect_id),
            )
            self._add_event(db, buoy_id, now, "defect_state", defect_id=defect_id, note=note,
                            detail={"code": row["code"], "from": row["state"], "to": state})  # fmt: skip
            row = db.execute("SELECT * FROM buoy_defects WHERE id = ?", (defect_id,)).fetchone()
        return _defect(row)

    def _add_to_register(self, db: Connection, mission_id: int, record: InspectionRecord) -> None:
        """A stored inspection record of a register buoy (the plan's mark names its register id) joins the buoy's
        history, in the record's transaction; a record stored again for the same buoy of the mission replaces its
        event. Each defect finding opens a defect unless one of its code is still open or confirmed."""
        buoy_id = self._register_id(db, mission_id, record.buoy)
        if buoy_id is None:
            return
        now = _now()
        db.execute(
            "DELETE FROM buoy_events WHERE kind = 'inspection' AND mission_id = ? AND mission_buoy = ?",
            (mission_id, record.buoy),
        )
        self._add_event(db, buoy_id, now, "inspection", mission_id=mission_id, mission_buoy=record.buoy,
                        verdict=record.result.verdict, detail=record.model_dump(mode="json"))  # fmt: skip
        for code, finding in defect_findings(record).items():
            unclosed = db.execute(
                "SELECT id FROM buoy_defects WHERE buoy_id = ? AND code = ? AND state IN (?, ?)",
                (buoy_id, code, *UNCLOSED),
            ).fetchone()
            if unclosed is not None:
                continue
            defect_id = int(
                db.execute(
                    "INSERT INTO buoy_defects (buoy_id, code, state, mission_id, finding, opened_at, updated_at)"
                    " VALUES (?, ?, 'open', ?, ?, ?, ?) RETURNING id",
                    (buoy_id, code, mission_id, _json(finding.model_dump(mode="json")), now, now),
                ).fetchone()["id"]
            )
            self._add_event(db, buoy_id, now, "defect_opened", mission_id=mission_id, mission_buoy=record.buoy,
                            defect_id=defect_id, detail={"code": code})  # fmt: skip

    @staticmethod
    def _register_id(db: Connection, mission_id: int, index: int) -> str | None:
        """The register id of buoy `index` of the mission's plan, when that buoy is in the register."""
        row = db.execute("SELECT plan FROM missions WHERE id = ?", (mission_id,)).fetchone()
        marks = (json.loads(row["plan"]).get("marks") or []) if row is not None else []
        register_id = marks[index].get("register_id") if index < len(marks) else None
        if register_id is None:
            return None
        known = db.execute("SELECT id FROM buoys WHERE id = ?", (register_id,)).fetchone()
        return None if known is None else str(register_id)

    @staticmethod
    def _add_event(db: Connection, buoy_id: str, at: str, kind: str, *, mission_id: int | None = None,
                   mission_buoy: int | None = None, defect_id: int | None = None, verdict: str | None = None,
                   detail: dict[str, Any], note: str | None = None) -> None:  # fmt: skip
        db.execute(
            "INSERT INTO buoy_events (buoy_id, at, kind, mission_id, mission_buoy, defect_id, verdict, detail, note)"
            " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (buoy_id, at, kind, mission_id, mission_buoy, defect_id, verdict, _json(detail), note),
        )

    # ----- removal
    def set_flight_log(self, mission_id: int, log: StoredFlightLog, data: bytes | None = None) -> None:
        """Record (or replace) the flight log fetched for a mission: its bytes, or None with a note."""
        with self._mission_write() as db:
            db.execute("DELETE FROM flight_logs WHERE mission_id = ?", (mission_id,))
            db.execute(
                "INSERT INTO flight_logs (mission_id, data, size_bytes, vehicle_log_id, downloaded_at, note) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (mission_id, data, log.size_bytes, log.vehicle_log_id, log.downloaded_at, log.note),
            )
            # the mission's report links the log: its version and time move so cached reads and drawings are redone
            db.execute(
                "UPDATE missions SET version = ?, updated_at = ? WHERE id = ?", (next_version(db), _now(), mission_id)
            )

    def flight_log(self, mission_id: int) -> StoredFlightLog | None:
        """What was recorded of the mission's flight log, without its bytes (None: nothing yet)."""
        with self._reading() as db:
            row = db.execute(
                "SELECT size_bytes, vehicle_log_id, downloaded_at, note FROM flight_logs WHERE mission_id = ?",
                (mission_id,),
            ).fetchone()
        if row is None:
            return None
        return StoredFlightLog(
            downloaded_at=row["downloaded_at"],
            size_bytes=_optional_int(row["size_bytes"]),
            vehicle_log_id=_optional_int(row["vehicle_log_id"]),
            note=row["note"],
        )

    def flight_log_data(self, mission_id: int) -> bytes | None:
        """The flight log's bytes (None: none was downloaded)."""
        with self._reading() as db:
            row = db.execute("SELECT data FROM flight_logs WHERE mission_id = ?", (mission_id,)).fetchone()
        return None if row is None or row["data"] is None else bytes(row["data"])

    def delete_mission(self, mission_id: int) -> bool:
        """Remove a mission and everything of it (a fleet mission: its parts too): events, telemetry, frames and
        inspections, in one transaction. False when there is no such mission."""
        with self._mission_write() as db:
            rows = db.execute(
                "SELECT id FROM missions WHERE id = ? OR (fleet_id = ? AND fleet_id <> id)", (mission_id, mission_id)
            ).fetchall()
            ids = sorted((int(row["id"]) for row in rows), reverse=True)  # parts (higher ids) before their fleet
            for table in ("frames", "inspections", "telemetry", "mission_events", "flight_logs"):
                db.executemany(f"DELETE FROM {table} WHERE mission_id = ?", [(i,) for i in ids])
            db.executemany("DELETE FROM fleet_coordination WHERE fleet_id = ?", [(i,) for i in ids])
            db.executemany("DELETE FROM missions WHERE id = ?", [(i,) for i in ids])
            if ids:
                next_version(db)  # the list changed: what was cached under the counter is stale
        return bool(ids)
