"""SQLite, the embedded default: one file, one connection shared by the service's threads under a lock.

WAL mode, so readers in other processes never wait for this one's writes. Writes are `BEGIN IMMEDIATE`
transactions: they take the file's write lock at once, which serialises writers across processes, so
migrations and version numbers need nothing more.
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
            self._migrate()
        except (sqlite3.Error, OSError) as error:
            raise StorageError(f"cannot open database {path}: {error}") from None

    @contextmanager
    def _reading(self) -> Iterator[Connection]:
        with self._lock:
            yield self._db

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
            self._db.close()
