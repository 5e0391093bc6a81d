"""Several vehicles share the buoys (issue 14, the planning core): ``plan_fleet``.

K vehicles, each starting and ending at its depot (one depot for all, or one each), visit every buoy once
between them; vehicle k's route takes

    T_k = takeoff_landing_s[k] + (its route's length) / speed_m_s[k] + sum of dwell_s over its buoys

(0 for a vehicle that gets no buoy: it stays on the ground), or, given ``leg_time_s`` (the time of each leg, one
matrix for every vehicle: planner.fleet_time builds it from the calibrated motion profiles, the stop at each buoy
included), the sum of its legs' times in place of length / speed. The plan minimises the makespan max_k T_k, the
time until the last vehicle is home, and then the total sum_k T_k. The method (route first, cluster second,
then improve, as planner.sorties):

1. a giant tour through every buoy and the first vehicle's depot (planner.sorties.giant_tour: 2-opt + Or-opt +
   ILS);
2. the exact min-max split of that order among the vehicles (planner.fleet_split), for a few rotations of the
   tour, both directions and a few orders of the vehicles (with several depots or speeds the order matters);
   the lexicographically best is kept;
3. inter- and intra-route local search for the min-max objective, then, until the time limit, SISR
   ruin-and-recreate with simulated-annealing acceptance (planner.fleet_search);
4. each vehicle's tour re-optimised by the single-tour planner (planner.sorties.reoptimise_sortie:
   Held-Karp up to 11 buoys, else the CHNN-GA), kept only if shorter.

Bad input raises InputError with a message naming the argument. Reproducible for a seed when stopped by
max_iterations (the annealing then follows the rounds, not the clock).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from planner.distances import check_points, euclidean_matrix
from planner.errors import InputError
from planner.fleet_search import local_search, search, update_score
from planner.fleet_split import minmax_split
from planner.local_search import neighbour_lists
from planner.sortie_cost import FlightEnergyModel
from planner.sortie_search import copy_solution, refresh, seed_rng
from planner.sorties import SortieSearchParameters, giant_tour, reoptimise_sortie, run_rounds
from planner.split import folded_matrices

_DEFAULT_FLIGHT = FlightEnergyModel()
DEFAULT_SPEED_M_S = _DEFAULT_FLIGHT.air_speed_m_s  # planner.scenario.CRUISE_SPEED_M_S
DEFAULT_DWELL_S = _DEFAULT_FLIGHT.dwell_s
DEFAULT_TAKEOFF_LANDING_S = _DEFAULT_FLIGHT.takeoff_s + _DEFAULT_FLIGHT.landing_s


@dataclass(frozen=True)
class FleetSearchParameters(SortieSearchParameters):
    """The sortie search's settings, plus the weight of the total time in the annealing's acceptance
    (makespan + total_weight x total: the total only steers among plans of about the same makespan) and how
    many rotations of the giant tour the split tries."""

    total_weight: float = 0.01
    split_rotations: int = 8
    split_vehicle_orders: int = 4  # with several depots, speeds or take-off times: orders of the vehicles tried


@dataclass
class VehicleRoute:
    """One vehicle's share: its buoys (node indices) in flying order from its depot and back."""

    vehicle: int
    depot: int
    buoys: list[int]
    time_s: float  # 0 when it has no buoy
    distance_m: float


@dataclass
class FleetPlan:
    routes: list[VehicleRoute]  # one per vehicle, in the order of depot_of_vehicle
    makespan_s: float  # the longest route: when the last vehicle is home
    total_time_s: float
    elapsed_s: float
    iterations: int  # ruin-and-recreate rounds
    split_makespan_s: float  # after route-first cluster-second, before the improvement
    history: list[dict] = field(default_factory=list)  # best makespan over time

    @property
    def total_distance_m(self) -> float:
        return float(sum(r.distance_m for r in self.routes))


@dataclass(frozen=True)
class Fleet:
    """The checked instance: the distances, each node's dwell, the vehicles' depots, 1 / speed and fixed time."""

    distance: np.ndarray  # (n, n) metres
    dwell: np.ndarray  # (n,) seconds, 0 at the depots
    depot: np.ndarray  # (K,) node index
    inv_speed: np.ndarray  # (K,) seconds per unit of `cost`
    cost: np.ndarray  # (n, n) what a leg costs before inv_speed: the distance, or the leg's time (inv_speed 1)
    fixed: np.ndarray  # (K,) seconds
    buoys: np.ndarray  # the nodes that are not depots

    def route_time(self, k: int, buoys) -> float:
        """T_k of vehicle k flying ``buoys`` in that order (0 when there is none)."""
        if len(buoys) == 0:
            return 0.0
        legs = self._path_sum(self.cost, k, buoys) * self.inv_speed[k]
        return float(self.fixed[k] + legs + self.dwell[list(buoys)].sum())

    def route_distance(self, k: int, buoys) -> float:
        return self._path_sum(self.distance, k, buoys)

    def _path_sum(self, matrix: np.ndarray, k: int, buoys) -> float:
        if len(buoys) == 0:
            return 0.0
        path = np.asarray([self.depot[k], *buoys, self.depot[k]])
        return float(matrix[path[:-1], path[1:]].sum())


def _per_vehicle(value, k: int, name: str, minimum: float, strict: bool) -> np.ndarray:
    """A number or one per vehicle, finite and above (strict) or at least the minimum."""
    try:
        values = np.broadcast_to(np.asarray(value, dtype=float), (k,)).copy()
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number or one number per vehicle ({k}); got {value!r}") from None
    bad = ~np.isfinite(values) | ((values <= minimum) if strict else (values < minimum))
    if bad.any():
        which = int(np.flatnonzero(bad)[0])
        relation = ">" if strict else ">="
        raise InputError(f"{name} of vehicle {which} must be finite and {relation} {minimum}; got {values[which]}")
    return values


def check_fleet(points, depot_of_vehicle, speed_m_s, dwell_s, takeoff_landing_s, leg_time_s=None) -> Fleet:
    """The instance as arrays, or InputError naming what is wrong."""
    pts = check_points(points)
    n = len(pts)
    distance = euclidean_matrix(pts)
    if leg_time_s is not None:
        leg_time_s = np.asarray(leg_time_s, dtype=float)
        if leg_time_s.shape != (n, n) or not np.all(np.isfinite(leg_time_s) & (leg_time_s >= 0)):
            raise InputError(f"leg_time_s must be a finite non-negative ({n}, {n}) matrix; got {leg_time_s.shape}")
        if not np.allclose(leg_time_s, leg_time_s.T):  # the search flies a stretch either way round at one cost
            raise InputError("leg_time_s must be symmetric (still air)")
    try:
        depots = np.asarray(depot_of_vehicle)
    except (TypeError, ValueError):
        depots = np.asarray([None])
    if depots.ndim != 1 or len(depots) == 0 or not np.issubdtype(depots.dtype, np.integer):
        raise InputError(f"depot_of_vehicle must be a non-empty list of node indices; got {depot_of_vehicle!r}")
    outside = np.flatnonzero((depots < 0) | (depots >= n))
    if len(outside):
        k = int(outside[0])
        raise InputError(f"depot_of_vehicle[{k}] = {depots[k]} is not a node index (0..{n - 1})")
    K = len(depots)
    is_depot = np.zeros(n, dtype=bool)
    is_depot[depots] = True
    if is_depot.all():
        raise InputError("every node is a depot: there is no buoy to visit")
    try:
        dwell = np.broadcast_to(np.asarray(dwell_s, dtype=float), (n,)).copy()
    except (TypeError, ValueError):
        raise InputError(f"dwell_s must be a number or one number per node ({n}); got {dwell_s!r}") from None
    if not np.all(np.isfinite(dwell) & (dwell >= 0)):
        raise InputError(f"dwell_s must be finite and >= 0; got {dwell_s!r}")
    dwell[is_depot] = 0.0
    inv_speed = 1.0 / _per_vehicle(speed_m_s, K, "speed_m_s", 0.0, strict=True)
    return Fleet(
        distance=distance,
        dwell=dwell,
        depot=depots.astype(np.int64),
        inv_speed=inv_speed if leg_time_s is None else np.ones(K),
        cost=distance if leg_time_s is None else np.ascontiguousarray(leg_time_s),
        fixed=_per_vehicle(takeoff_landing_s, K, "takeoff_landing_s", 0.0, strict=False),
        buoys=np.flatnonzero(~is_depot).astype(np.int64),
    )


def _split_candidates(
    fleet: Fleet, tour: np.ndarray, params: FleetSearchParameters, rng: np.random.Generator
) -> Iterator[tuple[list[list[int]], float, float]]:
    """(routes, makespan, total) of the min-max split for rotations and both directions of the buoy order
    ``tour``, and, when the vehicles differ, for a few orders of them (first: by where along the tour the
    buoy nearest to each depot lies)."""
    K = len(fleet.depot)
    nearest = np.argmin(fleet.distance[np.ix_(fleet.depot, tour)], axis=1)
    orders = [np.argsort(nearest, kind="stable")]
    alike = len(set(fleet.depot.tolist())) == 1 and np.ptp(fleet.inv_speed) == 0 and np.ptp(fleet.fixed) == 0
    if not alike:
        orders += [rng.permutation(K) for _ in range(params.split_vehicle_orders - 1)]
    m = len(tour)
    for shift in np.unique(np.linspace(0, m, params.split_rotations, endpoint=False).astype(int)):
        rotated = np.roll(tour, -shift)
        for order in (rotated, rotated[::-1]):
            for vehicles in orders:
                routes, makespan, total = minmax_split(
                    order, fleet.cost, fleet.dwell, fleet.depot[vehicles], fleet.inv_speed[vehicles],
                    fleet.fixed[vehicles],
                )  # fmt: skip
                by_vehicle: list[list[int]] = [[] for _ in range(K)]
                for position, k in enumerate(vehicles):
                    by_vehicle[k] = routes[position]
                yield by_vehicle, makespan, total


class _FleetSearch:
    """One instance's arrays for the numba kernels (planner.fleet_search): the problem, the candidate lists,
    the working solution and copies of the current and the best one."""

    def __init__(self, fleet: Fleet, routes: list[list[int]], params: FleetSearchParameters):
        n, K, m = len(fleet.distance), len(fleet.depot), len(fleet.buoys)
        D = np.ascontiguousarray(fleet.cost)
        _, W = folded_matrices(D, np.zeros(n), np.zeros((n, n)), fleet.dwell)
        self.problem = (D, W, fleet.dwell, fleet.inv_speed, fleet.fixed)
        self.buoys = fleet.buoys
        keyed = D.copy()
        keyed[:, fleet.depot] = np.inf  # candidates are buoys only: at most m - 1 of them (m >= 2)
        self.neighbours = neighbour_lists(keyed, min(params.neighbours, m - 1))
        self.adjacency = neighbour_lists(keyed, min(params.ruin_neighbours, m - 1))
        self.params = params
        width = m + 2
        self.sol = (
            np.zeros((K, width), dtype=np.int64),  # routes
            np.zeros(K, dtype=np.int64),  # rlen
            np.array([K, 0], dtype=np.int64),  # info: [routes, move counter]
            np.zeros(n, dtype=np.int64),  # route_of
            np.zeros(n, dtype=np.int64),  # pos
            np.zeros((4, K, width)),  # pref
            np.zeros(K, dtype=np.int64),  # stamp
            np.full(n, -1, dtype=np.int64),  # tested
            np.zeros(K),  # times
            np.zeros(2),  # score: [makespan, total]
        )
        for k, route in enumerate(routes):
            self.sol[0][k, : len(route) + 2] = [fleet.depot[k], *route, fleet.depot[k]]
            self.sol[1][k] = len(route) + 2
            refresh(k, self.sol[0], self.sol[1], self.sol[3], self.sol[4], self.sol[5], D, W)
        update_score(self.sol, fleet.inv_speed, fleet.fixed)
        self.buf = np.zeros((2, width), dtype=np.int64)
        self.cur = tuple(a.copy() for a in self.sol[:3])
        self.best = tuple(a.copy() for a in self.sol[:3])
        self.costs = np.zeros(3)  # [current annealing value, best makespan, best total]

    def _copy_to(self, target) -> None:
        copy_solution(*self.sol[:3], *target)

    def local_search(self) -> None:
        """Local search of the working solution, which then becomes the current and the best one."""
        local_search(self.problem, self.buoys, self.neighbours, self.sol, self.buf)
        self._copy_to(self.cur)
        self._copy_to(self.best)
        makespan, total = self.sol[9]
        self.costs[:] = makespan + self.params.total_weight * total, makespan, total

    def anneal(self, iterations: int, temp_start: float, temp_end: float) -> None:
        p = self.params
        search(self.problem, self.buoys, self.neighbours, self.adjacency, self.sol, self.buf, self.cur, self.best,
               self.costs, iterations, temp_start, temp_end,
               (p.mean_removed, p.max_string, p.blink, p.total_weight, p.local_search))  # fmt: skip

    def best_routes(self) -> list[list[int]]:
        routes, rlen, _ = self.best
        return [routes[k, 1 : rlen[k] - 1].tolist() for k in range(len(rlen))]


def _reoptimise(fleet: Fleet, k: int, buoys: list[int], seed: int, limit_s: float) -> list[int]:
    """Vehicle k's buoys in the single-tour planner's order (its depot as node 0 of the sub-problem)."""
    if len(buoys) < 3:
        return buoys
    nodes = np.array([fleet.depot[k], *buoys])
    sub = np.ascontiguousarray(fleet.cost[np.ix_(nodes, nodes)])
    local = list(range(1, len(nodes)))
    order = reoptimise_sortie(local, sub, np.zeros_like(sub), np.inf, seed, limit_s)
    return nodes[order].tolist()


def plan_fleet(
    points,
    depot_of_vehicle=(0,),
    speed_m_s=DEFAULT_SPEED_M_S,
    dwell_s=DEFAULT_DWELL_S,
    takeoff_landing_s=DEFAULT_TAKEOFF_LANDING_S,
    seed: int = 0,
    time_limit_s: float = 2.0,
    max_iterations: int | None = None,
    reoptimise: bool = True,
    params: FleetSearchParameters | None = None,
    leg_time_s=None,
) -> FleetPlan:
    """Share the buoys among the vehicles, minimising the makespan, then the total time.

    points: (n, 2) planar coordinates in metres; the nodes named in depot_of_vehicle are depots, every other
    node is a buoy. depot_of_vehicle: one depot node per vehicle (e.g. [0, 0, 0]: three vehicles at node 0).
    speed_m_s, takeoff_landing_s: a number or one per vehicle; dwell_s: a number or one per node (ignored at
    the depots). leg_time_s: None (legs at speed_m_s) or the (n, n) symmetric time of every leg, the same for
    every vehicle (speed_m_s is then not used). Stops at time_limit_s (wall clock, the whole call) or after
    max_iterations ruin-and-recreate rounds, whichever comes first. Raises InputError for bad input."""
    started = time.perf_counter()
    params = params or FleetSearchParameters()
    if not (isinstance(time_limit_s, int | float) and np.isfinite(time_limit_s) and time_limit_s > 0):
        raise InputError(f"time_limit_s must be a positive number of seconds; got {time_limit_s!r}")
    if max_iterations is not None and not (isinstance(max_iterations, int) and max_iterations >= 0):
        raise InputError(f"max_iterations must be None or a non-negative integer; got {max_iterations!r}")
    fleet = check_fleet(points, depot_of_vehicle, speed_m_s, dwell_s, takeoff_landing_s, leg_time_s)
    K, m = len(fleet.depot), len(fleet.buoys)
    rng = np.random.default_rng(seed)
    # 1-2: route first (through the buoys and the first depot), cluster second
    hub_and_buoys = np.array([fleet.depot[0], *fleet.buoys])
    sub = fleet.cost[np.ix_(hub_and_buoys, hub_and_buoys)]
    tour = hub_and_buoys[giant_tour(sub, "ils", seed, 0.1 * time_limit_s)[1:]]
    routes, split_makespan, _ = min(_split_candidates(fleet, tour, params, rng), key=lambda c: (c[1], c[2]))
    history = [{"elapsed_s": time.perf_counter() - started, "iterations": 0, "best": split_makespan}]
    if m < 2:  # one buoy: the split has tried it on every vehicle
        return _plan(fleet, routes, split_makespan, 0, history, started)
    # 3: local search, then ruin-and-recreate rounds under the annealing schedule
    seed_rng(seed)
    state = _FleetSearch(fleet, routes, params)
    state.local_search()
    history.append({"elapsed_s": time.perf_counter() - started, "iterations": 0, "best": float(state.costs[1])})
    flown = sum(fleet.route_time(k, r) - fleet.fixed[k] - fleet.dwell[r].sum() for k, r in enumerate(routes) if r)
    mean_arc = max(flown / (m + K), 1e-9)
    kept = params.reoptimise_s_per_sortie * K if reoptimise else 0.0
    search_end = max(time_limit_s - kept, 0.5 * time_limit_s)
    iterations = run_rounds(state.anneal, lambda: float(state.costs[1]), started, search_end, max_iterations,
                            mean_arc, params, history)  # fmt: skip
    best = state.best_routes()
    # 4: each vehicle's tour by the single-tour planner
    if reoptimise:
        share = max(1e-3, time_limit_s - (time.perf_counter() - started)) / K
        best = [_reoptimise(fleet, k, route, seed, share) for k, route in enumerate(best)]
    return _plan(fleet, best, split_makespan, iterations, history, started)


def _plan(fleet: Fleet, routes, split_makespan, iterations, history, started) -> FleetPlan:
    served = sorted(b for r in routes for b in r)
    assert served == fleet.buoys.tolist(), "the fleet planner lost or doubled a buoy"  # a bug, never bad input
    vehicles = [
        VehicleRoute(k, int(fleet.depot[k]), list(r), fleet.route_time(k, r), fleet.route_distance(k, r))
        for k, r in enumerate(routes)
    ]
    times = [v.time_s for v in vehicles]
    return FleetPlan(
        routes=vehicles,
        makespan_s=max(times),
        total_time_s=float(sum(times)),
        elapsed_s=time.perf_counter() - started,
        iterations=iterations,
        split_makespan_s=split_makespan,
        history=history,
    )


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every kernel on a tiny instance before a clock runs."""
    rng = np.random.default_rng(0)
    points = np.vstack([[0.0, 0.0], [50.0, 0.0], rng.uniform(-500.0, 500.0, (12, 2))])
    plan_fleet(points, [0, 1, 0], speed_m_s=[10.0, 12.0, 10.0], seed=0, time_limit_s=600.0, max_iterations=3)
