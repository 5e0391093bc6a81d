"""The mission protocol, vehicle side: upload, download, clear, set current.

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
from uavcore.mavlink import item_from_message, item_message, mavlink
from uavcore.mission import MavCmd, MavFrame, MissionItem

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
    items: list[MissionItem] = field(default_factory=list)
    last_request: float = 0.0
    last_progress: float = 0.0
    use_int: bool = True


def validate_item(item: MissionItem, expected_seq: int) -> int:
    """MAV_MISSION_RESULT for one item: ACCEPTED or the first reason it cannot be flown."""
    if item.seq != expected_seq:
        return mavlink.MAV_MISSION_INVALID_SEQUENCE
    if item.command not in frozenset(MavCmd):
        return mavlink.MAV_MISSION_UNSUPPORTED
    if item.frame not in frozenset(MavFrame):
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    positional = item.command != mavlink.MAV_CMD_DO_CHANGE_SPEED
    if positional and item.frame == MavFrame.MISSION and item.command != mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    if positional:
        if not -900_000_000 <= item.x <= 900_000_000:
            return mavlink.MAV_MISSION_INVALID_PARAM5_X
        if not -1_800_000_000 <= item.y <= 1_800_000_000:
            return mavlink.MAV_MISSION_INVALID_PARAM6_Y
        if not math.isfinite(item.z):
            return mavlink.MAV_MISSION_INVALID_PARAM7
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

    def _ack(self, peer, msg_or_upload, result: int, mission_type: int = MISSION) -> None:
        sysid = getattr(msg_or_upload, "sysid", None)
        if sysid is None:
            sysid, compid = msg_or_upload.get_srcSystem(), msg_or_upload.get_srcComponent()
        else:
            compid = msg_or_upload.compid
        self.send(mavlink.MAVLink_mission_ack_message(sysid, compid, result, mission_type), peer)

    # ----- upload
    def on_count(self, peer, msg) -> None:
        if msg.mission_type != MISSION:
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
            self.vehicle.set_mission([])
            self._ack(peer, msg, mavlink.MAV_MISSION_ACCEPTED)
            return
        now = time.monotonic()
        self.upload = Upload(
            peer=peer, sysid=msg.get_srcSystem(), compid=msg.get_srcComponent(), count=msg.count, last_progress=now
        )
        self._request_next(now)

    def _request_next(self, now: float) -> None:
        up = self.upload
        seq = len(up.items)
        request = mavlink.MAVLink_mission_request_int_message(up.sysid, up.compid, seq, MISSION)
        self.send(request, up.peer)
        up.last_request = now

    def on_item(self, peer, msg) -> None:
        up = self.upload
        if getattr(msg, "mission_type", MISSION) != MISSION:
            return
        done = self.accepted
        if up is None and done is not None and peer is done.peer and msg.seq == done.count - 1:
            self._ack(peer, done, mavlink.MAV_MISSION_ACCEPTED)  # our final ACK was lost: say it again
            return
        if up is None or peer is not up.peer:
            return  # not in a transfer with this peer: PX4 ignores stray items too
        expected = len(up.items)
        if msg.seq != expected:
            if msg.seq < expected:
                return  # a duplicate of one we already have (our request crossed its retry)
            self._fail(peer, mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        item = item_from_message(msg)
        result = validate_item(item, expected)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self._fail(peer, result)
            return
        up.items.append(item)
        now = time.monotonic()
        up.last_progress = now
        if len(up.items) < up.count:
            self._request_next(now)
            return
        self.upload, self.accepted = None, up
        self.vehicle.set_mission(up.items)
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
        count = len(self.vehicle.mission) if msg.mission_type == MISSION else 0  # no fence or rally points
        self.send(
            mavlink.MAVLink_mission_count_message(msg.get_srcSystem(), msg.get_srcComponent(), count, msg.mission_type),
            peer,
        )

    def on_request(self, peer, msg) -> None:
        mission = self.vehicle.mission if msg.mission_type == MISSION else []
        if not 0 <= msg.seq < len(mission):
            self._ack(peer, msg, mavlink.MAV_MISSION_INVALID_SEQUENCE, msg.mission_type)
            return
        item = mission[msg.seq]
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        if msg.get_type() == "MISSION_REQUEST_INT":
            reply = item_message(item, sysid, compid)
        else:
            reply = mavlink.MAVLink_mission_item_message(
                sysid,
                compid,
                item.seq,
                item.frame,
                item.command,
                item.current,
                item.autocontinue,
                item.param1,
                item.param2,
                item.param3,
                item.param4,
                item.lat,
                item.lon,
                item.z,
                item.mission_type,
            )
        self.send(reply, peer)

    # ----- clear, set current
    def on_clear_all(self, peer, msg) -> None:
        if msg.mission_type in (MISSION, mavlink.MAV_MISSION_TYPE_ALL):
            self.upload = self.accepted = None
            self.vehicle.set_mission([])
        self._ack(peer, msg, mavlink.MAV_MISSION_ACCEPTED, msg.mission_type)

    def on_set_current(self, peer, msg) -> None:
        if not self.vehicle.set_current_item(msg.seq):
            self._ack(peer, msg, mavlink.MAV_MISSION_INVALID_SEQUENCE)
