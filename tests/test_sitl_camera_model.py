"""The camera payload's pure parts: the gimbal (sitl_quad.gimbal) and the camera model (sitl_quad.camera)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_quad.camera import (
    DEFAULT_SPEC,
    CaptureSchedule,
    Environment,
    WorldView,
    camera_pose,
    image_name,
    rendered_buoy,
)
from sitl_quad.camera_render import DEFAULT_CAMERA, CameraPose, project
from sitl_quad.gimbal import SLEW_RATE_DEG_S, Gimbal, aim_angles
from uavcore.buoy_world import LIGHT_RGB, PAINT_RGB, World, WorldBuoy
from uavcore.geodesy import LocalFrame
from uavcore.light_character import parse
from uavcore.rotation import euler_from_quat

DT = 0.02


def settle(gimbal: Gimbal, seconds: float, camera_ned=(0.0, 0.0, -20.0), vehicle_yaw: float = 0.0) -> None:
    for _ in range(round(seconds / DT)):
        gimbal.update(DT, camera_ned, vehicle_yaw)


def optical_axis(q) -> np.ndarray:
    return CameraPose((0.0, 0.0, -1.0), tuple(q)).rotation()[:, 0]


# ----- gimbal
def test_gimbal_slews_at_its_rate_limit_and_reaches_the_target():
    gimbal = Gimbal()
    gimbal.set_angles(math.radians(-60), math.radians(45))
    settle(gimbal, 0.5)
    assert math.degrees(gimbal.pitch) == pytest.approx(-SLEW_RATE_DEG_S * 0.5, abs=1e-6)
    assert math.degrees(gimbal.yaw) == pytest.approx(45.0, abs=1e-6)  # reached: 45 < 90 * 0.5
    settle(gimbal, 1.0)
    assert math.degrees(gimbal.pitch) == pytest.approx(-60.0, abs=1e-6)


def test_gimbal_stops_at_its_mechanical_limits():
    gimbal = Gimbal()
    gimbal.set_angles(math.radians(-120), math.radians(0))
    settle(gimbal, 3.0)
    assert math.degrees(gimbal.pitch) == pytest.approx(-90.0)
    gimbal.set_angles(math.radians(60), math.nan)
    settle(gimbal, 3.0)
    assert math.degrees(gimbal.pitch) == pytest.approx(30.0)
    gimbal.set_rates(0.0, math.radians(100))  # a rate command winds to the stop, not past it
    settle(gimbal, 5.0)
    assert math.degrees(gimbal.yaw) == pytest.approx(180.0, abs=1e-6)
    gimbal.set_rates(0.0, math.radians(-100))
    settle(gimbal, 0.1)
    assert math.degrees(gimbal.yaw) < 180.0  # turns back at once: the target was not wound beyond the stop


def test_yaw_lock_keeps_the_bearing_while_the_vehicle_turns():
    gimbal = Gimbal()
    gimbal.set_angles(0.0, math.radians(90), yaw_lock=True)  # look east
    settle(gimbal, 2.0, vehicle_yaw=math.radians(30))
    assert math.degrees(gimbal.earth_yaw(math.radians(30))) == pytest.approx(90.0, abs=1e-6)
    assert math.degrees(gimbal.yaw) == pytest.approx(60.0, abs=1e-6)
    follow = Gimbal()
    follow.set_angles(0.0, math.radians(90))
    settle(follow, 2.0, vehicle_yaw=math.radians(30))
    assert math.degrees(follow.earth_yaw(math.radians(30))) == pytest.approx(120.0, abs=1e-6)


@pytest.mark.parametrize("vehicle_yaw_deg", [0.0, 75.0, -140.0])
def test_roi_puts_the_optical_axis_through_the_location(vehicle_yaw_deg):
    camera, roi = (10.0, -5.0, -30.0), (60.0, 40.0, 0.0)
    yaw = math.radians(vehicle_yaw_deg)
    gimbal = Gimbal()
    gimbal.point_at(roi)
    settle(gimbal, 4.0, camera, yaw)
    axis = optical_axis(gimbal.camera_quaternion(yaw))
    line = np.subtract(roi, camera)
    angle = math.degrees(math.acos(np.dot(axis, line) / np.linalg.norm(line)))
    assert angle < 0.1
    pitch, bearing = aim_angles(camera, roi)
    assert math.degrees(pitch) == pytest.approx(math.degrees(math.atan2(30, math.hypot(50, 45))) * -1, abs=1e-9)
    assert bearing == pytest.approx(math.atan2(45, 50))


def test_camera_attitude_ignores_the_vehicles_roll_and_pitch_and_reports_yaw_in_the_vehicle_frame():
    """The camera's attitude depends on the vehicle's heading only: roll and pitch are stabilised away."""
    gimbal = Gimbal()
    gimbal.set_angles(math.radians(-30), math.radians(20))
    settle(gimbal, 1.0, vehicle_yaw=math.radians(50))
    roll, pitch, yaw = euler_from_quat(gimbal.camera_quaternion(math.radians(50)))
    assert (math.degrees(roll), math.degrees(pitch), math.degrees(yaw)) == pytest.approx((0.0, -30.0, 70.0), abs=1e-6)
    _, device_pitch, device_yaw = euler_from_quat(gimbal.device_quaternion())
    assert (math.degrees(device_pitch), math.degrees(device_yaw)) == pytest.approx((-30.0, 20.0), abs=1e-6)


def test_neutral_levels_the_camera_straight_ahead():
    gimbal = Gimbal()
    gimbal.point_at((0.0, 50.0, 0.0))
    settle(gimbal, 2.0)
    gimbal.neutral()
    settle(gimbal, 2.0)
    assert (gimbal.pitch, gimbal.yaw) == (0.0, 0.0)


# ----- capture schedule, on simulated time
def run_schedule(schedule: CaptureSchedule, start: float, end: float) -> list[tuple[float, int]]:
    taken = []
    for k in range(round(start / DT), round(end / DT) + 1):
        t = k * DT
        index = schedule.take_due(t)
        if index is not None:
            taken.append((round(t, 6), index))
    return taken


def test_interval_and_count_capture_at_their_simulated_instants():
    schedule = CaptureSchedule()
    schedule.start(1.0, 0.2, 5)
    assert schedule.interval_running
    taken = run_schedule(schedule, 1.0, 5.0)
    assert taken == [(1.0, 0), (1.2, 1), (1.4, 2), (1.6, 3), (1.8, 4)]
    assert not schedule.interval_running and schedule.image_count == 5


def test_an_interval_sent_as_float32_still_captures_on_the_ticks_it_means():
    """MAVLink's float32 makes 0.1 s 0.10000000149 s and 0.075 s 0.07500000298 s: no capture may slip a tick."""
    for interval, expected in ((0.1, [1.0, 1.1, 1.2, 1.3, 1.4, 1.5]), (0.075, [1.0, 1.08, 1.16, 1.24, 1.3, 1.38])):
        schedule = CaptureSchedule()
        schedule.start(1.0, float(np.float32(interval)), len(expected))
        assert [t for t, _ in run_schedule(schedule, 1.0, 3.0)] == expected


def test_a_sequence_started_between_ticks_runs_from_its_first_capture():
    """A command handled after the tick at 1.0 (its capture already taken) is first captured by the tick at 1.02."""
    schedule = CaptureSchedule()
    schedule.start(1.0, 0.2, 3)
    assert [t for t, _ in run_schedule(schedule, 1.02, 3.0)] == [1.02, 1.22, 1.42]


def test_single_shot_and_numbering_across_sequences():
    schedule = CaptureSchedule()
    schedule.start(0.0, 0.0, 1)
    assert not schedule.interval_running
    assert run_schedule(schedule, 0.0, 1.0) == [(0.0, 0)]
    schedule.start(2.0, 0.5, 0)  # until stopped
    taken = run_schedule(schedule, 2.0, 3.9)
    assert [index for _, index in taken] == [1, 2, 3, 4]
    schedule.stop()
    assert run_schedule(schedule, 4.0, 6.0) == []
    assert schedule.image_count == 5


def test_schedule_refuses_a_sequence_without_an_interval():
    with pytest.raises(ValueError):
        CaptureSchedule().start(0.0, 0.0, 3)


# ----- the scene
def test_a_dark_light_renders_no_light_and_a_lit_one_its_colour():
    light = parse("Fl R 4s")
    lit = WorldBuoy("p1", "port", (38.9215, 121.663), light=light, actual_light=light)
    dark = WorldBuoy("p2", "port", (38.9215, 121.663), light=light, actual_light=None)  # light_out
    t_on = next(t for t in np.arange(0, 8, 0.05) if lit.light_on(t))
    t_off = next(t for t in np.arange(0, 8, 0.05) if not lit.light_on(t))
    assert rendered_buoy(lit, (1.0, 2.0), t_on).light_rgb == LIGHT_RGB["R"]
    assert rendered_buoy(lit, (1.0, 2.0), t_off).light_rgb is None
    assert all(rendered_buoy(dark, (1.0, 2.0), t).light_rgb is None for t in np.arange(0, 8, 0.05))
    port = rendered_buoy(dark, (1.0, 2.0), 0.0)
    assert (port.shape, list(port.bands), port.topmark) == ("can", [PAINT_RGB["red"]], "can")


def test_world_view_places_buoys_in_the_vehicles_frame():
    frame = LocalFrame(38.921, 121.663, 0.0)
    world = World.default([[38.9215, 121.663]], ["b1"])
    scene = WorldView(world, frame).scene(10.0, Environment())
    (buoy,) = scene.buoys
    charted_north = frame.to_ned(38.9215, 121.663, 0.0)[0]
    assert math.hypot(buoy.position_ne[0] - charted_north, buoy.position_ne[1]) <= world.buoys[0].swing_radius_m
    assert buoy.vertical_stripes  # the first buoy of a default world is safe water


def test_camera_spec_is_the_renderers_default_camera_and_names_are_deterministic():
    assert DEFAULT_SPEC.intrinsics == DEFAULT_CAMERA
    assert image_name(12) == "IMG_000012.jpg"


def test_camera_pose_puts_the_sea_at_down_zero():
    pose = camera_pose((5.0, 6.0, -20.0), 3.0, (1.0, 0.0, 0.0, 0.0))
    assert pose.position_ned == (5.0, 6.0, -23.0)  # 20 m above a home 3 m above the sea
    pixels, visible = project(pose, DEFAULT_CAMERA, np.array([[105.0, 6.0, -23.0]]))
    assert visible[0] and tuple(pixels[0]) == pytest.approx((DEFAULT_CAMERA.cx, DEFAULT_CAMERA.cy))
    assert camera_pose((0.0, 0.0, 0.0), 0.0, (1.0, 0.0, 0.0, 0.0)).height_m > 0  # on a quay at sea level
