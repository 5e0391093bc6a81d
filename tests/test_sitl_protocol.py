"""The vehicle's MAVLink protocols, checked from the wire with a pymavlink ground station.

Each test starts `python -m sitl_quad` as a subprocess (conftest.py) and checks what a GCS sees: parameters
(INT32 bytewise), COMMAND_ACK results, mission upload/download/clear and refusals, modes, requested messages,
message intervals, a lossy link, an aborted upload, and hostile datagrams.
"""

from __future__ import annotations

import itertools
import math
import random
import struct
import time

import pytest
from sitl_process import (
    GCS_SYSID,
    VEHICLE_COMPID,
    VEHICLE_SYSID,
    WAIT_S,
    GroundStation,
    mavlink,
    mission_item,
    short_mission,
)
from udp_relay import LossyUdpRelay

from uavcore.geodesy import DEFAULT_HOME
from uavcore.modes import FlightMode

pytestmark = [pytest.mark.integration, pytest.mark.timeout(240)]  # the first test also starts the vehicle

INT32, REAL32 = mavlink.MAV_PARAM_TYPE_INT32, mavlink.MAV_PARAM_TYPE_REAL32
ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
MISSION = mavlink.MAV_MISSION_TYPE_MISSION


def int_bytewise(value: int) -> float:
    """An INT32 parameter as PX4 puts it in param_value: the int's bytes read as a float."""
    return struct.unpack("<f", struct.pack("<i", value))[0]


def int_from_wire(param_value: float) -> int:
    return struct.unpack("<i", struct.pack("<f", param_value))[0]


def is_mode(mode: FlightMode):
    return lambda hb: hb.custom_mode == mode.custom_mode


def armed(hb) -> bool:
    return bool(hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def sys_status(gcs: GroundStation):
    status = gcs.recv("SYS_STATUS", timeout=10)
    assert status is not None, "no SYS_STATUS"
    return status


def clear_mission(gcs: GroundStation) -> None:
    gcs.mav.mission_clear_all_send(VEHICLE_SYSID, VEHICLE_COMPID, mavlink.MAV_MISSION_TYPE_MISSION)
    ack = gcs.recv("MISSION_ACK", timeout=5)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_ACCEPTED


# ----- identity
def test_heartbeat_identifies_a_px4_quadrotor_on_component_1(gcs):
    heartbeat = gcs.recv("HEARTBEAT", timeout=5)
    assert heartbeat.get_srcSystem() == VEHICLE_SYSID and heartbeat.get_srcComponent() == VEHICLE_COMPID
    assert heartbeat.type == mavlink.MAV_TYPE_QUADROTOR
    assert heartbeat.autopilot == mavlink.MAV_AUTOPILOT_PX4
    assert heartbeat.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not armed(heartbeat)
    assert FlightMode.from_custom_mode(heartbeat.custom_mode) is not None


# ----- parameters
def test_param_list_sends_every_index_once_with_the_count(gcs):
    gcs.mav.param_request_list_send(VEHICLE_SYSID, VEHICLE_COMPID)
    first = gcs.recv("PARAM_VALUE", timeout=5)
    assert first is not None
    count = first.param_count
    seen = {first.param_index: first.param_id}
    deadline = time.monotonic() + WAIT_S
    while len(seen) < count and time.monotonic() < deadline:
        value = gcs.recv("PARAM_VALUE", timeout=1)
        if value is not None:
            assert value.param_count == count
            seen[value.param_index] = value.param_id
    assert sorted(seen) == list(range(count))
    assert len(set(seen.values())) == count  # names are unique
    assert "OFFB_LOSS_T" in seen.values()  # fixed by the contract


def test_int32_parameter_travels_bytewise_both_ways(gcs):
    value = gcs.read_param("MC_ATT_CTRL")
    assert value is not None and value.param_type == INT32
    assert int_from_wire(value.param_value) == 0  # PID by default
    answer = gcs.set_param("MC_ATT_CTRL", int_bytewise(1), INT32)
    assert answer is not None and answer.param_type == INT32
    assert int_from_wire(answer.param_value) == 1
    assert answer.param_value != 1.0  # a float cast would read back as 1065353216 in MAVSDK
    assert int_from_wire(gcs.read_param("MC_ATT_CTRL").param_value) == 1
    assert int_from_wire(gcs.set_param("MC_ATT_CTRL", int_bytewise(0), INT32).param_value) == 0


def test_param_read_by_index_matches_read_by_name(gcs):
    by_name = gcs.read_param("OFFB_LOSS_T")
    assert by_name is not None and by_name.param_type == REAL32
    by_index = gcs.read_param(index=by_name.param_index)
    assert by_index.param_id == "OFFB_LOSS_T"
    assert by_index.param_value == by_name.param_value
    assert by_index.param_count == by_name.param_count


def test_param_set_within_limits_answers_the_new_value(gcs):
    answer = gcs.set_param("OFFB_LOSS_T", 0.75, REAL32)
    assert answer is not None and answer.param_value == pytest.approx(0.75)
    assert gcs.read_param("OFFB_LOSS_T").param_value == pytest.approx(0.75)


@pytest.mark.parametrize(
    ("name", "raw", "param_type"),
    [
        ("SIM_MASS", 1e6, REAL32),  # above its maximum
        ("SIM_MASS", math.nan, REAL32),
        ("MC_ATT_CTRL", int_bytewise(7), INT32),  # 0 PID, 1 ADRC, 2 geometric: nothing else
    ],
)
def test_param_set_refused_answers_the_old_value(gcs, name, raw, param_type):
    before = gcs.read_param(name)
    answer = gcs.set_param(name, raw, param_type)
    assert answer is not None, "a refused PARAM_SET must still be answered"
    assert answer.param_value == before.param_value
    assert gcs.read_param(name).param_value == before.param_value


def test_mavlink_ftp_request_is_refused_at_once(gcs):
    # MAVProxy asks for @PARAM/param.pck over MAVLink FTP first; a NAK lets it fall back to the
    # PARAM protocol at once instead of after its FTP timeouts.
    path = b"@PARAM/param.pck"
    open_read_only = 4
    request = (7).to_bytes(2, "little") + bytes([0, open_read_only, len(path), 0, 0, 0]) + bytes(4) + path
    gcs.mav.file_transfer_protocol_send(0, VEHICLE_SYSID, VEHICLE_COMPID, list(request.ljust(251, b"\0")))
    reply = gcs.recv("FILE_TRANSFER_PROTOCOL", timeout=5)
    assert reply is not None
    assert reply.target_system == gcs.mav.srcSystem
    payload = bytes(reply.payload)
    assert int.from_bytes(payload[0:2], "little") == 8  # the request's seq + 1
    assert payload[3] == 129 and payload[5] == open_read_only  # NAK of OpenFileRO
    assert payload[4] == 1 and payload[12] != 0  # one byte of data: a non-zero error code


# ----- commands
@pytest.mark.parametrize("use_int", [False, True], ids=["COMMAND_LONG", "COMMAND_INT"])
def test_unknown_command_is_acked_unsupported(gcs, use_int):
    ack = gcs.command(31999, 1, 2, 3, use_int=use_int)
    assert ack is not None and ack.result == mavlink.MAV_RESULT_UNSUPPORTED
    assert ack.target_system == gcs.mav.srcSystem and ack.target_component == gcs.mav.srcComponent


DENIED, UNSUPPORTED = mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_UNSUPPORTED


@pytest.mark.parametrize(
    ("command", "params", "expected"),
    [
        (mavlink.MAV_CMD_NAV_TAKEOFF, (), DENIED),  # disarmed
        (mavlink.MAV_CMD_NAV_LAND, (), ACCEPTED),  # a mode change: fine on the ground
        (mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, (), ACCEPTED),
        (mavlink.MAV_CMD_NAV_LOITER_UNLIM, (), ACCEPTED),
        (mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, (99,), DENIED),  # no such item
        (mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, (math.nan,), DENIED),
        (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (0.5,), DENIED),  # neither arm nor disarm
        (mavlink.MAV_CMD_DO_SET_MODE, (0, 4, 3), DENIED),  # no custom-mode flag
        (mavlink.MAV_CMD_DO_SET_MODE, (1, math.nan, 3), DENIED),
        (mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, (1,), ACCEPTED),
        (mavlink.MAV_CMD_REQUEST_PROTOCOL_VERSION, (1,), UNSUPPORTED),  # PROTOCOL_VERSION is deprecated
        (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, (65000, 1000), UNSUPPORTED),  # no such stream
        (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, (mavlink.MAVLINK_MSG_ID_ATTITUDE, math.nan), DENIED),
    ],
    ids=lambda v: str(v),
)
def test_each_command_is_acknowledged_with_its_result(gcs, command, params, expected):
    clear_mission(gcs)
    ack = gcs.command(command, *params)
    assert ack is not None, f"no COMMAND_ACK for command {command}"
    assert ack.result == expected
    assert gcs.set_mode(4, 3).result == ACCEPTED  # leave the shared vehicle in AUTO.LOITER


def test_arm_when_already_armed_is_temporarily_rejected(gcs):
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == ACCEPTED
    again = gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert again.result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == ACCEPTED  # on the ground: fine
    assert gcs.wait_heartbeat(lambda hb: not armed(hb)) is not None


def test_mission_start_without_a_mission_is_denied(gcs):
    clear_mission(gcs)
    ack = gcs.command(mavlink.MAV_CMD_MISSION_START, 0, 0)
    assert ack.result == mavlink.MAV_RESULT_DENIED


def test_disarm_in_the_air_is_denied(start_sitl):
    vehicle = start_sitl(speed=10)
    gcs = GroundStation(vehicle.port)
    gcs.connect()
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == ACCEPTED
    ack = gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF, *[math.nan] * 6, DEFAULT_HOME[2] + 5.0)
    assert ack.result == ACCEPTED
    airborne = gcs.recv("GLOBAL_POSITION_INT", timeout=WAIT_S, condition=lambda m: m.relative_alt > 2000)
    assert airborne is not None, "the vehicle did not climb above 2 m"
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == mavlink.MAV_RESULT_DENIED
    assert gcs.wait_heartbeat(armed, timeout=WAIT_S) is not None
    assert gcs.command(mavlink.MAV_CMD_NAV_LAND).result == ACCEPTED
    assert gcs.wait_heartbeat(lambda hb: not armed(hb), timeout=WAIT_S) is not None, "no disarm after landing"
    gcs.close()


def test_do_set_mode_changes_the_heartbeat_mode(gcs):
    assert gcs.set_mode(4, 5).result == ACCEPTED  # AUTO.RTL
    assert gcs.wait_heartbeat(is_mode(FlightMode.AUTO_RTL)) is not None
    assert gcs.set_mode(4, 3).result == ACCEPTED  # AUTO.LOITER
    assert gcs.wait_heartbeat(is_mode(FlightMode.AUTO_LOITER)) is not None


def test_do_set_mode_refuses_what_it_cannot_fly(gcs):
    clear_mission(gcs)
    assert gcs.set_mode(1).result == mavlink.MAV_RESULT_UNSUPPORTED  # MANUAL: no RC on this vehicle
    assert gcs.set_mode(4, 4).result == mavlink.MAV_RESULT_DENIED  # AUTO.MISSION with no mission


def test_set_mode_message_changes_the_mode_without_an_ack(gcs):
    gcs.mav.set_mode_send(VEHICLE_SYSID, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, FlightMode.POSCTL.custom_mode)
    assert gcs.wait_heartbeat(is_mode(FlightMode.POSCTL)) is not None
    gcs.mav.set_mode_send(VEHICLE_SYSID, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, FlightMode.AUTO_LOITER.custom_mode)
    assert gcs.wait_heartbeat(is_mode(FlightMode.AUTO_LOITER)) is not None


def test_request_message_autopilot_version_has_the_capabilities_tools_need(gcs):
    ack, version = gcs.request(
        mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION, reply="AUTOPILOT_VERSION"
    )
    assert ack is not None and ack.result == ACCEPTED
    assert version is not None
    for bit in (
        mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT,
        mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT,
        mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
        mavlink.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET,
        mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2,
    ):
        assert version.capabilities & bit, f"capability bit {bit} missing"


@pytest.mark.parametrize("how", ["REQUEST_MESSAGE", "GET_HOME_POSITION"])
def test_home_position_on_request_is_the_home(gcs, how):
    # Disable the periodic stream first, so the HOME_POSITION seen can only be the answer to the request.
    off = gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_HOME_POSITION, -1)
    assert off.result == ACCEPTED
    if how == "REQUEST_MESSAGE":
        ack, home = gcs.request(
            mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION, reply="HOME_POSITION"
        )
    else:
        ack, home = gcs.request(mavlink.MAV_CMD_GET_HOME_POSITION, reply="HOME_POSITION")
    assert ack is not None and ack.result == ACCEPTED
    assert home is not None
    assert home.latitude == round(DEFAULT_HOME[0] * 1e7) and home.longitude == round(DEFAULT_HOME[1] * 1e7)
    assert home.altitude == round(DEFAULT_HOME[2] * 1000)
    restore = gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_HOME_POSITION, 0)
    assert restore.result == ACCEPTED


def test_request_message_for_an_unknown_message_is_unsupported(gcs):
    ack = gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, 65000)
    assert ack.result == mavlink.MAV_RESULT_UNSUPPORTED


def test_set_message_interval_sets_disables_and_restores_a_stream(gcs):
    attitude = mavlink.MAVLINK_MSG_ID_ATTITUDE
    assert gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, attitude, 200_000).result == ACCEPTED
    stamps = []
    while len(stamps) < 4:
        msg = gcs.recv("ATTITUDE", timeout=5)
        assert msg is not None
        stamps.append(msg.time_boot_ms)
    gaps = [b - a for a, b in itertools.pairwise(stamps[1:])]  # the first gap may straddle the change
    assert all(180 <= gap <= 220 for gap in gaps), gaps  # 5 Hz of simulated time

    assert gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, attitude, -1).result == ACCEPTED
    # Disabled: in the next second of vehicle time other streams go on, and ATTITUDE never comes (one
    # stamped before the change may still be on its way).
    start = gcs.recv("LOCAL_POSITION_NED", timeout=5).time_boot_ms
    while True:
        msg = gcs.recv(["ATTITUDE", "LOCAL_POSITION_NED"], timeout=5)
        assert msg is not None
        assert msg.get_type() != "ATTITUDE" or msg.time_boot_ms <= start, "ATTITUDE still streams"
        if msg.time_boot_ms > start + 1000:
            break

    assert gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, attitude, 0).result == ACCEPTED
    assert gcs.recv("ATTITUDE", timeout=5) is not None  # back to its default rate


# ----- missions
def test_mission_upload_then_download_gives_the_items_back(gcs):
    items = short_mission(DEFAULT_HOME)
    ack = gcs.upload_mission(items)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_ACCEPTED
    assert ack.mission_type == mavlink.MAV_MISSION_TYPE_MISSION
    downloaded = gcs.download_mission()
    assert downloaded is not None and len(downloaded) == len(items)
    for sent, got in zip(items, downloaded, strict=True):
        for field in ("seq", "frame", "command", "current", "autocontinue", "x", "y", "z"):
            assert getattr(got, field) == getattr(sent, field), field
        for field in ("param1", "param2", "param3", "param4"):
            a, b = getattr(sent, field), getattr(got, field)
            assert (math.isnan(a) and math.isnan(b)) or a == b, field


def test_mission_clear_all_leaves_an_empty_mission(gcs):
    assert gcs.upload_mission(short_mission(DEFAULT_HOME)).type == mavlink.MAV_MISSION_ACCEPTED
    clear_mission(gcs)
    assert gcs.download_mission() == []


def _with(item, **changes):
    fields = {name: getattr(item, name) for name in item.fieldnames}
    fields.update(changes)
    return mavlink.MAVLink_mission_item_int_message(**fields)


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"command": 31999}, mavlink.MAV_MISSION_UNSUPPORTED),
        ({"frame": mavlink.MAV_FRAME_LOCAL_NED}, mavlink.MAV_MISSION_UNSUPPORTED_FRAME),
        ({"z": math.nan}, mavlink.MAV_MISSION_INVALID_PARAM7),
        ({"x": 950_000_000}, mavlink.MAV_MISSION_INVALID_PARAM5_X),  # latitude 95 degrees
        ({"y": -1_850_000_000}, mavlink.MAV_MISSION_INVALID_PARAM6_Y),
        ({"param1": -3.0}, mavlink.MAV_MISSION_INVALID_PARAM1),  # negative dwell
        ({"param2": -1.0}, mavlink.MAV_MISSION_INVALID_PARAM2),  # negative acceptance radius
        ({"seq": 5}, mavlink.MAV_MISSION_INVALID_SEQUENCE),
    ],
    ids=["command", "frame", "nan-altitude", "latitude", "longitude", "dwell", "radius", "sequence"],
)
def test_invalid_item_refuses_the_upload_with_its_reason_and_keeps_the_old_mission(gcs, change, expected):
    good = short_mission(DEFAULT_HOME)
    assert gcs.upload_mission(good).type == mavlink.MAV_MISSION_ACCEPTED
    bad = list(good)
    bad[1] = _with(good[1], **change)  # item 1 is a NAV_WAYPOINT
    ack = gcs.upload_mission(bad)
    assert ack is not None and ack.type == expected
    kept = gcs.download_mission()
    assert [(i.command, i.x, i.y) for i in kept] == [(i.command, i.x, i.y) for i in good]


def test_last_item_sent_again_after_a_lost_ack_is_acknowledged_again(gcs):
    # The GCS cannot tell a lost final MISSION_ACK from a lost last item: it sends the item again, and the
    # vehicle, which already has the whole mission, must answer with the ACK again (PX4 does) or the GCS
    # reports a failed upload that in fact succeeded.
    items = short_mission(DEFAULT_HOME)
    assert gcs.upload_mission(items).type == mavlink.MAV_MISSION_ACCEPTED
    gcs.send_item(items[-1])
    again = gcs.recv("MISSION_ACK", timeout=5)
    assert again is not None and again.type == mavlink.MAV_MISSION_ACCEPTED
    assert len(gcs.download_mission()) == len(items)


def test_mission_count_beyond_capacity_is_refused_no_space(gcs):
    gcs.mav.mission_count_send(VEHICLE_SYSID, VEHICLE_COMPID, 60000, mavlink.MAV_MISSION_TYPE_MISSION)
    ack = gcs.recv("MISSION_ACK", timeout=5)
    assert ack is not None and ack.type == mavlink.MAV_MISSION_NO_SPACE


@pytest.mark.parametrize(
    "mission_type", [mavlink.MAV_MISSION_TYPE_FENCE, mavlink.MAV_MISSION_TYPE_RALLY], ids=["fence", "rally"]
)
def test_fence_and_rally_lists_hold_their_own_items_only(gcs, mission_type):
    """A rally point is stored in the rally list and handed back; in the fence list it is refused."""
    assert gcs.download_mission(mission_type=mission_type) == []
    point = mission_item(0, mavlink.MAV_CMD_NAV_RALLY_POINT, *DEFAULT_HOME, mission_type=mission_type)
    ack = gcs.upload_mission([point], mission_type=mission_type, timeout=5)
    rally = mission_type == mavlink.MAV_MISSION_TYPE_RALLY
    assert ack is not None and ack.type == (mavlink.MAV_MISSION_ACCEPTED if rally else mavlink.MAV_MISSION_UNSUPPORTED)
    assert ack.mission_type == mission_type
    stored = gcs.download_mission(mission_type=mission_type)
    assert [(i.command, i.x, i.y) for i in stored] == ([(point.command, point.x, point.y)] if rally else [])
    gcs.mav.mission_clear_all_send(VEHICLE_SYSID, VEHICLE_COMPID, mission_type)
    cleared = gcs.recv("MISSION_ACK", timeout=5, condition=lambda m: m.mission_type == mission_type)
    assert cleared is not None and cleared.type == mavlink.MAV_MISSION_ACCEPTED
    assert gcs.download_mission(mission_type=mission_type) == []


def longer_mission(n_waypoints: int = 8) -> list:
    """Takeoff, n waypoints on a 20 m grid, RTL: enough items for a lossy link to lose some."""
    from uavcore.geodesy import LocalFrame

    frame = LocalFrame(*DEFAULT_HOME)
    items = [mission_item(0, mavlink.MAV_CMD_NAV_TAKEOFF, DEFAULT_HOME[0], DEFAULT_HOME[1], 5.0)]
    for k in range(n_waypoints):
        lat, lon, _ = frame.from_ned(20.0 * (k // 2 + 1), 20.0 * (k % 2), 0.0)
        items.append(mission_item(k + 1, mavlink.MAV_CMD_NAV_WAYPOINT, lat, lon, 5.0 + k))
    items.append(mission_item(n_waypoints + 1, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, frame=mavlink.MAV_FRAME_MISSION))
    return items


@pytest.mark.slow
def test_mission_upload_succeeds_through_a_link_dropping_20_percent_each_way(start_sitl):
    vehicle = start_sitl(speed=1)  # no flight here: real time keeps the telemetry light for the relay
    items = longer_mission(6)
    with LossyUdpRelay(vehicle.port, drop_fraction=0.2, seed=7) as relay:
        gcs = GroundStation(relay.port)
        gcs.connect()
        ack = gcs.upload_mission(items, timeout=30)
        assert ack is not None and ack.type == mavlink.MAV_MISSION_ACCEPTED
        downloaded = gcs.download_mission(timeout=30)
        gcs.close()
    assert relay.to_vehicle.dropped > 0 and relay.to_client.dropped > 0  # the link really was lossy
    assert downloaded is not None
    assert [(i.seq, i.command, i.x, i.y, i.z) for i in downloaded] == [(i.seq, i.command, i.x, i.y, i.z) for i in items]


@pytest.mark.slow  # waits out the vehicle's 5 s transfer timeout
def test_upload_aborted_half_way_leaves_the_next_upload_working(start_sitl):
    vehicle = start_sitl(speed=1)
    gcs = GroundStation(vehicle.port)
    gcs.connect()
    items = longer_mission()
    assert gcs.upload_mission(items, stop_after=len(items) // 2, timeout=10) is None  # the GCS went quiet
    # A new upload right away supersedes the stalled one.
    short = short_mission(DEFAULT_HOME)
    assert gcs.upload_mission(short).type == mavlink.MAV_MISSION_ACCEPTED
    assert len(gcs.download_mission()) == len(short)

    # Abandoned for good: the vehicle gives up after its timeout, says so, and takes the next upload.
    assert gcs.upload_mission(items, stop_after=len(items) // 2, timeout=10) is None
    cancelled = gcs.recv("MISSION_ACK", timeout=WAIT_S)
    assert cancelled is not None and cancelled.type == mavlink.MAV_MISSION_OPERATION_CANCELLED
    assert gcs.upload_mission(items).type == mavlink.MAV_MISSION_ACCEPTED
    assert len(gcs.download_mission()) == len(items)
    gcs.close()


def test_upload_taken_over_by_another_station_is_cancelled_for_the_first(gcs, shared_sitl):
    other = GroundStation(shared_sitl.port, sysid=250)
    try:
        other.connect()
        items = short_mission(DEFAULT_HOME)
        gcs.mav.mission_count_send(VEHICLE_SYSID, VEHICLE_COMPID, len(items), MISSION)
        assert gcs.recv("MISSION_REQUEST_INT", timeout=5) is not None  # the first station's upload is live
        assert other.upload_mission(items).type == mavlink.MAV_MISSION_ACCEPTED
        cancelled = gcs.recv("MISSION_ACK", timeout=5)
        assert cancelled is not None and cancelled.type == mavlink.MAV_MISSION_OPERATION_CANCELLED
    finally:
        other.close()


# ----- hostile input
def _garbage(rng: random.Random, valid_frames: list[bytes]) -> bytes:
    """One hostile datagram: random bytes, a valid frame with flipped bytes, truncated, or oddly sized."""
    kind = rng.randrange(6)
    if kind == 0:
        return rng.randbytes(rng.randrange(1, 300))
    frame = bytearray(rng.choice(valid_frames))
    if kind == 1:
        for _ in range(rng.randrange(1, 4)):
            frame[rng.randrange(len(frame))] ^= 1 << rng.randrange(8)
        return bytes(frame)
    if kind == 2:
        return bytes(frame[: rng.randrange(1, len(frame))])
    if kind == 3:  # a real frame's header with a random body: right start, wrong everything else
        return bytes(frame[:10]) + rng.randbytes(rng.randrange(0, 280))
    if kind == 4:
        return bytes([0xFD]) + rng.randbytes(rng.randrange(0, 20))
    return bytes(frame) + rng.randbytes(rng.randrange(1, 40))  # a good frame followed by junk


def test_garbage_datagrams_are_counted_and_the_vehicle_keeps_answering(start_sitl):
    sitl = start_sitl(speed=2)
    gcs = GroundStation(sitl.port)
    gcs.connect()
    before = sys_status(gcs)
    encoder = mavlink.MAVLink(None, srcSystem=200, srcComponent=1)
    samples = [
        mavlink.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0),
        mavlink.MAVLink_param_request_read_message(1, 1, b"SIM_MASS", -1),
        mavlink.MAVLink_mission_count_message(1, 1, 3, 0),
        mavlink.MAVLink_set_attitude_target_message(0, 1, 1, 0, [1, 0, 0, 0], 0, 0, 0, 0.5),
        mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3),
    ]
    valid_frames = [bytes(m.pack(encoder)) for m in samples]
    rng = random.Random(2024)
    for n in range(5000):
        gcs.conn.write(_garbage(rng, valid_frames))
        if n % 200 == 0:
            time.sleep(0.005)  # let the vehicle drain its socket buffer: we test parsing, not buffer size
    assert sitl.alive()
    gcs.connect(timeout=WAIT_S)
    assert gcs.read_param("SIM_MASS") is not None
    deadline = time.monotonic() + WAIT_S
    after = sys_status(gcs)
    while after.errors_comm <= before.errors_comm and time.monotonic() < deadline:
        after = sys_status(gcs)
    assert after.errors_comm > before.errors_comm
    assert after.errors_count1 > before.errors_count1  # malformed frames
    assert after.drop_rate_comm > 0
    gcs.close()


def test_wrong_target_is_ignored_and_counted(gcs):
    before = sys_status(gcs)
    gcs.mav.command_long_send(42, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    gcs.mav.command_long_send(VEHICLE_SYSID, 77, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    # The vehicle handles one peer's datagrams in order: once this later command is answered, the two above
    # have been seen, and neither may have armed the vehicle or been acknowledged.
    marker = gcs.command(31998)
    assert marker is not None
    late = gcs.conn.recv_match(
        type="COMMAND_ACK", blocking=False, condition=f"COMMAND_ACK.command=={mavlink.MAV_CMD_COMPONENT_ARM_DISARM}"
    )
    assert late is None
    assert not armed(gcs.recv("HEARTBEAT", timeout=5))
    after = sys_status(gcs)
    deadline = time.monotonic() + WAIT_S
    while after.errors_count3 < before.errors_count3 + 2 and time.monotonic() < deadline:
        after = sys_status(gcs)
    assert after.errors_count3 >= before.errors_count3 + 2


def test_unknown_message_id_is_counted_and_ignored(gcs):
    before = sys_status(gcs)
    # A well-formed MAVLink 2 frame whose id (60001) is in no dialect the vehicle knows.
    payload = b"\x01\x02\x03\x04"
    header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, 0, GCS_SYSID, 1, 60001 & 0xFFFF, 60001 >> 16)
    frame = header + payload + b"\x00\x00"  # the CRC cannot be checked without the message's CRC_EXTRA
    for _ in range(20):
        gcs.conn.write(frame)
    assert gcs.read_param("SIM_MASS") is not None  # still answering
    after = sys_status(gcs)
    deadline = time.monotonic() + WAIT_S
    while after.errors_comm <= before.errors_comm and time.monotonic() < deadline:
        after = sys_status(gcs)
    assert after.errors_comm > before.errors_comm
