"""ADRC against PID on the paper's buoy-inspection mission: a paired Monte Carlo over seeds, flown in lockstep.

The command line (see the package docstring, bench/control/__init__.py): flies every controller on every seed
in a pool of worker processes, then the step experiment, prints the tables and writes control.json (+ figures).

Operating points (--tunings, from bench/tune_control.py's control_tuning.json): "shared" flies the ADRC and the
PID at the one bandwidth tuned for both (its "chosen"), "own" flies each at its own best tuning (its
"own_best"). The results' rows ("controllers") are "adrc", "pid" at the shared bandwidth (the keys earlier
results had), "adrc@own", "pid@own" at the own best, and "px4", whose built-in cascade has no tuning and flies
once, as does "geometric" (Lee 2010's SE(3) controller, adrc_offboard/gains/geometric.json). A controller whose
own best is the shared tuning is not flown twice: its "@own" row repeats the shared flights
(operating_points.<name>.same_flights_as says so). The paper's variance-15 seeds fly the first operating point
only.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass
from multiprocessing import Pool
from pathlib import Path

from adrc_offboard.geometric import GeometricGains
from adrc_offboard.outer_loop import AdrcOuterGains, PidOuterGains, matched_gains
from bench.control import REPO, RESULTS
from bench.control import metrics as metrics_module
from bench.control.figures import draw_figures
from bench.control.flight import CONTROLLERS, LABELS, fly, step_response
from bench.control.metrics import ESO_METRICS, METRICS, STEP_METRICS, TARGETS
from bench.control.scenario import ACCEPTANCE_RADIUS_M, DWELL_S, Scenario, build_scenario
from bench.control.statistics import summarise
from gcs.domain.tracking_metrics import GUST_WINDOW_S, RECOVERED_M
from planner.scenario import TURBULENCE_SIGMA_M_S

TUNINGS = ("shared", "own")  # operating points read from control_tuning.json
TUNING_SELECTION = {"shared": "chosen", "own": "own_best"}  # ... and the key each is read from
TUNED = ("adrc", "pid")  # the controllers an operating point sets gains for
# the honest summary: one line per controller and operating point (the README's top table)
HEADLINE = (
    "rms_error_m",
    "gust_peak_m",
    "saturated_fraction",
    *(m for m in ESO_METRICS if m not in ("eso_disturbance_rms_m_s2", "eso_lateral_rel_error")),
)


@dataclass(frozen=True)
class OperatingPoint:
    """The outer-loop gains the ADRC and the PID fly at (None: the shipped gains files) and where they are from."""

    name: str  # "shared", "own" or "shipped"
    adrc: AdrcOuterGains | None
    pid: PidOuterGains | None
    described: dict

    def row(self, kind: str) -> str:
        """The results' key for controller `kind` at this point: bare at the shared bandwidth (and for px4)."""
        return kind if kind not in TUNED or self.name in ("shared", "shipped") else f"{kind}@{self.name}"

    def gains(self, kind: str) -> AdrcOuterGains | PidOuterGains | None:
        return self.adrc if kind == "adrc" else self.pid if kind == "pid" else None


# What every flight job shares, set once per worker process by _share (the pool's initializer):
# the scenario and, per results row, (controller, ADRC gains, PID gains)
_scenario: Scenario
_rows: dict[str, tuple[str, AdrcOuterGains | None, PidOuterGains | None]] = {}


def _share(scenario: Scenario, rows: dict) -> None:
    global _scenario, _rows
    _scenario, _rows = scenario, rows


def _flight_job(job: tuple) -> tuple:
    row, seed, paper, keep = job
    kind, adrc, pid = _rows[row]
    metrics, series = fly(kind, seed, _scenario, paper_disturbance=paper, adrc_gains=adrc, pid_gains=pid)
    return row, seed, paper, metrics, (series if keep else None)


def _step_job(job: tuple) -> tuple:
    row, seed, keep = job
    kind, adrc, pid = _rows[row]
    metrics, trace = step_response(kind, seed, _scenario, adrc, pid)
    return row, seed, metrics, (trace if keep else None)


def tuned_gains(path: Path, tuning: str = "shared") -> OperatingPoint:
    """The outer-loop gains bench/tune_control.py found (its JSON) for operating point `tuning`, rebuilt with
    outer_loop.matched_gains: "shared" its "chosen" (one bandwidth for both), "own" its "own_best"."""
    data = json.loads(path.read_text())
    grid, picks = data["grid"], data[TUNING_SELECTION[tuning]]
    if any(picks.get(kind) is None for kind in TUNED):
        raise ValueError(f"{path}: no admissible {TUNING_SELECTION[tuning]} tuning for every controller")
    adrc_pick, pid_pick = picks["adrc"], picks["pid"]
    adrc, _ = matched_gains(
        adrc_pick["omega_c"],
        grid["vertical_ratio"] * adrc_pick["omega_c"],
        observer_ratio=adrc_pick["second"],
        delta=grid["adrc_delta"],
        r1=tuple(grid["adrc_r1"]),
    )
    _, pid = matched_gains(
        pid_pick["omega_c"], grid["vertical_ratio"] * pid_pick["omega_c"], integral_ratio=pid_pick["second"]
    )
    path = path.resolve()

    def bandwidth(pick: dict) -> dict:
        return {
            "omega_c_horizontal": pick["omega_c"],
            "omega_c_vertical": grid["vertical_ratio"] * pick["omega_c"],
            "tuning_flight_rms_error_m": pick["rms_error_m"],
            "tuning_flight_saturated_fraction": pick["saturated_fraction"],
        }

    described = {
        "source": f"{path.relative_to(REPO) if path.is_relative_to(REPO) else path}: {TUNING_SELECTION[tuning]}",
        "adrc": {
            **bandwidth(adrc_pick),
            "observer_ratio": adrc_pick["second"],
            "delta": grid["adrc_delta"],
            "r1": grid["adrc_r1"],
        },
        "pid": {**bandwidth(pid_pick), "integral_ratio": pid_pick["second"], "gains": asdict(pid)},
    }
    return OperatingPoint(tuning, adrc, pid, described)


def print_table(title: str, summary: dict, metrics: tuple[str, ...], rows: list[str], pair: str) -> None:
    """Mean [95 % CI] of `metrics` for the results `rows`, with the paired p-values of test `pair`."""
    print(f"\n{title}")
    header = f"{'metric':36}" + "".join(f"{k:>26}" for k in rows) + f"{'p (t / W) ' + pair:>30}"
    print(header)
    print("-" * len(header))
    for m in metrics:
        cells = []
        for k in rows:
            c = summary["per_controller"][k][m]
            if c["mean"] is None:
                cells.append(f"{'-':>26}")
            elif c["ci95"] is None:
                cells.append(f"{c['mean']:>26.4g}")
            else:
                cells.append(f"{c['mean']:>10.4g} [{c['ci95'][0]:.3g}, {c['ci95'][1]:.3g}]".rjust(26))
        test = summary["paired"].get(pair, {}).get(m)
        p = f"{test['paired_t_p']:.2g} / {test['wilcoxon_p']:.2g}" if test else "-"
        print(f"{m:36}" + "".join(cells) + f"{p:>30}")


def headline(summary: dict, completed: dict[str, int], seeds: int, bandwidths: dict[str, float | None]) -> list:
    """One line per results row: its bandwidth, missions completed and the HEADLINE metrics' means."""
    return [
        {
            "controller": row,
            "omega_c_horizontal": bandwidths.get(row),
            "completed": completed[row],
            "seeds": seeds,
            **{m: summary["per_controller"][row][m]["mean"] for m in HEADLINE},
        }
        for row in summary["per_controller"]
    ]


def print_headline(title: str, lines: list[dict]) -> None:
    print(f"\n{title}")
    header = f"{'controller':14}{'omega_c':>8}{'done':>8}" + "".join(f"{m:>{max(len(m), 9) + 2}}" for m in HEADLINE)
    print(header)
    print("-" * len(header))
    for line in lines:
        w = line["omega_c_horizontal"]
        cells = "".join(f"{'-' if line[m] is None else format(line[m], '.3g'):>{max(len(m), 9) + 2}}" for m in HEADLINE)
        done = f"{line['completed']}/{line['seeds']}"
        print(f"{line['controller']:14}{'-' if w is None else format(w, 'g'):>8}{done:>8}" + cells)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.control", description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=30)
    p.add_argument("--paper-seeds", type=int, default=5, help="extra seeds with the paper's variance-15 D terms")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--no-figures", dest="figures", action="store_false")
    p.add_argument("--out", type=Path, default=RESULTS / "control.json")
    p.add_argument(
        "--tuning",
        type=Path,
        default=RESULTS / "control_tuning.json",
        help="outer-loop gains chosen by bench/tune_control.py (default); see --shipped-gains",
    )
    p.add_argument(
        "--tunings",
        help=f"operating points from --tuning, comma-separated, from {','.join(TUNINGS)} (default: all): "
        "the shared bandwidth, each controller's own best",
    )
    p.add_argument("--shipped-gains", action="store_true", help="fly adrc_offboard/gains/outer_*.json instead")
    args = p.parse_args(argv)
    if args.seeds < 3 or args.workers < 1 or args.paper_seeds < 0:
        p.error("need --seeds >= 3, --workers >= 1, --paper-seeds >= 0")
    started = time.perf_counter()
    scenario = build_scenario()
    if args.shipped_gains:
        if args.tunings:
            p.error("--tunings picks from --tuning's file; --shipped-gains flies the gains files instead")
        shipped = {"adrc": "adrc_offboard/gains/outer_adrc.json", "pid": "adrc_offboard/gains/outer_pid.json"}
        points = [OperatingPoint("shipped", None, None, shipped)]
    else:
        names = (args.tunings or ",".join(TUNINGS)).split(",")
        if not names or any(n not in TUNINGS for n in names) or len(set(names)) < len(names):
            p.error(f"--tunings: comma-separated, each once, from {', '.join(TUNINGS)}")
        if not args.tuning.exists():
            p.error(f"{args.tuning} not found: run python -m bench.tune_control or use --shipped-gains")
        try:
            points = [tuned_gains(args.tuning, name) for name in names]
        except ValueError as exc:
            p.error(str(exc))
    # the results rows: the first point's ADRC, PID and px4 (untuned, flown once), then the others' ADRC, PID;
    # a row whose gains equal the first point's repeats that row's flights
    first = points[0]
    rows: dict[str, tuple[str, OperatingPoint]] = {first.row(k): (k, first) for k in CONTROLLERS}
    rows |= {point.row(k): (k, point) for point in points[1:] for k in TUNED}
    same_flights_as = {
        row: first.row(kind)
        for row, (kind, point) in rows.items()
        if point is not first and point.gains(kind) == first.gains(kind)
    }
    flown = [row for row in rows if row not in same_flights_as]
    worker_rows = {row: (kind, point.adrc, point.pid) for row, (kind, point) in rows.items()}  # what _share hands out
    print(
        f"route {scenario.route_length_m:.0f} m, longest leg {scenario.longest_leg}, crosswind from "
        f"{scenario.crosswind_from_deg:.0f} deg, gust at {scenario.gust_start_s:g} s after takeoff, "
        f"W20 {scenario.wind.turbulence_w20_m_s} m/s; operating points {', '.join(pt.name for pt in points)}"
        + "".join(f"; {row} repeats the flights of {same}" for row, same in same_flights_as.items()),
        flush=True,
    )
    first_rows = [first.row(k) for k in CONTROLLERS]
    jobs = [(row, seed, False, seed == 0 and row in first_rows) for seed in range(args.seeds) for row in flown]
    jobs += [(row, seed, True, False) for seed in range(args.paper_seeds) for row in first_rows]
    step_jobs = [(row, seed, seed == 0 and row in first_rows) for seed in range(args.seeds) for row in flown]
    per_seed: dict[str, list] = {row: [None] * args.seeds for row in rows}
    paper: dict[str, list] = {row: [None] * args.paper_seeds for row in first_rows}
    steps: dict[str, list] = {row: [None] * args.seeds for row in rows}
    series, traces = {}, {}
    pool = (
        Pool(args.workers, _share, (scenario, worker_rows)) if args.workers > 1 else _InlinePool(scenario, worker_rows)
    )
    with pool:
        for done, (row, seed, is_paper, metrics, s) in enumerate(pool.imap_unordered(_flight_job, jobs), 1):
            (paper if is_paper else per_seed)[row][seed] = metrics
            if s is not None:
                series[rows[row][0]] = s  # seed 0 of the first point, for the figures (keyed by controller)
            print(
                f"  [{done}/{len(jobs)}] {row} seed {seed}{' (paper D)' if is_paper else ''}: "
                f"rms {metrics['rms_error_m']:.3f} m, gust peak {metrics['gust_peak_m']:.3f} m, "
                f"completed {metrics['completed']} ({time.perf_counter() - started:.0f} s)",
                flush=True,
            )
        for row, seed, metrics, trace in pool.imap_unordered(_step_job, step_jobs):
            steps[row][seed] = metrics
            if trace is not None:
                traces[rows[row][0]] = trace
    for row, same in same_flights_as.items():
        per_seed[row], steps[row] = per_seed[same], steps[same]
    elapsed = time.perf_counter() - started
    # each point's ADRC against the other rows (px4 and geometric are untuned: one row each, for every point)
    pairs = tuple((point.row("adrc"), point.row(other)) for point in points for other in ("pid", "px4", "geometric"))
    first_pairs = tuple(pair for pair in pairs if pair[0] == first.row("adrc"))
    summary = summarise(per_seed, METRICS, pairs)
    step_summary = summarise(steps, STEP_METRICS, pairs)
    completed = {row: sum(bool(r["completed"]) for r in results) for row, results in per_seed.items()}
    for point in points:
        point_rows = [point.row(k) for k in CONTROLLERS]
        pair = f"{point.row('adrc')}_vs_{point.row('pid')}"
        print_table(
            f"Reference mission, {args.seeds} paired seeds, {_point_title(point)} "
            "(mean [95% CI]; paired p: t-test / Wilcoxon)",
            summary,
            METRICS,
            point_rows,
            pair,
        )
        print_table(f"5 m lateral step at hover, {_point_title(point)}", step_summary, STEP_METRICS, point_rows, pair)
    bandwidths = {
        row: point.described[kind]["omega_c_horizontal"] if point.name != "shipped" and kind in TUNED else None
        for row, (kind, point) in rows.items()
    }
    if "geometric" in rows:  # its gains file's kx = omega_c^2
        bandwidths["geometric"] = math.sqrt(GeometricGains.load().kx_horizontal)
    headlines = {"mission": headline(summary, completed, args.seeds, bandwidths)}
    print_headline(f"Summary, reference mission ({args.seeds} seeds; means)", headlines["mission"])
    paper_summary = paper_completed = None
    if args.paper_seeds:
        paper_completed = {row: sum(bool(r["completed"]) for r in results) for row, results in paper.items()}
        paper_summary = summarise(paper, METRICS, first_pairs)
        headlines["paper_disturbance"] = headline(paper_summary, paper_completed, args.paper_seeds, bandwidths)
        print_headline(
            f"Summary, paper's variance-15 disturbance ({args.paper_seeds} seeds, {_point_title(first)}; means "
            "over the flights that reached each phase)",
            headlines["paper_disturbance"],
        )
    if args.paper_seeds >= 3:
        first_pair = f"{first.row('adrc')}_vs_{first.row('pid')}"
        print_table(
            f"Paper's variance-15 disturbance, {args.paper_seeds} seeds", paper_summary, METRICS, first_rows, first_pair
        )
    adrc = summary["per_controller"][first.row("adrc")]
    targets = {
        m: {"target_max": v, "adrc_mean": adrc[m]["mean"], "met": adrc[m]["mean"] is not None and adrc[m]["mean"] <= v}
        for m, v in TARGETS.items()
    }
    print(
        f"\nADRC targets ({_point_title(first)}): "
        + ", ".join(
            f"{m} {'-' if t['adrc_mean'] is None else format(t['adrc_mean'], '.3g')} <= {t['target_max']} "
            f"{'met' if t['met'] else 'MISSED'}"
            for m, t in targets.items()
        )
    )
    figures = draw_figures(scenario, series, traces, args.out.parent) if args.figures else []
    result = {
        "command": "python -m bench.control " + " ".join(argv if argv is not None else sys.argv[1:]),
        "elapsed_s": elapsed,
        "workers": args.workers,
        "cpu_count": os.cpu_count(),
        "scenario": {
            **{k: v for k, v in asdict(scenario).items() if k not in ("items", "wind", "disturbance")},
            "wind": asdict(scenario.wind),
            "disturbance": asdict(scenario.disturbance),
            "turbulence_sigma_uv_m_s": TURBULENCE_SIGMA_M_S,
            "dwell_s": DWELL_S,
            "acceptance_radius_m": ACCEPTANCE_RADIUS_M,
            "gust_window_s": GUST_WINDOW_S,
            "recovered_below_m": RECOVERED_M,
        },
        "metrics_definitions": metrics_module.__doc__,
        "controllers": {row: _label(kind, point) for row, (kind, point) in rows.items()},
        "operating_points": {
            point.name: {
                "rows": {k: point.row(k) for k in TUNED},
                "outer_gains": point.described,
                "same_flights_as": {r: same for r, same in same_flights_as.items() if rows[r][1] is point},
            }
            for point in points
        },
        "gains": {
            "outer": "per operating point: operating_points.<name>.outer_gains",
            "adrc_inner": "adrc_offboard/gains/attitude_adrc.json",
            "pid_inner": "the vehicle's PidAttitudeGains (PX4 defaults)",
            "geometric": "adrc_offboard/gains/geometric.json (outer loop and the vehicle's geometric attitude loop)",
        },
        "seeds": args.seeds,
        "headline": headlines,
        "mission": summary,
        "completed": completed,
        "step": step_summary,
        "paper_disturbance": paper_summary,
        "paper_disturbance_completed": paper_completed,
        "targets": targets,
        "per_seed": per_seed,
        "figures": figures,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(_finite_or_null(result), indent=1, default=float))
    print(f"\nwrote {args.out} ({elapsed:.0f} s){''.join(chr(10) + '  ' + f for f in figures)}")
    return 0


def _point_title(point: OperatingPoint) -> str:
    if point.name == "shipped":
        return "shipped gains"
    if point.name == "shared":
        return f"shared bandwidth omega_c {point.described['adrc']['omega_c_horizontal']:g} rad/s"
    return (
        "each at its own best tuning ("
        + ", ".join(f"{k} omega_c {point.described[k]['omega_c_horizontal']:g}" for k in TUNED)
        + " rad/s)"
    )


def _label(kind: str, point: OperatingPoint) -> str:
    """LABELS[kind], which describes the shared bandwidth, for the rows of the other operating points."""
    if kind not in TUNED or point.name in ("shared", "shipped"):
        return LABELS[kind]
    omega_c = point.described[kind]["omega_c_horizontal"]
    return f"{kind.upper()} outer + {kind.upper()} inner at its own best tuning (omega_c {omega_c:g} rad/s)"


def _finite_or_null(value):
    """NaN (a metric a crashed flight never reached) as JSON null, so the file stays strict JSON."""
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_null(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class _InlinePool:
    """Pool stand-in for --workers 1: runs the jobs in this process."""

    def __init__(self, scenario: Scenario, rows: dict) -> None:
        _share(scenario, rows)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    @staticmethod
    def imap_unordered(fn, jobs):
        return map(fn, jobs)


if __name__ == "__main__":
    sys.exit(main())
