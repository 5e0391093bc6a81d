"""Held-Karp against brute force, and the solvers against Held-Karp on many random small missions."""

import itertools

import numpy as np
import pytest

from planner import plan_tour
from planner.distances import closed_tour_length, euclidean_matrix, is_valid_tour
from planner.errors import TooLargeError
from planner.exact import EXACT_MAX_NODES, held_karp


def brute_force(dist: np.ndarray) -> float:
    n = len(dist)
    return min(closed_tour_length((0, *rest), dist) for rest in itertools.permutations(range(1, n)))


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6, 7, 8])
def test_held_karp_matches_brute_force(n):
    for seed in range(6):
        dist = euclidean_matrix(np.random.default_rng(seed).uniform(0, 1000, (n, 2)))
        order, length = held_karp(dist)
        assert is_valid_tour(order, n)
        assert length == pytest.approx(closed_tour_length(order, dist), rel=1e-12)
        assert length == pytest.approx(brute_force(dist), rel=1e-12)


def test_held_karp_handles_asymmetric_integer_matrices():
    rng = np.random.default_rng(3)
    dist = rng.integers(1, 100, (7, 7)).astype(float)
    np.fill_diagonal(dist, 0)
    order, length = held_karp(dist)
    assert length == brute_force(dist)
    assert closed_tour_length(order, dist) == length


def test_held_karp_refuses_more_than_its_limit():
    dist = euclidean_matrix(np.random.default_rng(0).uniform(0, 1, (EXACT_MAX_NODES + 1, 2)))
    with pytest.raises(TooLargeError, match="at most 16"):
        held_karp(dist)


@pytest.mark.parametrize("n", [4, 6, 9, 12, 14])
def test_chnn_ga_finds_the_optimum_of_small_missions(n):
    for seed in range(8):
        points = np.random.default_rng(100 * n + seed).uniform(0, 1000, (n, 2))
        _, optimum = held_karp(euclidean_matrix(points))
        result = plan_tour(points, method="chnn-ga", seed=seed, time_limit_s=10.0)
        assert is_valid_tour(result.order, n)
        assert result.length == pytest.approx(optimum, rel=1e-9)


def test_auto_is_exact_up_to_sixteen_nodes_and_chnn_ga_beyond():
    rng = np.random.default_rng(7)
    small = plan_tour(rng.uniform(0, 100, (16, 2)), method="auto")
    large = plan_tour(rng.uniform(0, 100, (17, 2)), method="auto", time_limit_s=5.0)
    assert small.method == "exact"
    assert large.method == "chnn-ga"
    assert is_valid_tour(large.order, 17)
