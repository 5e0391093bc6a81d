"""Planner benchmark: CHNN-GA against the exact optimum and LKH-3, side by side in one run.

    .venv/bin/python -m bench.planner_bench      # from the repository root: prints the table, writes
                                                 # bench/results/planner.json and bench/results/planner_narrative.png

Cases (targets from issue 2):
- 100 seeded 13-buoy missions (planner.scenario): CHNN-GA optimal on 100 %, median time <= 100 ms
- TSPLIB eil51, berlin52: the optimum on >= 4 of 5 seeds within 0.5 s each
- TSPLIB st70, uniform 100 and 280 buoys: mean gap to LKH <= 0.3 % (n <= 100), <= 1 % (n = 280) within 2 s
- the CHNN alone on the 13-buoy set: validity rate and mean gap (the paper: it sticks in local minima)
- ablations: the same memetic GA without the CHNN, and the CHNN's share of accepted children
LKH-3 runs through elkai (benchmark-only dependency) on integer distances: centimetres for metric missions,
TSPLIB's own integers for TSPLIB. The TSPLIB files and optima are tests/data/tsplib (TSPLIB95, see its README.md).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import elkai
import numpy as np

from planner import plan_tour
from planner.chnn_ga import GAParameters
from planner.distances import closed_tour_length, euclidean_matrix
from planner.exact import held_karp
from planner.local_search import warm_up
from planner.scenario import random_area_points, reference_scenario
from planner.tsplib import parse_tsp

REPO = Path(__file__).resolve().parents[1]
TSPLIB = REPO / "tests" / "data" / "tsplib"
RESULTS = REPO / "bench" / "results"
N_SMALL = 100
SEEDS = 5
NO_CHNN = GAParameters(use_chnn=False)


def lkh(dist: np.ndarray, scale: float) -> tuple[float, float]:
    """LKH-3's tour length on dist (rounded to integers after multiplying by scale) and its time."""
    started = time.perf_counter()
    tour = elkai.DistanceMatrix(np.rint(dist * scale).astype(int).tolist()).solve_tsp()
    return closed_tour_length(tour[:-1], dist), time.perf_counter() - started


def cold_compile_seconds() -> float:
    """First-call compile time of the numba kernels, measured in a fresh process with an empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        code = (
            "import time; t = time.perf_counter(); from planner.local_search import warm_up; warm_up(); "
            "print(time.perf_counter() - t)"
        )
        out = subprocess.run(
            [sys.executable, "-c", code],
            env={**os.environ, "NUMBA_CACHE_DIR": cache},
            capture_output=True,
            text=True,
            check=True,
        )
    return float(out.stdout.strip())


def small_missions() -> dict:
    """The 13-buoy set: exact, CHNN-GA, auto, CHNN alone, GA without CHNN, LKH."""
    rows = []
    for seed in range(N_SMALL):
        points = np.vstack([[0.0, 0.0], reference_scenario(seed=seed).buoys_local])
        dist = euclidean_matrix(points)
        started = time.perf_counter()
        _, optimum = held_karp(dist)
        exact_s = time.perf_counter() - started
        ga = plan_tour(points, method="chnn-ga", seed=seed)
        auto = plan_tour(points, method="auto", seed=seed)
        no_chnn = plan_tour(points, method="chnn-ga", seed=seed, ga=NO_CHNN)
        pure = plan_tour(points, method="chnn", seed=seed)
        first = pure.history[0]
        lkh_length, lkh_s = lkh(dist, 100.0)
        accepted = {"chnn": 0, "crossover": 0, "ils": 0}
        for generation in ga.history[1:]:
            for kind, count in generation["accepted"].items():
                accepted[kind] += count
        initial = ga.history[0]
        rows.append(
            {
                "seed": seed,
                "optimum": optimum,
                "exact_s": exact_s,
                "ga_length": ga.length,
                "ga_s": ga.elapsed_s,
                "ga_generations": len(ga.history) - 1,
                "auto_length": auto.length,
                "auto_s": auto.elapsed_s,
                "no_chnn_length": no_chnn.length,
                "no_chnn_s": no_chnn.elapsed_s,
                "chnn_length": pure.length,
                "chnn_s": pure.elapsed_s,
                "chnn_first_batch_valid": first["chnn_valid"] / first["chnn_children"],
                "ga_initial_chnn_valid": initial["chnn_valid"] / max(initial["chnn_children"], 1),
                "ga_initial_chnn_best": initial.get("chnn_best_length"),
                "ga_after_first_repair": initial["best_length"],
                "ga_accepted": accepted,
                "lkh_length": lkh_length,
                "lkh_s": lkh_s,
            }
        )

    def is_opt(key: str) -> float:
        return float(np.mean([abs(r[key] - r["optimum"]) < 1e-6 * r["optimum"] for r in rows]))

    def gap(key: str) -> float:
        return float(np.mean([(r[key] / r["optimum"] - 1) * 100 for r in rows if r[key] is not None]))

    accepted_total = {k: sum(r["ga_accepted"][k] for r in rows) for k in ("chnn", "crossover", "ils")}
    return {
        "instances": N_SMALL,
        "exact_median_s": float(np.median([r["exact_s"] for r in rows])),
        "chnn_ga_optimal_rate": is_opt("ga_length"),
        "chnn_ga_median_s": float(np.median([r["ga_s"] for r in rows])),
        "chnn_ga_max_s": float(np.max([r["ga_s"] for r in rows])),
        "auto_optimal_rate": is_opt("auto_length"),
        "auto_median_s": float(np.median([r["auto_s"] for r in rows])),
        "no_chnn_optimal_rate": is_opt("no_chnn_length"),
        "no_chnn_median_s": float(np.median([r["no_chnn_s"] for r in rows])),
        "chnn_alone_validity_rate": float(np.mean([r["chnn_first_batch_valid"] for r in rows])),
        "chnn_alone_mean_gap_pct": gap("chnn_length"),
        "chnn_alone_optimal_rate": is_opt("chnn_length"),
        "chnn_alone_median_s": float(np.median([r["chnn_s"] for r in rows])),
        "chnn_initial_population_mean_gap_pct": gap("ga_initial_chnn_best"),
        "after_first_local_search_mean_gap_pct": gap("ga_after_first_repair"),
        "ga_accepted_children": accepted_total,
        "lkh_optimal_rate": is_opt("lkh_length"),
        "lkh_median_s": float(np.median([r["lkh_s"] for r in rows])),
        "rows": rows,
    }


def read_optima() -> dict[str, int]:
    optima = {}
    for line in (TSPLIB / "OPTIMA.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, value = line.split()
            optima[name] = int(value)
    return optima


def tsplib_cases(optima: dict[str, int]) -> list[dict]:
    """Every TSPLIB instance: CHNN-GA on 5 seeds (0.5 s up to 52 nodes, 2 s beyond), LKH, and Held-Karp
    where it applies."""
    cases = []
    instances = {name: parse_tsp((TSPLIB / f"{name}.tsp").read_text()) for name in optima}
    for name in sorted(instances, key=lambda k: len(instances[k].coords)):
        dist = instances[name].distance_matrix()
        n = len(dist)
        limit = 0.5 if n <= 52 else 2.0
        runs = [plan_tour(None, distance=dist, method="chnn-ga", seed=s, time_limit_s=limit) for s in range(SEEDS)]
        no_chnn = [plan_tour(None, distance=dist, seed=s, time_limit_s=limit, ga=NO_CHNN) for s in range(SEEDS)]
        lkh_length, lkh_s = lkh(dist, 1.0)
        exact = held_karp(dist)[1] if n <= 16 else None
        lengths = [r.length for r in runs]
        cases.append(
            {
                "case": f"TSPLIB {name}",
                "n": n,
                "optimum": optima[name],
                "time_limit_s": limit,
                "chnn_ga_lengths": lengths,
                "chnn_ga_hits": sum(abs(x - optima[name]) < 0.5 for x in lengths),
                "chnn_ga_max_s": max(r.elapsed_s for r in runs),
                "chnn_ga_mean_gap_to_lkh_pct": float(np.mean([(x / lkh_length - 1) * 100 for x in lengths])),
                "no_chnn_lengths": [r.length for r in no_chnn],
                "no_chnn_hits": sum(abs(r.length - optima[name]) < 0.5 for r in no_chnn),
                "held_karp": exact,
                "lkh_length": lkh_length,
                "lkh_s": lkh_s,
            }
        )
    return cases


def random_cases() -> list[dict]:
    """Uniform random missions of 100 and 280 buoys (plus the depot) in a 1200 m x 700 m area scaled up."""
    cases = []
    for n_buoys, instances in ((100, SEEDS), (280, SEEDS)):
        gaps, no_chnn_gaps, times = [], [], []
        for seed in range(instances):
            rng = np.random.default_rng(1000 + seed)
            points = np.vstack([[0.0, 0.0], random_area_points(n_buoys, rng) * np.sqrt(n_buoys / 13)])
            dist = euclidean_matrix(points)
            result = plan_tour(points, method="chnn-ga", seed=seed, time_limit_s=2.0)
            no_chnn = plan_tour(points, method="chnn-ga", seed=seed, time_limit_s=2.0, ga=NO_CHNN)
            lkh_length, _ = lkh(dist, 100.0)
            gaps.append((result.length / lkh_length - 1) * 100)
            no_chnn_gaps.append((no_chnn.length / lkh_length - 1) * 100)
            times.append(result.elapsed_s)
        cases.append(
            {
                "case": f"uniform {n_buoys} buoys",
                "n": n_buoys + 1,
                "instances": instances,
                "time_limit_s": 2.0,
                "chnn_ga_gaps_to_lkh_pct": gaps,
                "chnn_ga_mean_gap_to_lkh_pct": float(np.mean(gaps)),
                "chnn_ga_max_s": max(times),
                "no_chnn_mean_gap_to_lkh_pct": float(np.mean(no_chnn_gaps)),
            }
        )
    return cases


def narrative_figure(path: Path) -> dict:
    """The paper's Figure 8 story on reference mission seed 1: random tour, CHNN local minimum, CHNN-GA,
    exact optimum, the CHNN energy trace; and the GA's best length per generation on a larger mission."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from planner.plot import draw_route

    points = np.vstack([[0.0, 0.0], reference_scenario(seed=1).buoys_local])
    dist = euclidean_matrix(points)
    rng = np.random.default_rng(1)
    random_order = [0, *(rng.permutation(len(points) - 1) + 1).tolist()]
    pure = plan_tour(points, method="chnn", seed=1)
    ga = plan_tour(points, method="chnn-ga", seed=1)
    exact = plan_tour(points, method="exact")
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    panels = [
        ("(a) random tour", random_order, closed_tour_length(random_order, dist)),
        ("(b) CHNN alone: local minimum", pure.order, pure.length),
        ("(c) CHNN-GA best", ga.order, ga.length),
        ("(d) exact optimum (Held-Karp)", exact.order, exact.length),
    ]
    for ax, (title, order, length) in zip(axes.flat[:4], panels, strict=True):
        draw_route(ax, points, order, f"{title}: {length:.0f} m")
    energy = pure.history[0]["energy"]
    axes.flat[4].semilogy(energy)  # every term of E is >= 0; the log scale shows the slow late phase
    axes.flat[4].set_title("(e) CHNN energy E = E1+E2+E3+E4 per Euler step (Fig. 8g)", fontsize=9)
    axes.flat[4].set_xlabel("step")
    axes.flat[4].set_ylabel("E")
    axes.flat[4].grid(True, alpha=0.3)
    # On 13 buoys the first generation is already optimal, so the GA's progress is shown on 100 buoys.
    big = np.vstack([[0.0, 0.0], random_area_points(100, np.random.default_rng(1000)) * np.sqrt(100 / 13)])
    big_run = plan_tour(big, method="chnn-ga", seed=1)
    reference, _ = lkh(euclidean_matrix(big), 100.0)
    generations = [h["generation"] for h in big_run.history]
    axes.flat[5].step(generations, [h["best_length"] for h in big_run.history], where="post", label="best")
    axes.flat[5].step(generations, [h["mean_length"] for h in big_run.history], where="post", label="population mean")
    axes.flat[5].axhline(reference, color="k", ls="--", lw=1, label="LKH-3")
    axes.flat[5].set_title("(f) CHNN-GA length per generation, 100-buoy mission", fontsize=9)
    axes.flat[5].set_xlabel("generation")
    axes.flat[5].set_ylabel("m")
    axes.flat[5].legend(fontsize=8)
    axes.flat[5].grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return {
        "random_m": panels[0][2],
        "chnn_m": pure.length,
        "chnn_ga_m": ga.length,
        "optimum_m": exact.length,
        "figure": str(path.relative_to(REPO)),
    }


def main() -> None:
    # No options: --help prints the docstring above; the run itself is the whole benchmark (a few minutes).
    argparse.ArgumentParser(
        prog="python -m bench.planner_bench",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    ).parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    compile_s = cold_compile_seconds()
    started = time.perf_counter()
    warm_up()
    cached_load_s = time.perf_counter() - started
    small = small_missions()
    optima = read_optima()
    tsplib = tsplib_cases(optima)
    uniform = random_cases()
    narrative = narrative_figure(RESULTS / "planner_narrative.png")

    print(f"numba kernels: first compile {compile_s:.1f} s (cold cache), cached load {cached_load_s:.2f} s\n")
    print("| case | measured | target |\n| --- | --- | --- |")
    print(
        f"| {N_SMALL} x 13 buoys, CHNN-GA | optimal {small['chnn_ga_optimal_rate']:.0%}, median "
        f"{small['chnn_ga_median_s'] * 1000:.0f} ms (max {small['chnn_ga_max_s'] * 1000:.0f} ms) "
        "| 100 %, <= 100 ms |"
    )
    print(
        f"| {N_SMALL} x 13 buoys, auto (Held-Karp) | optimal {small['auto_optimal_rate']:.0%}, median "
        f"{small['auto_median_s'] * 1000:.0f} ms | - |"
    )
    print(
        f"| {N_SMALL} x 13 buoys, GA without CHNN | optimal {small['no_chnn_optimal_rate']:.0%}, median "
        f"{small['no_chnn_median_s'] * 1000:.0f} ms | (ablation) |"
    )
    print(
        f"| {N_SMALL} x 13 buoys, CHNN alone | valid {small['chnn_alone_validity_rate']:.0%} of runs, mean gap "
        f"{small['chnn_alone_mean_gap_pct']:.1f} % (best of a batch of 8), optimal "
        f"{small['chnn_alone_optimal_rate']:.0%} | report |"
    )
    print(
        f"| {N_SMALL} x 13 buoys, LKH-3 (elkai) | optimal {small['lkh_optimal_rate']:.0%}, median "
        f"{small['lkh_median_s'] * 1000:.0f} ms | reference |"
    )
    for case in tsplib:
        target = "optimum on >= 4/5" if case["n"] <= 52 else "gap to LKH <= 0.3 %"
        print(
            f"| {case['case']} (n={case['n']}, {case['time_limit_s']} s) | optimum {case['optimum']}: hit "
            f"{case['chnn_ga_hits']}/{SEEDS} {case['chnn_ga_lengths']}, gap to LKH "
            f"{case['chnn_ga_mean_gap_to_lkh_pct']:.2f} %; without CHNN hit {case['no_chnn_hits']}/{SEEDS} "
            f"| {target} |"
        )
    for case in uniform:
        target = "<= 0.3 %" if case["n"] <= 101 else "<= 1 %"
        print(
            f"| {case['case']} ({case['instances']} instances, 2 s) | mean gap to LKH "
            f"{case['chnn_ga_mean_gap_to_lkh_pct']:.2f} % (max time {case['chnn_ga_max_s']:.2f} s); without CHNN "
            f"{case['no_chnn_mean_gap_to_lkh_pct']:.2f} % | {target} |"
        )
    print(
        f"\nwhere the quality comes from (13-buoy set): CHNN initial population best gap "
        f"{small['chnn_initial_population_mean_gap_pct']:.1f} % -> after 2-opt/Or-opt "
        f"{small['after_first_local_search_mean_gap_pct']:.2f} %; children accepted over all runs "
        f"{small['ga_accepted_children']}"
    )
    print(
        f"narrative (seed 1): random {narrative['random_m']:.0f} m, CHNN {narrative['chnn_m']:.0f} m, CHNN-GA "
        f"{narrative['chnn_ga_m']:.0f} m, optimum {narrative['optimum_m']:.0f} m -> {narrative['figure']}"
    )
    report = {
        "numba_first_compile_s": compile_s,
        "numba_cached_load_s": cached_load_s,
        "small_missions": small,
        "tsplib": tsplib,
        "uniform": uniform,
        "narrative": narrative,
    }
    (RESULTS / "planner.json").write_text(json.dumps(report, indent=1))
    print(f"wrote {(RESULTS / 'planner.json').relative_to(REPO)}")


if __name__ == "__main__":
    main()
