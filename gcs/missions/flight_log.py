"""A mission's flight log: the vehicle's newest ULog, downloaded over the MAVLink log protocol once the mission's
vehicle is down and disarmed (gcs.vehicle.logs), and stored with the mission (storage's flight_logs: its bytes in
the database, as the camera frames', so every instance on a shared database serves it). Served by
GET /missions/{id}/log and linked from the report.

The vehicle closes a log at its disarm and numbers its logs upwards, so the newest is the flight that just ended.
A download that fails (the vehicle has no logs, does not speak the log protocol, the link is gone, the vehicle is
still armed) is recorded as a note instead; the mission's own status and reason are never touched by it.
"""

from __future__ import annotations

import logging
from datetime import UTC, datetime

from gcs.domain.listing import stored_time
from gcs.storage import StorageError, StoredFlightLog
from gcs.storage.off_loop import AsyncStorage
from gcs.vehicle.errors import LinkError
from gcs.vehicle.link import LinkManager

log = logging.getLogger(__name__)


async def fetch_flight_log(link: LinkManager, storage: AsyncStorage, mission_id: int) -> None:
    """Download the vehicle's newest log for this mission and record it (or a note saying why not). Never raises
    for what a vehicle or a deleted mission can do: it runs in the background, after the mission ended."""
    record, data = await _download(link, stored_time(datetime.now(UTC)))
    if record.note is not None:
        log.warning("mission %s: %s", mission_id, record.note)
    try:
        await storage.set_flight_log(mission_id, record, data)
    except (StorageError, KeyError) as error:  # e.g. the mission was deleted meanwhile
        log.warning("mission %s: flight log not recorded: %s", mission_id, error)


async def _download(link: LinkManager, now: str) -> tuple[StoredFlightLog, bytes | None]:
    if not link.status.connected:
        return StoredFlightLog(downloaded_at=now, note="flight log not downloaded: no link to the vehicle"), None
    if link.status.armed:
        note = "flight log not downloaded: the vehicle is still armed, its log still being written"
        return StoredFlightLog(downloaded_at=now, note=note), None
    try:
        entry = await link.logs.latest()
        data = await link.logs.download(entry)
    except LinkError as error:  # the log protocol's own errors, or a link that is down
        return StoredFlightLog(downloaded_at=now, note=f"flight log not downloaded: {error}"), None
    return StoredFlightLog(downloaded_at=now, size_bytes=len(data), vehicle_log_id=entry.id), data
