"""The storage as code on the event loop uses it: each call runs in a thread, and the loop goes on meanwhile.

The event loop that answers HTTP also runs every vehicle link: heartbeats, command retries, mission transfers.
A query that waits on the database (a lock another instance holds, a slow disk, a PostgreSQL server far away)
must not stop them, so the loop never calls `Storage` itself: it awaits `AsyncStorage`, which runs each call
in a thread (`Storage` is thread-safe).

- Writes run in one thread, in the order the loop issued them: a mission's events and samples are stored in
  the order they happened, as when the loop wrote them itself. A write the caller stopped waiting for
  (cancelled) still completes: each is one transaction, never half a record.
- Reads run in a small pool: a long read (a two-hour mission's samples) holds up neither the writes nor other
  reads. A read issued after an awaited write sees it.
- Code already running in a worker thread (a report drawn, a track built for display) uses `blocking`, the
  wrapped storage, directly.
"""

from __future__ import annotations

import asyncio
import functools
import threading
from collections.abc import Callable, Hashable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, ParamSpec, TypeVar

from gcs.domain.fleet_coordination import FleetCoordination, Reshare
from gcs.domain.inspection import InspectionRecord, StoredFrame
from gcs.domain.listing import MissionFilter, PageKey
from gcs.domain.planning import FlightParams, Plan
from gcs.domain.records import MissionProgress, MissionResults
from gcs.domain.register import BuoyEvent, BuoyFilter, Defect, DefectState, RegisterBuoy, StoredBuoy
from gcs.domain.schemas import SeparationOut
from gcs.domain.status import MissionStatus
from gcs.storage.base import MissionRecord, Storage, StoredFlightLog

P = ParamSpec("P")
T = TypeVar("T")

READ_THREADS = 4  # the PostgreSQL pool has a connection for each of these and the writer (postgres.POOL_SIZE)


class AsyncStorage:
    """`Storage`'s calls that the service makes from the event loop, as coroutines."""

    def __init__(self, storage: Storage, read_threads: int = READ_THREADS) -> None:
        self.blocking = storage
        self._writer = ThreadPoolExecutor(1, thread_name_prefix="storage-write")
        self._readers = ThreadPoolExecutor(read_threads, thread_name_prefix="storage-read")
        self._queued: dict[Hashable, asyncio.Future[Any]] = {}  # coalesced reads not begun yet, by what they read
        self._queued_lock = threading.Lock()

    async def _run(self, pool: ThreadPoolExecutor, call: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
        return await asyncio.get_running_loop().run_in_executor(pool, functools.partial(call, *args, **kwargs))

    async def _read_coalesced(self, key: Hashable, call: Callable[[], T]) -> T:
        """A read that callers arriving while it still waits for a thread share. One that has begun is not
        joined: it may have read before a newcomer's write committed. So each caller's answer is read after it
        asked, as if it had read alone; 50 clients asking a mission's version at once cost a few thread hops,
        not 50 (the read cache asks it once per request)."""
        with self._queued_lock:
            future = self._queued.get(key)
            if future is None:

                def run() -> T:
                    with self._queued_lock:
                        del self._queued[key]  # begun: a caller from now on reads anew
                    return call()

                future = asyncio.get_running_loop().run_in_executor(self._readers, run)
                self._queued[key] = future
        return await asyncio.shield(future)  # a caller cancelled leaves the read to the others

    async def close(self) -> None:
        """Finish the writes issued, then close the storage."""
        await asyncio.to_thread(self._close)

    def _close(self) -> None:
        self._writer.shutdown(wait=True)
        self._readers.shutdown(wait=True)
        self.blocking.close()

    # ----- writes, one at a time in the order issued
    async def create_mission(self, flight: FlightParams, plan: Plan, vehicle_sysid: int | None = None) -> int:
        return await self._run(self._writer, self.blocking.create_mission, flight, plan, vehicle_sysid=vehicle_sysid)

    async def create_fleet_mission(
        self, flight: FlightParams, plan: Plan, parts: list[tuple[FlightParams, Plan, int]]
    ) -> tuple[int, list[int]]:
        return await self._run(self._writer, self.blocking.create_fleet_mission, flight, plan, parts)

    async def set_status(self, mission_id: int, status: MissionStatus, reason: str | None = None) -> None:
        await self._run(self._writer, self.blocking.set_status, mission_id, status, reason)

    async def set_progress(self, mission_id: int, progress: MissionProgress) -> None:
        await self._run(self._writer, self.blocking.set_progress, mission_id, progress)

    async def set_plan(self, mission_id: int, plan: Plan) -> None:
        await self._run(self._writer, self.blocking.set_plan, mission_id, plan)

    async def set_results(self, mission_id: int, results: MissionResults) -> None:
        await self._run(self._writer, self.blocking.set_results, mission_id, results)

    async def claim_fleet(self, fleet_id: int, coordinator: str) -> FleetCoordination:
        return await self._run(self._writer, self.blocking.claim_fleet, fleet_id, coordinator)

    async def set_fleet_separation(self, fleet_id: int, separation: SeparationOut) -> None:
        await self._run(self._writer, self.blocking.set_fleet_separation, fleet_id, separation)

    async def record_reshare(self, fleet_id: int, plan: Plan, reshare: Reshare, reason: str) -> None:
        await self._run(self._writer, self.blocking.record_reshare, fleet_id, plan, reshare, reason)

    async def add_telemetry(self, mission_id: int, samples: list[dict[str, Any]]) -> None:
        await self._run(self._writer, self.blocking.add_telemetry, mission_id, samples)

    async def add_frame(self, mission_id: int, frame: StoredFrame, data: bytes, max_mission_bytes: int) -> int:
        return await self._run(self._writer, self.blocking.add_frame, mission_id, frame, data, max_mission_bytes)

    async def set_inspection(self, mission_id: int, record: InspectionRecord) -> None:
        await self._run(self._writer, self.blocking.set_inspection, mission_id, record)

    async def delete_mission(self, mission_id: int) -> bool:
        return await self._run(self._writer, self.blocking.delete_mission, mission_id)

    async def store_basemap(self, cell: str, edition: str | None, update: str | None, features: str) -> None:
        await self._run(self._writer, self.blocking.store_basemap, cell, edition, update, features)

    async def upsert_buoys(self, buoys: list[RegisterBuoy]) -> tuple[list[str], list[str], int]:
        return await self._run(self._writer, self.blocking.upsert_buoys, buoys)

    async def set_buoy_mmsi(self, buoy_id: str, mmsi: int | None) -> bool:
        return await self._run(self._writer, self.blocking.set_buoy_mmsi, buoy_id, mmsi)

    async def set_defect_state(self, buoy_id: str, defect_id: int, state: DefectState, note: str) -> Defect | None:
        return await self._run(self._writer, self.blocking.set_defect_state, buoy_id, defect_id, state, note)

    # ----- reads, side by side
    async def get_mission(self, mission_id: int) -> MissionRecord | None:
        return await self._run(self._readers, self.blocking.get_mission, mission_id)

    async def existing_mission(self, mission_id: int) -> MissionRecord:
        """A mission known to be stored (one being flown or followed: such a mission cannot be deleted)."""
        record = await self.get_mission(mission_id)
        assert record is not None, f"mission {mission_id} is not stored"
        return record

    async def list_missions(
        self, limit: int = 100, where: MissionFilter | None = None, after: PageKey | None = None
    ) -> list[MissionRecord]:
        return await self._run(self._readers, self.blocking.list_missions, limit, where, after)

    async def fleet_parts(self, fleet_id: int) -> list[MissionRecord]:
        return await self._run(self._readers, self.blocking.fleet_parts, fleet_id)

    async def fleet_coordination(self, fleet_id: int) -> FleetCoordination | None:
        return await self._run(self._readers, self.blocking.fleet_coordination, fleet_id)

    async def unfinished_missions(self, vehicle_sysid: int | None = None) -> list[int]:
        return await self._run(self._readers, self.blocking.unfinished_missions, vehicle_sysid)

    async def unfinished_fleets(self) -> list[int]:
        return await self._run(self._readers, self.blocking.unfinished_fleets)

    async def mission_version(self, mission_id: int) -> int | None:
        key = ("mission_version", mission_id)
        return await self._read_coalesced(key, functools.partial(self.blocking.mission_version, mission_id))

    async def latest_version(self) -> int:
        return await self._read_coalesced("latest_version", self.blocking.latest_version)

    async def telemetry(self, mission_id: int, limit: int | None = None) -> list[dict[str, Any]]:
        return await self._run(self._readers, self.blocking.telemetry, mission_id, limit)

    async def telemetry_count(self, mission_id: int) -> int:
        key = ("telemetry_count", mission_id)
        return await self._read_coalesced(key, functools.partial(self.blocking.telemetry_count, mission_id))

    async def set_flight_log(self, mission_id: int, log: StoredFlightLog, data: bytes | None = None) -> None:
        await self._run(self._writer, self.blocking.set_flight_log, mission_id, log, data)

    async def flight_log(self, mission_id: int) -> StoredFlightLog | None:
        return await self._run(self._readers, self.blocking.flight_log, mission_id)

    async def flight_log_data(self, mission_id: int) -> bytes | None:
        return await self._run(self._readers, self.blocking.flight_log_data, mission_id)

    async def frames(self, mission_id: int) -> list[StoredFrame]:
        return await self._run(self._readers, self.blocking.frames, mission_id)

    async def frame_data(self, mission_id: int, frame_id: int) -> bytes | None:
        return await self._run(self._readers, self.blocking.frame_data, mission_id, frame_id)

    async def inspections(self, mission_id: int) -> list[InspectionRecord]:
        return await self._run(self._readers, self.blocking.inspections, mission_id)

    async def known_buoys(self, ids: list[str]) -> set[str]:
        return await self._run(self._readers, self.blocking.known_buoys, ids)

    async def basemaps(self) -> list[str]:
        return await self._run(self._readers, self.blocking.basemaps)

    async def buoys(self, where: BuoyFilter | None = None) -> list[StoredBuoy]:
        return await self._run(self._readers, self.blocking.buoys, where)

    async def buoy(self, buoy_id: str) -> StoredBuoy | None:
        return await self._run(self._readers, self.blocking.buoy, buoy_id)

    async def buoy_events(self, buoy_id: str) -> list[BuoyEvent]:
        return await self._run(self._readers, self.blocking.buoy_events, buoy_id)

    async def defects(self, buoy_id: str | None = None, code: str | None = None) -> list[Defect]:
        """Open and confirmed defects, of one buoy and of one code when given."""
        return await self._run(self._readers, self.blocking.defects, buoy_id, code)
