"""sitl_quad.camera_render: the pinhole projection and its inverse, the horizon, and buoys drawn where the
projection puts them, lit or dark, occluding, culled behind the camera and past the horizon; frames
deterministic per seed and instant, the sea moving with time."""

from __future__ import annotations

import dataclasses
import io
import math

import numpy as np
import pytest
from PIL import Image

from sitl_quad.camera_render import (
    DEFAULT_CAMERA,
    CameraPose,
    Intrinsics,
    RenderedBuoy,
    Scene,
    encode_jpeg,
    pixel_to_sea,
    project,
    render,
)

MAGENTA, CYAN, BLACK, YELLOW = (255, 0, 255), (0, 255, 255), (20, 20, 20), (250, 200, 0)
EARTH_RADIUS_M = 6_371_000.0
DOWN_10 = math.radians(-10)


def magenta(frame: np.ndarray) -> np.ndarray:
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    return (r > 150) & (b > 150) & (g < 100)


def cyan(frame: np.ndarray) -> np.ndarray:
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    return (g > 150) & (b > 150) & (r < 100)


def green(frame: np.ndarray) -> np.ndarray:
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    return (g > 200) & (r < 100) & (b < 100)


def centroid(mask: np.ndarray) -> np.ndarray:
    rows, columns = np.nonzero(mask)
    return np.array([columns.mean(), rows.mean()])


def first_sea_rows(frame: np.ndarray, columns: list[int]) -> list[int]:
    """Per column, the row below the largest drop in brightness: the sea under the horizon's brighter sky."""
    brightness = frame.astype(int).sum(axis=2)
    return [int(np.argmax(brightness[:-1, c] - brightness[1:, c])) + 1 for c in columns]


def can(position: tuple[float, float], bands: list, height: float = 3.0, diameter: float = 1.0, **kw) -> RenderedBuoy:
    return RenderedBuoy(position, bands, "can", height, diameter, **kw)


def test_default_camera_is_a_69_degree_one_with_square_pixels() -> None:
    assert math.degrees(DEFAULT_CAMERA.horizontal_fov_rad) == pytest.approx(68.9, abs=0.1)
    assert DEFAULT_CAMERA.fx == pytest.approx(DEFAULT_CAMERA.fy)
    assert (DEFAULT_CAMERA.cx, DEFAULT_CAMERA.cy) == (639.5, 359.5)


def test_project_and_pixel_to_sea_round_trip() -> None:
    pose = CameraPose.from_euler((3.0, -2.0, -12.0), math.radians(4), math.radians(-25), math.radians(40))
    rng = np.random.default_rng(1)
    for u, v in rng.uniform((0, 200), (1279, 719), size=(50, 2)):
        sea = pixel_to_sea(pose, DEFAULT_CAMERA, u, v)
        assert sea is not None
        pixel, visible = project(pose, DEFAULT_CAMERA, np.array([[sea[0], sea[1], 0.0]]))
        assert visible[0]
        assert np.abs(pixel[0] - (u, v)).max() < 1e-6
    # Sea points 10-150 m ahead (the camera looks north-east): projected, then back to within a millimetre.
    bearing, reach = rng.uniform(math.radians(20), math.radians(60), 50), rng.uniform(10, 150, 50)
    points = np.column_stack((3 + reach * np.cos(bearing), -2 + reach * np.sin(bearing), np.zeros(50)))
    pixels, visible = project(pose, DEFAULT_CAMERA, points)
    for point, (u, v) in zip(points[visible], pixels[visible], strict=True):
        assert np.abs(pixel_to_sea(pose, DEFAULT_CAMERA, u, v) - point[:2]).max() < 1e-3
    assert visible.sum() > 25


def test_pixels_at_or_above_the_horizon_have_no_sea_point() -> None:
    level = CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, 0.0, 0.0)
    assert pixel_to_sea(level, DEFAULT_CAMERA, 640.0, 100.0) is None
    assert pixel_to_sea(level, DEFAULT_CAMERA, 640.0, DEFAULT_CAMERA.cy) is None  # level: above the dipped horizon
    assert pixel_to_sea(level, DEFAULT_CAMERA, 640.0, 500.0) is not None


def test_project_flags_points_behind_the_camera_or_off_the_frame() -> None:
    pose = CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, 0.0, 0.0)
    pixels, visible = project(pose, DEFAULT_CAMERA, np.array([[-10.0, 0.0, 0.0], [10.0, 50.0, 0.0], [10.0, 0, -5]]))
    assert visible.tolist() == [False, False, True]
    assert np.isnan(pixels[0]).all()
    assert pixels[1, 0] > DEFAULT_CAMERA.width


def test_horizon_rows_of_a_level_camera_match_the_analytic_dipped_horizon() -> None:
    height = 100.0
    pose = CameraPose.from_euler((0.0, 0.0, -height), 0.0, 0.0, 0.0)
    frame = render(pose, DEFAULT_CAMERA, Scene(sea_seed=2))
    dip = math.acos(EARTH_RADIUS_M / (EARTH_RADIUS_M + height))
    columns = [5, 300, 640, 1000, 1274]
    # The horizon is a cone of rays dip below level: the ray (1, y, z) is on it where z = tan(dip) sqrt(1 + y^2),
    # a curve sagging toward the frame's sides (6.3 px below level there, 5.2 px in the middle).
    y = (np.array(columns) - DEFAULT_CAMERA.cx) / DEFAULT_CAMERA.fx
    horizon_rows = DEFAULT_CAMERA.cy + DEFAULT_CAMERA.fy * math.tan(dip) * np.sqrt(1 + y**2)
    assert horizon_rows.min() - DEFAULT_CAMERA.cy > 4  # the dip is there, not a flat sea's 0
    for row, expected in zip(first_sea_rows(frame, columns), horizon_rows, strict=True):
        assert 0 < row - expected <= 1  # the first row whose pixel centre is below it


def test_horizon_tilts_with_roll() -> None:
    roll = math.radians(10)
    pose = CameraPose.from_euler((0.0, 0.0, -100.0), roll, 0.0, 0.0)
    frame = render(pose, DEFAULT_CAMERA, Scene(sea_seed=2))
    dip = math.acos(EARTH_RADIUS_M / (EARTH_RADIUS_M + 100.0))
    azimuths = np.radians([-25, -10, 0, 10, 25])
    horizon = np.column_stack(
        (np.cos(dip) * np.cos(azimuths), np.cos(dip) * np.sin(azimuths), np.full(5, math.sin(dip)))
    )
    pixels, visible = project(pose, DEFAULT_CAMERA, np.array(pose.position_ned) + 1e5 * horizon)
    assert visible.all()
    columns = [round(u) for u in pixels[:, 0]]
    rows = first_sea_rows(frame, columns)
    for row, expected in zip(rows, pixels[:, 1], strict=True):
        assert abs(row - expected) <= 1
    # Rolled right, the horizon rises to the right, by tan(roll) per column (square pixels).
    assert rows[0] - rows[-1] == pytest.approx(math.tan(roll) * (columns[-1] - columns[0]), abs=2)


def test_buoy_appears_at_its_projected_pixel() -> None:
    pose = CameraPose.from_euler((0.0, 0.0, -4.0), 0.0, DOWN_10, 0.0)
    position, radius = np.array([30.0, 2.0]), 0.5
    buoy = can(tuple(position), [BLACK, MAGENTA, YELLOW], height=3.0, diameter=2 * radius)
    frame = render(pose, DEFAULT_CAMERA, Scene([buoy], sea_seed=4))
    # The magenta band (1-2 m above the waterline) as seen: its side facing the camera at mid-height.
    facing = position + radius * (-position / np.linalg.norm(position))
    (expected,), _ = project(pose, DEFAULT_CAMERA, np.array([[*facing, -1.5]]))
    found = magenta(frame)
    assert found.sum() > 200
    assert np.linalg.norm(centroid(found) - expected) < 2.0
    # Its waterline: the lowest row of the yellow bottom band, at the projected front of the waterline.
    (waterline,), _ = project(pose, DEFAULT_CAMERA, np.array([[*facing, 0.0]]))
    r, g, b = (frame[..., k].astype(int) for k in range(3))
    yellow_rows = np.nonzero(((r > 180) & (g > 140) & (b < 80)).any(axis=1))[0]
    assert abs(yellow_rows.max() - waterline[1]) < 2.0


def test_a_lit_light_glows_in_its_colour_at_the_buoys_top_and_a_dark_one_does_not() -> None:
    pose = CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, DOWN_10, 0.0)
    for distance in (20.0, 80.0):
        lit = RenderedBuoy((distance, 0.0), [BLACK, YELLOW], "pillar", 2.5, 1.2, light_rgb=(0, 255, 0))
        dark = dataclasses.replace(lit, light_rgb=None)
        green_lit, green_dark = (green(render(pose, DEFAULT_CAMERA, Scene([b], sea_seed=5))) for b in (lit, dark))
        (top,), _ = project(pose, DEFAULT_CAMERA, np.array([[distance, 0.0, -2.6]]))  # the lantern, 0.1 m up
        assert green_lit.sum() >= 12  # a disc a few pixels across even at 80 m
        assert np.linalg.norm(centroid(green_lit) - top) < 2.0
        assert not green_dark.any()


def test_a_near_buoy_hides_the_far_one_behind_it_whatever_the_list_order() -> None:
    pose = CameraPose.from_euler((0.0, 0.0, -2.0), 0.0, 0.0, 0.0)
    near = can((20.0, 0.0), [MAGENTA], height=3.0, diameter=1.0)
    far = can((40.0, 0.0), [CYAN], height=6.0, diameter=3.0)
    frame = render(pose, DEFAULT_CAMERA, Scene([near, far], sea_seed=6))
    (behind,), _ = project(pose, DEFAULT_CAMERA, np.array([[40.0, 0.0, -1.0]]))  # far's axis, 1 m up
    u, v = np.round(behind).astype(int)
    assert magenta(frame)[v, u]
    assert cyan(frame).sum() > 100  # far shows above and beside near
    assert np.array_equal(frame, render(pose, DEFAULT_CAMERA, Scene([far, near], sea_seed=6)))


def test_a_buoy_behind_the_camera_is_absent() -> None:
    pose = CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, DOWN_10, 0.0)
    assert magenta(render(pose, DEFAULT_CAMERA, Scene([can((20.0, 0.0), [MAGENTA])]))).any()
    assert not magenta(render(pose, DEFAULT_CAMERA, Scene([can((-20.0, 0.0), [MAGENTA])]))).any()


def test_a_buoy_past_the_horizon_is_absent() -> None:
    """A 10 m buoy seen from 5 m shows to sqrt(2Rh) + sqrt(2R 10 m) = 19.3 km. Through a 100 mm lens it would
    still be 4 px tall at 25 km on a flat sea."""
    telephoto = Intrinsics.from_sensor(640, 480, 100.0, 6.17, 4.55)
    pose = CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, 0.0, 0.0)

    def seen(distance: float) -> int:
        scene = Scene([can((distance, 0.0), [MAGENTA], height=10.0, diameter=4.0)], visibility_m=1e9)
        return int(magenta(render(pose, telephoto, scene)).sum())

    assert seen(15_000.0) >= 4
    assert seen(25_000.0) == 0


def test_same_seed_and_time_give_the_same_frame_and_the_sea_moves_with_time() -> None:
    pose = CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, math.radians(-20), 0.0)
    frame = render(pose, DEFAULT_CAMERA, Scene(sea_seed=7, t_s=1.0))
    assert np.array_equal(frame, render(pose, DEFAULT_CAMERA, Scene(sea_seed=7, t_s=1.0)))
    sea = slice(400, 720)
    for other in (Scene(sea_seed=7, t_s=1.5), Scene(sea_seed=8, t_s=1.0)):
        change = np.abs(render(pose, DEFAULT_CAMERA, other)[sea].astype(int) - frame[sea].astype(int)).mean()
        assert change > 3  # well above the sensor noise's own 2 levels between two frames


def test_sea_clutter_has_no_red_green_or_yellow_in_it() -> None:
    pose = CameraPose.from_euler((0.0, 0.0, -3.0), 0.0, math.radians(-30), 0.0)
    frame = render(pose, DEFAULT_CAMERA, Scene(sea_seed=9, t_s=3.0, sea_state=1.0)).astype(int)
    r, g, b = frame[..., 0], frame[..., 1], frame[..., 2]
    assert (np.maximum(r, g) - b).max() < 12  # blue to grey everywhere: only noise-deep departures


def test_frame_size_dtype_and_jpeg() -> None:
    small = Intrinsics.from_sensor(320, 240, 4.5, 6.17, 4.55)
    frame = render(CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, DOWN_10, 0.0), small, Scene())
    assert frame.shape == (240, 320, 3)
    assert frame.dtype == np.uint8
    jpeg = encode_jpeg(frame, 80)
    assert jpeg[:2] == b"\xff\xd8"
    assert Image.open(io.BytesIO(jpeg)).size == (320, 240)


def test_invalid_buoys_and_underwater_cameras_are_refused() -> None:
    with pytest.raises(ValueError):
        RenderedBuoy((0.0, 0.0), [MAGENTA], shape="barrel")
    with pytest.raises(ValueError):
        render(CameraPose.from_euler((0.0, 0.0, 1.0), 0.0, 0.0, 0.0), DEFAULT_CAMERA, Scene())
