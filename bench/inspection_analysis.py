"""Inspection analysis benchmark: seeded random worlds (World.random), one burst per case of a target buoy seen
from 15-40 m, analysed as the ground station does (gcs.domain.buoy_detection, gcs.domain.inspection).

    .venv/bin/python -m bench.inspection_analysis [--cases 30] [--width 960 --height 540]

Prints per kind: detection rate (frames), position error of the observed position against the buoy's true mean
position over the burst, the light read right (the burst's reading matches the light it really shows), CPU ms per
frame to analyse; and over all cases the precision and recall of the defect findings against the injected faults
(off_station, light_out, wrong_character, each scored as its own code; wrong_period and wrong_colour count as
wrong_character, the world's one name for a changed light). Writes
bench/results/inspection_analysis.json.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from bench.inspection_scenes import HOME, capture_burst
from gcs.domain.buoy_detection import BuoyDetection, ChartedBuoy, detect_buoy
from gcs.domain.camera_geometry import FrameGeotag
from gcs.domain.inspection import BuoyInspection, inspect_buoy
from gcs.domain.light_reading import read_light
from uavcore.buoy_world import World
from uavcore.light_character import LightCharacter, matches

RESULTS = Path(__file__).resolve().parents[1] / "bench" / "results"
BUOYS_PER_WORLD = 3  # the target and two others nearby, often in view
FAULT_PROBABILITY = 0.4  # more than World.random's default, so that the defects are enough to count
WRONG_LIGHT = {"wrong_character", "wrong_period", "wrong_colour"}  # light_character.matches' names for a changed light


def charted_of(world: World, index: int) -> ChartedBuoy:
    buoy = world.buoys[index]
    light = None if buoy.light is None else buoy.light.abbreviation()
    return ChartedBuoy(buoy.charted[0], buoy.charted[1], buoy.kind, light, buoy.swing_radius_m)


def run_case(seed: int, resolution: tuple[int, int]) -> dict:
    """One seeded case: a world, a target, a burst, its analysis; figures and truth."""
    rng = np.random.default_rng(seed)
    spots = rng.uniform(-40, 40, size=(BUOYS_PER_WORLD, 2))  # north, east of a point 100 m north of home
    lat_lons = HOME.unproject(spots[:, ::-1] + [0.0, 100.0])
    world = World.random(seed, lat_lons, [f"b{seed}-{k}" for k in range(BUOYS_PER_WORLD)], FAULT_PROBABILITY)
    target = int(rng.integers(BUOYS_PER_WORLD))
    burst = capture_burst(world, target, rng.uniform(15, 40), rng.uniform(0, 360), resolution=resolution, sea_seed=seed)
    charted = charted_of(world, target)
    started = time.process_time()
    frames = [(shot.geotag, detect_buoy(shot.image, burst.model, shot.geotag, charted)) for shot in burst.shots]
    inspection = inspect_buoy(charted, frames)
    cpu_ms = 1000 * (time.process_time() - started) / len(frames)
    buoy = world.buoys[target]
    truth = np.mean([shot.true_north_east for shot in burst.shots], axis=0)
    return {
        "seed": seed,
        "kind": buoy.kind,
        "faults": buoy.faults,
        "frames": len(frames),
        "detected": sum(d.found for _, d in frames),
        "position_error_m": _position_error(inspection, truth),
        "light_read_right": _light_read_right(buoy.actual_light, frames),
        "verdict": inspection.verdict,
        "findings": [f.code for f in inspection.findings],
        "light_seen": inspection.light_seen,
        "ms_per_frame": cpu_ms,
    }


def _position_error(inspection: BuoyInspection, truth_ne: np.ndarray) -> float | None:
    if inspection.observed is None:
        return None
    north, east, _ = HOME.to_ned(inspection.observed.lat, inspection.observed.lon)
    return float(math.hypot(north - truth_ne[0], east - truth_ne[1]))


def _light_read_right(actual: LightCharacter | None, frames: list[tuple[FrameGeotag, BuoyDetection]]) -> bool:
    """Whether the burst's reading of the light matches what it really shows (dark for a light out)."""
    spotted = sorted(((g.t_s, d.light) for g, d in frames if d.light is not None), key=lambda pair: pair[0])
    observed = read_light([t for t, _ in spotted], [s for _, s in spotted if s is not None])
    return observed.rhythm == "dark" if actual is None else not matches(actual, observed)


def summarise(cases: list[dict]) -> dict:
    """Per-kind figures and the findings' precision and recall against the injected faults."""
    per_kind: dict[str, list[dict]] = defaultdict(list)
    for case in cases:
        per_kind[case["kind"]].append(case)
    kinds = {}
    for kind, group in sorted(per_kind.items()):
        errors = [
            c["position_error_m"]
            for c in group
            if c["position_error_m"] is not None and "off_station" not in c["faults"]
        ]
        kinds[kind] = {
            "cases": len(group),
            "detection_rate": sum(c["detected"] for c in group) / sum(c["frames"] for c in group),
            "position_rms_m": float(np.sqrt(np.mean(np.square(errors)))) if errors else None,
            "light_read_right": sum(c["light_read_right"] for c in group) / len(group),
            "ms_per_frame": float(np.mean([c["ms_per_frame"] for c in group])),
        }
    counts = {"true_positive": 0, "false_positive": 0, "false_negative": 0}
    for case in cases:
        # scored code by code: a light that is out must be found out, not merely "wrong"; the world's
        # wrong_character is any change of rhythm, period or colour, which matches() names one of three ways
        found = {"wrong_character" if code in WRONG_LIGHT else code for code in case["findings"]}
        found &= {"off_station", "light_out", "wrong_character", "wrong_body_colour", "not_found"}
        truth = set(case["faults"])
        counts["true_positive"] += len(found & truth)
        counts["false_positive"] += len(found - truth)
        counts["false_negative"] += len(truth - found)
    tp = counts["true_positive"]
    errors = [
        c["position_error_m"] for c in cases if c["position_error_m"] is not None and "off_station" not in c["faults"]
    ]
    return {
        "kinds": kinds,
        "findings": counts,
        "precision": tp / max(1, tp + counts["false_positive"]),
        "recall": tp / max(1, tp + counts["false_negative"]),
        "position_rms_m": float(np.sqrt(np.mean(np.square(errors)))),
        "light_read_right": sum(c["light_read_right"] for c in cases) / len(cases),
        "verdicts_right": sum((c["verdict"] == "defect") == bool(c["faults"]) for c in cases) / len(cases),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=30)
    parser.add_argument("--width", type=int, default=960)
    parser.add_argument("--height", type=int, default=540)
    args = parser.parse_args()
    cases = []
    for seed in range(args.cases):
        cases.append(run_case(seed, (args.width, args.height)))
        c = cases[-1]
        print(
            f"case {seed:2d} {c['kind']:16s} faults {','.join(c['faults']) or '-':16s} -> {c['verdict']:13s} "
            f"{','.join(c['findings']) or '-':24s} light {c['light_seen']}",
            flush=True,
        )
    summary = summarise(cases)
    print(f"\n{'kind':16s} {'cases':>5s} {'detected':>9s} {'pos RMS m':>10s} {'light ok':>9s} {'ms/frame':>9s}")
    for kind, k in summary["kinds"].items():
        rms = "-" if k["position_rms_m"] is None else f"{k['position_rms_m']:.2f}"
        print(
            f"{kind:16s} {k['cases']:5d} {k['detection_rate']:9.1%} {rms:>10s} "
            f"{k['light_read_right']:9.0%} {k['ms_per_frame']:9.1f}"
        )
    print(
        f"\nposition RMS {summary['position_rms_m']:.2f} m, light read right {summary['light_read_right']:.0%}, "
        f"defect findings precision {summary['precision']:.2f} recall {summary['recall']:.2f}, "
        f"verdicts right {summary['verdicts_right']:.0%}"
    )
    RESULTS.mkdir(parents=True, exist_ok=True)
    resolution = {"width": args.width, "height": args.height}
    report = {"resolution": resolution, "summary": summary, "cases": cases}
    (RESULTS / "inspection_analysis.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
