"""The ground station's inspection analysis (gcs.domain camera_geometry, buoy_detection, light_reading,
inspection) on frames the simulator's camera renders (bench/inspection_scenes.py): JPEG-encoded and decoded, as
the station receives them.

Resolutions: the geometry and position tests at 960 x 540; the full light bursts (up to 413 frames) at 640 x 360,
the same lens, to keep the run short. Every test renders frames: the module is in the slow tier.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np
import pytest

from bench.inspection_scenes import HOME, Burst, capture_burst
from gcs.domain.buoy_detection import BuoyDetection, ChartedBuoy, detect_buoy
from gcs.domain.camera_geometry import FrameGeotag, pixel_to_sea, sea_to_pixel
from gcs.domain.inspection import BuoyInspection, against_target, inspect_buoy
from sitl_quad import camera_render
from uavcore.buoy_world import APPEARANCE, KINDS, World, WorldBuoy, default_light
from uavcore.light_character import parse

# every test here renders frames (bursts of up to 413): the slow tier, out of `make test-fast`
pytestmark = pytest.mark.slow

LIGHT_BURST = (640, 360)
SHORT_BURST_KINDS = ("port", "starboard", "north", "isolated_danger", "special")
LONG_BURST_KINDS = ("east", "south", "west", "safe_water")


def world_buoy(
    kind: str, north: float, east: float, shows: str | None = "charted", swing_radius_m: float = 5.0, **faults: object
) -> WorldBuoy:
    """A buoy of the kind at (north, east) of HOME with its default light; shows: "dark", another character's
    text, or "charted"."""
    lat, lon, _ = HOME.from_ned(north, east)
    light = default_light(kind)
    actual = light if shows == "charted" else None if shows == "dark" else parse(shows)
    position = (float(lat), float(lon))
    return WorldBuoy(f"{kind}-{north:g}-{east:g}", kind, position, light, swing_radius_m, actual, **faults)  # type: ignore[arg-type]


def charted(buoy: WorldBuoy) -> ChartedBuoy:
    light = None if buoy.light is None else buoy.light.abbreviation()
    return ChartedBuoy(buoy.charted[0], buoy.charted[1], buoy.kind, light, buoy.swing_radius_m)


def analyse(burst: Burst, buoy: WorldBuoy) -> tuple[list[tuple[FrameGeotag, BuoyDetection]], BuoyInspection]:
    frames = [(s.geotag, detect_buoy(s.image, burst.model, s.geotag, charted(buoy))) for s in burst.shots]
    return frames, inspect_buoy(charted(buoy), frames)


@functools.cache
def inspected(kind: str, shows: str | None = "charted", offset_m: tuple[float, float] = (0.0, 0.0)) -> BuoyInspection:
    """A full burst of one buoy 30 m off, and its inspection (cached: several tests read one)."""
    buoy = world_buoy(kind, 60.0, 20.0, shows, offset_m=offset_m)
    world = World((buoy,), seed=KINDS.index(kind))
    return analyse(capture_burst(world, 0, 30.0, 200.0, resolution=LIGHT_BURST), buoy)[1]


def test_pixel_to_sea_and_sea_to_pixel_agree_with_the_renderers_pinhole_geometry() -> None:
    rng = np.random.default_rng(4)
    burst_model = capture_burst(World((world_buoy("port", 50.0, 0.0),)), 0, 20.0, 180.0, frames=1).model
    intrinsics = camera_render.Intrinsics.from_sensor(960, 540, 4.5, 6.17, 6.17 * 540 / 960)
    for _ in range(20):
        north, east = rng.uniform(-50, 50, size=2)
        roll, pitch, yaw = rng.uniform(-0.2, 0.2), rng.uniform(-0.6, -0.1), rng.uniform(-math.pi, math.pi)
        pose = camera_render.CameraPose.from_euler((north, east, -rng.uniform(3, 30)), roll, pitch, yaw)
        lat, lon, _ = HOME.from_ned(north, east)
        geotag = FrameGeotag(float(lat), float(lon), pose.height_m, pose.attitude, 0.0)
        u, v = rng.uniform(0, 959), rng.uniform(200, 539)
        oracle = camera_render.pixel_to_sea(pose, intrinsics, u, v)
        mine = pixel_to_sea(burst_model, geotag, u, v)
        assert (oracle is None) == (mine is None)
        if oracle is None or mine is None:
            continue
        sea_north, sea_east, _ = HOME.to_ned(*mine)
        assert math.hypot(sea_north - oracle[0], sea_east - oracle[1]) < 0.03
        pixel, _ = camera_render.project(pose, intrinsics, np.array([[oracle[0], oracle[1], 0.0]]))
        back = sea_to_pixel(burst_model, geotag, *mine)
        assert back is not None and math.hypot(back[0] - pixel[0, 0], back[1] - pixel[0, 1]) < 1.0


def test_a_pixel_above_the_horizon_has_no_sea_point() -> None:
    model = capture_burst(World((world_buoy("port", 50.0, 0.0),)), 0, 20.0, 180.0, frames=1).model
    level = FrameGeotag(HOME.lat0, HOME.lon0, 5.0, (1.0, 0.0, 0.0, 0.0), 0.0)
    assert pixel_to_sea(model, level, 480.0, 100.0) is None
    assert pixel_to_sea(model, level, 480.0, 400.0) is not None


def test_frame_geotag_from_camera_image_captured_fields() -> None:
    geotag = FrameGeotag.from_capture(389210000, 1216630000, 5250, [1.0, 0.0, 0.0, 0.0], 12345, 7)
    assert (geotag.lat, geotag.lon, geotag.height_m, geotag.t_s, geotag.image_index) == (
        38.921,
        121.663,
        5.25,
        12.345,
        7,
    )


def test_observed_positions_are_within_a_metre_rms_of_the_true_ones_for_every_kind() -> None:
    errors = []
    for k, kind in enumerate(KINDS):
        for range_m in (15.0, 27.0, 40.0):
            buoy = world_buoy(kind, 60.0, -20.0)
            burst = capture_burst(World((buoy,), seed=k), 0, range_m, 40.0 * k + range_m, frames=3, sea_seed=k)
            _, inspection = analyse(burst, buoy)
            assert inspection.observed is not None, (kind, range_m)
            north, east, _ = HOME.to_ned(inspection.observed.lat, inspection.observed.lon)
            truth = np.mean([s.true_north_east for s in burst.shots], axis=0)
            errors.append(math.hypot(north - truth[0], east - truth[1]))
    assert math.sqrt(np.mean(np.square(errors))) <= 1.0
    assert max(errors) < 1.5


def fault_free_reads_right(kind: str) -> None:
    inspection = inspected(kind)
    assert inspection.verdict == "ok", inspection.findings
    assert inspection.findings == [] and inspection.offset_m is not None and inspection.offset_m < 5.0
    assert inspection.light_seen not in ("dark", "unreadable")


@pytest.mark.parametrize("kind", SHORT_BURST_KINDS)
def test_a_fault_free_buoy_is_ok_and_its_light_reads_as_charted(kind: str) -> None:
    fault_free_reads_right(kind)


@pytest.mark.parametrize("kind", LONG_BURST_KINDS)
def test_a_fault_free_buoy_with_a_long_light_period_is_ok_and_its_light_reads_as_charted(kind: str) -> None:
    fault_free_reads_right(kind)


def test_a_buoy_off_station_by_three_swing_radii_is_a_defect_with_its_offset() -> None:
    inspection = inspected("port", offset_m=(-15.0, 0.0))  # 15 m toward the camera: still in view
    assert inspection.verdict == "defect"
    assert [f.code for f in inspection.findings] == ["off_station"]
    assert 10.0 < inspection.findings[0].model_dump()["offset_m"] < 20.0


def test_a_dark_light_is_light_out() -> None:
    inspection = inspected("starboard", shows="dark")
    assert (inspection.verdict, [f.code for f in inspection.findings]) == ("defect", ["light_out"])
    assert inspection.light_seen == "dark"


def test_a_light_showing_another_character_is_wrong_character_with_both_texts() -> None:
    inspection = inspected("special", shows="Fl(2) Y 4s")
    assert inspection.verdict == "defect"
    finding = inspection.findings[0].model_dump()
    assert (finding["code"], finding["charted"]) == ("wrong_character", "Fl Y 4s")
    assert finding["seen"].startswith("flashing ..")


def test_a_light_slower_than_its_burst_can_read_is_still_a_wrong_character() -> None:
    """Charted Fl R 4s, showing Fl R 8s: the burst (two charted periods and a second) holds one flash at most, too
    little to read a rhythm, but its dark outlasts the chart's longest: a defect, not "its light could not be read"
    (the campaign's two misses of this kind)."""
    inspection = inspected("port", shows="Fl R 8s")
    assert inspection.verdict == "defect", inspection
    finding = inspection.findings[0].model_dump()
    assert finding["code"] == "wrong_character" and finding["charted"] == "Fl R 4s", finding
    assert finding["seen"].startswith("dark up to "), finding


def test_frames_without_the_buoy_are_not_found_even_with_other_buoys_in_view() -> None:
    target = world_buoy("port", 60.0, 0.0)
    others = (world_buoy("starboard", 62.0, 8.0), world_buoy("north", 58.0, -9.0))
    burst = capture_burst(World((target, *others)), 0, 25.0, 180.0, frames=4, hide_target=True)
    frames, inspection = analyse(burst, target)
    assert not any(d.found for _, d in frames)
    assert (inspection.verdict, [f.code for f in inspection.findings]) == ("defect", ["not_found"])


def test_sea_clutter_alone_gives_no_detection_of_any_kind() -> None:
    for seed in range(3):
        hidden = world_buoy("special", 60.0, 0.0)
        burst = capture_burst(World((hidden,)), 0, 20.0, 90.0 * seed, frames=2, sea_seed=seed, hide_target=True)
        for kind in KINDS:
            buoy = world_buoy(kind, 60.0, 0.0)
            assert not any(detect_buoy(s.image, burst.model, s.geotag, charted(buoy)).found for s in burst.shots)


def test_the_buoy_nearest_the_chart_is_picked_among_others_of_its_colours() -> None:
    target = world_buoy("port", 60.0, 0.0)
    others = (
        world_buoy("port", 75.0, 12.0),
        world_buoy("isolated_danger", 55.0, -10.0),
        world_buoy("starboard", 64.0, 6.0),
    )
    burst = capture_burst(World((target, *others)), 0, 25.0, 180.0, frames=2)
    for (_, detection), shot in zip(analyse(burst, target)[0], burst.shots, strict=True):
        assert detection.position is not None
        north, east, _ = HOME.to_ned(*detection.position)
        assert math.hypot(north - shot.true_north_east[0], east - shot.true_north_east[1]) < 1.0


HALF_FIELD_DEG = math.degrees(math.atan(480 / (4.5 / 6.17 * 960)))  # the 960 x 540 frame's, either side


@pytest.mark.parametrize("kind", ["port", "east", "safe_water"])
@pytest.mark.parametrize("side", [-1, 1])
def test_a_buoy_cut_by_the_frames_side_is_placed_from_the_side_in_view(kind: str, side: int) -> None:
    """A buoy at the frame's side (far off station, at the edge of a frame aimed at its chart position): with its
    middle in view it is placed within half a metre, and neither its colours (its bands cut short) nor a lamp cut
    by the edge are read; with less of it in view it is found but not placed."""
    buoy = world_buoy(kind, 60.0, 0.0, swing_radius_m=0.05)  # held still: the share in view is the one set here
    half_body_deg = math.degrees(math.asin(APPEARANCE[kind].diameter_m / 2 / 25.0))
    for share in (0.75, 0.6, 0.25):  # of its width in view
        yaw = side * (HALF_FIELD_DEG + (1 - 2 * share) * half_body_deg)
        burst = capture_burst(World((buoy,)), 0, 25.0, 180.0, frames=1, yaw_offset_deg=yaw)
        shot = burst.shots[0]
        detection = detect_buoy(shot.image, burst.model, shot.geotag, charted(buoy))
        assert detection.found and detection.waterline_px is None and detection.colours == (), (share, detection)
        if share < 0.5:
            assert detection.why.startswith("clipped") and detection.position is None and detection.light is None
            continue
        assert detection.cut and detection.position is not None, (share, detection.why)
        north, east, _ = HOME.to_ned(*detection.position)
        assert math.hypot(north - shot.true_north_east[0], east - shot.true_north_east[1]) < 0.6, share


def test_a_buoy_cut_by_the_frames_bottom_is_found_without_a_waterline_colours_or_light() -> None:
    buoy = world_buoy("east", 60.0, 0.0)
    half_height_deg = math.degrees(math.atan(270 / (4.5 / 6.17 * 960)))
    burst = capture_burst(World((buoy,)), 0, 25.0, 180.0, frames=1, pitch_offset_deg=half_height_deg + 1.0)
    detection = detect_buoy(burst.shots[0].image, burst.model, burst.shots[0].geotag, charted(buoy))
    assert detection.found and detection.why.startswith("clipped"), detection.why
    assert (detection.waterline_px, detection.position, detection.colours, detection.light) == (None, None, (), None)


def test_an_off_station_buoy_at_the_frames_side_is_off_station_not_a_wrong_colour_or_a_dark_light() -> None:
    """A buoy dragged sideways, so far that the frame aimed at its charted position cuts it in every frame: the
    verdict says where it is (off_station), not what the cut body and a lamp half in view would suggest."""
    aside = 30.0 * math.tan(math.radians(HALF_FIELD_DEG))  # at 30 m across the camera's axis (bearing 20 deg)
    across = math.radians(20.0 + 90.0)
    inspection = inspected("north", offset_m=(aside * math.cos(across), aside * math.sin(across)))
    assert inspection.verdict == "defect"
    assert [f.code for f in inspection.findings] == ["off_station"], inspection.findings


def test_a_burst_looking_away_from_the_buoy_is_not_inspected() -> None:
    buoy = world_buoy("port", 60.0, 0.0)
    burst = capture_burst(World((buoy,)), 0, 25.0, 180.0, frames=3, yaw_offset_deg=120.0)
    inspection = analyse(burst, buoy)[1]
    assert inspection.verdict == "not_inspected" and inspection.reason is not None


def test_a_buoy_dragged_beyond_the_search_window_is_found_where_ais_saw_it_and_judged_against_the_chart() -> None:
    # the world has the buoy where its AIS report puts it; the chart, 40 m south (8 swing radii: beyond the search
    # window the chart alone would give): the mission looks at the report, the inspection judges by the chart
    buoy = world_buoy("starboard", 60.0, 20.0)
    burst = capture_burst(World((buoy,), seed=3), 0, 30.0, 200.0, resolution=LIGHT_BURST)
    chart_lat, chart_lon, _ = HOME.from_ned(20.0, 20.0)
    on_chart = ChartedBuoy(float(chart_lat), float(chart_lon), "starboard", charted(buoy).light, 5.0)
    sought_at_chart = [detect_buoy(s.image, burst.model, s.geotag, on_chart) for s in burst.shots]
    assert not any(d.found for d in sought_at_chart)
    frames = [(s.geotag, detect_buoy(s.image, burst.model, s.geotag, charted(buoy))) for s in burst.shots]
    inspection = against_target(inspect_buoy(on_chart, frames), buoy.charted)
    assert [f.code for f in inspection.findings] == ["off_station"]
    assert 39.0 < inspection.offset_m < 41.0 and inspection.offset_from_target_m < 1.0
    assert (inspection.target.lat, inspection.target.lon) == buoy.charted


def test_a_region_b_starboard_buoy_is_red_and_ok_there_and_not_found_by_region_as_green() -> None:
    # a US chart's starboard buoy (IALA region B: red, a cone), its light red as charted there
    light = parse("Fl R 4s")
    buoy = replace(world_buoy("starboard", 60.0, 20.0), region="B", light=light, actual_light=light)
    burst = capture_burst(World((buoy,), seed=5), 0, 30.0, 200.0, resolution=LIGHT_BURST)
    results = {}
    for region in ("B", "A"):
        chart = charted(buoy)._replace(region=region)
        frames = [(s.geotag, detect_buoy(s.image, burst.model, s.geotag, chart)) for s in burst.shots]
        results[region] = inspect_buoy(chart, frames)
    assert (results["B"].verdict, results["B"].findings, results["B"].buoy.region) == ("ok", [], "B")
    assert results["B"].light_seen.startswith("flashing . R")
    # looked for in region A's green, the red cone is not there: the region must be right, as the chart says
    assert [f.code for f in results["A"].findings] == ["not_found"]
