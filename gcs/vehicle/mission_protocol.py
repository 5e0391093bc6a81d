"""The MAVLink mission protocol, client side: upload and download over the link manager.

Upload: MISSION_COUNT -> (MISSION_REQUEST_INT seq -> MISSION_ITEM_INT seq)* -> MISSION_ACK.
Download: MISSION_REQUEST_LIST -> MISSION_COUNT -> (MISSION_REQUEST_INT -> MISSION_ITEM_INT)* -> MISSION_ACK.
Each step waits `step_timeout_s` (wall clock) and resends the last message up to `retries` times, as QGC and
MAVSDK do; a refusal (MISSION_ACK with an error) or silence ends the transfer with a typed exception whose
message names the step and the vehicle's reason. `mission_type` picks the list: the mission (default), the
geofence or the rally points.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from uavcore.mavlink import (
    GCS_SYSID,
    item_from_message,
    item_message,
    mavlink,
    result_name,
)
from uavcore.mission import MissionItem

if TYPE_CHECKING:
    from gcs.vehicle.link import LinkManager

MISSION = mavlink.MAV_MISSION_TYPE_MISSION


class MissionTransferError(RuntimeError):
    """The transfer did not complete (the message says at which step and why)."""


def list_name(mission_type: int) -> str:
    """What a list of this MAV_MISSION_TYPE is called in a transfer's errors."""
    names = {
        MISSION: "mission",
        mavlink.MAV_MISSION_TYPE_FENCE: "geofence",
        mavlink.MAV_MISSION_TYPE_RALLY: "rally points",
    }
    return names.get(mission_type, f"list of mission type {mission_type}")


class MissionRejectedError(MissionTransferError):
    def __init__(self, result: int, step: str, mission_type: int = MISSION) -> None:
        self.result = result
        super().__init__(
            f"the vehicle refused the {list_name(mission_type)} ({result_name('MAV_MISSION_RESULT', result)}) {step}"
        )


class MissionTimeoutError(MissionTransferError):
    pass


def _for_us(message: Any, mission_type: int) -> bool:
    target = getattr(message, "target_system", 0)
    return target in (0, GCS_SYSID) and getattr(message, "mission_type", MISSION) == mission_type


async def _next(inbox: asyncio.Queue, timeout_s: float, mission_type: int) -> Any | None:
    """The next message for this GCS, or None once timeout_s passes without one."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while (remaining := deadline - loop.time()) > 0:
        try:
            async with asyncio.timeout(remaining):
                message = await inbox.get()
        except TimeoutError:
            return None
        if _for_us(message, mission_type):
            return message
    return None


async def upload_items(
    link: LinkManager,
    items: Sequence[MissionItem],
    step_timeout_s: float = 1.0,
    retries: int = 5,
    mission_type: int = MISSION,
) -> None:
    """Upload items (seq 0..n-1); returns when the vehicle acknowledges with MAV_MISSION_ACCEPTED."""
    if not items:
        raise ValueError("an upload needs at least one mission item")
    count = link.encoder.mission_count_encode(*link.target, len(items), mission_type)
    what = list_name(mission_type)
    with link.subscribe({"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"}) as inbox:
        last_sent, step, tries_left, highest_sent = count, "after MISSION_COUNT", retries, -1
        link.send(count)
        while True:
            message = await _next(inbox, step_timeout_s, mission_type)
            if message is None:
                if tries_left == 0:
                    raise MissionTimeoutError(f"{what} upload: no answer {step} ({retries} retries)")
                tries_left -= 1
                link.send(last_sent)
                continue
            if message.get_type() == "MISSION_ACK":
                if message.type != mavlink.MAV_MISSION_ACCEPTED:
                    raise MissionRejectedError(message.type, step, mission_type)
                if highest_sent == len(items) - 1:
                    return
                raise MissionTransferError(
                    f"{what} upload: accepted after only {highest_sent + 1} of {len(items)} items"
                )
            seq = message.seq
            if not 0 <= seq < len(items):
                raise MissionTransferError(f"{what} upload: the vehicle asked for item {seq} of {len(items)}")
            last_sent = item_message(items[seq], *link.target)
            step, tries_left = f"after item {seq}", retries
            highest_sent = max(highest_sent, seq)
            link.send(last_sent)


async def _exchange(
    link: LinkManager,
    inbox: asyncio.Queue,
    request: Any,
    accept,
    what: str,
    timeout_s: float,
    retries: int,
    mission_type: int,
) -> Any:
    """Send request until a message satisfying accept(message) arrives."""
    for _ in range(retries + 1):
        link.send(request)
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        while (remaining := deadline - loop.time()) > 0:
            message = await _next(inbox, remaining, mission_type)
            if message is None:
                break
            if message.get_type() == "MISSION_ACK" and message.type != mavlink.MAV_MISSION_ACCEPTED:
                raise MissionRejectedError(message.type, f"while waiting for {what}", mission_type)
            if accept(message):
                return message
    raise MissionTimeoutError(f"mission download: no {what} ({retries} retries)")


async def download_items(
    link: LinkManager, step_timeout_s: float = 1.0, retries: int = 5, mission_type: int = MISSION
) -> list[MissionItem]:
    """The list stored on the vehicle, item by item, acknowledged at the end."""
    with link.subscribe({"MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ACK"}) as inbox:
        count = await _exchange(
            link,
            inbox,
            link.encoder.mission_request_list_encode(*link.target, mission_type),
            lambda m: m.get_type() == "MISSION_COUNT",
            "MISSION_COUNT",
            step_timeout_s,
            retries,
            mission_type,
        )
        items = []
        for seq in range(count.count):
            message = await _exchange(
                link,
                inbox,
                link.encoder.mission_request_int_encode(*link.target, seq, mission_type),
                lambda m, seq=seq: m.get_type() == "MISSION_ITEM_INT" and m.seq == seq,
                f"MISSION_ITEM_INT {seq}",
                step_timeout_s,
                retries,
                mission_type,
            )
            items.append(item_from_message(message))
        link.send(link.encoder.mission_ack_encode(*link.target, mavlink.MAV_MISSION_ACCEPTED, mission_type))
    return items
