"""The camera component and the gimbal manager over real UDP, a pymavlink ground station on the other end.

The vehicle runs as a process with a one-buoy world (`--world`) and its images in a temporary directory.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import VehicleStarter, connected
from PIL import Image
from sitl_process import VEHICLE_SYSID, WAIT_S, GroundStation, SitlProcess, mavlink, mission_item

from sitl_quad.camera_render import DEFAULT_CAMERA
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.rotation import euler_from_quat

pytestmark = [pytest.mark.integration, pytest.mark.timeout(300)]

CAMERA = mavlink.MAV_COMP_ID_CAMERA
ACCEPTED, DENIED = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_DENIED
FRAME = LocalFrame(*DEFAULT_HOME)
BUOY_NE = (40.0, 0.0)  # a port buoy (a red can) 40 m north of home, nearly still on a short chain
BUOY_LAT, BUOY_LON, _ = FRAME.from_ned(*BUOY_NE, 0.0)
HOVER_M = 20.0


@pytest.fixture(scope="module")
def camera_vehicle(tmp_path_factory) -> Iterator[tuple[SitlProcess, Path]]:
    root = tmp_path_factory.mktemp("camera")
    world = root / "world.geojson"
    buoy = {"id": "P1", "kind": "port", "swing_radius_m": 0.3}
    point = {"type": "Point", "coordinates": [float(BUOY_LON), float(BUOY_LAT)]}
    world.write_text(
        json.dumps(
            {"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": point, "properties": buoy}]}
        )
    )
    images = root / "images"
    starter = VehicleStarter()
    yield starter(speed=4.0, extra_args=("--world", str(world), "--image-dir", str(images))), images
    starter.stop_all()


@pytest.fixture
def gcs(camera_vehicle) -> Iterator[GroundStation]:
    station = connected(camera_vehicle[0])
    yield station
    station.close()


def from_camera(msg) -> bool:
    return msg.get_srcComponent() == CAMERA


def camera_command(gcs: GroundStation, command: int, *params: float, timeout: float = 5.0):
    """COMMAND_LONG to the camera component; its COMMAND_ACK (from component 100)."""
    p = [*params, *[math.nan] * (7 - len(params))]
    gcs.mav.command_long_send(VEHICLE_SYSID, CAMERA, command, 0, *p)
    return gcs.recv("COMMAND_ACK", timeout=timeout, condition=lambda m: from_camera(m) and m.command == command)


def camera_request(gcs: GroundStation, msg_id: int, reply: str, timeout: float = 5.0):
    """REQUEST_MESSAGE to the camera: (its COMMAND_ACK, the message), the message sent before the ACK."""
    gcs.mav.command_long_send(VEHICLE_SYSID, CAMERA, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, msg_id, *[0.0] * 6)
    kinds = ["COMMAND_ACK", reply]
    answer = gcs.recv(kinds, timeout=timeout, condition=lambda m: from_camera(m) and m.get_type() == reply)
    ack = gcs.recv("COMMAND_ACK", timeout=timeout, condition=from_camera)
    return ack, answer


def take_off(gcs: GroundStation) -> None:
    if gcs.recv("GLOBAL_POSITION_INT", timeout=5.0).relative_alt > (HOVER_M - 1) * 1000:
        return
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == ACCEPTED
    assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF, *[math.nan] * 6, DEFAULT_HOME[2] + HOVER_M).result == ACCEPTED
    up = gcs.recv("GLOBAL_POSITION_INT", timeout=WAIT_S, condition=lambda m: m.relative_alt > (HOVER_M - 0.5) * 1000)
    assert up is not None, "no climb to the hover height"


def valid_jpeg(path: Path) -> np.ndarray:
    with Image.open(path) as image:
        assert image.format == "JPEG" and image.size == (DEFAULT_CAMERA.width, DEFAULT_CAMERA.height)
        return np.asarray(image.convert("RGB"))


def test_camera_component_heartbeats_and_describes_itself(gcs):
    beat = gcs.recv("HEARTBEAT", timeout=10.0, condition=from_camera)
    assert beat is not None, "no HEARTBEAT from component 100"
    assert (beat.type, beat.autopilot) == (mavlink.MAV_TYPE_CAMERA, mavlink.MAV_AUTOPILOT_INVALID)
    info_id = mavlink.MAVLINK_MSG_ID_CAMERA_INFORMATION
    ack, info = camera_request(gcs, info_id, "CAMERA_INFORMATION")
    assert ack.result == ACCEPTED and info is not None
    assert (info.resolution_h, info.resolution_v) == (DEFAULT_CAMERA.width, DEFAULT_CAMERA.height)
    assert info.focal_length / info.sensor_size_h * info.resolution_h == pytest.approx(DEFAULT_CAMERA.fx, rel=1e-5)
    assert info.flags & mavlink.CAMERA_CAP_FLAGS_CAPTURE_IMAGE
    # the autopilot does not pretend to be a camera; the camera refuses what it does not know
    assert gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, info_id).result == mavlink.MAV_RESULT_UNSUPPORTED
    assert camera_command(gcs, mavlink.MAV_CMD_SET_CAMERA_ZOOM, 0, 1).result == mavlink.MAV_RESULT_UNSUPPORTED


def test_interval_capture_writes_geotagged_jpegs(gcs, camera_vehicle):
    _, images = camera_vehicle
    stop = camera_command(gcs, mavlink.MAV_CMD_IMAGE_STOP_CAPTURE, 0)
    assert stop.result == ACCEPTED
    assert camera_command(gcs, mavlink.MAV_CMD_IMAGE_START_CAPTURE, 0, 0.2, 5, 0).result == ACCEPTED
    # the vehicle's estimate, by time: the geotag must be where it was at the capture's instant
    captured, positions = [], {}
    while len(captured) < 5:
        msg = gcs.recv(["CAMERA_IMAGE_CAPTURED", "GLOBAL_POSITION_INT"], timeout=WAIT_S)
        assert msg is not None, f"only {len(captured)} CAMERA_IMAGE_CAPTURED"
        if msg.get_type() == "GLOBAL_POSITION_INT":
            positions[msg.time_boot_ms] = msg
        else:
            captured.append(msg)
    indices = [m.image_index for m in captured]
    assert indices == list(range(indices[0], indices[0] + 5))
    times = [m.time_boot_ms for m in captured]
    assert [b - a for a, b in itertools.pairwise(times)] == [200] * 4  # simulated 0.2 s apart
    for msg in captured:
        assert msg.capture_result == 1 and from_camera(msg)
        name = f"IMG_{msg.image_index:06d}.jpg"
        assert msg.file_url == f"mftp://[;comp=100]/{name}"
        valid_jpeg(images / name)
        nearest = positions[min(positions, key=lambda t: abs(t - msg.time_boot_ms))]
        assert abs(nearest.time_boot_ms - msg.time_boot_ms) <= 100
        assert (msg.lat, msg.lon) == pytest.approx((nearest.lat, nearest.lon), abs=10)  # 1e-6 deg: about 0.1 m
        assert msg.relative_alt == pytest.approx(nearest.relative_alt, abs=300)
    # a sequence while none runs is refused, a negative count denied
    assert camera_command(gcs, mavlink.MAV_CMD_IMAGE_START_CAPTURE, 0, 0.2, -1, 0).result == DENIED
    assert camera_command(gcs, mavlink.MAV_CMD_IMAGE_START_CAPTURE, 0, 0.0, 3, 0).result == DENIED


def test_gimbal_obeys_only_the_client_in_control(gcs):
    pitch_yaw = mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
    configure = mavlink.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE
    info_id = mavlink.MAVLINK_MSG_ID_GIMBAL_MANAGER_INFORMATION
    ack, info = gcs.request(mavlink.MAV_CMD_REQUEST_MESSAGE, info_id, reply="GIMBAL_MANAGER_INFORMATION")
    assert ack.result == ACCEPTED and info.gimbal_device_id == 1
    assert info.cap_flags & mavlink.GIMBAL_MANAGER_CAP_FLAGS_CAN_POINT_LOCATION_GLOBAL
    assert gcs.command(configure, -3, -3, -1, -1, 0, 0, 1).result == ACCEPTED  # release (nothing held)
    assert gcs.command(pitch_yaw, -30, 10, math.nan, math.nan, 0, 0, 1).result == DENIED
    assert gcs.command(configure, 255, 190, -1, -1, 0, 0, 1).result == ACCEPTED
    status = gcs.recv("GIMBAL_MANAGER_STATUS", condition=lambda m: m.primary_control_sysid == 255)
    assert status is not None and status.primary_control_compid == 190
    assert gcs.command(pitch_yaw, -30, 10, math.nan, math.nan, 0, 0, 1).result == ACCEPTED
    settled = gcs.recv("GIMBAL_DEVICE_ATTITUDE_STATUS", timeout=WAIT_S, condition=lambda m: angles_near(m, -30, 10))
    assert settled is not None, "the gimbal did not reach pitch -30 yaw 10"
    assert settled.flags & mavlink.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
    assert gcs.command(configure, -3, -3, -1, -1, 0, 0, 1).result == ACCEPTED
    assert gcs.command(pitch_yaw, 0, 0, math.nan, math.nan, 0, 0, 1).result == DENIED


def angles_near(msg, pitch_deg: float, yaw_deg: float, tolerance_deg: float = 0.5) -> bool:
    _, pitch, yaw = euler_from_quat(msg.q)
    return abs(math.degrees(pitch) - pitch_deg) < tolerance_deg and abs(math.degrees(yaw) - yaw_deg) < tolerance_deg


def aims_north(msg, pitch_deg: float) -> bool:
    """Earth-frame bearing north (the quaternion's yaw is relative to the vehicle's heading, delta_yaw)."""
    _, pitch, yaw = euler_from_quat(msg.q)
    bearing = math.degrees((yaw + msg.delta_yaw + math.pi) % (2 * math.pi) - math.pi)
    return abs(math.degrees(pitch) - pitch_deg) < 1.0 and abs(bearing) < 1.0


def test_roi_aims_the_gimbal_at_the_buoy_and_the_image_shows_it(gcs, camera_vehicle):
    _, images = camera_vehicle
    take_off(gcs)
    # MAVSDK's set_roi_location: COMMAND_INT, frame GLOBAL_RELATIVE_ALT, altitude taken as AMSL (as PX4 does)
    ack = gcs.command(
        mavlink.MAV_CMD_DO_SET_ROI_LOCATION, 1, 0, 0, 0, BUOY_LAT * 1e7, BUOY_LON * 1e7, 0.0, use_int=True
    )
    assert ack.result == ACCEPTED

    def aims_at_buoy(msg) -> bool:
        position = gcs.recv("GLOBAL_POSITION_INT")
        north, east, down = FRAME.to_ned(position.lat * 1e-7, position.lon * 1e-7, position.alt * 1e-3)
        pitch = -math.atan2(-down, math.hypot(BUOY_NE[0] - north, BUOY_NE[1] - east))
        yaw = math.atan2(BUOY_NE[1] - east, BUOY_NE[0] - north) - math.radians(position.hdg / 100)
        yaw = (yaw + math.pi) % (2 * math.pi) - math.pi
        return angles_near(msg, math.degrees(pitch), math.degrees(yaw), tolerance_deg=1.0)

    settled = gcs.recv("GIMBAL_DEVICE_ATTITUDE_STATUS", timeout=WAIT_S, condition=aims_at_buoy)
    assert settled is not None, "GIMBAL_DEVICE_ATTITUDE_STATUS never aimed at the ROI"
    assert camera_command(gcs, mavlink.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, 1, 0).result == ACCEPTED
    shot = gcs.recv("CAMERA_IMAGE_CAPTURED", timeout=WAIT_S, condition=from_camera)
    assert shot is not None and shot.capture_result == 1
    pixels = valid_jpeg(images / f"IMG_{shot.image_index:06d}.jpg").astype(int)
    red, green, blue = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    rows, columns = np.nonzero((red > 120) & (green < 70) & (blue < 70))  # the can's traffic red
    assert len(rows) > 50, "no red buoy in the frame"
    centre_u, centre_v = columns.mean(), rows.mean()
    assert abs(centre_u - DEFAULT_CAMERA.cx) < 60 and abs(centre_v - DEFAULT_CAMERA.cy) < 60
    assert gcs.command(mavlink.MAV_CMD_DO_SET_ROI_NONE).result == ACCEPTED
    assert gcs.recv("GIMBAL_DEVICE_ATTITUDE_STATUS", timeout=WAIT_S, condition=lambda m: angles_near(m, 0, 0))


def test_mission_items_point_the_gimbal_and_take_a_photo(start_sitl, tmp_path):
    """ROI, capture and ROI-none as mission items: run when the navigator reaches them (PX4 re-issues them)."""
    vehicle = start_sitl(speed=4.0, extra_args=("--camera", "--image-dir", str(tmp_path)))
    gcs = connected(vehicle)
    mission_frame = mavlink.MAV_FRAME_MISSION
    south_lat, south_lon, _ = FRAME.from_ned(-20.0, 0.0, 0.0)
    items = [
        mission_item(0, mavlink.MAV_CMD_NAV_TAKEOFF, DEFAULT_HOME[0], DEFAULT_HOME[1], HOVER_M),
        mission_item(1, mavlink.MAV_CMD_DO_SET_ROI_LOCATION, BUOY_LAT, BUOY_LON, 0.0),
        mission_item(2, mavlink.MAV_CMD_NAV_WAYPOINT, south_lat, south_lon, HOVER_M, params=(2.0, 1.0, 0.0, math.nan)),
        mission_item(3, mavlink.MAV_CMD_IMAGE_START_CAPTURE, frame=mission_frame, params=(0.0, 0.0, 1.0, 0.0)),
        mission_item(4, mavlink.MAV_CMD_DO_SET_ROI_NONE, frame=mission_frame),
    ]
    assert gcs.upload_mission(items).type == mavlink.MAV_MISSION_ACCEPTED
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == ACCEPTED
    assert gcs.command(mavlink.MAV_CMD_MISSION_START, 0, 0).result == ACCEPTED
    # from 20 m south and 20 m up the buoy is 60 m north: pitch -18.4 deg, bearing north whatever the heading
    aimed = gcs.recv("GIMBAL_DEVICE_ATTITUDE_STATUS", timeout=WAIT_S, condition=lambda m: aims_north(m, -18.4))
    assert aimed is not None, "the ROI item did not aim the gimbal at the buoy"
    # the last two items are reached in one tick: the photo is taken at its end, after the reports
    seen: dict[str, object] = {}
    while len(seen) < 2:
        kinds = ["CAMERA_IMAGE_CAPTURED", "MISSION_ITEM_REACHED"]
        msg = gcs.recv(kinds, timeout=WAIT_S, condition=lambda m: m.get_type() != "MISSION_ITEM_REACHED" or m.seq == 4)
        assert msg is not None, f"only {sorted(seen)}"
        seen[msg.get_type()] = msg
    shot = seen["CAMERA_IMAGE_CAPTURED"]
    assert shot.capture_result == 1
    valid_jpeg(tmp_path / f"IMG_{shot.image_index:06d}.jpg")
    assert gcs.recv("GIMBAL_DEVICE_ATTITUDE_STATUS", timeout=WAIT_S, condition=lambda m: angles_near(m, 0, 0))
    gcs.close()
