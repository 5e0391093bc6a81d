"""The schema, as a list of migrations: each upgrades it by one version, in both dialects.

Never edit a released migration, append a new one. The status CHECK lists MissionStatus's values: a status added
later needs a migration that rebuilds the CHECK (migration 6 shows how: PostgreSQL replaces the constraint,
SQLite rewrites the table's definition, the procedure SQLite's ALTER TABLE documentation gives for a CHECK).

Dialect differences: SQLite's `INTEGER PRIMARY KEY AUTOINCREMENT` is PostgreSQL's `BIGINT GENERATED ALWAYS AS
IDENTITY`; SQLite's REAL is DOUBLE PRECISION. Timestamps are ISO 8601 text and JSON documents are TEXT in both:
they are read and written whole, never queried field by field, so both backends hand back the same strings.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from gcs.domain.status import MissionStatus

# The statuses of migration 1, as released (MissionStatus has grown since: migration 6)
_FIRST_STATUSES = "'planned', 'uploading', 'uploaded', 'flying', 'completed', 'aborted', 'failed'"
_STATUSES = ", ".join(f"'{status.value}'" for status in MissionStatus)


@dataclass(frozen=True)
class Migration:
    sqlite: str
    postgresql: str
    sqlite_steps: Callable[[Any], None] | None = None  # run after the SQLite statements, with the connection

    def statements(self, dialect: str) -> list[str]:
        script = self.sqlite if dialect == "sqlite" else self.postgresql
        return [statement for statement in script.split(";") if statement.strip()]


def _first_schema(integer: str, key: str, real: str) -> str:
    """Migration 1: missions, their status history and their telemetry (integer, key and float types per dialect)."""
    return f"""
    CREATE TABLE missions (
        id {key},
        created_at TEXT NOT NULL,
        updated_at TEXT NOT NULL,
        status TEXT NOT NULL CHECK (status IN ({_FIRST_STATUSES})),
        reason TEXT,
        flight TEXT NOT NULL,
        plan TEXT NOT NULL,
        progress TEXT NOT NULL DEFAULT '{{}}',
        results TEXT
    );
    CREATE TABLE mission_events (
        id {key},
        mission_id {integer} NOT NULL REFERENCES missions(id),
        at TEXT NOT NULL,
        status TEXT NOT NULL,
        reason TEXT
    );
    CREATE TABLE telemetry (
        mission_id {integer} NOT NULL REFERENCES missions(id),
        t_s {real} NOT NULL,
        sample TEXT NOT NULL
    );
    CREATE INDEX telemetry_by_mission ON telemetry (mission_id, t_s);
    CREATE INDEX events_by_mission ON mission_events (mission_id, id);
    """


def _change_counter(integer: str) -> str:
    """Migration 2: a change counter per mission, so readers (a read cache, a stand-by service) can tell cheaply
    whether a mission or the list changed: every write to a mission sets its version above every other mission's."""
    return f"""
    ALTER TABLE missions ADD COLUMN version {integer} NOT NULL DEFAULT 0;
    CREATE INDEX missions_by_version ON missions (version);
    """


# Migration 3: one sample per mission and instant. A stand-by service taking over a flying mission may record
# again samples the failed owner already stored; with this index add_telemetry skips them. Duplicates stored
# before it are removed first, keeping the first stored (PostgreSQL's telemetry has no row id: its table is
# append-only, so the lowest ctid is the first stored).
_ONE_SAMPLE_PER_INSTANT = """
    DROP INDEX telemetry_by_mission;
    CREATE UNIQUE INDEX telemetry_by_mission ON telemetry (mission_id, t_s);
"""


TRACK_COLUMNS = ("lat", "lon", "cross_track_m")  # the sample fields migration 4 copies into columns


def _track_columns(real: str, field: str) -> str:
    """Migration 4: the position and cross-track error of each sample as columns beside its document, so the
    display track of a long mission (72 000 samples for 2 hours) is read without decoding every document."""
    added = "".join(f"ALTER TABLE telemetry ADD COLUMN {column} {real};" for column in TRACK_COLUMNS)
    filled = ", ".join(f"{column} = {field.format(column)}" for column in TRACK_COLUMNS)
    return f"{added} UPDATE telemetry SET {filled};"


def _fleet_columns(integer: str) -> str:
    """Migration 5: which vehicle a mission flies on (its MAVLink system id; NULL: the service's one vehicle, as
    every mission before a fleet), and for a fleet mission's part, the fleet mission it belongs to."""
    return f"""
    ALTER TABLE missions ADD COLUMN vehicle_sysid {integer};
    ALTER TABLE missions ADD COLUMN fleet_id {integer} REFERENCES missions(id);
    CREATE INDEX missions_by_fleet ON missions (fleet_id);
    """


def _inspection_tables(integer: str, key: str, blob: str) -> str:
    """Migration 7: the inspection's camera frames (the image's bytes beside what the camera said of it and what
    was found in it) and each buoy's inspection record, both removed with their mission."""
    return f"""
    CREATE TABLE frames (
        id {key},
        mission_id {integer} NOT NULL REFERENCES missions(id),
        buoy {integer} NOT NULL,
        captured TEXT NOT NULL,
        size {integer} NOT NULL,
        data {blob} NOT NULL
    );
    CREATE INDEX frames_by_mission ON frames (mission_id, buoy, id);
    CREATE TABLE inspections (
        mission_id {integer} NOT NULL REFERENCES missions(id),
        buoy {integer} NOT NULL,
        record TEXT NOT NULL,
        PRIMARY KEY (mission_id, buoy)
    );
    """


def _register_tables(integer: str, key: str, real: str) -> str:
    """Migration 8: the buoy register. A buoy by its register id (the chart's LNAM, or the id given) with its
    charted attributes (`charted`: a JSON document); its defects, one per finding code an inspection found, with the
    state an operator sets; and its history of events. The events and defects name the mission they came from
    without a foreign key: a buoy's history outlives a mission deleted later."""
    return f"""
    CREATE TABLE buoys (
        id TEXT PRIMARY KEY,
        name TEXT,
        lat {real} NOT NULL,
        lon {real} NOT NULL,
        kind TEXT,
        light TEXT,
        swing_radius_m {real} NOT NULL,
        charted TEXT NOT NULL,
        mmsi {integer},
        source TEXT NOT NULL,
        created_at TEXT NOT NULL,
        updated_at TEXT NOT NULL
    );
    CREATE INDEX buoys_by_mmsi ON buoys (mmsi);
    CREATE TABLE buoy_defects (
        id {key},
        buoy_id TEXT NOT NULL REFERENCES buoys(id),
        code TEXT NOT NULL,
        state TEXT NOT NULL CHECK (state IN ('open', 'confirmed', 'closed')),
        mission_id {integer} NOT NULL,
        finding TEXT NOT NULL,
        opened_at TEXT NOT NULL,
        updated_at TEXT NOT NULL,
        note TEXT
    );
    CREATE INDEX defects_by_buoy ON buoy_defects (buoy_id, state);
    CREATE TABLE buoy_events (
        id {key},
        buoy_id TEXT NOT NULL REFERENCES buoys(id),
        at TEXT NOT NULL,
        kind TEXT NOT NULL,
        mission_id {integer},
        mission_buoy {integer},
        defect_id {integer} REFERENCES buoy_defects(id),
        verdict TEXT,
        detail TEXT NOT NULL,
        note TEXT
    );
    CREATE INDEX events_by_buoy ON buoy_events (buoy_id, id);
    CREATE INDEX buoy_events_by_mission ON buoy_events (mission_id, mission_buoy);
    """


# Migration 9: GET /missions lists newest first by (created_at, id) and pages with `(created_at, id) < (?, ?)`:
# this index gives that order and starts each page where the last one ended, instead of sorting every mission
# per request (created_at is fixed-width ISO text in UTC, so the text order is the time order).
_BY_CREATION = "CREATE INDEX missions_by_creation ON missions (created_at, id);"
# Migration 10: the base map from the register's chart cells (gcs.domain.chart_basemap), a cell's features
# as one JSON list under its name: a newer edition or update replaces them
_CHART_BASEMAPS = """
    CREATE TABLE chart_basemaps (
        cell TEXT PRIMARY KEY,
        edition TEXT,
        update_number TEXT,
        imported_at TEXT NOT NULL,
        features TEXT NOT NULL
    );
"""
# Migration 11: the change counter in a table of its own (gcs.storage.base.next_version), from the highest version
# stored: derived from the missions, it fell back when the latest mission was deleted and gave its number again
_MISSION_CHANGES = """
    CREATE TABLE mission_changes (id INTEGER PRIMARY KEY CHECK (id = 1), version BIGINT NOT NULL);
    INSERT INTO mission_changes (id, version) SELECT 1, COALESCE(MAX(version), 0) FROM missions;
"""

# Migration 12: a fleet mission's coordinator state (gcs.domain.fleet_coordination), one row per fleet mission, so
# that another service instance can carry the fleet mission on: the separation so far, the re-shares decided (JSON:
# a list, read and written whole), and the instance following it
_FLEET_COORDINATION = """
    CREATE TABLE fleet_coordination (
        fleet_id {integer} PRIMARY KEY REFERENCES missions(id),
        coordinator TEXT,
        min_horizontal_m {real},
        min_vertical_m {real},
        min_distance_m {real},
        reshares TEXT NOT NULL DEFAULT '[]',
        updated_at TEXT NOT NULL
    );
"""


def _flight_logs(blob: str) -> str:
    """Migration 13: the flight log a mission's vehicle kept (ULog, downloaded over the MAVLink log protocol after the
    landing), its bytes in the database as the camera frames' (every instance on a shared database serves it), or,
    when the download failed, only the note saying why (data NULL)."""
    return f"""
    CREATE TABLE flight_logs (
        mission_id BIGINT PRIMARY KEY REFERENCES missions(id),
        data {blob},
        size_bytes BIGINT,
        vehicle_log_id BIGINT,
        downloaded_at TEXT NOT NULL,
        note TEXT
    );
"""


def _sqlite_status_check(db: Any) -> None:
    """Migration 6 in SQLite: the missions table's CHECK lists every MissionStatus. SQLite cannot alter a
    constraint; a CHECK that admits more values changes no stored row, so the table's definition is rewritten in
    place and the schema version raised, so every connection reads the new definition (sqlite.org/lang_altertable
    .html, "making other kinds of table schema changes")."""
    version = db.execute("PRAGMA schema_version").fetchone()[0]
    db.execute("PRAGMA writable_schema=ON")
    db.execute(
        "UPDATE sqlite_master SET sql = replace(sql, ?, ?) WHERE type = 'table' AND name = 'missions'",
        (f"CHECK (status IN ({_FIRST_STATUSES}))", f"CHECK (status IN ({_STATUSES}))"),
    )
    db.execute(f"PRAGMA schema_version={int(version) + 1}")
    db.execute("PRAGMA writable_schema=OFF")


MIGRATIONS: list[Migration] = [
    Migration(
        sqlite=_first_schema("INTEGER", "INTEGER PRIMARY KEY AUTOINCREMENT", "REAL"),
        postgresql=_first_schema("BIGINT", "BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY", "DOUBLE PRECISION"),
    ),
    Migration(sqlite=_change_counter("INTEGER"), postgresql=_change_counter("BIGINT")),
    Migration(
        sqlite="DELETE FROM telemetry WHERE rowid NOT IN (SELECT MIN(rowid) FROM telemetry GROUP BY mission_id, t_s);"
        + _ONE_SAMPLE_PER_INSTANT,
        postgresql="DELETE FROM telemetry AS later USING telemetry AS first WHERE later.mission_id = first.mission_id"
        " AND later.t_s = first.t_s AND later.ctid > first.ctid;" + _ONE_SAMPLE_PER_INSTANT,
    ),
    Migration(
        sqlite=_track_columns("REAL", "json_extract(sample, '$.{}')"),
        postgresql=_track_columns("DOUBLE PRECISION", "(sample::jsonb ->> '{}')::double precision"),
    ),
    Migration(sqlite=_fleet_columns("INTEGER"), postgresql=_fleet_columns("BIGINT")),
    # Migration 6: the status waiting_for_battery (a mission between sorties, until the operator swaps the pack)
    Migration(
        sqlite="",
        postgresql="ALTER TABLE missions DROP CONSTRAINT missions_status_check;"
        f"ALTER TABLE missions ADD CONSTRAINT missions_status_check CHECK (status IN ({_STATUSES}));",
        sqlite_steps=_sqlite_status_check,
    ),
    Migration(
        sqlite=_inspection_tables("INTEGER", "INTEGER PRIMARY KEY AUTOINCREMENT", "BLOB"),
        postgresql=_inspection_tables("BIGINT", "BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY", "BYTEA"),
    ),
    Migration(
        sqlite=_register_tables("INTEGER", "INTEGER PRIMARY KEY AUTOINCREMENT", "REAL"),
        postgresql=_register_tables("BIGINT", "BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY", "DOUBLE PRECISION"),
    ),
    Migration(sqlite=_BY_CREATION, postgresql=_BY_CREATION),
    Migration(sqlite=_CHART_BASEMAPS, postgresql=_CHART_BASEMAPS),
    Migration(sqlite=_MISSION_CHANGES, postgresql=_MISSION_CHANGES),
    Migration(
        sqlite=_FLEET_COORDINATION.format(integer="INTEGER", real="REAL"),
        postgresql=_FLEET_COORDINATION.format(integer="BIGINT", real="DOUBLE PRECISION"),
    ),
    Migration(sqlite=_flight_logs("BLOB"), postgresql=_flight_logs("BYTEA")),
]
