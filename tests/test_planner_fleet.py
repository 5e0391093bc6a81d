"""Fleet planning (issue 14): every buoy once, the makespan is the longest route, the exact min-max split,
the optimum on tiny instances against an exhaustive search, several depots, one vehicle = the single tour,
idle vehicles, determinism and typed errors for bad input."""

import itertools

import numpy as np
import pytest

from planner.errors import InputError
from planner.fleet import check_fleet, plan_fleet
from planner.fleet_split import minmax_split
from planner.tour import plan_tour


def uniform(n_buoys: int, seed: int, depots=((0.0, 0.0),), size: float = 600.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.vstack([np.asarray(depots, dtype=float), rng.uniform(-size, size, (n_buoys, 2))])


def route_time(points, depot, buoys, speed, dwell, fixed) -> float:
    """A route's time recomputed from the coordinates, independently of the planner."""
    if not buoys:
        return 0.0
    path = points[[depot, *buoys, depot]]
    return fixed + np.linalg.norm(np.diff(path, axis=0), axis=1).sum() / speed + dwell * len(buoys)


def exhaustive_optimum(points, depots, speeds, dwell, fixed) -> tuple[float, float]:
    """(makespan, total) lexicographic optimum over every assignment of the buoys to the vehicles and every
    order of each route: the best closed path of each vehicle through each set of buoys by a subset DP."""
    n, K = len(points), len(depots)
    buoys = [b for b in range(n) if b not in set(depots)]
    m = len(buoys)
    D = np.linalg.norm(points[:, None] - points[None], axis=-1)
    route = np.zeros((K, 1 << m))  # route[k, S]: vehicle k's least time through the set S
    for k, depot in enumerate(depots):
        ends = np.full((1 << m, m), np.inf)  # least path depot -> S ending at buoy j
        for j in range(m):
            ends[1 << j, j] = D[depot, buoys[j]]
        for mask in range(1, 1 << m):
            for j in range(m):
                if ends[mask, j] < np.inf:
                    for nxt in range(m):
                        if not mask >> nxt & 1:
                            step = ends[mask, j] + D[buoys[j], buoys[nxt]]
                            ends[mask | 1 << nxt, nxt] = min(ends[mask | 1 << nxt, nxt], step)
        for mask in range(1, 1 << m):
            closed = min(ends[mask, j] + D[buoys[j], depot] for j in range(m) if mask >> j & 1)
            route[k, mask] = fixed[k] + closed / speeds[k] + dwell * bin(mask).count("1")
    best = (np.inf, np.inf)
    for assignment in itertools.product(range(K), repeat=m):
        masks = [0] * K
        for j, k in enumerate(assignment):
            masks[k] |= 1 << j
        times = [route[k, masks[k]] for k in range(K)]
        best = min(best, (max(times), sum(times)))
    return best


def check_plan(plan, points, depots, speeds, dwell, fixed) -> None:
    """Every buoy exactly once; each route's time, recomputed, is the plan's; the makespan is the longest."""
    buoys = sorted(set(range(len(points))) - set(depots))
    assert sorted(b for r in plan.routes for b in r.buoys) == buoys
    assert [r.depot for r in plan.routes] == list(depots)
    for k, r in enumerate(plan.routes):
        assert r.vehicle == k
        assert r.time_s == pytest.approx(route_time(points, depots[k], r.buoys, speeds[k], dwell, fixed[k]), rel=1e-9)
    assert plan.makespan_s == max(r.time_s for r in plan.routes)
    assert plan.total_time_s == pytest.approx(sum(r.time_s for r in plan.routes), rel=1e-12)


@pytest.mark.parametrize(
    ("n_buoys", "depots", "speeds", "fixed"),
    [(60, [0, 0, 0, 0], [10.0] * 4, [24.0] * 4), (80, [0, 1, 2, 0], [10.0, 8.0, 12.0, 10.0], [24.0, 30.0, 0.0, 5.0])],
)
def test_every_buoy_is_served_once_and_the_makespan_is_the_longest_route(n_buoys, depots, speeds, fixed):
    points = uniform(n_buoys, 3, depots=[(0.0, 0.0), (400.0, 300.0), (-500.0, 100.0)][: len(set(depots))])
    plan = plan_fleet(points, depots, speed_m_s=speeds, dwell_s=15.0, takeoff_landing_s=fixed, time_limit_s=0.5)
    check_plan(plan, points, depots, speeds, 15.0, fixed)
    assert plan.makespan_s <= plan.split_makespan_s + 1e-9  # the improvement never loses what the split had
    assert sum(1 for r in plan.routes if r.buoys) == len(depots)  # with this many buoys every vehicle flies


def test_the_split_is_the_best_min_max_cut_of_its_order():
    points = uniform(9, 5, depots=[(0.0, 0.0), (300.0, -200.0)])
    fleet = check_fleet(points, [0, 1, 0], [10.0, 7.0, 12.0], 20.0, [24.0, 10.0, 40.0])
    order = np.random.default_rng(0).permutation(fleet.buoys)
    routes, makespan, total = minmax_split(order, fleet.distance, fleet.dwell, fleet.depot, fleet.inv_speed,
                                           fleet.fixed)  # fmt: skip
    assert [b for r in routes for b in r] == order.tolist()  # consecutive stretches, vehicles in order
    best = (np.inf, np.inf)
    for cuts in itertools.combinations_with_replacement(range(len(order) + 1), 2):  # every cut into 3 stretches
        bounds = [0, *cuts, len(order)]
        times = [fleet.route_time(k, order[a:b].tolist()) for k, (a, b) in enumerate(itertools.pairwise(bounds))]
        best = min(best, (max(times), sum(times)))
    assert (makespan, total) == pytest.approx(best, rel=1e-12)
    times = [fleet.route_time(k, r) for k, r in enumerate(routes)]
    assert (max(times), sum(times)) == pytest.approx((makespan, total), rel=1e-12)


# Tiny instances: two and three vehicles from one depot, then several depots with different speeds and
# take-off times. The first two seeds are arbitrary; the others are those (of 60 tried) where the split and its
# local search alone end above the optimum: the ruin-and-recreate must close the gap.
TINY = [
    (7, [0, 0], [10.0, 10.0], [24.0, 24.0], 11),
    (8, [0, 0, 0], [10.0, 10.0, 10.0], [24.0, 24.0, 24.0], 13),
    (7, [0, 0], [10.0, 10.0], [24.0, 24.0], 124),
    (7, [0, 0], [10.0, 10.0], [24.0, 24.0], 132),
    (8, [0, 1, 1], [10.0, 6.0, 14.0], [24.0, 0.0, 60.0], 118),
    (7, [0, 1], [9.0, 11.0], [30.0, 12.0], 139),
]


@pytest.mark.parametrize(("n_buoys", "depots", "speeds", "fixed", "seed"), TINY)
def test_tiny_instances_reach_the_exhaustive_min_max_optimum(n_buoys, depots, speeds, fixed, seed):
    points = uniform(n_buoys, seed, depots=[(0.0, 0.0), (350.0, -250.0)][: len(set(depots))])
    optimum = exhaustive_optimum(points, depots, speeds, 10.0, fixed)
    plan = plan_fleet(points, depots, speed_m_s=speeds, dwell_s=10.0, takeoff_landing_s=fixed, seed=0,
                      time_limit_s=60.0, max_iterations=300)  # fmt: skip
    check_plan(plan, points, depots, speeds, 10.0, fixed)
    assert plan.makespan_s == pytest.approx(optimum[0], rel=1e-9)
    assert plan.total_time_s == pytest.approx(optimum[1], rel=1e-9)  # and the least total among those


def test_several_depots_each_vehicle_serves_the_cluster_at_its_own_depot():
    rng = np.random.default_rng(4)
    depots_xy = np.array([[0.0, 0.0], [3000.0, 0.0], [0.0, 3000.0]])
    clusters = [centre + rng.uniform(-200.0, 200.0, (12, 2)) for centre in depots_xy]
    points = np.vstack([depots_xy, *clusters])
    plan = plan_fleet(points, [0, 1, 2], seed=1, time_limit_s=30.0, max_iterations=100)
    check_plan(plan, points, [0, 1, 2], [10.0] * 3, 10.0, [24.0] * 3)
    for k, route in enumerate(plan.routes):
        assert sorted(route.buoys) == list(range(3 + 12 * k, 3 + 12 * (k + 1)))


def test_one_vehicle_is_the_single_tour():
    points = uniform(12, 8)
    plan = plan_fleet(points, [0], speed_m_s=8.0, dwell_s=12.0, takeoff_landing_s=20.0, time_limit_s=30.0,
                      max_iterations=50)  # fmt: skip
    tour = plan_tour(points, method="exact")
    (route,) = plan.routes
    assert route.buoys in (tour.order[1:], tour.order[1:][::-1])
    assert route.distance_m == pytest.approx(tour.length, rel=1e-9)
    assert plan.makespan_s == pytest.approx(20.0 + tour.length / 8.0 + 12.0 * 12, rel=1e-9)


def test_more_vehicles_than_buoys_leaves_vehicles_idle_at_no_time():
    points = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 150.0], [-120.0, -20.0]])
    plan = plan_fleet(points, [0] * 5, time_limit_s=30.0, max_iterations=20)
    check_plan(plan, points, [0] * 5, [10.0] * 5, 10.0, [24.0] * 5)
    assert sorted(len(r.buoys) for r in plan.routes) == [0, 0, 1, 1, 1]  # one buoy each: the shortest makespan
    assert all(r.time_s == 0.0 and r.distance_m == 0.0 for r in plan.routes if not r.buoys)
    single = plan_fleet(points[:2], [0, 0], time_limit_s=5.0)  # one buoy: one vehicle flies
    assert sorted(len(r.buoys) for r in single.routes) == [0, 1]


def test_the_same_seed_gives_the_same_plan():
    points = uniform(70, 2)
    runs = [plan_fleet(points, [0, 0, 0], seed=5, time_limit_s=60.0, max_iterations=150) for _ in range(2)]
    assert runs[0].iterations == runs[1].iterations == 150
    assert [r.buoys for r in runs[0].routes] == [r.buoys for r in runs[1].routes]
    assert runs[0].makespan_s == runs[1].makespan_s


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"depot_of_vehicle": []}, "depot_of_vehicle must be a non-empty list"),
        ({"depot_of_vehicle": [0, 9]}, "depot_of_vehicle[1] = 9 is not a node index (0..3)"),
        ({"depot_of_vehicle": [0.5]}, "depot_of_vehicle must be a non-empty list"),
        ({"depot_of_vehicle": [0, 1, 2, 3]}, "every node is a depot"),
        ({"speed_m_s": [10.0, 0.0]}, "speed_m_s of vehicle 1 must be finite and > 0"),
        ({"speed_m_s": [10.0, 10.0, 10.0]}, "speed_m_s must be a number or one number per vehicle (2)"),
        ({"dwell_s": -1.0}, "dwell_s must be finite and >= 0"),
        ({"dwell_s": [1.0, 2.0]}, "dwell_s must be a number or one number per node (4)"),
        ({"takeoff_landing_s": float("nan")}, "takeoff_landing_s of vehicle 0 must be finite and >= 0"),
        ({"time_limit_s": 0}, "time_limit_s must be a positive number"),
        ({"max_iterations": -3}, "max_iterations must be None or a non-negative integer"),
        ({"points": [[0.0, 0.0], [1.0, 1.0], [1.0, 1.0], [2.0, 0.0]]}, "points [1, 2] are at the same place"),
        ({"points": [[0.0, 0.0]]}, "need a depot and at least one buoy"),
    ],
)
def test_bad_input_raises_input_error_naming_the_argument(kwargs, message):
    arguments = {"points": [[0.0, 0.0], [100.0, 0.0], [0.0, 100.0], [50.0, 50.0]], "depot_of_vehicle": [0, 0],
                 "time_limit_s": 1.0}  # fmt: skip
    arguments.update(kwargs)
    with pytest.raises(InputError) as caught:
        plan_fleet(**arguments)
    assert message in str(caught.value)
