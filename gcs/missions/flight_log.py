"""A mission's flight log: the vehicle's newest ULog, downloaded over the MAVLink log protocol once the mission's
vehicle is down and disarmed (gcs.vehicle.logs), kept as `mission_<id>.ulg` in the service's flight-log directory
and recorded with the mission (storage's flight_logs). Served by GET /missions/{id}/log and linked from the report.

The vehicle closes a log at its disarm and numbers its logs upwards, so the newest is the flight that just ended.
A download that fails (the vehicle has no logs, does not speak the log protocol, the link is gone, the vehicle is
still armed) is recorded as a note instead; the mission's own record is never touched by it.
"""

from __future__ import annotations

import asyncio
import logging
from datetime import UTC, datetime
from pathlib import Path

from gcs.domain.listing import stored_time
from gcs.storage import StorageError, StoredFlightLog
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.errors import LinkError
from gcs.vehicle.link import LinkManager

log = logging.getLogger(__name__)


def log_file_name(mission_id: int) -> str:
    return f"mission_{mission_id}.ulg"


async def fetch_flight_log(link: LinkManager, storage: AsyncStorage, directory: Path, mission_id: int) -> None:
    """Download the vehicle's newest log for this mission and record it (or a note saying why not). Never raises
    for what a vehicle, a disk or a deleted mission can do: it runs in the background, after the mission ended."""
    now = stored_time(datetime.now(UTC))
    record = await _download(link, directory, mission_id, now)
    if record.note is not None:
        log.warning("mission %s: %s", mission_id, record.note)
    try:
        await storage.set_flight_log(mission_id, record)
    except (StorageError, KeyError) as error:  # e.g. the mission was deleted meanwhile
        log.warning("mission %s: flight log not recorded: %s", mission_id, error)
        await asyncio.to_thread((directory / log_file_name(mission_id)).unlink, True)


async def _download(link: LinkManager, directory: Path, mission_id: int, now: str) -> StoredFlightLog:
    if not link.status.connected:
        return StoredFlightLog(downloaded_at=now, note="flight log not downloaded: no link to the vehicle")
    if link.status.armed:
        note = "flight log not downloaded: the vehicle is still armed, its log still being written"
        return StoredFlightLog(downloaded_at=now, note=note)
    try:
        entry = await link.logs.latest()
        data = await link.logs.download(entry)
    except LinkError as error:  # the log protocol's own errors, or a link that is down
        return StoredFlightLog(downloaded_at=now, note=f"flight log not downloaded: {error}")
    name = log_file_name(mission_id)
    try:
        await asyncio.to_thread(_write, directory / name, data)
    except OSError as error:
        return StoredFlightLog(
            downloaded_at=now, note=f"flight log downloaded but not stored: {error.strerror or error}"
        )
    return StoredFlightLog(downloaded_at=now, file=name, size_bytes=len(data), vehicle_log_id=entry.id)


def _write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".part")
    partial.write_bytes(data)
    partial.replace(path)  # atomic: a reader never sees half a log
