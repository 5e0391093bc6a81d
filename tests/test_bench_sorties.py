"""The multi-sortie benchmark's plumbing: the reference solvers are given our costs and read back correctly,
and every answer is judged by our own checker."""

import numpy as np

from bench.sorties import harbour_instance, integer_matrices, judge, solve_ortools, solve_pyvrp
from planner.sorties import objective_matrices


def test_integer_energies_never_understate_the_true_ones():
    cost = harbour_instance(30, 0)
    time_int, energy_int, fixed, cap = integer_matrices(cost)
    C, E, fixed_s, cap_wh = objective_matrices(cost, "time")
    assert np.all(energy_int / 1e5 >= E - 1e-12)  # a route within the integer budget is within the true one
    assert cap / 1e5 <= cap_wh
    assert np.abs(time_int / 1e3 - C).max() <= 5e-4 and fixed == round(fixed_s * 1e3)


def test_both_reference_solvers_return_complete_feasible_plans_read_in_our_node_numbers():
    cost = harbour_instance(25, 1)
    for solver in (solve_pyvrp, solve_ortools):
        verdict = judge(cost, solver(cost, 0.5, 0))  # solve_pyvrp also checks its reading against PyVRP's cost
        assert verdict["feasible"], (solver.__name__, verdict["problems"])
        assert verdict["sorties"] >= 2
