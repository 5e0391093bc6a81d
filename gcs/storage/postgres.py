"""PostgreSQL, for a database several service instances share (a stand-by taking over from a failed one).

A small connection pool (psycopg_pool) in autocommit mode: a read takes a free connection and never waits
behind another thread's write; a write is an explicit transaction on its own connection. The shared SQL's `?`
placeholders become psycopg's `%s` here.

Instances serialise through transaction-level advisory locks, released at commit (after the commit is visible):
- MIGRATION_LOCK around the whole migration, so two instances starting at once migrate once;
- VERSION_LOCK in every mission write, so versions are taken one at a time and committed in increasing order.
They use pg_advisory_xact_lock's single 64-bit key; locks of other modules (the stand-by's per-vehicle lock)
must use the two-key form, which never collides with these.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, ClassVar
from urllib.parse import urlsplit, urlunsplit

import psycopg
from psycopg.conninfo import conninfo_to_dict
from psycopg.rows import dict_row
from psycopg_pool import ConnectionPool

from gcs.storage.base import Connection, Cursor, Storage, StorageError

URL_SCHEMES = ("postgresql://", "postgres://")
MIGRATION_LOCK = 0x6275_6F79_6763_0001  # "buoygc" + 1
VERSION_LOCK = 0x6275_6F79_6763_0002
CONNECT_TIMEOUT_S = 10  # unless the URL says otherwise: an unreachable server is an error, not a hang
# One connection for each thread that may hold one at once: AsyncStorage's readers (4) and writer, and two worker
# threads using the storage directly (a report drawn, a track built): none waits for a connection another holds.
POOL_SIZE = 7


def is_postgres_url(target: object) -> bool:
    return isinstance(target, str) and target.startswith(URL_SCHEMES)


def redacted(url: str) -> str:
    """The URL without its password, for messages and logs."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    return urlunsplit(parts._replace(netloc=parts.netloc.replace(f":{parts.password}@", ":***@", 1)))


class _Placeholders:
    """A psycopg connection taking the shared SQL's `?` placeholders (none of our SQL has a `?` or `%` in a
    literal)."""

    def __init__(self, connection: psycopg.Connection) -> None:
        self._connection = connection

    def execute(self, sql: str, parameters: Sequence[Any] = ()) -> Cursor:
        return self._connection.execute(sql.replace("?", "%s"), parameters or None)

    def executemany(self, sql: str, rows: Iterable[Sequence[Any]]) -> Cursor:
        cursor = self._connection.cursor()
        cursor.executemany(sql.replace("?", "%s"), rows)
        return cursor


class PostgresStorage(Storage):
    dialect: ClassVar[str] = "postgresql"
    constraint_errors: ClassVar[tuple[type[Exception], ...]] = (psycopg.IntegrityError,)

    def __init__(self, url: str) -> None:
        self.location = redacted(url)
        options: dict[str, Any] = {"autocommit": True, "row_factory": dict_row}
        try:
            if "connect_timeout" not in conninfo_to_dict(url):
                options["connect_timeout"] = CONNECT_TIMEOUT_S
            # one connection first: an unreachable server or a bad URL is libpq's own message, not a pool timeout
            psycopg.connect(url, **options).close()
        except psycopg.Error as error:
            raise StorageError(f"cannot connect to {self.location}: {error}") from None
        self._pool = ConnectionPool(url, min_size=1, max_size=POOL_SIZE, kwargs=options, open=False)
        try:
            self._pool.open(wait=True, timeout=CONNECT_TIMEOUT_S)
            self._migrate()
        except (psycopg.Error, StorageError) as error:
            self._pool.close()
            if isinstance(error, StorageError):
                raise
            raise StorageError(f"cannot open database {self.location}: {error}") from None

    @contextmanager
    def _reading(self) -> Iterator[Connection]:
        with self._pool.connection() as connection:
            yield _Placeholders(connection)

    @contextmanager
    def _begin(self) -> Iterator[Connection]:
        with self._pool.connection() as connection, connection.transaction():
            yield _Placeholders(connection)

    def _serialise_migrations(self, db: Connection) -> None:
        db.execute("SELECT pg_advisory_xact_lock(?)", (MIGRATION_LOCK,))

    def _serialise_versions(self, db: Connection) -> None:
        db.execute("SELECT pg_advisory_xact_lock(?)", (VERSION_LOCK,))

    def close(self) -> None:
        self._pool.close()
