"""The mission protocol, vehicle side: upload, download, clear, set current, for the three lists a vehicle
stores (MAV_MISSION_TYPE): the mission, the geofence (MAV_CMD_NAV_FENCE_* items, see uavcore.geofence) and the
rally points (MAV_CMD_NAV_RALLY_POINT).

Upload: MISSION_COUNT -> MISSION_REQUEST_INT(seq) ... <- MISSION_ITEM_INT -> MISSION_ACK. A missing item is
re-requested after RETRY_S of wall-clock time; the transfer is abandoned after TIMEOUT_S without progress;
every way a transfer ends (accepted, refused, timed out, superseded by a new MISSION_COUNT, cancelled)
resets the state, so an aborted upload never blocks the next one. Items are stored verbatim. The last item
arriving again after an accepted upload means the GCS lost our final MISSION_ACK: it is acknowledged again,
as PX4 does, or a lossy link turns a successful upload into a reported failure.
Download needs no state: each MISSION_REQUEST(_INT) is answered from the stored mission.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

from sitl_quad.vehicle import Vehicle
from uavcore.geofence import FenceError
from uavcore.mavlink import item_from_message, item_message, mavlink
from uavcore.mission import (
    COMMANDS_OF_TYPE,
    GLOBAL_FRAMES,
    ITEM_FRAMES,
    UNPLACED_COMMANDS,
    MavFrame,
    MissionItem,
    MissionType,
)

log = logging.getLogger(__name__)

RETRY_S = 0.25
TIMEOUT_S = 5.0
MAX_ITEMS = 1000
MISSION = mavlink.MAV_MISSION_TYPE_MISSION


@dataclass
class Upload:
    peer: object
    sysid: int
    compid: int
    count: int
    mission_type: int = MISSION
    items: list[MissionItem] = field(default_factory=list)
    last_request: float = 0.0
    last_progress: float = 0.0
    use_int: bool = True


def _place_result(item: MissionItem, need_altitude: bool) -> int:
    """MAV_MISSION_RESULT for an item's latitude, longitude (degE7) and altitude."""
    if not -900_000_000 <= item.x <= 900_000_000:
        return mavlink.MAV_MISSION_INVALID_PARAM5_X
    if not -1_800_000_000 <= item.y <= 1_800_000_000:
        return mavlink.MAV_MISSION_INVALID_PARAM6_Y
    if need_altitude and not math.isfinite(item.z):
        return mavlink.MAV_MISSION_INVALID_PARAM7
    return mavlink.MAV_MISSION_ACCEPTED


def validate_item(item: MissionItem, expected_seq: int, mission_type: int = MISSION) -> int:
    """MAV_MISSION_RESULT for one item of a list of `mission_type`: ACCEPTED or the first reason it cannot be
    used. Fence and rally items name places (a fence's own consistency is checked once the list is complete)."""
    if item.seq != expected_seq:
        return mavlink.MAV_MISSION_INVALID_SEQUENCE
    if item.command not in COMMANDS_OF_TYPE[MissionType(mission_type)]:
        return mavlink.MAV_MISSION_UNSUPPORTED
    if mission_type != MISSION:
        if item.frame not in GLOBAL_FRAMES:
            return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
        return _place_result(item, need_altitude=mission_type == MissionType.RALLY)
    if item.frame not in ITEM_FRAMES:
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    positional = item.command not in UNPLACED_COMMANDS
    if positional and item.frame == MavFrame.MISSION and item.command != mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    if positional and (result := _place_result(item, need_altitude=True)) != mavlink.MAV_MISSION_ACCEPTED:
        return result
    if item.command in (mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LOITER_TIME):
        if math.isfinite(item.param1) and item.param1 < 0:
            return mavlink.MAV_MISSION_INVALID_PARAM1  # negative dwell / loiter time
        if item.command == mavlink.MAV_CMD_NAV_WAYPOINT and math.isfinite(item.param2) and item.param2 < 0:
            return mavlink.MAV_MISSION_INVALID_PARAM2  # negative acceptance radius
    if item.command == mavlink.MAV_CMD_DO_CHANGE_SPEED and math.isfinite(item.param2) and item.param2 > 50:
        return mavlink.MAV_MISSION_INVALID_PARAM2
    return mavlink.MAV_MISSION_ACCEPTED


class MissionProtocol:
    def __init__(self, vehicle: Vehicle, send, sysid: int = 1, compid: int = 1) -> None:
        self.vehicle = vehicle
        self.send = send  # callable(msg, peer=None)
        self.sysid, self.compid = sysid, compid
        self.upload: Upload | None = None
        self.accepted: Upload | None = None  # the last upload that succeeded, to repeat its ACK if asked
        self.transfers_completed = 0
        self.transfers_failed = 0

    def handlers(self) -> dict:
        return {
            "MISSION_COUNT": self.on_count,
            "MISSION_ITEM_INT": self.on_item,
            "MISSION_ITEM": self.on_item,
            "MISSION_REQUEST_LIST": self.on_request_list,
            "MISSION_REQUEST_INT": self.on_request,
            "MISSION_REQUEST": self.on_request,
            "MISSION_CLEAR_ALL": self.on_clear_all,
            "MISSION_ACK": self.on_ack,
            "MISSION_SET_CURRENT": self.on_set_current,
        }

    def _ack(self, peer, msg_or_upload, result: int, mission_type: int | None = None) -> None:
        """MISSION_ACK to the sender of a message, or to an upload's peer (for the upload's list by default)."""
        sysid = getattr(msg_or_upload, "sysid", None)
        if sysid is None:
            sysid, compid = msg_or_upload.get_srcSystem(), msg_or_upload.get_srcComponent()
        else:
            compid = msg_or_upload.compid
        if mission_type is None:
            mission_type = getattr(msg_or_upload, "mission_type", MISSION)
        self.send(mavlink.MAVLink_mission_ack_message(sysid, compid, result, mission_type), peer)

    def stored(self, mission_type: int) -> list[MissionItem]:
        """The list of a MAV_MISSION_TYPE as the vehicle holds it (empty for a type it does not store)."""
        if mission_type == MissionType.FENCE:
            return self.vehicle.fence_items
        if mission_type == MissionType.RALLY:
            return self.vehicle.rally_points
        return self.vehicle.mission if mission_type == MISSION else []

    def _store(self, mission_type: int, items: list[MissionItem]) -> int:
        """Give the vehicle a complete list; MAV_MISSION_RESULT (a fence that describes no zones is refused)."""
        if mission_type == MissionType.FENCE:
            try:
                self.vehicle.set_fence(items)
            except FenceError as exc:
                log.info("fence upload refused: %s", exc)
                return mavlink.MAV_MISSION_INVALID_PARAM1  # vertex counts and radii are both param1
        elif mission_type == MissionType.RALLY:
            self.vehicle.set_rally_points(items)
        else:
            self.vehicle.set_mission(items)
        return mavlink.MAV_MISSION_ACCEPTED

    # ----- upload
    def on_count(self, peer, msg) -> None:
        if msg.mission_type not in COMMANDS_OF_TYPE:
            self._ack(peer, msg, mavlink.MAV_MISSION_UNSUPPORTED, msg.mission_type)
            return
        old = self.upload
        if old is not None:
            log.info("new MISSION_COUNT while uploading: previous transfer dropped")
            if old.peer is not peer:  # another GCS took over: tell the first one rather than leave it hanging
                self._ack(old.peer, old, mavlink.MAV_MISSION_OPERATION_CANCELLED)
        self.upload = self.accepted = None
        if msg.count > MAX_ITEMS:
            self._ack(peer, msg, mavlink.MAV_MISSION_NO_SPACE)
            return
        if msg.count == 0:
            self._ack(peer, msg, self._store(msg.mission_type, []))
            return
        now = time.monotonic()
        self.upload = Upload(
            peer=peer,
            sysid=msg.get_srcSystem(),
            compid=msg.get_srcComponent(),
            count=msg.count,
            mission_type=msg.mission_type,
            last_progress=now,
        )
        self._request_next(now)

    def _request_next(self, now: float) -> None:
        up = self.upload
        seq = len(up.items)
        request = mavlink.MAVLink_mission_request_int_message(up.sysid, up.compid, seq, up.mission_type)
        self.send(request, up.peer)
        up.last_request = now

    def on_item(self, peer, msg) -> None:
        up = self.upload
        mission_type = getattr(msg, "mission_type", MISSION)
        done = self.accepted
        last_again = done is not None and peer is done.peer and msg.seq == done.count - 1
        if up is None and last_again and mission_type == done.mission_type:
            self._ack(peer, done, mavlink.MAV_MISSION_ACCEPTED)  # our final ACK was lost: say it again
            return
        if up is None or peer is not up.peer or mission_type != up.mission_type:
            return  # not in a transfer with this peer (of this list): PX4 ignores stray items too
        expected = len(up.items)
        if msg.seq != expected:
            if msg.seq < expected:
                return  # a duplicate of one we already have (our request crossed its retry)
            self._fail(peer, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        item = item_from_message(msg)
        result = validate_item(item, expected, up.mission_type)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self._fail(peer, result)
            return
        up.items.append(item)
        now = time.monotonic()
        up.last_progress = now
        if len(up.items) < up.count:
            self._request_next(now)
            return
        self.upload = None
        result = self._store(up.mission_type, up.items)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self.transfers_failed += 1
            self._ack(peer, up, result)
            return
        self.accepted = up
        self.transfers_completed += 1
        self._ack(peer, up, mavlink.MAV_MISSION_ACCEPTED)

    def _fail(self, peer, result: int) -> None:
        up, self.upload = self.upload, None
        self.transfers_failed += 1
        log.info("mission upload refused: MAV_MISSION_RESULT %d", result)
        self._ack(peer, up, result)

    def on_ack(self, peer, msg) -> None:
        """A GCS ack during our upload means it gave up (e.g. OPERATION_CANCELLED)."""
        if self.upload is not None and peer is self.upload.peer and msg.type != mavlink.MAV_MISSION_ACCEPTED:
            self.upload = None
            self.transfers_failed += 1

    def poll(self, now: float) -> None:
        """Wall-clock timers: re-request a missing item, abandon a stalled transfer."""
        up = self.upload
        if up is None:
            return
        if now - up.last_progress > TIMEOUT_S:
            self.upload = None
            self.transfers_failed += 1
            log.info("mission upload timed out at item %d of %d", len(up.items), up.count)
            self._ack(up.peer, up, mavlink.MAV_MISSION_OPERATION_CANCELLED)
        elif now - up.last_request > RETRY_S:
            self._request_next(now)

    # ----- download
    def on_request_list(self, peer, msg) -> None:
        count = len(self.stored(msg.mission_type))
        self.send(
            mavlink.MAVLink_mission_count_message(msg.get_srcSystem(), msg.get_srcComponent(), count, msg.mission_type),
            peer,
        )

    def on_request(self, peer, msg) -> None:
        mission = self.stored(msg.mission_type)
        if not 0 <= msg.seq < len(mission):
            self._ack(peer, msg, mavlink.MAV_MISSION_INVALID_SEQUENCE, msg.mission_type)
            return
        item = mission[msg.seq]
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        reply = item_message(item, sysid, compid, integer=msg.get_type() == "MISSION_REQUEST_INT")
        self.send(reply, peer)

    # ----- clear, set current
    def on_clear_all(self, peer, msg) -> None:
        cleared = COMMANDS_OF_TYPE if msg.mission_type == mavlink.MAV_MISSION_TYPE_ALL else [msg.mission_type]
        for mission_type in cleared:
            if mission_type in COMMANDS_OF_TYPE:
                self.upload = self.accepted = None
                self._store(mission_type, [])
        self._ack(peer, msg, mavlink.MAV_MISSION_ACCEPTED, msg.mission_type)

    def on_set_current(self, peer, msg) -> None:
        if not self.vehicle.set_current_item(msg.seq):
            self._ack(peer, msg, mavlink.MAV_MISSION_INVALID_SEQUENCE)
