"""Fleet benchmark: our min-max plan against PyVRP and OR-Tools on the same instances, same time limits.

    .venv/bin/python -m bench.fleet            # 3 / 5 / 10 vehicles x 60 / 150 / 300 buoys x 2 seeds x 2 s, 10 s
    .venv/bin/python -m bench.fleet --quick    # 5 vehicles, 60 and 150 buoys, 1 seed, 2 s (writes *_quick.*)

Prints the table, writes bench/results/fleet.json (with the machine and its load average) and
bench/results/fleet.png (the routes of the three methods on one instance, and every instance's gaps).
The planned makespan against the flown one (fleet missions through the whole stack) is bench/fleet_flown.py.

Instances: n buoys uniform in the reference area (planner.scenario.random_area_points: 1200 m x 700 m, the depot
at its reference place), K identical vehicles at that depot, 10 m/s, 10 s dwell per buoy, 24 s take-off and
landing per flying vehicle (the planner's defaults). Objective: the makespan (the time until the last vehicle
is home), then the total time. Every method's answer is re-checked (every buoy once) and re-timed by OUR
evaluator in floating point (planner.fleet.Fleet.route_time).

The reference solvers get the same times, in integer ms: arc i -> j takes d_ij / speed + dwell_j, and an arc
leaving the depot for a buoy also carries the take-off and landing time, so a route's arcs add up to its time
and an idle vehicle costs nothing.
- OR-Tools 9.15 routing, the closest min-max objective it offers: a "time" dimension over those arcs with
  SetGlobalSpanCostCoefficient(100) (the span cost is 100 x (latest end - earliest start) = 100 x makespan,
  all vehicles start at 0), plus the arcs' total as the arc cost (the tie-break); first solution
  PATH_CHEAPEST_ARC (``--ortools-first`` to change), GUIDED_LOCAL_SEARCH, the time limit.
- PyVRP 0.14 (hybrid genetic search) minimises a total cost only; it has no min-max objective. We bisect on
  its per-vehicle maximum duration (VehicleType.shift_duration) within the same wall-clock limit: a first
  solve without the bound (least total time; its makespan is the first upper bound), then solves with the
  bound halfway between the best makespan found and a lower bound (max of the farthest buoy alone and the
  first total / K), each solve with an equal share of the limit; the best feasible answer's makespan counts.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from bench.sorties import ortools_search
from planner.fleet import Fleet, check_fleet, plan_fleet, warm_up
from planner.scenario import random_area_points

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
SPEED_M_S, DWELL_S, TAKEOFF_LANDING_S = 10.0, 10.0, 24.0
TIME_SCALE = 1000.0  # integer ms for the reference solvers
SPAN_COEFFICIENT = 100  # OR-Tools: the makespan weighs 100 x the total
PYVRP_SOLVES = 6  # PyVRP: one unbounded solve and five bisection steps share the limit
GAP_AXIS_PCT = 40.0  # the figure's gap axis: OR-Tools' larger gaps are written on their bars


def fleet_points(n_buoys: int, seed: int) -> np.ndarray:
    """The depot (node 0, at the reference depot) then n buoys uniform in the reference area, metres."""
    return np.vstack([[0.0, 0.0], random_area_points(n_buoys, np.random.default_rng(seed))])


def instance(n_buoys: int, vehicles: int, seed: int) -> tuple[np.ndarray, Fleet]:
    points = fleet_points(n_buoys, seed)
    return points, check_fleet(points, [0] * vehicles, SPEED_M_S, DWELL_S, TAKEOFF_LANDING_S)


def integer_times(fleet: Fleet) -> np.ndarray:
    """Arc times in ms with the arriving buoy's dwell, and the take-off/landing on the arcs leaving the depot
    (identical vehicles at depot 0)."""
    seconds = fleet.distance * fleet.inv_speed[0] + fleet.dwell[None, :]
    seconds[0, 1:] += fleet.fixed[0]
    times = np.rint(seconds * TIME_SCALE).astype(np.int64)
    np.fill_diagonal(times, 0)
    return times


def solve_ours(fleet: Fleet, points: np.ndarray, time_limit_s: float, seed: int) -> list[list[int]]:
    plan = plan_fleet(points, [0] * len(fleet.depot), SPEED_M_S, DWELL_S, TAKEOFF_LANDING_S, seed, time_limit_s)
    return [r.buoys for r in plan.routes]


def solve_ortools(
    fleet: Fleet, points, time_limit_s: float, seed: int, first: str = "PATH_CHEAPEST_ARC", solutions: int | None = None
):
    """OR-Tools within the time limit, or (``solutions``) after that many solutions, a reproducible search
    whatever the machine's load (the time limit is then a backstop)."""
    from ortools.constraint_solver import pywrapcp

    del points, seed  # OR-Tools' routing search is deterministic
    times = integer_times(fleet)
    K = len(fleet.depot)
    manager = pywrapcp.RoutingIndexManager(len(times), K, 0)
    routing = pywrapcp.RoutingModel(manager)
    transit = routing.RegisterTransitMatrix(times.tolist())
    routing.SetArcCostEvaluatorOfAllVehicles(transit)
    routing.AddDimension(transit, 0, int(times.sum()), True, "time")
    routing.GetDimensionOrDie("time").SetGlobalSpanCostCoefficient(SPAN_COEFFICIENT)
    solution = ortools_search(routing, first, time_limit_s, solutions)
    if solution is None:
        return []
    routes = []
    for v in range(K):
        index, route = solution.Value(routing.NextVar(routing.Start(v))), []
        while not routing.IsEnd(index):
            route.append(manager.IndexToNode(index))
            index = solution.Value(routing.NextVar(index))
        routes.append(route)
    return routes


def _pyvrp_solve(times: np.ndarray, K: int, shift_ms: int | None, limit_s: float, seed: int, iterations: int | None):
    import pyvrp
    from pyvrp.stop import MaxIterations, MaxRuntime

    n = len(times)
    bound = {} if shift_ms is None else {"shift_duration": int(shift_ms)}
    data = pyvrp.ProblemData(
        [pyvrp.Location(x=0, y=0) for _ in range(n)],  # coordinates unused: the matrices are given
        [pyvrp.Client(location=i) for i in range(1, n)],
        [pyvrp.Depot(location=0)],
        [pyvrp.VehicleType(num_available=K, unit_distance_cost=1, **bound)],
        [times],
        [times],
    )
    stop = MaxRuntime(limit_s) if iterations is None else MaxIterations(iterations)
    result = pyvrp.solve(data, stop=stop, seed=seed, collect_stats=False, display=False)
    if not result.is_feasible():
        return None
    # a client activity's idx counts the clients from 0; client k is our node k + 1 (the depot is node 0)
    return [[a.idx + 1 for a in route if a.is_client()] for route in result.best.routes()]


def solve_pyvrp(fleet: Fleet, points, time_limit_s: float, seed: int, iterations: int | None = None) -> list[list[int]]:
    """Bisection on the per-vehicle maximum duration (PyVRP minimises the total only); see the module doc.
    With ``iterations`` each solve stops after that many iterations and every bisection step runs: a
    reproducible search whatever the machine's load (the time limit is then ignored)."""
    import pyvrp  # noqa: F401  (imported before the clock starts: a first import is not search time)

    del points
    started = time.perf_counter()
    times, K = integer_times(fleet), len(fleet.depot)

    def makespan(routes) -> int:
        return max(sum(times[a, b] for a, b in zip([0, *r], [*r, 0], strict=True)) for r in routes)

    share = time_limit_s / PYVRP_SOLVES
    best = _pyvrp_solve(times, K, None, share, seed, iterations)
    high = makespan(best)
    total = sum(times[a, b] for r in best for a, b in zip([0, *r], [*r, 0], strict=True))
    low = max(int((times[0, 1:] + times[1:, 0]).max()), math.ceil(total / K)) - 1  # infeasible below
    for _ in range(PYVRP_SOLVES - 1):
        in_time = iterations is not None or time.perf_counter() - started + share <= time_limit_s * 1.02
        if high - low <= 1 or not in_time:
            break
        bound = (low + high) // 2
        routes = _pyvrp_solve(times, K, bound, share, seed, iterations)
        if routes is None:
            low = bound
        else:
            best, high = routes, makespan(routes)
    return [r for r in best if r] + [[] for _ in range(K - sum(1 for r in best if r))]


SOLVERS = {"ours": solve_ours, "pyvrp": solve_pyvrp, "ortools": solve_ortools}


def judge(fleet: Fleet, routes: list[list[int]]) -> dict:
    """Our evaluator's verdict and times of any method's routes (vehicles are identical: any order)."""
    served = sorted(b for r in routes for b in r)
    times = [fleet.route_time(0, r) for r in routes]
    return {
        "feasible": served == fleet.buoys.tolist() and len(routes) <= len(fleet.depot),
        "makespan_s": max(times, default=math.inf),
        "total_time_s": float(sum(times)),
        "flying": sum(1 for r in routes if r),
    }


def run_case(vehicles: int, n_buoys: int, seed: int, limits: list[float], solvers: dict) -> dict:
    points, fleet = instance(n_buoys, vehicles, seed)
    case = {"vehicles": vehicles, "n_buoys": n_buoys, "seed": seed, "runs": {}}
    for limit in limits:
        runs = {}
        for name, solver in solvers.items():
            started = time.perf_counter()
            routes = solver(fleet, points, limit, seed)
            runs[name] = {**judge(fleet, routes), "wall_s": time.perf_counter() - started, "routes": routes}
        feasible = {k: r["makespan_s"] for k, r in runs.items() if r["feasible"]}
        best = min(feasible.values(), default=math.nan)
        reference = min((feasible[k] for k in ("pyvrp", "ortools") if k in feasible), default=math.nan)
        for name, r in runs.items():
            r["gap_to_best_pct"] = 100.0 * (r["makespan_s"] / best - 1.0) if name in feasible else None
            r["gap_to_reference_pct"] = 100.0 * (r["makespan_s"] / reference - 1.0) if name in feasible else None
        case["runs"][str(limit)] = runs
    return case


def summary(cases: list[dict]) -> list[dict]:
    """Per fleet size, buoys and limit: mean makespan of each method and ours against the better reference."""
    rows = []
    keys = sorted({(c["vehicles"], c["n_buoys"], float(lim)) for c in cases for lim in c["runs"]})
    for vehicles, n, lim in keys:
        chosen = [c["runs"][str(lim)] for c in cases if c["vehicles"] == vehicles and c["n_buoys"] == n]
        row = {"vehicles": vehicles, "n_buoys": n, "time_limit_s": lim, "instances": len(chosen)}
        for name in SOLVERS:
            row[f"{name}_makespan_s"] = [r[name]["makespan_s"] if r[name]["feasible"] else None for r in chosen]
        gaps = [r["ours"]["gap_to_reference_pct"] for r in chosen if r["ours"]["gap_to_reference_pct"] is not None]
        row["ours_vs_better_reference_pct"] = gaps
        row["ours_vs_better_reference_mean_pct"] = float(np.mean(gaps)) if gaps else None
        rows.append(row)
    return rows


def figure(cases: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = next((c for c in cases if c["vehicles"] == 5 and c["n_buoys"] == 150), cases[0])
    points = fleet_points(shown["n_buoys"], shown["seed"])
    limit = min(shown["runs"], key=float)
    fig = plt.figure(figsize=(16, 9))
    for k, name in enumerate(SOLVERS):
        ax = fig.add_subplot(2, 3, k + 1)
        run = shown["runs"][limit][name]
        for v, route in enumerate(run["routes"]):
            xy = points[[0, *route, 0]]
            ax.plot(xy[:, 0], xy[:, 1], "-o", ms=2.5, lw=1.2, color=plt.get_cmap("tab10")(v % 10))
        ax.plot(*points[0], "k*", ms=14)
        infeasible = "" if run["feasible"] else " (INFEASIBLE)"
        ax.set_title(f"{name}: makespan {run['makespan_s']:.0f} s, total {run['total_time_s']:.0f} s{infeasible}",
                     fontsize=10)  # fmt: skip
        ax.set_aspect("equal")
        ax.set_xlabel("east of the depot (m)")
        ax.set_ylabel("north (m)")
    ax = fig.add_subplot(2, 1, 2)
    rows = [(c, lim) for c in cases for lim in sorted(c["runs"], key=float)]
    width = 0.8 / len(SOLVERS)
    for i, (case, lim) in enumerate(rows):
        for k, name in enumerate(SOLVERS):
            gap = case["runs"][lim][name]["gap_to_best_pct"]
            shown_gap = min(gap, GAP_AXIS_PCT) if gap is not None else 0.0
            ax.bar(i + (k - 1) * width, shown_gap, width, color=f"C{k}", hatch="" if gap is not None else "xx",
                   label=name if i == 0 else None)  # fmt: skip
            if gap is not None and gap > GAP_AXIS_PCT:  # off the axis: its value written at the top
                ax.text(i + (k - 1) * width, GAP_AXIS_PCT, f"{gap:.0f}", rotation=90, ha="center", va="top",
                        fontsize=6, color="white")  # fmt: skip
    labels = [f"K{c['vehicles']} n{c['n_buoys']} s{c['seed']} {float(lim):.0f} s" for c, lim in rows]
    ax.set_xticks(range(len(rows)), labels, fontsize=7, rotation=90)
    ax.set_ylim(0, GAP_AXIS_PCT)
    ax.set_ylabel(f"makespan gap to the best of the three (%, cut at {GAP_AXIS_PCT:.0f})")
    ax.legend()
    ax.grid(True, axis="y", alpha=0.3)
    fig.suptitle(f"Fleet min-max routing; {shown['vehicles']} vehicles, {shown['n_buoys']} buoys at {limit} s")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _fmt(values) -> str:
    known = [v for v in values if v is not None]
    return f"{np.mean(known):.1f}" if len(known) == len(values) else f"{np.mean(known):.1f} ({len(known)} ok)"


def main() -> None:
    parser = argparse.ArgumentParser(
        prog="python -m bench.fleet", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="5 vehicles, 60 and 150 buoys, 1 seed, 2 s")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--ortools-first", default="PATH_CHEAPEST_ARC", help="OR-Tools first solution strategy")
    args = parser.parse_args()
    fleets, sizes, seeds, limits = ([5], [60, 150], 1, [2.0]) if args.quick else ([3, 5, 10], [60, 150, 300],
                                                                                  args.seeds, [2.0, 10.0])  # fmt: skip
    solvers = {**SOLVERS, "ortools": lambda *a: solve_ortools(*a, first=args.ortools_first)}
    warm_up()  # compile / load the numba kernels before any clock runs
    load_before = os.getloadavg()
    cases = []
    for vehicles in fleets:
        for n in sizes:
            for seed in range(seeds):
                cases.append(run_case(vehicles, n, seed, limits, solvers))
                for lim, r in cases[-1]["runs"].items():
                    print(f"{vehicles:2d} vehicles {n:3d} buoys seed {seed} {lim:>4s} s: " + "  ".join(
                        f"{k} {v['makespan_s']:7.1f} s{'' if v['feasible'] else ' INFEASIBLE'}"
                        f" ({v['gap_to_best_pct'] or 0:+.2f} %)" for k, v in r.items()), flush=True)  # fmt: skip
    rows = summary(cases)
    print("\n| vehicles | buoys | limit | makespan (s) ours / PyVRP / OR-Tools, mean | ours vs better reference |")
    print("| --- | --- | --- | --- | --- |")
    for row in rows:
        spans = " / ".join(_fmt(row[f"{k}_makespan_s"]) for k in SOLVERS)
        per = ", ".join(f"{g:+.2f}" for g in row["ours_vs_better_reference_pct"])
        mean = row["ours_vs_better_reference_mean_pct"]
        print(f"| {row['vehicles']} | {row['n_buoys']} | {row['time_limit_s']:.0f} s | {spans} "
              f"| {mean:+.2f} % ({per}) |")  # fmt: skip
    RESULTS.mkdir(parents=True, exist_ok=True)
    stem = "fleet_quick" if args.quick else "fleet"
    figure(cases, RESULTS / f"{stem}.png")
    report = {
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()},
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "quick": args.quick,
        "ortools_first_solution": args.ortools_first,
        "summary": rows,
        "cases": cases,
    }
    out = RESULTS / f"{stem}.json"
    out.write_text(json.dumps(report, indent=1))
    print(f"load average before {load_before}, after {report['load_average_after']}; wrote {out.relative_to(REPO)}")


if __name__ == "__main__":
    main()
