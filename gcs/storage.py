"""SQLite persistence: the only module that knows SQL.

One file (WAL mode, so readers never wait for the recorder's writes), a schema versioned by a
`schema_migrations` table, and every write inside a transaction so a crash or an error never leaves half a
record. Structured parts of a mission (plan, flight parameters, progress, results) are JSON documents: they
are read and written whole, never queried field by field.
"""

from __future__ import annotations

import json
import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from gcs.status import UNFINISHED, MissionStatus

# Each entry upgrades the schema by one version; never edit a released one, append a new one. (The status CHECK
# lists MissionStatus's values: a status added later needs a migration that rebuilds the table's CHECK.)
MIGRATIONS: list[str] = [
    f"""
    CREATE TABLE missions (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        created_at TEXT NOT NULL,
        updated_at TEXT NOT NULL,
        status TEXT NOT NULL CHECK (status IN ({", ".join(f"'{s.value}'" for s in MissionStatus)})),
        reason TEXT,
        flight TEXT NOT NULL,
        plan TEXT NOT NULL,
        progress TEXT NOT NULL DEFAULT '{{}}',
        results TEXT
    );
    CREATE TABLE mission_events (
        id INTEGER PRIMARY KEY AUTOINCREMENT,
        mission_id INTEGER NOT NULL REFERENCES missions(id),
        at TEXT NOT NULL,
        status TEXT NOT NULL,
        reason TEXT
    );
    CREATE TABLE telemetry (
        mission_id INTEGER NOT NULL REFERENCES missions(id),
        t_s REAL NOT NULL,
        sample TEXT NOT NULL
    );
    CREATE INDEX telemetry_by_mission ON telemetry (mission_id, t_s);
    CREATE INDEX events_by_mission ON mission_events (mission_id, id);
    """,
    # 2: a change counter per mission, so readers (a read cache, a stand-by service) can tell cheaply whether a
    # mission or the list changed: every write to a mission sets its version above every other mission's.
    """
    ALTER TABLE missions ADD COLUMN version INTEGER NOT NULL DEFAULT 0;
    CREATE INDEX missions_by_version ON missions (version);
    """,
]

# The next version, taken inside the write's transaction (BEGIN IMMEDIATE serialises writers, so it is unique).
NEXT_VERSION = "(SELECT COALESCE(MAX(version), 0) + 1 FROM missions)"


class StorageError(RuntimeError):
    """The database cannot be opened or is from a newer version of the service."""


@dataclass
class MissionRecord:
    id: int
    created_at: str
    updated_at: str
    status: MissionStatus
    reason: str | None
    flight: dict[str, Any]
    plan: dict[str, Any]
    progress: dict[str, Any]
    results: dict[str, Any] | None
    events: list[dict[str, Any]] = field(default_factory=list)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def _json(value: Any) -> str:
    # allow_nan=False: a NaN would make the stored document unreadable by strict JSON clients
    return json.dumps(value, allow_nan=False, separators=(",", ":"))


class Storage:
    """Missions, their status history and their telemetry. Safe to share between threads (one lock)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if str(path) != ":memory:":
            self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            # autocommit mode: transactions are explicit (BEGIN IMMEDIATE ... COMMIT) in transaction()
            self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
        except sqlite3.Error as error:
            raise StorageError(f"cannot open database {path}: {error}") from None
        self._lock = threading.RLock()
        self._db.row_factory = sqlite3.Row
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA foreign_keys=ON")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._migrate()

    # ----- plumbing
    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """All statements inside commit together or not at all."""
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield self._db
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")

    def schema_version(self) -> int:
        with self._lock:
            row = self._db.execute("SELECT COALESCE(MAX(version), 0) FROM schema_migrations").fetchone()
        return int(row[0])

    def _migrate(self) -> None:
        with self.transaction() as db:
            db.execute(
                "CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, applied_at TEXT NOT NULL)"
            )
        current = self.schema_version()
        if current > len(MIGRATIONS):
            raise StorageError(f"{self.path}: schema version {current} is newer than this service ({len(MIGRATIONS)})")
        for version in range(current + 1, len(MIGRATIONS) + 1):
            with self.transaction() as db:
                for statement in MIGRATIONS[version - 1].split(";"):
                    if statement.strip():
                        db.execute(statement)
                db.execute("INSERT INTO schema_migrations VALUES (?, ?)", (version, _now()))

    def close(self) -> None:
        with self._lock:
            self._db.close()

    # ----- missions
    def create_mission(
        self, flight: dict[str, Any], plan: dict[str, Any], status: MissionStatus = MissionStatus.PLANNED
    ) -> int:
        now = _now()
        with self.transaction() as db:
            cursor = db.execute(
                f"INSERT INTO missions (created_at, updated_at, status, flight, plan, version)"
                f" VALUES (?, ?, ?, ?, ?, {NEXT_VERSION})",
                (now, now, status, _json(flight), _json(plan)),
            )
            mission_id = int(cursor.lastrowid)
            db.execute(
                "INSERT INTO mission_events (mission_id, at, status) VALUES (?, ?, ?)", (mission_id, now, status)
            )
        return mission_id

    def set_status(self, mission_id: int, status: MissionStatus, reason: str | None = None) -> None:
        now = _now()
        with self.transaction() as db:
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

    def set_progress(self, mission_id: int, progress: dict[str, Any]) -> None:
        with self.transaction() as db:
            db.execute(
                f"UPDATE missions SET progress = ?, updated_at = ?, version = {NEXT_VERSION} WHERE id = ?",
                (_json(progress), _now(), mission_id),
            )

    def set_results(self, mission_id: int, results: dict[str, Any]) -> None:
        with self.transaction() as db:
            db.execute(
                f"UPDATE missions SET results = ?, updated_at = ?, version = {NEXT_VERSION} WHERE id = ?",
                (_json(results), _now(), mission_id),
            )

    def unfinished_missions(self) -> list[int]:
        """Ids of missions a previous run of the service left uploading, uploaded or flying, oldest first."""
        with self._lock:
            rows = self._db.execute(
                f"SELECT id FROM missions WHERE status IN ({', '.join('?' * len(UNFINISHED))}) ORDER BY id",
                UNFINISHED,
            ).fetchall()
        return [int(row["id"]) for row in rows]

    def _record(self, row: sqlite3.Row, events: list[dict[str, Any]]) -> MissionRecord:
        return MissionRecord(
            id=int(row["id"]),
            created_at=row["created_at"],
            updated_at=row["updated_at"],
            status=MissionStatus(row["status"]),
            reason=row["reason"],
            flight=json.loads(row["flight"]),
            plan=json.loads(row["plan"]),
            progress=json.loads(row["progress"]),
            results=json.loads(row["results"]) if row["results"] else None,
            events=events,
        )

    def get_mission(self, mission_id: int) -> MissionRecord | None:
        with self._lock:
            row = self._db.execute("SELECT * FROM missions WHERE id = ?", (mission_id,)).fetchone()
            if row is None:
                return None
            events = self._db.execute(
                "SELECT at, status, reason FROM mission_events WHERE mission_id = ? ORDER BY id", (mission_id,)
            ).fetchall()
        return self._record(row, [dict(event) for event in events])

    def mission_version(self, mission_id: int) -> int | None:
        """The mission's change counter (None: no such mission): it grows at every write to the mission."""
        with self._lock:
            row = self._db.execute("SELECT version FROM missions WHERE id = ?", (mission_id,)).fetchone()
        return None if row is None else int(row[0])

    def latest_version(self) -> int:
        """The highest change counter of all missions: it grows whenever any mission is created or changes."""
        with self._lock:
            row = self._db.execute("SELECT COALESCE(MAX(version), 0) FROM missions").fetchone()
        return int(row[0])

    def list_missions(self, limit: int = 100) -> list[MissionRecord]:
        with self._lock:
            rows = self._db.execute("SELECT * FROM missions ORDER BY id DESC LIMIT ?", (limit,)).fetchall()
        return [self._record(row, []) for row in rows]

    # ----- telemetry
    def add_telemetry(self, mission_id: int, samples: list[dict[str, Any]]) -> None:
        """Append samples (each with a `t_s` key) in one transaction: all of them or none."""
        if not samples:
            return
        with self.transaction() as db:
            db.executemany(
                "INSERT INTO telemetry (mission_id, t_s, sample) VALUES (?, ?, ?)",
                [(mission_id, float(s["t_s"]), _json(s)) for s in samples],
            )

    def telemetry(self, mission_id: int, limit: int | None = None) -> list[dict[str, Any]]:
        with self._lock:
            rows = self._db.execute(
                "SELECT sample FROM telemetry WHERE mission_id = ? ORDER BY rowid LIMIT ?",
                (mission_id, -1 if limit is None else limit),
            ).fetchall()
        return [json.loads(row["sample"]) for row in rows]

    def telemetry_count(self, mission_id: int) -> int:
        with self._lock:
            row = self._db.execute("SELECT COUNT(*) FROM telemetry WHERE mission_id = ?", (mission_id,)).fetchone()
        return int(row[0])
