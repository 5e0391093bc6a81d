"""The paper's Figures 6, 7 and 9 from our own flights: ADRC against PID on the reference mission.

    .venv/bin/python -m bench.paper_figures                       # the benchmark's weather (bench/control)
    .venv/bin/python -m bench.paper_figures --disturbance paper   # the paper's 0.1 s wind change instead
    .venv/bin/python -m bench.paper_figures --disturbance paper --paper-variance   # ... and its variance-15 D terms

Writes bench/results/paper_fig6.png, paper_fig7.png, paper_fig9.png and paper_figures.json (what was flown: the
seed, the controllers, their designs, the disturbance, the planner's run). Reuses bench/control:
its scenario (`build_scenario`), its recorded flight (`flight.fly`, `FlightRecorder`) and its figure functions
(`figures.tracking_figure`, `eso_figure`, `route_figure`).

- Controllers: "adrc" (the cascade dual ADRC: ADRC outer loop + ADRC attitude loop) and "pid" (PID outer loop +
  the vehicle's PX4-style PID attitude loop), each at its family's shipped design (adrc_offboard/gains/design.json,
  both loops; chosen by `python -m bench.tune`), as bench/control flies them.
- Disturbance "reference" (default): bench/control's weather, 5 m/s crosswind, a 4 m/s 1-cosine gust (rise 1 s,
  held 10 s) at mid longest leg, Dryden turbulence (sigma 1 m/s), D terms of variance 0.05.
- Disturbance "paper": the paper's "sudden change in wind force at T = [0.5, 0.6]": a wind step of
  --step-m-s (default 8 m/s) along the crosswind lasting --step-s (default 0.1 s: a 20 ms rise, held, a 20 ms
  fall) at the same instant (mid longest leg); the 5 m/s mean crosswind stays, the turbulence is off so the step
  stands out; D terms of variance 0.05, or the paper's variance 15 with --paper-variance
  (DisturbanceConfig.paper(): no controller completes the mission with it on this airframe: both fail 30-60 s
  into it, so the disturbance then starts at 15 s, on the first leg, unless --onset-s says otherwise).
- Fig. 9's planner: the CHNN-GA (planner.chnn_ga) on the reference scenario's buoys in their charted order, its
  history per generation; the flown route is bench/control's (Held-Karp's optimum, the same length).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from adrc_offboard.design import describe, load_design
from bench.control import REPO, RESULTS
from bench.control.figures import eso_figure, mission_time, route_figure, tracking_figure
from bench.control.flight import fly
from bench.control.scenario import Scenario, build_scenario
from planner.chnn_ga import chnn_ga
from planner.distances import closed_tour_length, euclidean_matrix
from planner.exact import held_karp
from planner.scenario import reference_scenario
from sitl_quad.disturbances import DisturbanceConfig
from uavcore.airframe import Airframe
from uavcore.geodesy import LocalFrame

CONTROLLERS = ("adrc", "pid")
FLOWN = {
    "adrc": "ADRC outer + ADRC attitude loop (the cascade dual ADRC) at the ADRC design",
    "pid": "PID outer + the vehicle's PX4-style PID attitude loop at the PID design",
}
PAPER_VARIANCE_ONSET_S = 15.0  # mid first leg: with variance-15 D terms the flights fail after 30-60 s
STEP_RISE_S = 0.02  # the paper's wind change: rise (and fall) of the step, within --step-s


def paper_scenario(scenario: Scenario, step_m_s: float, step_s: float, onset_s: float | None) -> Scenario:
    """The scenario with the paper's wind change instead of the gust: a step of step_m_s along the gust's
    direction, rising in STEP_RISE_S (at most half of step_s), held so that it lasts step_s from its start to
    the start of its (mirrored) fall, at onset_s (default the scenario's gust onset); no turbulence."""
    rise = min(STEP_RISE_S, step_s / 2)
    wind = dataclasses.replace(
        scenario.wind,
        gust_amplitude_m_s=step_m_s,
        gust_rise_time_s=rise,
        gust_hold_s=step_s - rise,
        gust_start_s=scenario.gust_start_s if onset_s is None else onset_s,
        turbulence_w20_m_s=0.0,
    )
    return dataclasses.replace(scenario, wind=wind, gust_start_s=wind.gust_start_s)


def disturbance_window(scenario: Scenario, kind: str) -> tuple[float, float]:
    """(start, end) of the wind change on the mission clock: the gust's rise for "reference", the whole
    step for "paper"."""
    wind = scenario.wind
    if kind == "paper":
        return wind.gust_start_s, wind.gust_start_s + wind.gust_rise_time_s + wind.gust_hold_s
    return wind.gust_start_s, wind.gust_start_s + wind.gust_rise_time_s


def plan_history(seed: int, time_limit_s: float) -> dict:
    """The CHNN-GA on the reference scenario's buoys (charted order), in the flight's north-east metres."""
    reference = reference_scenario()
    frame = LocalFrame(*reference.home)
    buoys = [frame.to_ned(lat, lon, frame.alt0)[:2] for lat, lon in reference.buoys_lat_lon.tolist()]
    points = np.asarray([[0.0, 0.0], *buoys], dtype=float)
    dist = euclidean_matrix(points)
    started = time.perf_counter()
    result = chnn_ga(dist, seed=seed, time_limit_s=time_limit_s)
    elapsed = time.perf_counter() - started
    _, optimum = held_karp(dist)
    return {
        "points_ne": points.tolist(),
        "order": result.order,
        "length": result.length,
        "history": result.history,
        "optimum_m": float(optimum),
        "input_order_m": float(closed_tour_length(list(range(len(points))), dist)),
        "elapsed_s": elapsed,
        "seed": seed,
        "time_limit_s": time_limit_s,
    }


def window_numbers(series: dict[str, dict[str, np.ndarray]], onset: tuple[float, float], after_s: float = 8.0) -> dict:
    """What the figures show, in numbers, from the onset to after_s later: per controller the peak horizontal
    and altitude errors (the figures' alignment: truth at a tick's start against the reference for it) and
    the RMS attitude tracking error (true angle against the target acting in the tick); for the ADRC, each
    ESO's RMS z3 error against its truth (the outer ESO's z3 at tick k against the external acceleration at
    the end of tick k - 1, the inner's both at the end of tick k) and the truth's RMS."""
    out: dict = {}
    for kind, s in series.items():
        t = mission_time(s)
        w = (t[:-1] >= onset[0]) & (t[:-1] <= onset[0] + after_s)
        if not w.any():
            continue
        horizontal = np.hypot(s["x"][:-1] - s["x_ref"][1:], s["y"][:-1] - s["y_ref"][1:])[w]
        row = {
            "horizontal_error_peak_m": float(horizontal.max()),
            "altitude_error_peak_m": float(np.abs(s["z"][:-1] - s["z_ref"][1:])[w].max()),
        }
        for axis in ("roll", "pitch"):
            error = np.degrees(s[f"att_{axis}"][1:] - s[f"att_ref_{axis}"][1:])[w]
            row[f"{axis}_error_rms_deg"] = float(np.sqrt(np.mean(error**2)))
        if kind == "adrc":
            for axis in "xyz":
                error = (s[f"z3_{axis}"][1:] - s[f"ext_{axis}"][:-1])[w]
                row[f"eso_{axis}_z3_error_rms_m_s2"] = float(np.sqrt(np.mean(error**2)))
                row[f"eso_{axis}_truth_rms_m_s2"] = float(np.sqrt(np.mean(s[f"ext_{axis}"][:-1][w] ** 2)))
            for axis in ("roll", "pitch", "yaw"):
                error = (s[f"iz3_{axis}"] - s[f"if_{axis}"])[1:][w]
                row[f"eso_{axis}_z3_error_rms_rad_s2"] = float(np.sqrt(np.mean(error**2)))
                row[f"eso_{axis}_truth_rms_rad_s2"] = float(np.sqrt(np.mean(s[f"if_{axis}"][1:][w] ** 2)))
        out[kind] = row
    return out


def _jsonable(history: list[dict]) -> list[dict]:
    """The planner's history for the JSON: lengths and counts, not the CHNN energy traces."""
    return [{k: v for k, v in h.items() if k != "energy"} for h in history]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.paper_figures", description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=0, help="the flights' seed (wind, turbulence, D terms, noise)")
    p.add_argument("--disturbance", choices=("reference", "paper"), default="reference")
    p.add_argument("--paper-variance", action="store_true", help="the paper's variance-15 D terms")
    p.add_argument("--step-m-s", type=float, default=8.0, help="--disturbance paper: the wind step (m/s)")
    p.add_argument("--step-s", type=float, default=0.1, help="--disturbance paper: how long it lasts (s)")
    p.add_argument(
        "--onset-s",
        type=float,
        help="the disturbance's start, s after the mission start (default: mid longest leg; with --paper-variance "
        f"{PAPER_VARIANCE_ONSET_S:g} s, on the first leg)",
    )
    p.add_argument("--duration-s", type=float, default=900.0, help="cut each flight this long after the start")
    p.add_argument(
        "--window-s",
        type=float,
        nargs=2,
        metavar=("BEFORE", "AFTER"),
        help="Fig. 6 and 7's window around the onset (default 2 8; with --disturbance paper 1 4)",
    )
    p.add_argument("--ga-time-s", type=float, default=2.0, help="the CHNN-GA's time limit")
    p.add_argument("--out-dir", type=Path, default=RESULTS)
    args = p.parse_args(argv)
    if args.step_s <= 0 or args.step_m_s < 0 or args.duration_s <= 0 or args.ga_time_s <= 0:
        p.error("--step-s, --duration-s and --ga-time-s must be positive, --step-m-s >= 0")
    started = time.perf_counter()
    args.out_dir.mkdir(parents=True, exist_ok=True)

    scenario = build_scenario()
    if args.paper_variance and args.onset_s is None:
        args.onset_s = PAPER_VARIANCE_ONSET_S  # the flights fail long before the route's longest leg
    if args.disturbance == "paper":
        scenario = paper_scenario(scenario, args.step_m_s, args.step_s, args.onset_s)
    elif args.onset_s is not None:
        wind = dataclasses.replace(scenario.wind, gust_start_s=args.onset_s)
        scenario = dataclasses.replace(scenario, wind=wind, gust_start_s=args.onset_s)
    onset = disturbance_window(scenario, args.disturbance)
    before_s, after_s = args.window_s or ((1.0, 4.0) if args.disturbance == "paper" else (2.0, 8.0))
    series, flights = {}, {}
    for kind in CONTROLLERS:
        t0 = time.perf_counter()
        metrics, series[kind] = fly(
            kind,
            args.seed,
            scenario,
            paper_disturbance=args.paper_variance,
            timeout_s=args.duration_s,
        )
        flights[kind] = {
            "label": FLOWN[kind],
            "completed": metrics["completed"],
            "flight_s": metrics.get("flight_s"),
            "rms_error_m": metrics.get("rms_error_m"),
            "gust_peak_m": metrics.get("gust_peak_m"),
            "wall_s": time.perf_counter() - t0,
        }
        print(f"{kind}: completed {metrics['completed']}, {flights[kind]['wall_s']:.1f} s wall")
    plan = plan_history(args.seed, args.ga_time_s)

    what = (
        f"the paper's wind change ({args.step_m_s:g} m/s for {args.step_s:g} s)"
        if args.disturbance == "paper"
        else "a 4 m/s gust in 5 m/s crosswind + turbulence"
    )
    if args.paper_variance:
        what += ", variance-15 D terms"
    figures = [
        tracking_figure(
            series,
            onset,
            args.out_dir / "paper_fig6.png",
            f"Fig. 6: tracking per channel around {what} (seed {args.seed})",
            before_s,
            after_s,
        ),
        eso_figure(
            series["adrc"],
            onset,
            args.out_dir / "paper_fig7.png",
            f"Fig. 7: the cascade ADRC's six ESOs around {what} (seed {args.seed}); "
            "inner ESOs sampled at the 50 Hz outer tick (they run at 250 Hz)",
            before_s,
            after_s,
        ),
        route_figure(
            scenario,
            series,
            plan,
            onset[0],
            args.out_dir / "paper_fig9.png",
            f"Fig. 9: the planned route and the flown tracks ({what}), and the CHNN-GA per iteration",
        ),
    ]
    record = {
        "command": " ".join(["python -m bench.paper_figures", *(sys.argv[1:] if argv is None else argv)]),
        "seed": args.seed,
        "controllers": flights,
        "designs": {kind: describe(Airframe.table2(), load_design(kind)) for kind in CONTROLLERS},
        "design_file": "adrc_offboard/gains/design.json (both loops of each family; bench.tune's choice)",
        "disturbance": {
            "kind": args.disturbance,
            "window_s": list(onset),
            "wind": _plain(dataclasses.asdict(scenario.wind)),
            "d_terms": _plain(
                dataclasses.asdict(DisturbanceConfig.paper() if args.paper_variance else scenario.disturbance)
            ),
        },
        "duration_s": args.duration_s,
        "window_s": [before_s, after_s],
        "after_onset": window_numbers(series, onset, after_s),
        "planner": {k: v for k, v in plan.items() if k != "history"} | {"history": _jsonable(plan["history"])},
        "figures": figures,
        "wall_s": time.perf_counter() - started,
    }
    out = args.out_dir / "paper_figures.json"
    out.write_text(json.dumps(_plain(record), indent=1, allow_nan=False) + "\n")
    for path in [*figures, _relative(out)]:
        print(path)
    print(f"{record['wall_s']:.1f} s")
    return 0


def _plain(value):
    """JSON-safe: infinities and NaN as strings, tuples as lists."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return value


def _relative(path: Path) -> str:
    path = path.resolve()
    return str(path.relative_to(REPO) if path.is_relative_to(REPO) else path)


if __name__ == "__main__":
    raise SystemExit(main())
