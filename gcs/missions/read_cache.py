"""The read side's maintained view: each document the read routes serve, encoded once per version.

A GET of a mission (or of the list) used to rebuild the document per request: read the row, parse its JSON
columns, rebuild the plan, validate the document against the response model and encode it, all on the event
loop. Here the encoded bytes are kept with the storage's change counter they were built at
(`Storage.mission_version`, `Storage.latest_version`) and served while the counter has not moved: one indexed
query per request. The counter lives in the database, so a second service instance writing to the same database
moves it too, and no instance serves a document older than what another one wrote.

Correctness needs one ordering only: read the version *before* building. The document built is then at least as
new as that version (a write in between only makes it newer, and the next request, seeing the higher version,
builds again); it can never be older than the version it is filed under.
"""

from __future__ import annotations

import asyncio
import threading
from collections import OrderedDict
from collections.abc import Awaitable, Callable, Hashable, Sized
from dataclasses import dataclass
from typing import Generic, TypeVar

# What a document's validity is checked against: the storage's change counter, or a tuple of such counters
# (a track also depends on how many samples are stored, which the mission's version does not count).
Version = int | tuple[int, ...]
# What is cached: encoded bytes, or a document with what is sent beside them (a page of GET /missions and its next
# page's cursor, gcs.reports.views.MissionsPage); its len() is its size in bytes, for the byte budget.
D = TypeVar("D", bound=Sized)


@dataclass(frozen=True)
class CachedDocument(Generic[D]):
    version: Version
    body: D


class VersionedCache(Generic[D]):
    """Encoded documents by key, each valid while its version is the current one; least recently used entries
    go first beyond `max_entries` or `max_bytes` (a track with a large max_points is megabytes: the byte budget
    bounds the memory whatever keys clients ask for). `lookup` and `store` are thread-safe; `get` runs on the
    event loop."""

    def __init__(self, max_entries: int = 256, max_bytes: int = 64 * 2**20) -> None:
        self.max_entries, self.max_bytes = max_entries, max_bytes
        self._entries: OrderedDict[Hashable, CachedDocument[D]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self._building: dict[tuple[Hashable, Version], asyncio.Future[D]] = {}  # on the event loop only
        self.hits = self.misses = 0  # for tests and the benchmark: how often the cache answered

    async def get(self, key: Hashable, version: Version, build: Callable[[], Awaitable[D]]) -> D:
        """The document for `key` at `version` (read from storage before this call), built by `build` when the
        cache has none at that version: once, however many requests miss together (after a write moved the
        version, 50 clients polling a flying mission would otherwise each read and encode it again). One slow
        build never holds up reads of other keys or versions. Called on the event loop."""
        body = self.lookup(key, version)
        if body is not None:
            return body
        pending = self._building.get((key, version))
        if pending is None:
            pending = self._building[(key, version)] = asyncio.ensure_future(self._build(key, version, build))
        return await asyncio.shield(pending)  # a request cancelled leaves the build to the others

    async def _build(self, key: Hashable, version: Version, build: Callable[[], Awaitable[D]]) -> D:
        try:
            body = await build()
            self.store(key, version, body)
            return body
        finally:
            del self._building[(key, version)]

    def lookup(self, key: Hashable, version: Version) -> D | None:
        """The document for `key` if the cache holds it at exactly `version`."""
        with self._lock:
            entry = self._entries.get(key)
            if entry is None or entry.version != version:
                self.misses += 1
                return None
            self._entries.move_to_end(key)
            self.hits += 1
            return entry.body

    def store(self, key: Hashable, version: Version, body: D) -> None:
        # Two builds racing may leave the older one filed last: a lookup needs the exact version, so that only
        # costs one more build, never a stale answer.
        with self._lock:
            if (previous := self._entries.pop(key, None)) is not None:
                self._bytes -= len(previous.body)
            self._entries[key] = CachedDocument(version, body)
            self._bytes += len(body)
            while len(self._entries) > 1 and (len(self._entries) > self.max_entries or self._bytes > self.max_bytes):
                _, evicted = self._entries.popitem(last=False)
                self._bytes -= len(evicted.body)

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def size_bytes(self) -> int:
        return self._bytes
