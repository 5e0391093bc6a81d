"""Multi-sortie planning: the exact split, feasibility, asymmetric costs, the single-sortie case, the unreachable
buoy, determinism, and optimality against an exhaustive search on tiny instances."""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from planner.errors import UnreachableBuoyError
from planner.sortie_cost import EnergyBudget, FlightEnergyModel, SortieCost, default_sortie_cost, ground_speed
from planner.sorties import SortieSearchParameters, objective_matrices, plan_sorties, warm_up
from planner.split import split_tour
from planner.tour import plan_tour

WINDY = FlightEnergyModel(wind_east_m_s=4.0, wind_north_m_s=-3.0, dwell_s=20.0)


def instance(n_buoys: int, seed: int, capacity_wh: float, model: FlightEnergyModel = WINDY, size: float = 2000.0):
    rng = np.random.default_rng(seed)
    points = np.vstack([[0.0, 0.0], rng.uniform(-size, size, (n_buoys, 2))])
    # never below what the farthest buoy needs alone (+5 %): every buoy reachable
    farthest = default_sortie_cost(points, EnergyBudget(1e9), model).alone_energy_wh().max()
    return default_sortie_cost(points, EnergyBudget(max(capacity_wh, 1.05 * farthest / 0.8), reserve=0.2), model)


def route_cost(route, M) -> float:
    return sum(M[a, b] for a, b in itertools.pairwise([0, *route, 0]))


def brute_force_split(order, C, E, fixed, cap) -> float:
    """Every way of cutting the order into consecutive sorties (2^(m-1) of them)."""
    m = len(order)
    best = np.inf
    for cuts in itertools.product((False, True), repeat=m - 1):
        bounds = [0, *[k + 1 for k, cut in enumerate(cuts) if cut], m]
        pieces = [order[a:b] for a, b in itertools.pairwise(bounds)]
        if all(route_cost(p, E) <= cap for p in pieces):
            best = min(best, sum(route_cost(p, C) + fixed for p in pieces))
    return best


def exhaustive_optimum(cost, objective: str) -> float:
    """The optimum over every partition of the buoys into sorties and every order of each sortie."""
    C, E, fixed, cap = objective_matrices(cost, objective)
    m = cost.n - 1
    single = np.full(1 << m, np.inf)  # best feasible order of each set of buoys
    for mask in range(1, 1 << m):
        members = [b + 1 for b in range(m) if mask >> b & 1]
        for order in itertools.permutations(members):
            if route_cost(order, E) <= cap:
                single[mask] = min(single[mask], route_cost(order, C) + fixed)
    best = np.full(1 << m, np.inf)
    best[0] = 0.0
    for mask in range(1, 1 << m):
        low = mask & -mask
        rest = mask ^ low
        sub = rest
        while True:  # every subset of mask that contains its lowest buoy
            chosen = sub | low
            best[mask] = min(best[mask], single[chosen] + best[mask ^ chosen])
            if sub == 0:
                break
            sub = (sub - 1) & rest
    return float(best[-1])


@pytest.mark.parametrize("seed", range(6))
def test_split_is_the_best_cut_of_its_order(seed):
    cost = instance(10, seed, capacity_wh=40.0)
    C, E, fixed, cap = objective_matrices(cost, "time")
    order = (np.random.default_rng(seed).permutation(10) + 1).tolist()
    sorties, total = split_tour(order, C, E, fixed, cap)
    assert [b for s in sorties for b in s] == order  # consecutive stretches of the order
    assert len(sorties) >= 2  # the budget does force a split
    assert total == pytest.approx(brute_force_split(order, C, E, fixed, cap), rel=1e-12)
    assert total == pytest.approx(sum(route_cost(s, C) + fixed for s in sorties), rel=1e-12)


@pytest.mark.parametrize(("n_buoys", "capacity"), [(30, 45.0), (60, 60.0), (120, 90.0)])
def test_every_sortie_fits_the_battery_and_every_buoy_is_served_once(n_buoys, capacity):
    cost = instance(n_buoys, 7, capacity_wh=capacity)
    plan = plan_sorties(cost, time_limit_s=0.5, seed=1)
    assert cost.violations(plan.sorties) == []
    assert sorted(b for s in plan.sorties for b in s) == list(range(1, n_buoys + 1))
    assert max(plan.energy_wh) <= cost.budget_wh
    assert len(plan.sorties) >= 2
    assert plan.cost == pytest.approx(plan.total_time_s, rel=1e-12)
    assert plan.cost <= plan.split_cost + 1e-9  # the improvement never loses what the split had


def test_constant_wind_gives_the_wind_triangle_and_asymmetric_legs():
    # along-track wind adds to the air speed, crosswind is crabbed away: v_g = w.u + sqrt(V_a^2 - |w_perp|^2)
    speed = ground_speed(10.0, np.array([4.0, -3.0]), np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]]))
    assert speed == pytest.approx([4.0 + np.sqrt(100 - 9), -4.0 + np.sqrt(100 - 9), -3.0 + np.sqrt(100 - 16)])
    cost = instance(6, 3, capacity_wh=1000.0)
    assert not np.allclose(cost.leg_time_s, cost.leg_time_s.T)
    # ... yet a closed sortie takes as long either way round: t = d (sqrt(V_a^2 - |w|^2 + (w.u)^2) - w.u) /
    # (V_a^2 - |w|^2), and the w.u terms sum to w . (total displacement) = 0 around a loop
    assert cost.time_s([1, 2, 3, 4]) == pytest.approx(cost.time_s([4, 3, 2, 1]), rel=1e-12)


def asymmetric_instance(n_buoys: int, seed: int, capacity_wh: float) -> SortieCost:
    """Leg times that are not a potential difference away from symmetric (e.g. wind that varies in space):
    reversing a sortie changes its cost."""
    rng = np.random.default_rng(seed)
    points = np.vstack([[0.0, 0.0], rng.uniform(-1200.0, 1200.0, (n_buoys, 2))])
    base = default_sortie_cost(points, EnergyBudget(capacity_wh), FlightEnergyModel(dwell_s=20.0))
    leg_time = base.leg_time_s * rng.uniform(0.8, 1.4, base.leg_time_s.shape)
    np.fill_diagonal(leg_time, 0.0)
    return replace(base, leg_time_s=leg_time, leg_energy_wh=leg_time * 160.0 / 3600.0)


def test_asymmetric_costs_are_flown_the_cheaper_way_round():
    cost = asymmetric_instance(6, 3, capacity_wh=1000.0)
    plan = plan_sorties(cost, time_limit_s=30.0, seed=0, max_iterations=200)
    (sortie,) = plan.sorties
    assert cost.time_s(sortie) < cost.time_s(sortie[::-1]) - 1.0  # reversing it is measurably slower
    assert plan.time_s[0] == pytest.approx(cost.time_s(sortie))
    assert plan.cost == pytest.approx(exhaustive_optimum(cost, "time"), rel=1e-9)


def test_a_battery_that_covers_everything_gives_one_sortie_equal_to_the_tsp_tour():
    still = FlightEnergyModel(dwell_s=15.0)
    cost = instance(12, 5, capacity_wh=1000.0, model=still)
    plan = plan_sorties(cost, time_limit_s=0.5, seed=0, max_iterations=100)
    assert len(plan.sorties) == 1
    tsp = plan_tour(distance=cost.leg_time_s, method="exact")
    assert plan.cost == pytest.approx(tsp.length + cost.sortie_time_s + cost.dwell_time_s.sum(), rel=1e-9)
    by_distance = plan_sorties(cost, objective="distance", time_limit_s=0.5, seed=0, max_iterations=100)
    assert by_distance.cost == pytest.approx(plan_tour(distance=cost.leg_distance_m, method="exact").length)


def test_a_buoy_out_of_reach_even_alone_is_named_with_its_shortfall():
    points = np.array([[0.0, 0.0], [500.0, 0.0], [9000.0, 0.0], [0.0, 700.0]])
    cost = default_sortie_cost(points, EnergyBudget(50.0, reserve=0.2), FlightEnergyModel())
    with pytest.raises(UnreachableBuoyError) as caught:
        plan_sorties(cost, time_limit_s=0.2)
    error = caught.value
    need = cost.alone_energy_wh()[2]
    assert error.buoys == [2]
    assert error.shortfall_wh == pytest.approx([need - 40.0])
    assert error.shortfall_pct == pytest.approx([100 * (need - 40.0) / 40.0])
    assert "buoy 2" in str(error) and f"{need - 40.0:.1f} Wh" in str(error)


def test_the_same_seed_gives_the_same_plan():
    cost = instance(50, 2, capacity_wh=50.0)
    warm_up()  # compiled before, so that a loaded machine's compile cannot eat the time limit of the first call
    # the rounds stop both runs; the time limit is only a backstop
    first = plan_sorties(cost, seed=4, time_limit_s=600.0, max_iterations=300)
    second = plan_sorties(cost, seed=4, time_limit_s=600.0, max_iterations=300)
    assert first.iterations == second.iterations == 300
    assert first.sorties == second.sorties
    assert first.cost == second.cost


# Odd seeds are asymmetric instances. The ones after the first three are those (of 120 tried) where the
# route-first start with its local search alone ends above the optimum: the search itself must close the gap.
@pytest.mark.parametrize(
    ("seed", "capacity", "objective"),
    [(100, 24.0, "time"), (102, 24.0, "distance"), (103, 24.0, "time"), (109, 40.0, "time"), (111, 40.0, "time"),
     (113, 40.0, "time"), (149, 40.0, "time"), (157, 30.0, "time")],
)  # fmt: skip
def test_tiny_instances_reach_the_exhaustive_optimum(seed, capacity, objective):
    cost = instance(7, seed, capacity_wh=capacity, size=1200.0)
    if seed % 2:
        cost = asymmetric_instance(7, seed, capacity_wh=cost.budget_wh / 0.8)
    optimum = exhaustive_optimum(cost, objective)
    plan = plan_sorties(cost, objective=objective, seed=0, time_limit_s=30.0, max_iterations=400)
    assert len(plan.sorties) >= 2  # the battery does force several sorties
    assert plan.cost == pytest.approx(optimum, rel=1e-9)


def test_the_local_search_leaves_no_improving_feasible_relocate_swap_or_reversal():
    """Brute force over every single-buoy relocation, swap and within-sortie reversal of the plan the local
    search ends on (full candidate lists, no ruin-and-recreate): none is both feasible and improving, so every
    move was priced right under asymmetric costs."""
    cost = asymmetric_instance(24, 8, capacity_wh=30.0)
    C, E, fixed, cap = objective_matrices(cost, "time")
    params = SortieSearchParameters(neighbours=24, ruin_neighbours=24)
    plan = plan_sorties(cost, seed=0, time_limit_s=30.0, max_iterations=0, reoptimise=False, params=params)
    assert len(plan.sorties) >= 3

    def total(sorties) -> float:
        return sum(route_cost(s, C) + fixed for s in sorties if s)

    def feasible(sorties) -> bool:
        return all(route_cost(s, E) <= cap for s in sorties if s)

    base = total(plan.sorties)
    assert base == pytest.approx(plan.cost, rel=1e-12)
    tried = 0
    for r, sortie in enumerate(plan.sorties):
        for k, buoy in enumerate(sortie):
            without = [list(s) for s in plan.sorties]
            del without[r][k]
            for s in range(len(without)):  # relocate
                for place in range(len(without[s]) + 1):
                    moved = [list(x) for x in without]
                    moved[s].insert(place, buoy)
                    tried += 1
                    assert not (feasible(moved) and total(moved) < base - 1e-6), (buoy, s, place)
        for i in range(len(sortie)):  # reversal of sortie[i..j]
            for j in range(i + 1, len(sortie)):
                turned = [list(s) for s in plan.sorties]
                turned[r][i : j + 1] = turned[r][i : j + 1][::-1]
                assert not (feasible(turned) and total(turned) < base - 1e-6), (r, i, j)
    for (r, a), (s, b) in itertools.combinations(
        [(r, k) for r, sortie in enumerate(plan.sorties) for k in range(len(sortie))], 2
    ):
        if r != s:  # swap
            swapped = [list(x) for x in plan.sorties]
            swapped[r][a], swapped[s][b] = swapped[s][b], swapped[r][a]
            assert not (feasible(swapped) and total(swapped) < base - 1e-6), (r, a, s, b)
    assert tried > 500
