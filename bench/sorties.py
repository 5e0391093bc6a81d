"""Multi-sortie benchmark: our planner against PyVRP and OR-Tools on the same instances, same time limits.

    .venv/bin/python -m bench.sorties            # 50 / 100 / 200 buoys x 3 seeds x 2 s and 10 s (about 4 min)
    .venv/bin/python -m bench.sorties --quick    # 100 buoys, 2 seeds, 2 s only (development; writes *_quick.*)

Prints the table, writes bench/results/sorties.json (with the machine and its load average) and
bench/results/sorties.png (the 100-buoy instance's sorties for the three methods, and the gaps).

Instances (``harbour_instance``): n buoys uniform, or in clusters, in a 4 km x 3 km harbour, the depot in the
middle of its west side; the default flight model (planner.sortie_cost) with a 5 m/s south-westerly wind (so
A->B and B->A differ) and a 30 s inspection hover per buoy; a battery sized so that about 4-8 sorties are
needed. Objective: total flight time. Every method gets the same arc matrices (services folded into the arcs
that arrive at a buoy, planner.split.folded_matrices), integerised for the two reference solvers: time in
ms, rounded; energy in 1e-5 Wh, rounded UP with the budget rounded down, so a solution within their
integer budget is within the true one. Every method's answer is re-checked and re-costed by OUR checker
(SortieCost.violations) in floating point: an infeasible answer counts as failed, never as a win.

Configurations (each method's best reasonable setting):
- ours: plan_sorties defaults (ILS giant tour, exact split both ways, SISR ruin-and-recreate + local search
  under simulated annealing, per-sortie re-optimisation by the single-sortie planner).
- PyVRP 0.14 (hybrid genetic search): default SolveParams, MaxRuntime; one vehicle type with as many
  vehicles as buoys, max_distance = energy budget (the "distance" matrix carries energy with
  unit_distance_cost = 0), unit_duration_cost = 1 on the time matrix, fixed_cost = the per-sortie time.
- OR-Tools 9.15 routing: arc cost = time matrix, SetFixedCostOfAllVehicles(per-sortie time), an "energy"
  dimension with the budget as capacity, first solution SAVINGS (it beat PATH_CHEAPEST_ARC and
  PARALLEL_CHEAPEST_INSERTION in a trial on these instances; ``--ortools-first`` to change), GUIDED_LOCAL_SEARCH,
  time limit; vehicles = 2 x a lower bound on the sorties + 3.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from planner.sortie_cost import EnergyBudget, FlightEnergyModel, SortieCost, default_sortie_cost
from planner.sorties import objective_matrices, plan_sorties, warm_up

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
AREA_M = (4000.0, 3000.0)
DEPOT_M = (0.0, 1500.0)
WIND_M_S = (3.5, 3.5)  # from the south-west, 4.9 m/s
MODEL = FlightEnergyModel(wind_east_m_s=WIND_M_S[0], wind_north_m_s=WIND_M_S[1], dwell_s=30.0)
TARGET_SORTIES = {50: 3, 100: 4, 200: 5}  # the battery is sized by this estimate: 4-8 sorties come out
RESERVE = 0.2
TIME_SCALE = 1000.0  # integer ms for the reference solvers
ENERGY_SCALE = 1e5  # integer 1e-5 Wh


def harbour_points(n_buoys: int, seed: int, layout: str = "uniform") -> np.ndarray:
    """Depot then n buoys, metres east/north, in the harbour area."""
    rng = np.random.default_rng(seed)
    if layout == "uniform":
        buoys = rng.uniform((0.0, 0.0), AREA_M, (n_buoys, 2))
    else:  # clusters: channel markers in groups of about 10 around random centres
        centres = rng.uniform((300.0, 300.0), (AREA_M[0] - 300.0, AREA_M[1] - 300.0), (max(2, n_buoys // 10), 2))
        buoys = centres[rng.integers(len(centres), size=n_buoys)] + rng.normal(0.0, 150.0, (n_buoys, 2))
        buoys = np.clip(buoys, (0.0, 0.0), AREA_M)
    buoys[:, 0] = np.maximum(buoys[:, 0], 1.0)  # never on the depot
    return np.vstack([DEPOT_M, buoys])


def harbour_instance(n_buoys: int, seed: int, layout: str = "uniform") -> SortieCost:
    """The instance with a battery sized for about TARGET_SORTIES[n] sorties (rounded up to 5 Wh), and never
    smaller than what the farthest buoy needs alone (plus 25 %)."""
    points = harbour_points(n_buoys, seed, layout)
    probe = default_sortie_cost(points, EnergyBudget(1e9, RESERVE), MODEL)
    # estimate of the whole work: a TSP through everything (Beardwood-Halton-Hammersley, 0.7124 sqrt(n A))
    tour_s = 0.7124 * math.sqrt(n_buoys * AREA_M[0] * AREA_M[1]) / MODEL.air_speed_m_s
    work_wh = MODEL.cruise_power_w * tour_s / 3600.0 + probe.dwell_energy_wh.sum()
    target = TARGET_SORTIES.get(n_buoys, max(3, n_buoys // 25))
    usable = max(work_wh / target + probe.sortie_energy_wh, 1.25 * probe.alone_energy_wh().max())
    capacity = 5.0 * math.ceil(usable / (1.0 - RESERVE) / 5.0)
    return default_sortie_cost(points, EnergyBudget(capacity, RESERVE), MODEL)


def integer_matrices(cost: SortieCost) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Time (ms, rounded) and energy (1e-5 Wh, rounded up) arc matrices, the fixed per-sortie time and the
    energy capacity (rounded down) for the reference solvers."""
    C, E, fixed, cap = objective_matrices(cost, "time")
    time_int = np.rint(C * TIME_SCALE).astype(np.int64)
    energy_int = np.ceil(E * ENERGY_SCALE - 1e-6).astype(np.int64)
    np.fill_diagonal(time_int, 0)
    np.fill_diagonal(energy_int, 0)
    return time_int, energy_int, round(fixed * TIME_SCALE), math.floor(cap * ENERGY_SCALE)


def sortie_lower_bound(cost: SortieCost) -> int:
    """Sorties needed at least: every buoy's cheapest arrival and service energy, over the budget for arcs."""
    _, E, _, cap = objective_matrices(cost, "time")
    arrivals = E[:, 1:] + np.diag(np.full(cost.n, np.inf))[:, 1:]
    return max(1, math.ceil(arrivals.min(axis=0).sum() / cap))


def solve_pyvrp(cost: SortieCost, time_limit_s: float, seed: int) -> list[list[int]]:
    import pyvrp
    from pyvrp.stop import MaxRuntime

    time_int, energy_int, fixed, cap = integer_matrices(cost)
    n = cost.n
    locations = [pyvrp.Location(x=0, y=0) for _ in range(n)]  # coordinates unused: the matrices are given
    depots = [pyvrp.Depot(location=0)]
    clients = [pyvrp.Client(location=i) for i in range(1, n)]
    vehicles = [
        pyvrp.VehicleType(
            num_available=n - 1,
            max_distance=cap,
            fixed_cost=fixed,
            unit_distance_cost=0,
            unit_duration_cost=1,
        )
    ]
    data = pyvrp.ProblemData(locations, clients, depots, vehicles, [energy_int], [time_int])
    result = pyvrp.solve(data, stop=MaxRuntime(time_limit_s), seed=seed, collect_stats=False, display=False)
    # a client activity's idx counts the clients from 0; client k is our node k + 1 (the depot is node 0)
    sorties = [[a.idx + 1 for a in route if a.is_client()] for route in result.best.routes()]
    assert abs(result.cost() - sum(time_int[a, b] for s in sorties for a, b in zip([0, *s], [*s, 0], strict=True))
               - fixed * len(sorties)) <= 1, "PyVRP's routes were read wrongly"  # fmt: skip
    return sorties


def ortools_search(routing, first: str, time_limit_s: float, solutions: int | None = None):
    """OR-Tools' routing search: the named first-solution strategy, then guided local search until the time
    limit (or after ``solutions`` solutions, if that comes first); the solution or None."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = getattr(routing_enums_pb2.FirstSolutionStrategy, first)
    params.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    params.time_limit.FromMilliseconds(int(time_limit_s * 1000))
    if solutions is not None:
        params.solution_limit = solutions
    return routing.SolveWithParameters(params)


def solve_ortools(cost: SortieCost, time_limit_s: float, seed: int, first: str = "SAVINGS") -> list[list[int]]:
    from ortools.constraint_solver import pywrapcp

    del seed  # OR-Tools' routing search is deterministic
    time_int, energy_int, fixed, cap = integer_matrices(cost)
    n = cost.n
    vehicles = min(n - 1, 2 * sortie_lower_bound(cost) + 3)
    manager = pywrapcp.RoutingIndexManager(n, vehicles, 0)
    routing = pywrapcp.RoutingModel(manager)
    time_cb = routing.RegisterTransitMatrix(time_int.tolist())
    routing.SetArcCostEvaluatorOfAllVehicles(time_cb)
    routing.SetFixedCostOfAllVehicles(fixed)
    energy_cb = routing.RegisterTransitMatrix(energy_int.tolist())
    routing.AddDimension(energy_cb, 0, cap, True, "energy")
    solution = ortools_search(routing, first, time_limit_s)
    if solution is None:
        return []
    sorties = []
    for v in range(vehicles):
        index = routing.Start(v)
        route = []
        while not routing.IsEnd(index):
            node = manager.IndexToNode(index)
            if node != 0:
                route.append(node)
            index = solution.Value(routing.NextVar(index))
        if route:
            sorties.append(route)
    return sorties


def solve_ours(cost: SortieCost, time_limit_s: float, seed: int) -> list[list[int]]:
    return plan_sorties(cost, time_limit_s=time_limit_s, seed=seed).sorties


SOLVERS = {"ours": solve_ours, "pyvrp": solve_pyvrp, "ortools": solve_ortools}


def judge(cost: SortieCost, sorties: list[list[int]]) -> dict:
    """Our checker's verdict and costs of any method's sorties."""
    problems = cost.violations(sorties) if sorties else ["no solution"]
    return {
        "feasible": not problems,
        "problems": problems[:3],
        "total_time_s": float(sum(cost.time_s(s) for s in sorties)),
        "total_distance_m": float(sum(cost.distance_m(s) for s in sorties)),
        "sorties": len(sorties),
        "max_energy_share": float(max((cost.energy_wh(s) for s in sorties), default=0.0) / cost.budget_wh),
    }


def run_case(n_buoys: int, seed: int, layout: str, limits: list[float], solvers: dict) -> dict:
    cost = harbour_instance(n_buoys, seed, layout)
    case = {"n_buoys": n_buoys, "seed": seed, "layout": layout, "budget_wh": cost.budget_wh, "runs": {}}
    for limit in limits:
        runs = {}
        for name, solver in solvers.items():
            started = time.perf_counter()
            sorties = solver(cost, limit, seed)
            verdict = judge(cost, sorties)
            verdict["wall_s"] = time.perf_counter() - started
            verdict["routes"] = sorties
            runs[name] = verdict
        best = min((r["total_time_s"] for r in runs.values() if r["feasible"]), default=math.nan)
        reference = min(
            (runs[k]["total_time_s"] for k in ("pyvrp", "ortools") if runs[k]["feasible"]), default=math.nan
        )
        for r in runs.values():
            r["gap_to_best_pct"] = 100.0 * (r["total_time_s"] / best - 1.0) if r["feasible"] else None
            r["gap_to_reference_pct"] = 100.0 * (r["total_time_s"] / reference - 1.0) if r["feasible"] else None
        case["runs"][str(limit)] = runs
    return case


def figure(cases: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = next((c for c in cases if c["n_buoys"] == 100), cases[0])
    points = harbour_points(shown["n_buoys"], shown["seed"], shown["layout"])
    limit = min(shown["runs"], key=float)
    fig = plt.figure(figsize=(16, 9))
    for k, name in enumerate(SOLVERS):
        ax = fig.add_subplot(2, 3, k + 1)
        run = shown["runs"][limit][name]
        colours = plt.get_cmap("tab10")
        for s, sortie in enumerate(run["routes"]):
            path_xy = points[[0, *sortie, 0]]
            ax.plot(path_xy[:, 0], path_xy[:, 1], "-o", ms=2.5, lw=1.2, color=colours(s % 10))
        ax.plot(*points[0], "k*", ms=14)
        ax.set_title(
            f"{name}: {run['sorties']} sorties, {run['total_time_s']:.0f} s"
            f"{'' if run['feasible'] else ' (INFEASIBLE)'}",
            fontsize=10,
        )
        ax.set_aspect("equal")
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
    ax = fig.add_subplot(2, 1, 2)
    labels, width = [], 0.8 / len(SOLVERS)
    rows = [(c, lim) for c in cases for lim in sorted(c["runs"], key=float)]
    for i, (case, lim) in enumerate(rows):
        labels.append(f"{case['n_buoys']} s{case['seed']} {case['layout'][:4]}\n{lim} s")
        for k, name in enumerate(SOLVERS):
            gap = case["runs"][lim][name]["gap_to_best_pct"]
            ax.bar(i + (k - 1) * width, gap if gap is not None else 0.0, width, color=f"C{k}",
                   hatch="" if gap is not None else "xx", label=name if i == 0 else None)  # fmt: skip
    ax.set_xticks(range(len(rows)), labels, fontsize=7)
    ax.set_ylabel("gap to the best of the three (%)")
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.legend()
    ax.grid(True, axis="y", alpha=0.3)
    fig.suptitle(
        f"Multi-sortie routing, total flight time; the {shown['n_buoys']}-buoy instance at {limit} s", fontsize=11
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def summary(cases: list[dict]) -> list[dict]:
    """Per size and limit: mean gap of ours to the better reference, of each method to the best, sorties."""
    rows = []
    for n in sorted({c["n_buoys"] for c in cases}):
        for lim in sorted({lim for c in cases for lim in c["runs"]}, key=float):
            chosen = [c["runs"][lim] for c in cases if c["n_buoys"] == n and lim in c["runs"]]
            row = {"n_buoys": n, "time_limit_s": float(lim), "instances": len(chosen)}
            for name in SOLVERS:
                gaps = [r[name]["gap_to_best_pct"] for r in chosen]
                row[f"{name}_feasible"] = sum(g is not None for g in gaps)
                row[f"{name}_mean_gap_pct"] = (
                    float(np.mean([g for g in gaps if g is not None])) if any(g is not None for g in gaps) else None
                )
                row[f"{name}_sorties"] = [r[name]["sorties"] for r in chosen]
            ours = [r["ours"]["gap_to_reference_pct"] for r in chosen if r["ours"]["gap_to_reference_pct"] is not None]
            row["ours_vs_better_reference_pct"] = ours
            row["ours_vs_better_reference_mean_pct"] = float(np.mean(ours)) if ours else None
            rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        prog="python -m bench.sorties", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="100 buoys, 2 seeds, 2 s only")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--ortools-first", default="SAVINGS", help="OR-Tools first solution strategy")
    args = parser.parse_args()
    sizes, seeds, limits = ([100], 2, [2.0]) if args.quick else ([50, 100, 200], args.seeds, [2.0, 10.0])
    solvers = {**SOLVERS, "ortools": functools.partial(solve_ortools, first=args.ortools_first)}
    warm_up()  # compile / load the numba kernels before any clock runs
    load_before = os.getloadavg()
    cases = []
    for n in sizes:
        for seed in range(seeds):
            layout = "uniform" if seed % 3 != 2 else "clustered"
            cases.append(run_case(n, seed, layout, limits, solvers))
            runs = cases[-1]["runs"]
            for lim, r in runs.items():
                print(
                    f"{n:4d} buoys seed {seed} {layout:9s} {lim:>4s} s: "
                    + "  ".join(
                        f"{k} {v['total_time_s']:8.1f} s {v['sorties']:2d} sorties"
                        f"{'' if v['feasible'] else ' INFEASIBLE'} ({v['gap_to_best_pct'] or 0:+.2f} %)"
                        for k, v in r.items()
                    ),
                    flush=True,
                )
    rows = summary(cases)
    print(
        "\n| buoys | limit | ours vs better of PyVRP/OR-Tools (mean, per instance) "
        "| gap to best: ours / PyVRP / OR-Tools | sorties ours / PyVRP / OR-Tools |"
    )
    print("| --- | --- | --- | --- | --- |")
    for row in rows:
        per = ", ".join(f"{g:+.2f}" for g in row["ours_vs_better_reference_pct"])
        mean = row["ours_vs_better_reference_mean_pct"]
        gaps = " / ".join(
            "n/a" if row[f"{k}_mean_gap_pct"] is None else f"{row[f'{k}_mean_gap_pct']:.2f} %" for k in SOLVERS
        )
        sorties = " / ".join(str(row[f"{k}_sorties"]) for k in SOLVERS)
        print(f"| {row['n_buoys']} | {row['time_limit_s']:.0f} s | {mean:+.2f} % ({per}) | {gaps} | {sorties} |")
    RESULTS.mkdir(parents=True, exist_ok=True)
    figure(cases, RESULTS / ("sorties_quick.png" if args.quick else "sorties.png"))
    report = {
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()},
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "quick": args.quick,
        "ortools_first_solution": args.ortools_first,
        "summary": rows,
        "cases": cases,
    }
    out = RESULTS / ("sorties_quick.json" if args.quick else "sorties.json")
    out.write_text(json.dumps(report, indent=1))
    print(f"load average before {load_before}, after {report['load_average_after']}; wrote {out.relative_to(REPO)}")


if __name__ == "__main__":
    main()
