"""ADRC against PID on the paper's buoy-inspection mission: a paired Monte Carlo over seeds, flown in lockstep.

The command line (see the package docstring, bench/control/__init__.py): flies every controller on every seed
in a pool of worker processes, then the step experiment, prints the tables and writes control.json (+ figures).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import asdict
from multiprocessing import Pool
from pathlib import Path

from adrc_offboard.outer_loop import AdrcOuterGains, PidOuterGains, matched_gains
from bench.control import REPO, RESULTS
from bench.control.figures import draw_figures
from bench.control.flight import CONTROLLERS, LABELS, fly, step_response
from bench.control.metrics import METRICS, STEP_METRICS, TARGETS
from bench.control.scenario import ACCEPTANCE_RADIUS_M, DWELL_S, Scenario, build_scenario
from bench.control.statistics import summarise
from gcs.tracking import GUST_WINDOW_S, RECOVERED_M
from planner.scenario import TURBULENCE_SIGMA_M_S

Gains = tuple[AdrcOuterGains | None, PidOuterGains | None]  # None: the shipped gains files

# What every flight job shares, set once per worker process by _share (the pool's initializer)
_scenario: Scenario
_gains: Gains = (None, None)


def _share(scenario: Scenario, gains: Gains) -> None:
    global _scenario, _gains
    _scenario, _gains = scenario, gains


def _flight_job(job: tuple) -> tuple:
    kind, seed, paper, keep = job
    metrics, series = fly(kind, seed, _scenario, paper_disturbance=paper, adrc_gains=_gains[0], pid_gains=_gains[1])
    return kind, seed, paper, metrics, (series if keep else None)


def _step_job(job: tuple) -> tuple:
    kind, seed = job
    metrics, trace = step_response(kind, seed, _scenario, *_gains)
    return kind, seed, metrics, (trace if seed == 0 else None)


def tuned_gains(path: Path) -> tuple[tuple[AdrcOuterGains, PidOuterGains], dict]:
    """The outer-loop gains bench/tune_control.py chose (its JSON), rebuilt with outer_loop.matched_gains."""
    data = json.loads(path.read_text())
    grid, chosen = data["grid"], data["chosen"]
    omega_c = float(data["shared_omega_c"])
    adrc, _ = matched_gains(
        omega_c,
        grid["vertical_ratio"] * omega_c,
        observer_ratio=chosen["adrc"]["second"],
        delta=grid["adrc_delta"],
        r1=tuple(grid["adrc_r1"]),
    )
    _, pid = matched_gains(omega_c, grid["vertical_ratio"] * omega_c, integral_ratio=chosen["pid"]["second"])
    path = path.resolve()
    described = {
        "source": str(path.relative_to(REPO) if path.is_relative_to(REPO) else path),
        "omega_c_horizontal": omega_c,
        "omega_c_vertical": grid["vertical_ratio"] * omega_c,
        "adrc_observer_ratio": chosen["adrc"]["second"],
        "pid_integral_ratio": chosen["pid"]["second"],
        "adrc_delta": grid["adrc_delta"],
        "adrc_r1": grid["adrc_r1"],
        "pid": asdict(pid),
    }
    return (adrc, pid), described


def print_table(title: str, summary: dict, metrics: tuple[str, ...]) -> None:
    kinds = list(summary["per_controller"])
    print(f"\n{title}")
    header = f"{'metric':30}" + "".join(f"{k:>26}" for k in kinds) + f"{'p (t / W) adrc-pid':>24}"
    print(header)
    print("-" * len(header))
    for m in metrics:
        cells = []
        for k in kinds:
            c = summary["per_controller"][k][m]
            if c["mean"] is None:
                cells.append(f"{'-':>26}")
            elif c["ci95"] is None:
                cells.append(f"{c['mean']:>26.4g}")
            else:
                cells.append(f"{c['mean']:>10.4g} [{c['ci95'][0]:.3g}, {c['ci95'][1]:.3g}]".rjust(26))
        test = summary["paired"].get("adrc_vs_pid", {}).get(m)
        p = f"{test['paired_t_p']:.2g} / {test['wilcoxon_p']:.2g}" if test else "-"
        print(f"{m:30}" + "".join(cells) + f"{p:>24}")


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
    p.add_argument("--shipped-gains", action="store_true", help="fly adrc_offboard/gains/outer_*.json instead")
    args = p.parse_args(argv)
    if args.seeds < 3 or args.workers < 1 or args.paper_seeds < 0:
        p.error("need --seeds >= 3, --workers >= 1, --paper-seeds >= 0")
    started = time.perf_counter()
    scenario = build_scenario()
    gains: Gains = (None, None)
    gains_used = {
        "adrc_outer": "adrc_offboard/gains/outer_adrc.json",
        "pid_outer": "adrc_offboard/gains/outer_pid.json",
    }
    if not args.shipped_gains:
        if not args.tuning.exists():
            p.error(f"{args.tuning} not found: run python -m bench.tune_control or use --shipped-gains")
        gains, gains_used = tuned_gains(args.tuning)
    print(
        f"route {scenario.route_length_m:.0f} m, longest leg {scenario.longest_leg}, crosswind from "
        f"{scenario.crosswind_from_deg:.0f} deg, gust at {scenario.gust_start_s:g} s after takeoff, "
        f"W20 {scenario.wind.turbulence_w20_m_s} m/s",
        flush=True,
    )
    jobs = [(k, seed, False, seed == 0) for seed in range(args.seeds) for k in CONTROLLERS]
    jobs += [(k, seed, True, False) for seed in range(args.paper_seeds) for k in CONTROLLERS]
    step_jobs = [(k, seed) for seed in range(args.seeds) for k in CONTROLLERS]
    per_seed: dict[str, list] = {k: [None] * args.seeds for k in CONTROLLERS}
    paper: dict[str, list] = {k: [None] * args.paper_seeds for k in CONTROLLERS}
    steps: dict[str, list] = {k: [None] * args.seeds for k in CONTROLLERS}
    series, traces = {}, {}
    pool = Pool(args.workers, _share, (scenario, gains)) if args.workers > 1 else _InlinePool(scenario, gains)
    with pool:
        for done, (kind, seed, is_paper, metrics, s) in enumerate(pool.imap_unordered(_flight_job, jobs), 1):
            (paper if is_paper else per_seed)[kind][seed] = metrics
            if s is not None:
                series[kind] = s
            print(
                f"  [{done}/{len(jobs)}] {kind} seed {seed}{' (paper D)' if is_paper else ''}: "
                f"rms {metrics['rms_error_m']:.3f} m, gust peak {metrics['gust_peak_m']:.3f} m, "
                f"completed {metrics['completed']} ({time.perf_counter() - started:.0f} s)",
                flush=True,
            )
        for kind, seed, metrics, trace in pool.imap_unordered(_step_job, step_jobs):
            steps[kind][seed] = metrics
            if trace is not None:
                traces[kind] = trace
    elapsed = time.perf_counter() - started
    summary = summarise(per_seed, METRICS)
    step_summary = summarise(steps, STEP_METRICS)
    print_table(
        f"Reference mission, {args.seeds} paired seeds (mean [95% CI]; paired p: t-test / Wilcoxon)", summary, METRICS
    )
    print_table("5 m lateral step at hover", step_summary, STEP_METRICS)
    paper_summary = None
    if args.paper_seeds >= 3:
        paper_summary = summarise(paper, METRICS)
        print_table(f"Paper's variance-15 disturbance, {args.paper_seeds} seeds", paper_summary, METRICS)
    adrc = summary["per_controller"]["adrc"]
    targets = {
        m: {"target_max": v, "adrc_mean": adrc[m]["mean"], "met": adrc[m]["mean"] is not None and adrc[m]["mean"] <= v}
        for m, v in TARGETS.items()
    }
    print(
        "\nADRC targets: "
        + ", ".join(
            f"{m} {t['adrc_mean']:.3g} <= {t['target_max']} {'met' if t['met'] else 'MISSED'}"
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
        "controllers": LABELS,
        "gains": {
            **gains_used,
            "adrc_inner": "adrc_offboard/gains/attitude_adrc.json",
            "pid_inner": "the vehicle's PidAttitudeGains (PX4 defaults)",
        },
        "seeds": args.seeds,
        "mission": summary,
        "completed": {k: sum(bool(r["completed"]) for r in rows) for k, rows in per_seed.items()},
        "step": step_summary,
        "paper_disturbance": paper_summary,
        "paper_disturbance_completed": {k: sum(bool(r["completed"]) for r in rows) for k, rows in paper.items()}
        if args.paper_seeds
        else None,
        "targets": targets,
        "per_seed": per_seed,
        "figures": figures,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(_finite_or_null(result), indent=1, default=float))
    print(f"\nwrote {args.out} ({elapsed:.0f} s){''.join(chr(10) + '  ' + f for f in figures)}")
    return 0


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

    def __init__(self, scenario: Scenario, gains: Gains) -> None:
        _share(scenario, gains)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    @staticmethod
    def imap_unordered(fn, jobs):
        return map(fn, jobs)


if __name__ == "__main__":
    sys.exit(main())
