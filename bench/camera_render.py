"""Camera renderer benchmark: frames per second at a few resolutions with 13 buoys in view.

    .venv/bin/python -m bench.camera_render                  # prints a table, writes bench/results/camera_render.json
    .venv/bin/python -m bench.camera_render --examples DIR   # also writes two example frames as PNG

The scene is the inspection camera's: 5 m above the sea, gimbal pitched 15 deg down, 13 IALA marks (cardinals,
laterals, safe water, isolated danger, special; some lit) 15-100 m ahead across the field of view, the sea's
clutter moving from frame to frame. Each resolution keeps the default camera's lens and sensor (same field of
view). Speed is CPU time per frame (process_time, so other load on the shared machine counts less), the mean
over the frames after one warm-up; target >= 10 fps so rendering keeps the simulator's lockstep.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np
from PIL import Image

from sitl_quad.camera_render import CameraPose, Intrinsics, RenderedBuoy, Scene, render

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
RESOLUTIONS = ((640, 360), (960, 540), (1280, 720), (1920, 1080))
FRAMES = 30
TARGET_FPS = 10.0
GIMBAL = CameraPose.from_euler((0.0, 0.0, -5.0), 0.0, math.radians(-15), 0.0)

BLACK, YELLOW, RED, GREEN, WHITE = (20, 20, 20), (245, 200, 0), (200, 25, 35), (0, 140, 70), (240, 240, 240)
WHITE_LIGHT, RED_LIGHT, GREEN_LIGHT, YELLOW_LIGHT = (255, 255, 255), (255, 40, 40), (40, 255, 80), (255, 210, 60)
MARKS = {  # name: (bands top to bottom, shape, topmark, topmark colour, light colour, vertical stripes)
    "north": ((BLACK, YELLOW), "pillar", "cones_up", BLACK, WHITE_LIGHT, False),
    "south": ((YELLOW, BLACK), "pillar", "cones_down", BLACK, WHITE_LIGHT, False),
    "east": ((BLACK, YELLOW, BLACK), "pillar", "cones_base_to_base", BLACK, WHITE_LIGHT, False),
    "west": ((YELLOW, BLACK, YELLOW), "pillar", "cones_point_to_point", BLACK, WHITE_LIGHT, False),
    "port": ((RED,), "can", "can", RED, RED_LIGHT, False),
    "starboard": ((GREEN,), "cone", "cone", GREEN, GREEN_LIGHT, False),
    "safe_water": ((RED, WHITE), "sphere", "sphere", RED, WHITE_LIGHT, True),
    "isolated_danger": ((BLACK, RED, BLACK), "pillar", "two_spheres", BLACK, WHITE_LIGHT, False),
    "special": ((YELLOW,), "spar", "x", YELLOW, YELLOW_LIGHT, False),
}


def mark(name: str, north: float, east: float, lit: bool = True) -> RenderedBuoy:
    """An IALA mark (region A) of the kind named, its waterline centre at (north, east)."""
    bands, shape, topmark, topmark_rgb, light, stripes = MARKS[name]
    height, diameter = {"sphere": (1.4, 1.6), "spar": (3.0, 0.4), "cone": (2.0, 1.2)}.get(shape, (2.5, 1.2))
    return RenderedBuoy(
        (north, east), bands, shape, height, diameter, stripes, topmark, topmark_rgb, light if lit else None
    )


def thirteen_in_view() -> list[RenderedBuoy]:
    """13 marks 15-100 m ahead of GIMBAL, spread across 60 deg of its 69 deg field of view; every other one lit."""
    names = [*MARKS, "north", "port", "starboard", "special"]
    buoys = []
    for k, name in enumerate(names):
        bearing, distance = math.radians(-30 + 5 * k), 15 + 85 * ((k * 7) % 13) / 12
        buoys.append(mark(name, distance * math.cos(bearing), distance * math.sin(bearing), lit=k % 2 == 0))
    return buoys


def frames_per_second(width: int, height: int, buoys: list[RenderedBuoy]) -> dict:
    """Mean CPU ms per frame over FRAMES frames 1/15 s apart (after a warm-up frame), and the fps it makes."""
    camera = Intrinsics.from_sensor(width, height, 4.5, 6.17, 6.17 * height / width)
    render(GIMBAL, camera, Scene(buoys, sea_seed=1))
    times = []
    for k in range(FRAMES):
        started = time.process_time()
        render(GIMBAL, camera, Scene(buoys, sea_seed=1, t_s=k / 15))
        times.append(time.process_time() - started)
    mean = float(np.mean(times))
    return {
        "width": width,
        "height": height,
        "frames": FRAMES,
        "ms_per_frame_mean": mean * 1e3,
        "ms_per_frame_p95": float(np.percentile(times, 95)) * 1e3,
        "fps": 1 / mean,
    }


def write_examples(directory: Path) -> list[Path]:
    """A north cardinal at 20 m and a port can at 60 m seen by GIMBAL at 1280x720: both lights on, then both
    dark a second later (the sea moved on)."""
    directory.mkdir(parents=True, exist_ok=True)
    camera = Intrinsics.from_sensor(1280, 720, 4.5, 6.17, 6.17 * 9 / 16)
    paths = []
    for lit, t_s in ((True, 0.0), (False, 1.0)):
        buoys = [mark("north", 20.0, -2.0, lit), mark("port", 60.0, 8.0, lit)]
        path = directory / f"north_20m_port_60m_{'lit' if lit else 'dark'}.png"
        Image.fromarray(render(GIMBAL, camera, Scene(buoys, sea_seed=3, t_s=t_s))).save(path)
        paths.append(path)
    return paths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=Path, help="write two example frames (PNG) into this directory")
    args = parser.parse_args()
    load = os.getloadavg()
    buoys = thirteen_in_view()
    rows = [frames_per_second(width, height, buoys) for width, height in RESOLUTIONS]
    result = {
        "machine_load_average_1_5_15": load,
        "scene": "13 IALA marks 15-100 m ahead, camera 5 m up, gimbal -15 deg, 68.9 deg horizontal field of view",
        "target_fps": TARGET_FPS,
        "resolutions": rows,
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "camera_render.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} (shared machine)")
    print("\nresolution     ms/frame mean   p95      fps   (target >= 10)")
    for row in rows:
        flag = "" if row["fps"] >= TARGET_FPS else "  below target"
        print(
            f"  {row['width']:4d} x {row['height']:<4d} {row['ms_per_frame_mean']:10.1f} "
            f"{row['ms_per_frame_p95']:7.1f} {row['fps']:8.1f}{flag}"
        )
    if args.examples:
        for path in write_examples(args.examples):
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
