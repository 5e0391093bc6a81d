"""The fleet benchmark's plumbing: the reference solvers are given our times and read back in our node numbers,
and every answer is judged by our own evaluator."""

import functools

import numpy as np
import pytest

from bench.fleet import instance, integer_times, judge, solve_ortools, solve_pyvrp


def test_integer_arcs_add_up_to_our_route_time():
    _, fleet = instance(20, 3, 0)
    times = integer_times(fleet)
    route = [5, 2, 17, 9]
    arcs = sum(times[a, b] for a, b in zip([0, *route], [*route, 0], strict=True))
    assert arcs / 1e3 == pytest.approx(fleet.route_time(0, route), abs=5 * 5e-4)  # 5 arcs rounded to the ms
    assert np.all(np.diag(times) == 0)


def test_both_reference_solvers_return_complete_plans_for_the_fleet():
    points, fleet = instance(25, 3, 1)
    # counted searches (PyVRP iterations, OR-Tools solutions), not a time limit: a loaded machine must get the
    # same answers (OR-Tools' first solution alone flies one vehicle); 60 s is only a backstop
    pyvrp = functools.partial(solve_pyvrp, iterations=100)
    ortools = functools.partial(solve_ortools, solutions=100)
    for solver in (pyvrp, ortools):
        verdict = judge(fleet, solver(fleet, points, 60.0, 0))
        assert verdict["feasible"], solver.func.__name__
        assert verdict["flying"] >= 2  # the min-max objective puts more than one vehicle in the air
