"""Does the CHNN earn its place in the CHNN-GA? Paired comparison of the ways it can contribute.

    .venv/bin/python -m bench.chnn_contribution     # from the repository root: prints the tables, writes
                                                    # bench/results/chnn_contribution.json and .png

Arms (planner.chnn_ga.GAParameters), every one run on the same instances with the same seeds:
- "paper": the CHNN-GA as the paper has it: CHNN initial population (<= 30 buoys) and CHNN window mutation
- "chnn-candidates": the CHNN's edge frequencies (planner.chnn_guidance) fill half of each 2-opt / Or-opt
  candidate list; CHNN mutation off (it is never accepted, bench/planner_bench.py)
- "chnn-edge-crossover": edge crossover weighted by the CHNN's edge frequencies instead of OX; mutation off
- "no-chnn": the same memetic GA with random tours and no CHNN
- "edge-crossover-control": the edge crossover with a zero prior and no CHNN (the operator without the CHNN)
Instance families: the 13-buoy reference scenario (a new mission per seed, optimum by Held-Karp), TSPLIB
eil51, berlin52, st70 (known optima) and uniform missions of 100 and 200 buoys (a new one per seed; best
known = LKH-3 through elkai). Metrics per run: time to reach the optimum / best known (target-stopped run,
stall stop off, censored at CAP_S), the gap at 0.1 s (a real 0.1 s run with the default stop rules) and the
gap at 0.5 s (the target-stopped run's best at 0.5 s). Paired statistics over seeds, arm minus reference:
Wilcoxon signed-rank (scipy.stats.wilcoxon, zero differences dropped) and the paired t 95 % CI of the mean
difference (scipy.stats.ttest_rel). Times are wall clock (perf_counter, what the time limit uses) and CPU
(process_time); the machine is shared, so the load average is recorded and the arms are interleaved per seed.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import elkai
import numpy as np
from scipy import stats

from planner.chnn_ga import GAParameters, chnn_ga
from planner.distances import closed_tour_length, euclidean_matrix
from planner.exact import held_karp
from planner.scenario import random_area_points, reference_scenario
from planner.tsplib import parse_tsp

REPO = Path(__file__).resolve().parents[1]
TSPLIB = REPO / "tests" / "data" / "tsplib"
RESULTS = REPO / "bench" / "results"
SEEDS = 30
CAP_S = 1.0  # time-to-target runs stop here (censored: counted as CAP_S, reported as a hit rate)
BUDGETS_S = (0.1, 0.5)
ARMS = {
    "paper": GAParameters(),
    "chnn-candidates": GAParameters(p_chnn=0.0, chnn_candidates=5),
    "chnn-edge-crossover": GAParameters(p_chnn=0.0, edge_crossover=True),
    "no-chnn": GAParameters(use_chnn=False),
    "edge-crossover-control": GAParameters(use_chnn=False, edge_crossover=True),
}
COMPARISONS = [  # (arm, reference): the question each answers is in the README's verdict
    ("chnn-candidates", "no-chnn"),
    ("chnn-edge-crossover", "edge-crossover-control"),
    ("chnn-candidates", "paper"),
    ("chnn-edge-crossover", "paper"),
    ("paper", "no-chnn"),
]


@dataclass(frozen=True)
class Instance:
    family: str
    seed: int
    dist: np.ndarray
    target: float  # optimum or best known length


def lkh_length(dist: np.ndarray) -> float:
    """LKH-3's tour on centimetre-rounded distances, measured in the real ones."""
    tour = elkai.DistanceMatrix(np.rint(dist * 100).astype(int).tolist()).solve_tsp()
    return closed_tour_length(tour[:-1], dist)


def read_optima() -> dict[str, int]:
    lines = (TSPLIB / "OPTIMA.txt").read_text().splitlines()
    return {line.split()[0]: int(line.split()[1]) for line in lines if line.strip() and not line.startswith("#")}


def instances(seed: int, optima: dict[str, int]) -> list[Instance]:
    """Every family's instance for one seed (TSPLIB instances are the same for every seed)."""
    points = np.vstack([[0.0, 0.0], reference_scenario(seed=seed).buoys_local])
    dist = euclidean_matrix(points)
    made = [Instance("13 buoys", seed, dist, held_karp(dist)[1])]
    for name in ("eil51", "berlin52", "st70"):
        dist = parse_tsp((TSPLIB / f"{name}.tsp").read_text()).distance_matrix()
        made.append(Instance(name, seed, dist, float(optima[name])))
    for n_buoys in (100, 200):
        rng = np.random.default_rng(1000 + seed)
        dist = euclidean_matrix(np.vstack([[0.0, 0.0], random_area_points(n_buoys, rng) * np.sqrt(n_buoys / 13)]))
        made.append(Instance(f"uniform {n_buoys}", seed, dist, lkh_length(dist)))
    return made


def gap_pct(length: float, target: float) -> float:
    return (length / target - 1.0) * 100.0


def measure(instance: Instance, ga: GAParameters) -> dict:
    """One arm on one instance: the target-stopped run (time to target, gap at 0.5 s) and a 0.1 s run."""
    hunting = replace(ga, stall_generations=10**9, stall_per_node=0.0)
    run = chnn_ga(instance.dist, seed=instance.seed, time_limit_s=CAP_S, ga=hunting, target_length=instance.target)
    hit = run.length <= instance.target + 1e-9
    last = run.history[-1]
    at_half = [h["best_length"] for h in run.history if h["elapsed_s"] <= BUDGETS_S[1]]
    short = chnn_ga(instance.dist, seed=instance.seed, time_limit_s=BUDGETS_S[0], ga=ga)
    return {
        "hit": hit,
        "time_to_target_s": last["elapsed_s"] if hit else CAP_S,
        "cpu_to_target_s": last["cpu_s"] if hit else None,
        "gap_0.1s_pct": gap_pct(short.length, instance.target),
        "elapsed_0.1s_run_s": short.history[-1]["elapsed_s"],
        "gap_0.5s_pct": gap_pct(min(at_half), instance.target) if at_half else None,
    }


def both_defined(arm: list[dict], reference: list[dict], metric: str) -> tuple[list[float], list[float]]:
    """The metric's seed pairs where both runs have it (the gap at 0.5 s is undefined for a run whose first
    tour came after 0.5 s)."""
    pairs = [(a[metric], r[metric]) for a, r in zip(arm, reference, strict=True) if None not in (a[metric], r[metric])]
    return [a for a, _ in pairs], [r for _, r in pairs]


def paired(arm: list[float], reference: list[float]) -> dict:
    """Arm minus reference over the same seeds: mean, paired-t 95 % CI and p, Wilcoxon signed-rank p."""
    diff = np.asarray(arm, float) - np.asarray(reference, float)
    out = {"mean_diff": float(diff.mean()), "median_diff": float(np.median(diff)), "n": len(diff)}
    if np.allclose(diff, 0.0, atol=1e-12):
        return {**out, "ci95": [0.0, 0.0], "t_p": 1.0, "wilcoxon_p": 1.0, "note": "all differences zero"}
    t = stats.ttest_rel(arm, reference)
    ci = t.confidence_interval(0.95)
    nonzero = diff[np.abs(diff) > 1e-12]
    w = stats.wilcoxon(nonzero) if len(nonzero) >= 1 else None
    return {
        **out,
        "ci95": [float(ci.low), float(ci.high)],
        "t_p": float(t.pvalue),
        "wilcoxon_p": float(w.pvalue) if w is not None else 1.0,
        "nonzero_pairs": len(nonzero),
    }


def warm_up() -> None:
    """Compile every numba kernel (local search, ILS, edge crossover) and the guidance paths outside the clock."""
    rng = np.random.default_rng(0)
    for n in (14, 60):
        dist = euclidean_matrix(rng.uniform(0, 1000, (n, 2)))
        for ga in ARMS.values():
            chnn_ga(dist, seed=0, time_limit_s=0.3, ga=ga)


def summarise(rows: list[dict]) -> dict:
    families = list(dict.fromkeys(r["family"] for r in rows))
    summary: dict = {}
    for family in families:
        by_arm = {arm: [r["arms"][arm] for r in rows if r["family"] == family] for arm in ARMS}
        arms = {
            arm: {
                "hit_rate": float(np.mean([m["hit"] for m in ms])),
                "median_time_to_target_ms": float(np.median([m["time_to_target_s"] for m in ms]) * 1000),
                "mean_time_to_target_ms": float(np.mean([m["time_to_target_s"] for m in ms]) * 1000),
                "mean_gap_0.1s_pct": float(np.mean([m["gap_0.1s_pct"] for m in ms])),
                "mean_gap_0.5s_pct": float(np.mean([m["gap_0.5s_pct"] for m in ms if m["gap_0.5s_pct"] is not None])),
            }
            for arm, ms in by_arm.items()
        }
        tests = {}
        for arm, reference in COMPARISONS:
            tests[f"{arm} - {reference}"] = {
                metric: paired(*both_defined(by_arm[arm], by_arm[reference], metric))
                for metric in ("time_to_target_s", "gap_0.1s_pct", "gap_0.5s_pct")
            }
        summary[family] = {"arms": arms, "paired": tests}
    return summary


def print_tables(summary: dict) -> None:
    print("| family | arm | hit target | median time to target | mean gap @0.1 s | mean gap @0.5 s |")
    print("| --- | --- | --- | --- | --- | --- |")
    for family, result in summary.items():
        for arm, a in result["arms"].items():
            print(
                f"| {family} | {arm} | {a['hit_rate']:.0%} | {a['median_time_to_target_ms']:.1f} ms | "
                f"{a['mean_gap_0.1s_pct']:.3f} % | {a['mean_gap_0.5s_pct']:.3f} % |"
            )
    print("\npaired over seeds, arm - reference: mean difference [95 % CI], Wilcoxon p")
    print("| family | arm - reference | time to target (ms) | gap @0.1 s (% points) | gap @0.5 s (% points) |")
    print("| --- | --- | --- | --- | --- |")
    for family, result in summary.items():
        for name, test in result["paired"].items():
            t = test["time_to_target_s"]
            gaps = " | ".join(
                f"{g['mean_diff']:+.3f} [{g['ci95'][0]:+.3f}, {g['ci95'][1]:+.3f}], p={g['wilcoxon_p']:.2g}"
                for g in (test["gap_0.1s_pct"], test["gap_0.5s_pct"])
            )
            print(
                f"| {family} | {name} | {t['mean_diff'] * 1000:+.1f} [{t['ci95'][0] * 1000:+.1f}, "
                f"{t['ci95'][1] * 1000:+.1f}], p={t['wilcoxon_p']:.2g} | {gaps} |"
            )


def figure(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    families = list(summary)
    x = np.arange(len(families))
    width = 0.8 / len(ARMS)
    fig, axes = plt.subplots(1, 2, figsize=(14, 4.8))
    for i, arm in enumerate(ARMS):
        times = [summary[f]["arms"][arm]["mean_time_to_target_ms"] for f in families]
        gaps = [summary[f]["arms"][arm]["mean_gap_0.1s_pct"] for f in families]
        axes[0].bar(x + i * width, times, width, label=arm)
        axes[1].bar(x + i * width, gaps, width, label=arm)
    axes[0].set_yscale("log")
    axes[0].set_ylabel(f"mean time to optimum / best known (ms, censored at {CAP_S:.0f} s)")
    axes[1].set_ylabel("mean gap at 0.1 s (%)")
    for ax in axes:
        ax.set_xticks(x + 0.4 - width / 2, families, fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"CHNN contribution, {SEEDS} paired seeds per family (bench/chnn_contribution.py)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(
        prog="python -m bench.chnn_contribution",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--seeds", type=int, default=SEEDS, help=f"paired seeds per family (default {SEEDS})")
    seeds = parser.parse_args().seeds
    RESULTS.mkdir(parents=True, exist_ok=True)
    warm_up()
    optima = read_optima()
    load_before = os.getloadavg()
    started, cpu_started = time.perf_counter(), time.process_time()
    rows = []
    for seed in range(seeds):
        for instance in instances(seed, optima):
            # arms interleaved per instance, so a change of machine load hits every arm alike
            arms = {arm: measure(instance, ga) for arm, ga in ARMS.items()}
            rows.append({"family": instance.family, "seed": seed, "target": instance.target, "arms": arms})
        print(f"seed {seed + 1}/{seeds} done, {time.perf_counter() - started:.0f} s", flush=True)
    wall_s, cpu_s = time.perf_counter() - started, time.process_time() - cpu_started
    summary = summarise(rows)
    print_tables(summary)
    print(f"\nrun: {wall_s:.0f} s wall, {cpu_s:.0f} s CPU; load average before {load_before}, after {os.getloadavg()}")
    figure(summary, RESULTS / "chnn_contribution.png")
    report = {
        "seeds": seeds,
        "cap_s": CAP_S,
        "arms": {arm: ga.__dict__ for arm, ga in ARMS.items()},
        "wall_s": wall_s,
        "cpu_s": cpu_s,
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "summary": summary,
        "rows": rows,
    }
    (RESULTS / "chnn_contribution.json").write_text(json.dumps(report, indent=1))
    print(f"wrote {(RESULTS / 'chnn_contribution.json').relative_to(REPO)} and chnn_contribution.png")


if __name__ == "__main__":
    main()
