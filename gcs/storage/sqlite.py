"""SQLite, the embedded default: one file; writes on one connection shared by the service's threads under a lock,
reads on a connection of each thread's own.

WAL mode, so readers (other processes, and this one's other threads) never wait for a write, nor for another
read: a 2-hour mission's telemetry read in a worker thread does not hold up the event loop's version lookups.
Writes are `BEGIN IMMEDIATE` transactions: they take the file's write lock at once, which serialises writers
across processes, so migrations and version numbers need nothing more.
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import ClassVar

from gcs.storage.base import Connection, Storage, StorageError


class SqliteStorage(Storage):
    dialect: ClassVar[str] = "sqlite"
    constraint_errors: ClassVar[tuple[type[Exception], ...]] = (sqlite3.IntegrityError,)

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.location = str(path)
        try:
            if str(path) != ":memory:":
                self.path.parent.mkdir(parents=True, exist_ok=True)
            # autocommit mode: transactions are explicit (BEGIN IMMEDIATE ... COMMIT) in _begin()
            self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None)
            self._lock = threading.RLock()
            self._db.row_factory = sqlite3.Row
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA foreign_keys=ON")
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._readers = threading.local()
            self._reader_connections: list[sqlite3.Connection] = []
            self._migrate()
        except (sqlite3.Error, OSError) as error:
            raise StorageError(f"cannot open database {path}: {error}") from None

    @contextmanager
    def _reading(self) -> Iterator[Connection]:
        if str(self.path) == ":memory:":  # one in-memory database per connection: share the writer's
            with self._lock:
                yield self._db
            return
        reader = getattr(self._readers, "connection", None)
        if reader is None:
            reader = sqlite3.connect(str(self.path), check_same_thread=False, isolation_level=None)
            reader.row_factory = sqlite3.Row
            self._readers.connection = reader
            with self._lock:
                self._reader_connections.append(reader)
        yield reader

    @contextmanager
    def _begin(self) -> Iterator[Connection]:
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield self._db
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")

    def _serialise_migrations(self, db: Connection) -> None:
        """BEGIN IMMEDIATE already holds the file's write lock."""

    def _serialise_versions(self, db: Connection) -> None:
        """BEGIN IMMEDIATE already holds the file's write lock."""

    def close(self) -> None:
        with self._lock:
            for reader in self._reader_connections:
                reader.close()
            self._db.close()
