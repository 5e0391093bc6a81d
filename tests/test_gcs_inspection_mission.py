"""The inspection's mission items and layout, and the camera's reports as the ground station checks them: pure
computation on plans and on MAVLink messages built with the project's own encoder."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from stored_missions import FLIGHT

from gcs.domain.planning import (
    BURST_HOLD_MARGIN_S,
    FIRST_BUOY_SEQ,
    INSPECTION_GROUP,
    BuoyMark,
    MissionLayout,
    buoy_of_seq,
    inspection_time_s,
    mission_items,
    sorties_plan,
    standoff_point,
)
from gcs.vehicle.camera import CameraError, CameraInfo, Capture, CaptureReportError
from uavcore.geodesy import LocalFrame
from uavcore.light_character import burst_for, parse
from uavcore.mavlink import mavlink
from uavcore.mission import MavCmd

DEPOT = (55.0, 12.0)
FRAME = LocalFrame(*DEPOT)
MARKS = [BuoyMark("port", "Fl(2) R 6s", 8.0), BuoyMark("north", "Q W", 5.0), BuoyMark("special", None, 5.0)]


def plan_of(*north_east: tuple[float, float], marks: list[BuoyMark] | None = MARKS):
    lat_lon = [FRAME.from_ned(n, e)[:2] for n, e in north_east]
    plan = sorties_plan(DEPOT, lat_lon, [f"B{i + 1}" for i in range(len(lat_lon))], [list(range(len(lat_lon)))], "t", 0)
    return replace(plan, marks=None if marks is None else marks[: len(lat_lon)])


def north_east(item) -> np.ndarray:
    north, east, _ = FRAME.to_ned(item.x / 1e7, item.y / 1e7)
    return np.array([north, east])


def test_each_buoy_is_an_inspection_group_aiming_at_it_from_the_way_in_with_the_burst_its_light_needs():
    plan = plan_of((200.0, 0.0), (200.0, 300.0), (0.0, 300.0))
    items = mission_items(plan, FLIGHT, camera=True)
    assert [i.seq for i in items] == list(range(len(items)))
    assert len(items) == FIRST_BUOY_SEQ + INSPECTION_GROUP * 3 + 1  # takeoff, speed, the groups, the return
    previous = np.zeros(2)
    for position, index in enumerate(plan.order):
        roi, approach, start, hold, stop, release, visit = items[FIRST_BUOY_SEQ + INSPECTION_GROUP * position :][:7]
        commands = [i.command for i in (roi, approach, start, hold, stop, release, visit)]
        assert commands == [MavCmd.DO_SET_ROI_LOCATION, MavCmd.NAV_WAYPOINT, MavCmd.IMAGE_START_CAPTURE,
                            MavCmd.NAV_WAYPOINT, MavCmd.IMAGE_STOP_CAPTURE, MavCmd.DO_SET_ROI_NONE,
                            MavCmd.NAV_WAYPOINT]  # fmt: skip
        buoy = np.array(FRAME.to_ned(*plan.buoys_lat_lon[index], 0.0)[:2])
        assert np.allclose(north_east(roi), buoy, atol=0.02) and np.allclose(north_east(visit), buoy, atol=0.02)
        # the standoff: on the straight way in, 20 m short of the buoy, held as long as the burst and a margin
        assert (approach.x, approach.y) == (hold.x, hold.y)
        standoff = north_east(approach)
        assert math.dist(standoff, buoy) == pytest.approx(FLIGHT.inspection_range_m, abs=0.05)
        way_in = (buoy - previous) / np.linalg.norm(buoy - previous)
        assert np.allclose((buoy - standoff) / np.linalg.norm(buoy - standoff), way_in, atol=1e-3)
        duration, rate = burst_for(None if plan.mark(index).light is None else parse(plan.mark(index).light))
        count = math.ceil(duration * rate)
        assert (start.param2, start.param3) == pytest.approx((1.0 / rate, count))
        assert hold.param1 == pytest.approx(count / rate + BURST_HOLD_MARGIN_S) and approach.param1 == 0.0
        assert visit.param1 == FLIGHT.dwell_s and visit.param2 == FLIGHT.acceptance_radius_m
        previous = buoy
    assert inspection_time_s(plan) > sum(i.param1 for i in items if i.command == MavCmd.NAV_WAYPOINT) - 3.0


def test_without_a_camera_or_with_inspect_off_each_buoy_is_one_waypoint():
    plan = plan_of((200.0, 0.0), (200.0, 300.0))
    plain = mission_items(plan, FLIGHT)
    assert mission_items(plan, replace(FLIGHT, inspect=False), camera=True) == plain
    assert [i.command for i in plain[FIRST_BUOY_SEQ:-1]] == [MavCmd.NAV_WAYPOINT] * 2


def test_a_short_leg_is_looked_at_from_its_middle_and_a_buoy_at_the_point_before_from_the_south():
    plan = plan_of((30.0, 0.0), (30.0, 0.0))  # 30 m from the depot, then the same place again
    first = np.array(FRAME.to_ned(*standoff_point(plan, 0, 20.0), 0.0)[:2])
    assert np.allclose(first, [15.0, 0.0], atol=0.05)
    second = np.array(FRAME.to_ned(*standoff_point(plan, 1, 20.0), 0.0)[:2])
    assert np.allclose(second, [10.0, 0.0], atol=0.05)


def test_the_layout_says_which_buoy_and_leg_each_item_belongs_to_and_only_the_visit_counts_as_reaching_it():
    plan = plan_of((200.0, 0.0), (200.0, 300.0), (0.0, 300.0))
    layout = MissionLayout(3, inspected=True)
    items = mission_items(plan, FLIGHT, camera=True)
    visits = [layout.visit_seq(p) for p in range(3)]
    assert all(items[seq].command == MavCmd.NAV_WAYPOINT and items[seq].param1 == FLIGHT.dwell_s for seq in visits)
    assert [buoy_of_seq(seq, plan, layout) for seq in range(len(items))] == [
        plan.order[visits.index(seq)] if seq in visits else None for seq in range(len(items))
    ]
    assert [layout.position_of(seq) for seq in (0, 1, 2, 8, 9, 22, 23)] == [None, None, 0, 0, 1, 2, None]
    assert [layout.leg_of_seq(seq) for seq in (None, 1, 2, 8, 9, 22, 23)] == [None, None, 0, 0, 1, 2, 3]
    plain = MissionLayout(3)
    assert [plain.leg_of_seq(seq) for seq in (2, 3, 4, 5)] == [0, 1, 2, 3] and plain.visit_seq(1) == 3


def test_an_uncharted_buoy_gets_the_short_burst_and_a_stored_plan_without_marks_reads_as_uncharted():
    plan = plan_of((200.0, 0.0), marks=None)
    assert plan.mark(0) == BuoyMark() and plan.mark(0).burst() == burst_for(None)
    assert type(plan).from_dict(plan.to_dict()) == plan
    charted = plan_of((200.0, 0.0))
    assert type(charted).from_dict(charted.to_dict()) == charted


# ----- the camera's reports
ENCODER = mavlink.MAVLink(None, srcSystem=1, srcComponent=100)


def captured(**changes):
    fields = dict(time_boot_ms=12_500, time_utc=0, camera_id=0, lat=389_210_000, lon=1_216_630_000, alt=5000,
                  relative_alt=5250, q=[1.0, 0.0, 0.0, 0.0], image_index=7, capture_result=1,
                  file_url=b"mftp://[;comp=100]/IMG_000007.jpg")  # fmt: skip
    message = ENCODER.camera_image_captured_encode(**(fields | changes))
    return mavlink.MAVLink(None).decode(bytearray(message.pack(ENCODER)))


def test_a_capture_report_gives_its_geotag_and_file_url():
    capture = Capture.from_message(captured())
    g = capture.geotag
    assert (capture.component, capture.file_url) == (100, "mftp://[;comp=100]/IMG_000007.jpg")
    assert (g.lat, g.lon, g.height_m, g.t_s, g.image_index) == pytest.approx((38.921, 121.663, 5.25, 12.5, 7))


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        ({"capture_result": 0}, "capture_result is 0"),
        ({"q": [0.0, 0.0, 0.0, 0.0]}, "not a unit quaternion"),
        ({"q": [float("nan"), 0.0, 0.0, 0.0]}, "not a unit quaternion"),
        ({"file_url": b""}, "file_url is empty"),
        ({"lat": 950_000_000}, "are not a position"),
        ({"image_index": -1}, "image_index is -1"),
    ],
)
def test_a_capture_report_that_does_not_add_up_is_refused_naming_the_field(changes, named):
    with pytest.raises(CaptureReportError, match=named):
        Capture.from_message(captured(**changes))


def camera_information(**changes):
    fields = dict(time_boot_ms=0, vendor_name=list(b"<b>acme</b>".ljust(32, b"\0")),
                  model_name=list(b"cam".ljust(32, b"\0")), firmware_version=1, focal_length=4.5,
                  sensor_size_h=6.17, sensor_size_v=3.47, resolution_h=1280, resolution_v=720, lens_id=0, flags=0,
                  cam_definition_version=0, cam_definition_uri=b"")  # fmt: skip
    message = ENCODER.camera_information_encode(**(fields | changes))
    return mavlink.MAVLink(None).decode(bytearray(message.pack(ENCODER)))


def test_camera_information_gives_the_pinhole_model_and_the_cameras_names_as_text():
    info = CameraInfo.from_message(camera_information())
    assert (info.component, info.vendor, info.model_name) == (100, "<b>acme</b>", "cam")
    assert (info.model.width_px, info.model.height_px, info.model.focal_length_mm) == (1280, 720, 4.5)


@pytest.mark.parametrize("changes", [{"focal_length": 0.0}, {"sensor_size_v": float("nan")}, {"resolution_h": 0}])
def test_camera_information_without_a_usable_lens_or_sensor_is_refused(changes):
    with pytest.raises(CameraError):
        CameraInfo.from_message(camera_information(**changes))
