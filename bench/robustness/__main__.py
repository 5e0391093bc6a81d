"""Robustness sweeps: every controller at its shipped design, flown on the short scenario under each condition.

    .venv/bin/python -m bench.robustness [--seeds 10] [--conditions NAMES|GROUPS] [--controllers adrc,pid,...]
                                         [--workers ray|serial] [--address ADDR] [--cpus N] [--no-figures]

Conditions (bench/robustness/conditions.py, a list that is data): model error (the vehicle's real airframe
perturbed, the controllers designed for the nominal one), wind (mean 0-12 m/s with gust and turbulence scaled,
a wandering mean wind), the paper's disturbances (a 0.1 s wind change, D-term variance 0.05-15), sensors (noise
x0/x3, delay 20/60 ms), two other airframes. Each family flies its shipped design (adrc_offboard/gains/design.json,
chosen by `python -m bench.tune`): its gains for both loops derived from the airframe its controllers are designed
for (adrc_offboard.design): the nominal Table 2 under model error, the other airframe's own file for the airframe
conditions; "px4" flies the vehicle's PX4 defaults.

Per flight (bench/robustness/flight.py): bench.control.metrics' tracking RMS and peak error, cross-track,
along-track lag, gust peak and recovery, saturated fraction; success = the mission completed and the 3-D tracking
error stayed under 10 m; the wind the vehicle met (mean, std and peak of the horizontal wind speed, spread of the
wind vector). Seeds 0..N-1 are paired: a seed fixes the air, so every controller meets the same air.
Statistics per condition and controller: mean and 95 % CI (bench.control.statistics), success rate, and paired
tests of each controller against "adrc" (paired t and Wilcoxon signed-rank on the seeds both completed).

Flights run through bench.campaign.run_tasks: the store bench/results/robustness_flights.jsonl keeps every
finished flight, and a rerun flies only the missing ones (delete it to start over after a change of the code or
the gains files). Writes bench/results/robustness.json and bench/results/robustness_<group>.png.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from bench.campaign import run_tasks
from bench.control import RESULTS
from bench.control.flight import CONTROLLERS
from bench.control.statistics import mean_ci, summarise
from bench.robustness.conditions import CONDITIONS, GROUPS, select
from bench.robustness.flight import KEPT, SUCCESS_MAX_ERROR_M, fly_condition

STATS_METRICS = (
    *KEPT[:-1],
    "wind_mean_m_s",
    "wind_std_m_s",
    "wind_peak_m_s",
    "wind_vector_spread_m_s",
)
TESTED = ("rms_error_m", "max_error_m", "gust_peak_m", "along_track_lag_rms_m", "along_track_lag_mean_m")
REFERENCE = "adrc"


def task_key(condition: str, kind: str, seed: int) -> str:
    return f"{condition}|{kind}|{seed}"


def analyse(flights: dict[str, dict], conditions: list[dict], controllers: list[str], seeds: list[int]) -> dict:
    """Per condition: per controller the statistics, and the paired tests against REFERENCE."""
    out: dict = {}
    for c in conditions:
        name = c["name"]
        rows: dict[str, dict[int, dict]] = {k: {} for k in controllers}
        errors: dict[str, list[str]] = {}
        for kind in controllers:
            for seed in seeds:
                r = flights.get(task_key(name, kind, seed))
                if r is None:
                    continue
                if "error" in r:
                    errors.setdefault(kind, []).append(f"seed {seed}: {r['error']}")
                    continue
                rows[kind][seed] = r
        entry: dict = {"group": c["group"], "spec": c, "per_controller": {}, "paired_vs_" + REFERENCE: {}}
        for kind, by_seed in rows.items():
            flown = list(by_seed.values())
            stats = {m: mean_ci(_column(flown, m)) for m in STATS_METRICS}
            n = len(flown)
            successes = sum(bool(r["success"]) for r in flown)
            entry["per_controller"][kind] = {
                "n": n,
                "success_rate": successes / n if n else None,
                "completed_rate": sum(bool(r["completed"]) for r in flown) / n if n else None,
                "failures": sorted({r["failure"] for r in flown if r.get("failure")}),
                "task_errors": errors.get(kind, []),
                **stats,
            }
        if REFERENCE in rows:
            for kind in controllers:
                if kind == REFERENCE:
                    continue
                common = sorted(set(rows[REFERENCE]) & set(rows[kind]))
                per_seed = {
                    REFERENCE: [_nan_none(rows[REFERENCE][s]) for s in common],
                    kind: [_nan_none(rows[kind][s]) for s in common],
                }
                tests = summarise(per_seed, TESTED, pairs=((REFERENCE, kind),))["paired"]
                entry["paired_vs_" + REFERENCE][kind] = tests.get(f"{REFERENCE}_vs_{kind}", {})
        out[name] = entry
    return out


def _nan_none(row: dict) -> dict:
    return {k: (np.nan if v is None else v) for k, v in row.items()}


def _column(rows: list[dict], metric: str) -> np.ndarray:
    return np.array([np.nan if r.get(metric) is None else r[metric] for r in rows], dtype=float)


def _fmt(stat: dict, digits: int = 3) -> str:
    if stat["mean"] is None:
        return "-"
    return f"{stat['mean']:.{digits}f}"


def print_table(results: dict, controllers: list[str]) -> None:
    head = (
        f"{'condition':28}{'ctrl':6}{'n':>3}{'succ':>6}{'rms m':>8}{'95% CI':>16}{'max m':>8}{'gust m':>8}"
        f"{'lag m':>7}{'mean':>7}{'sat':>6}{'wind m/s mean/std/peak/spread':>31}{'p(rms) vs adrc t/W':>20}"
    )
    print(head)
    for name, entry in results.items():
        for kind in controllers:
            s = entry["per_controller"].get(kind)
            if s is None:
                continue
            rms = s["rms_error_m"]
            ci = f"[{rms['ci95'][0]:.3f},{rms['ci95'][1]:.3f}]" if rms["ci95"] else "-"
            succ = f"{100 * s['success_rate']:.0f}%" if s["success_rate"] is not None else "-"
            wind = "/".join(
                _fmt(s[m], 1) for m in ("wind_mean_m_s", "wind_std_m_s", "wind_peak_m_s", "wind_vector_spread_m_s")
            )
            test = entry["paired_vs_" + REFERENCE].get(kind, {}).get("rms_error_m")
            p = f"{test['paired_t_p']:.3f}/{test['wilcoxon_p']:.3f}" if test else ""
            print(
                f"{name:28}{kind:6}{s['n']:>3}{succ:>6}{_fmt(rms):>8}{ci:>16}{_fmt(s['max_error_m']):>8}"
                f"{_fmt(s['gust_peak_m']):>8}{_fmt(s['along_track_lag_rms_m']):>7}{_fmt(s['along_track_lag_mean_m']):>7}"
                f"{_fmt(s['saturated_fraction'], 2):>6}"
                f"{wind:>31}{p:>20}"
            )


def draw(results: dict, controllers: list[str], out_dir: Path) -> list[str]:
    """Per condition group: RMS tracking error (mean, 95 % CI bars; log scale) and success rate per controller."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for group in GROUPS:
        names = [n for n, e in results.items() if e["group"] == group]
        if not names:
            continue
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(max(6.0, 1.3 * len(names) + 2), 7), sharex=True)
        width = 0.8 / len(controllers)
        x = np.arange(len(names))
        for i, kind in enumerate(controllers):
            means, lo, hi, succ = [], [], [], []
            for n in names:
                s = results[n]["per_controller"].get(kind, {})
                rms = s.get("rms_error_m", {"mean": None, "ci95": None})
                m = rms["mean"] if rms["mean"] is not None else np.nan
                means.append(m)
                lo.append(m - rms["ci95"][0] if rms["ci95"] else 0.0)
                hi.append(rms["ci95"][1] - m if rms["ci95"] else 0.0)
                succ.append(100 * s["success_rate"] if s.get("success_rate") is not None else np.nan)
            pos = x + (i - (len(controllers) - 1) / 2) * width
            ax.bar(pos, means, width, yerr=[lo, hi], capsize=3, label=kind)
            ax2.bar(pos, succ, width, label=kind)
        ax.set_yscale("log")
        ax.set_ylabel("RMS tracking error, m (95 % CI)")
        ax.set_title(f"robustness: {group} (shipped designs, short scenario)")
        ax.legend()
        ax2.set_ylabel(f"success % (completed, max error < {SUCCESS_MAX_ERROR_M:g} m)")
        ax2.set_ylim(0, 105)
        ax2.set_xticks(x, names, rotation=30, ha="right")
        fig.tight_layout()
        path = out_dir / f"robustness_{group}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(str(path))
    return paths


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 per (condition, controller), paired")
    p.add_argument("--conditions", default=None, help="comma-separated condition names or groups (default all)")
    known = ",".join(CONTROLLERS)
    p.add_argument("--controllers", default=known, help="comma-separated, from " + known)
    p.add_argument("--workers", choices=("ray", "serial"), default="ray")
    p.add_argument("--address", default=None, help='an existing Ray cluster: "auto" or "ray://HOST:10001"')
    p.add_argument("--cpus", type=int, default=None, help="CPUs of a local Ray (default: all)")
    p.add_argument("--store", type=Path, default=RESULTS / "robustness_flights.jsonl")
    p.add_argument("--out", type=Path, default=RESULTS / "robustness.json")
    p.add_argument("--no-figures", action="store_true")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--list", action="store_true", help="list the conditions and exit")
    args = p.parse_args(argv)
    if args.list:
        for c in CONDITIONS:
            print(f"{c['group']:9}{c['name']:28}{ {k: v for k, v in c.items() if k not in ('name', 'group')} }")
        return 0
    controllers = [k.strip() for k in args.controllers.split(",") if k.strip()]
    unknown = [k for k in controllers if k not in CONTROLLERS]
    try:
        conditions = select(args.conditions)
    except ValueError as exc:
        print(f"robustness: error: {exc}", file=sys.stderr)
        return 2
    if unknown or args.seeds < 1:
        message = f"unknown controller(s) {unknown} (known: {CONTROLLERS}) or --seeds < 1"
        print(f"robustness: error: {message}", file=sys.stderr)
        return 2
    seeds = list(range(args.seeds))
    tasks = [
        (task_key(c["name"], kind, seed), {"condition": c["name"], "kind": kind, "seed": seed})
        for c in conditions
        for seed in seeds
        for kind in controllers
    ]
    started = time.perf_counter()
    flights = run_tasks(
        fly_condition,
        tasks,
        args.store,
        workers=args.workers,
        address=args.address,
        num_cpus=args.cpus,
        desc="robustness flights",
        progress=not args.no_progress,
    )
    elapsed = time.perf_counter() - started
    results = analyse(flights, conditions, controllers, seeds)
    print_table(results, controllers)
    errors = sum("error" in flights[k] for k, _ in tasks)
    figures = [] if args.no_figures else draw(results, controllers, args.out.parent)
    out = {
        "command": "python -m bench.robustness " + " ".join(argv if argv is not None else sys.argv[1:]),
        "method": __doc__,
        "success_criterion": f"mission completed and max 3-D tracking error < {SUCCESS_MAX_ERROR_M:g} m",
        "controllers": controllers,
        "seeds": seeds,
        "store": str(args.store),
        "elapsed_s": elapsed,
        "flights": len(tasks),
        "task_errors": errors,
        "conditions": results,
        "figures": figures,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1))
    print(f"wrote {args.out} ({len(tasks)} flights, {errors} task errors, {elapsed:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
