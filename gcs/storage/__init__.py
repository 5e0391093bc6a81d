"""Persistence: the only package that knows SQL. SQLite (a file, the embedded default) or PostgreSQL (a
`postgresql://` URL, a database several service instances can share).

Missions, their status history, their telemetry and their inspections (camera frames and a record per buoy),
in a schema versioned by a `schema_migrations` table, and every write inside a transaction so a crash or an
error never leaves half a record. Structured parts of a mission (plan, flight parameters, progress, results,
inspection records) are JSON documents: read and written whole, never queried field by field.

Design: one `Storage` class (`base`) holds every query, written once; a dialect subclass (`sqlite`,
`postgres`) only says how to connect, how transactions and cross-instance serialisation work, and which
driver errors mean a broken constraint; `migrations` keeps each schema version's SQL for both dialects side
by side. The two databases differ in so little (placeholders, identity columns, locks) that a query layer per
dialect would mostly repeat the same SQL. Callers open one with `open_storage(target)` and see only `Storage`.
"""

from __future__ import annotations

from pathlib import Path

from gcs.storage.base import ConstraintError, FramesFullError, MissionRecord, Storage, StorageError, StoredFlightLog
from gcs.storage.migrations import MIGRATIONS
from gcs.storage.postgres import PostgresStorage, is_postgres_url, redacted
from gcs.storage.sqlite import SqliteStorage

__all__ = [
    "MIGRATIONS",
    "ConstraintError",
    "FramesFullError",
    "MissionRecord",
    "PostgresStorage",
    "SqliteStorage",
    "Storage",
    "StorageError",
    "StoredFlightLog",
    "is_postgres_url",
    "open_storage",
    "redacted",
]


def open_storage(target: str | Path) -> Storage:
    """The storage at `target`, migrated to this service's schema: a `postgresql://` (or `postgres://`) URL,
    else a SQLite file. Raises StorageError (with a message naming the database) when it cannot be opened."""
    if is_postgres_url(target):
        return PostgresStorage(str(target))
    return SqliteStorage(target)
