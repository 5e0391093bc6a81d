"""The controller families on the paper's buoy-inspection mission: a paired Monte Carlo over seeds, flown in lockstep.

The command line (see the package docstring, bench/control/__init__.py): flies every controller on every seed
in a pool of worker processes, then the step experiment, prints the tables and writes control.json (+ figures).
Every family flies its shipped design (adrc_offboard/gains/design.json), which `python -m bench.tune` chose for
each by the same optimiser and budget: the comparison is tuned against tuned. "px4" is the vehicle's own cascade
at PX4's default gains, untuned. Paired tests compare "adrc" with each other controller.
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

from adrc_offboard.design import describe, load_designs
from bench.control import RESULTS
from bench.control import metrics as metrics_module
from bench.control.figures import draw_figures
from bench.control.flight import CONTROLLERS, LABELS, fly, step_response
from bench.control.metrics import ESO_METRICS, METRICS, STEP_METRICS, TARGETS
from bench.control.scenario import ACCEPTANCE_RADIUS_M, DWELL_S, Scenario, build_scenario
from bench.control.statistics import summarise
from gcs.domain.tracking_metrics import GUST_WINDOW_S, RECOVERED_M
from planner.scenario import TURBULENCE_SIGMA_M_S
from uavcore.airframe import Airframe

# the honest summary: one line per controller and operating point (the README's top table)
HEADLINE = (
    "rms_error_m",
    "gust_peak_m",
    "saturated_fraction",
    *(m for m in ESO_METRICS if m not in ("eso_disturbance_rms_m_s2", "eso_lateral_rel_error")),
)


# What every flight job shares, set once per worker process by _share (the pool's initializer): the scenario
_scenario: Scenario


def _share(scenario: Scenario) -> None:
    global _scenario
    _scenario = scenario


def _flight_job(job: tuple) -> tuple:
    kind, seed, paper, keep = job
    metrics, series = fly(kind, seed, _scenario, paper_disturbance=paper)
    return kind, seed, paper, metrics, (series if keep else None)


def _step_job(job: tuple) -> tuple:
    kind, seed, keep = job
    metrics, trace = step_response(kind, seed, _scenario)
    return kind, seed, metrics, (trace if keep else None)


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
    """One line per results row: its horizontal position bandwidth, missions completed and the HEADLINE metrics'
    means."""
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
    p.add_argument("--controllers", default=",".join(CONTROLLERS), help=f"from {', '.join(CONTROLLERS)}")
    p.add_argument("--no-figures", dest="figures", action="store_false")
    p.add_argument("--out", type=Path, default=RESULTS / "control.json")
    args = p.parse_args(argv)
    controllers = args.controllers.split(",")
    if args.seeds < 3 or args.workers < 1 or args.paper_seeds < 0:
        p.error("need --seeds >= 3, --workers >= 1, --paper-seeds >= 0")
    if "adrc" not in controllers or any(c not in CONTROLLERS for c in controllers):
        p.error(f"--controllers: from {', '.join(CONTROLLERS)}, adrc among them (the pairs compare with it)")
    started = time.perf_counter()
    scenario = build_scenario()
    print(
        f"route {scenario.route_length_m:.0f} m, longest leg {scenario.longest_leg}, crosswind from "
        f"{scenario.crosswind_from_deg:.0f} deg, gust at {scenario.gust_start_s:g} s after takeoff, "
        f"W20 {scenario.wind.turbulence_w20_m_s} m/s; controllers {', '.join(controllers)} at their shipped designs",
        flush=True,
    )
    jobs = [(kind, seed, False, seed == 0) for seed in range(args.seeds) for kind in controllers]
    jobs += [(kind, seed, True, False) for seed in range(args.paper_seeds) for kind in controllers]
    step_jobs = [(kind, seed, seed == 0) for seed in range(args.seeds) for kind in controllers]
    per_seed: dict[str, list] = {kind: [None] * args.seeds for kind in controllers}
    paper: dict[str, list] = {kind: [None] * args.paper_seeds for kind in controllers}
    steps: dict[str, list] = {kind: [None] * args.seeds for kind in controllers}
    series, traces = {}, {}
    pool = Pool(args.workers, _share, (scenario,)) if args.workers > 1 else _InlinePool(scenario)
    with pool:
        for done, (kind, seed, is_paper, metrics, s) in enumerate(pool.imap_unordered(_flight_job, jobs), 1):
            (paper if is_paper else per_seed)[kind][seed] = metrics
            if s is not None:
                series[kind] = s  # seed 0, for the figures
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
    pairs = tuple(("adrc", other) for other in controllers if other != "adrc")
    summary = summarise(per_seed, METRICS, pairs)
    step_summary = summarise(steps, STEP_METRICS, pairs)
    completed = {kind: sum(bool(r["completed"]) for r in results) for kind, results in per_seed.items()}
    for _, other in pairs:
        title = f"Reference mission, {args.seeds} paired seeds, tuned designs (mean [95% CI]; paired p: t / Wilcoxon)"
        print_table(title, summary, METRICS, controllers, f"adrc_vs_{other}")
    print_table("5 m lateral step at hover, tuned designs", step_summary, STEP_METRICS, controllers, "adrc_vs_pid")
    airframe = Airframe.table2()
    designs = load_designs()
    bandwidths = {k: designs[k].bandwidths(airframe)["horizontal"] if k in designs else None for k in controllers}
    headlines = {"mission": headline(summary, completed, args.seeds, bandwidths)}
    print_headline(f"Summary, reference mission ({args.seeds} seeds; means)", headlines["mission"])
    paper_summary = paper_completed = None
    if args.paper_seeds:
        paper_completed = {kind: sum(bool(r["completed"]) for r in results) for kind, results in paper.items()}
        paper_summary = summarise(paper, METRICS, pairs)
        headlines["paper_disturbance"] = headline(paper_summary, paper_completed, args.paper_seeds, bandwidths)
        print_headline(
            f"Summary, paper's variance-15 disturbance ({args.paper_seeds} seeds; means over the flights that "
            "reached each phase)",
            headlines["paper_disturbance"],
        )
    if args.paper_seeds >= 3:
        print_table(
            f"Paper's variance-15 disturbance, {args.paper_seeds} seeds",
            paper_summary,
            METRICS,
            controllers,
            "adrc_vs_pid",
        )
    adrc = summary["per_controller"]["adrc"]
    targets = {
        m: {"target_max": v, "adrc_mean": adrc[m]["mean"], "met": adrc[m]["mean"] is not None and adrc[m]["mean"] <= v}
        for m, v in TARGETS.items()
    }
    print(
        "\nADRC targets: "
        + ", ".join(
            f"{m} {'-' if t['adrc_mean'] is None else format(t['adrc_mean'], '.3g')} <= {t['target_max']} "
            f"{'met' if t['met'] else 'MISSED'}"
            for m, t in targets.items()
        )
    )
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
        "controllers": {kind: LABELS[kind] for kind in controllers},
        "designs": {k: describe(airframe, designs[k]) for k in controllers if k in designs},
        "design_file": "adrc_offboard/gains/design.json (bench.tune's choice: bench/results/tune.json)",
        "seeds": args.seeds,
        "headline": headlines,
        "mission": summary,
        "completed": completed,
        "step": step_summary,
        "paper_disturbance": paper_summary,
        "paper_disturbance_completed": paper_completed,
        "targets": targets,
        "per_seed": per_seed,
        "figures": [],
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(_finite_or_null(result), indent=1, default=float))  # before the figures: kept
    if args.figures:
        result["figures"] = draw_figures(scenario, series, traces, args.out.parent)
        args.out.write_text(json.dumps(_finite_or_null(result), indent=1, default=float))
    print(f"\nwrote {args.out} ({elapsed:.0f} s){''.join(chr(10) + '  ' + f for f in result['figures'])}")
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

    def __init__(self, scenario: Scenario) -> None:
        _share(scenario)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    @staticmethod
    def imap_unordered(fn, jobs):
        return map(fn, jobs)


if __name__ == "__main__":
    sys.exit(main())
