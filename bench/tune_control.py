"""Tune the ADRC and PID outer loops by the same method and effort, to one shared closed-loop bandwidth.

    .venv/bin/python -m bench.tune_control                  # table + bench/results/control_tuning.json
    .venv/bin/python -m bench.tune_control --write-gains    # also rewrite adrc_offboard/gains/outer_*.json

Method (rerunnable, deterministic):
1. Flight: a short, representative piece of the benchmark mission (bench/control/): the reference route's
   longest leg and the leg after it (with the turn between them), translated to start at home, flown at
   10 m/s and 5 m in the benchmark's air (5 m/s crosswind perpendicular to that leg, the 4 m/s 1-cosine gust
   halfway along it, Dryden sigma 1 m/s, D terms and sensor noise), ending with a landing at the last point.
   Both controllers fly it on the same seeds in the in-process lockstep harness (sitl_quad.lockstep_harness),
   with their own inner loop (ADRC + ADRC, PID + PID) as in the benchmark.
2. Grid, same size for both: horizontal bandwidth omega_c in OMEGA_C (vertical = VERTICAL_RATIO x
   horizontal, as in the shipped gains) times one second parameter per controller, the one its method
   leaves free: for the ADRC the observer ratio k (omega_o = k omega_c), for the PID the integrator-pole
   ratio (`outer_loop.pid_gains_for_bandwidth`). Both come from `outer_loop.matched_gains`, so at one
   omega_c the two share the critically damped pair at omega_c. ADRC's delta and r1 stay as shipped.
3. Limits: a set is admissible if it builds (the ADRC's discrete ESO and closed loop must be stable at
   50 Hz, `adrc.AdrcChannelParameters.validate`), completes the flight on every seed, keeps the mixer out of
   saturation in at least (1 - MAX_SATURATED) of the tracking ticks and its thrust command's tick-to-tick
   RMS change under MAX_THRUST_STEP (no chatter).
4. Choice: for each controller and omega_c, the admissible second parameter with the lowest mean RMS
   tracking error over the seeds; then the one omega_c shared by both that minimises the larger of the two
   controllers' errors (so neither is tuned at the other's expense). Each controller's own best omega_c is
   reported too.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from adrc_offboard.adrc import AdrcParameterError
from adrc_offboard.gains import load_gains, make_channel
from adrc_offboard.outer_loop import matched_gains
from bench.control import RESULTS
from bench.control.flight import fly
from bench.control.scenario import Scenario, build_scenario
from gcs.domain.planning import FIRST_BUOY_SEQ
from planner.scenario import MissionTimeline
from uavcore.geodesy import LocalFrame
from uavcore.mission import MavCmd, MavFrame, MissionItem

GAINS_DIR = Path(__file__).resolve().parent.parent / "adrc_offboard" / "gains"
OMEGA_C = (1.0, 1.5, 2.0, 2.5, 3.0)
VERTICAL_RATIO = 1.25
OBSERVER_RATIOS = (3.0, 4.0, 6.0)
INTEGRAL_RATIOS = (0.1, 0.25, 0.5)
ADRC_DELTA = 0.02
ADRC_R1 = (5.0, 4.0)
MAX_SATURATED = 0.15
MAX_THRUST_STEP = 0.05
LEGS = 2


def short_scenario(base: Scenario) -> Scenario:
    """The longest leg and the next, translated to start at home; gust halfway along the first."""
    waypoints = np.asarray(base.waypoints_ne)
    legs = np.diff(waypoints, axis=0)[base.longest_leg - 1 : base.longest_leg - 1 + LEGS]
    points = np.vstack([[0.0, 0.0], np.cumsum(legs, axis=0)])
    frame = LocalFrame(*base.home)
    takeoff, speed = base.items[0], base.items[1]
    items = [takeoff, speed]
    for north, east in points[1:]:
        lat, lon, _ = frame.from_ned(float(north), float(east), 0.0)
        items.append(
            MissionItem(
                seq=len(items),
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                command=MavCmd.NAV_WAYPOINT,
                param1=base.items[FIRST_BUOY_SEQ].param1,
                param2=base.items[FIRST_BUOY_SEQ].param2,
                param3=0.0,
                x=round(float(lat) * 1e7),
                y=round(float(lon) * 1e7),
                z=takeoff.z,
            )
        )
    last = items[-1]
    items.append(
        MissionItem(
            seq=len(items), frame=MavFrame.GLOBAL_RELATIVE_ALT_INT, command=MavCmd.NAV_LAND, x=last.x, y=last.y, z=0.0
        )
    )
    start, duration = MissionTimeline().legs(points[:, ::-1])[0]  # points are [north, east]
    gust = round(start + 0.5 * duration, 1)
    return replace(
        base,
        items=items,
        waypoints_ne=points.tolist(),
        longest_leg=1,
        gust_start_s=gust,
        wind=replace(base.wind, gust_start_s=gust),
    )


def candidate(kind: str, omega_c: float, second: float):
    """(ADRC gains, PID gains) from matched_gains for this grid point; raises AdrcParameterError if unusable."""
    adrc, pid = matched_gains(
        omega_c,
        VERTICAL_RATIO * omega_c,
        observer_ratio=second if kind == "adrc" else 4.0,
        integral_ratio=second if kind == "pid" else 0.25,
        delta=ADRC_DELTA,
        r1=ADRC_R1,
    )
    if kind == "adrc":
        for spec in (adrc.horizontal, adrc.vertical):
            make_channel(spec, 1.0 / 50.0)  # validates the discrete ESO and loop at 50 Hz
    return adrc, pid


def _evaluate(job: tuple) -> dict:
    kind, omega_c, second, seeds = job
    row = {"controller": kind, "omega_c": omega_c, "second": second}
    try:
        adrc, pid = candidate(kind, omega_c, second)
    except AdrcParameterError as exc:
        return row | {"admissible": False, "reason": str(exc)[:120]}
    metrics = [fly(kind, seed, SHORT, adrc_gains=adrc, pid_gains=pid, items=SHORT.items)[0] for seed in seeds]
    mean = {
        m: float(np.mean([r[m] for r in metrics]))
        for m in ("rms_error_m", "gust_peak_m", "saturated_fraction", "thrust_step_rms", "max_error_m")
    }
    completed = all(r["completed"] for r in metrics)
    reasons = []
    if not completed:
        reasons.append("did not complete")
    if mean["saturated_fraction"] > MAX_SATURATED:
        reasons.append(f"saturated {mean['saturated_fraction']:.2f}")
    if mean["thrust_step_rms"] > MAX_THRUST_STEP:
        reasons.append(f"thrust chatter {mean['thrust_step_rms']:.3f}")
    return row | mean | {"admissible": not reasons, "reason": "; ".join(reasons)}


SHORT: Scenario


def choose(rows: list[dict]) -> dict:
    best: dict = {"per_omega_c": {}, "own_best": {}}
    for kind in ("adrc", "pid"):
        for omega_c in OMEGA_C:
            ok = [r for r in rows if r["controller"] == kind and r["omega_c"] == omega_c and r["admissible"]]
            if ok:
                best["per_omega_c"].setdefault(omega_c, {})[kind] = min(ok, key=lambda r: r["rms_error_m"])
        own = [v[kind] for v in best["per_omega_c"].values() if kind in v]
        best["own_best"][kind] = min(own, key=lambda r: r["rms_error_m"]) if own else None
    shared = [
        (max(v["adrc"]["rms_error_m"], v["pid"]["rms_error_m"]), w)
        for w, v in best["per_omega_c"].items()
        if "adrc" in v and "pid" in v
    ]
    if not shared:
        raise SystemExit("tune_control.py: no bandwidth is admissible for both controllers")
    _, omega_c = min(shared)
    best["shared_omega_c"] = omega_c
    best["chosen"] = best["per_omega_c"][omega_c]
    return best


def write_gains(chosen: dict) -> list[str]:
    """Rewrite the numbers of outer_adrc.json / outer_pid.json (comments kept, provenance appended)."""
    omega_c = chosen["adrc"]["omega_c"]
    adrc_ratio, pid_ratio = chosen["adrc"]["second"], chosen["pid"]["second"]
    _, pid = matched_gains(omega_c, VERTICAL_RATIO * omega_c, integral_ratio=pid_ratio)
    note = (
        f" Tuned by bench/tune_control.py: shared omega_c = {omega_c:g} rad/s horizontal, "
        f"{VERTICAL_RATIO * omega_c:g} vertical."
    )
    adrc_data = load_gains("outer_adrc")
    for axis, w in (("horizontal", omega_c), ("vertical", VERTICAL_RATIO * omega_c)):
        adrc_data[axis].update({"omega_c": w, "omega_o": round(adrc_ratio * w, 6)})
    adrc_data["comment"] = adrc_data["comment"].split(" Tuned by")[0] + note + f" omega_o = {adrc_ratio:g} omega_c."
    pid_data = load_gains("outer_pid")
    for axis, gains in (("horizontal", pid.horizontal), ("vertical", pid.vertical)):
        pid_data[axis] = {"kp": gains.kp, "ki": gains.ki, "kd": gains.kd, "i_max": gains.i_max}
    pid_data["comment"] = pid_data["comment"].split(" Tuned by")[0] + note + f" Integrator pole {pid_ratio:g} omega_c."
    paths = []
    for name, data in (("outer_adrc.json", adrc_data), ("outer_pid.json", pid_data)):
        (GAINS_DIR / name).write_text(json.dumps(data, indent=2) + "\n")
        paths.append(str(GAINS_DIR / name))
    return paths


def main(argv: list[str] | None = None) -> int:
    global SHORT
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=2, help="seeds per grid point (0..N-1)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument(
        "--write-gains", action="store_true", help="rewrite adrc_offboard/gains/outer_adrc.json, outer_pid.json"
    )
    p.add_argument("--out", type=Path, default=RESULTS / "control_tuning.json")
    args = p.parse_args(argv)
    if args.seeds < 1 or args.workers < 1:
        print("tune_control.py: error: --seeds and --workers must be >= 1", file=sys.stderr)
        return 2
    started = time.perf_counter()
    SHORT = short_scenario(build_scenario())
    seeds = tuple(range(args.seeds))
    jobs = [("adrc", w, k, seeds) for w in OMEGA_C for k in OBSERVER_RATIOS]
    jobs += [("pid", w, r, seeds) for w in OMEGA_C for r in INTEGRAL_RATIOS]
    with Pool(args.workers) as pool:
        rows = list(pool.imap_unordered(_evaluate, jobs))
    rows.sort(key=lambda r: (r["controller"], r["omega_c"], r["second"]))
    elapsed = time.perf_counter() - started
    print(f"{'ctrl':5}{'omega_c':>8}{'2nd':>6}{'rms m':>8}{'gust m':>8}{'max m':>8}{'sat':>7}{'dT rms':>8}  admissible")
    for r in rows:
        if "rms_error_m" in r:
            print(
                f"{r['controller']:5}{r['omega_c']:>8g}{r['second']:>6g}{r['rms_error_m']:>8.3f}{r['gust_peak_m']:>8.3f}"
                f"{r['max_error_m']:>8.3f}{r['saturated_fraction']:>7.3f}{r['thrust_step_rms']:>8.4f}  "
                f"{'yes' if r['admissible'] else 'no: ' + r['reason']}"
            )
        else:
            print(f"{r['controller']:5}{r['omega_c']:>8g}{r['second']:>6g}{'':>38}  no: {r['reason']}")
    best = choose(rows)
    chosen = best["chosen"]
    print(
        f"\nshared omega_c {best['shared_omega_c']:g} rad/s: ADRC k = {chosen['adrc']['second']:g} "
        f"(rms {chosen['adrc']['rms_error_m']:.3f} m), PID integrator ratio {chosen['pid']['second']:g} "
        f"(rms {chosen['pid']['rms_error_m']:.3f} m)"
    )
    for kind, own in best["own_best"].items():
        print(
            f"{kind} alone would pick omega_c {own['omega_c']:g}, second {own['second']:g}: "
            f"rms {own['rms_error_m']:.3f} m"
        )
    written = write_gains(chosen) if args.write_gains else []
    result = {
        "command": "python -m bench.tune_control " + " ".join(argv if argv is not None else sys.argv[1:]),
        "elapsed_s": elapsed,
        "method": __doc__,
        "flight": {
            "waypoints_ne": SHORT.waypoints_ne,
            "gust_start_s": SHORT.gust_start_s,
            "crosswind_from_deg": SHORT.crosswind_from_deg,
            "seeds": list(seeds),
        },
        "grid": {
            "omega_c": OMEGA_C,
            "vertical_ratio": VERTICAL_RATIO,
            "adrc_observer_ratio": OBSERVER_RATIOS,
            "pid_integral_ratio": INTEGRAL_RATIOS,
            "adrc_delta": ADRC_DELTA,
            "adrc_r1": ADRC_R1,
        },
        "limits": {"max_saturated_fraction": MAX_SATURATED, "max_thrust_step_rms": MAX_THRUST_STEP},
        "rows": rows,
        "shared_omega_c": best["shared_omega_c"],
        "chosen": chosen,
        "own_best": best["own_best"],
        "gains_written": written,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1, default=float))
    print(f"wrote {args.out} ({elapsed:.0f} s){' and ' + ', '.join(written) if written else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
