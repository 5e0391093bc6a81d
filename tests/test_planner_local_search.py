"""2-opt / Or-opt / ILS kernels: they keep tours valid, report true lengths, and leave no improving move."""

import numpy as np
import pytest

from planner.distances import euclidean_matrix
from planner.local_search import iterated_local_search, local_search, neighbour_lists, tour_length


def instance(n: int, seed: int):
    dist = euclidean_matrix(np.random.default_rng(seed).uniform(0, 1000, (n, 2)))
    return dist, neighbour_lists(dist, n - 1)  # full lists: the local optimum is a true 2-opt/Or-opt one


def length(tour, dist) -> float:
    return float(dist[tour, np.roll(tour, -1)].sum())


def best_two_opt_gain(tour, dist) -> float:
    n = len(tour)
    best = 0.0
    for i in range(n - 1):
        for j in range(i + 2, n if i > 0 else n - 1):
            a, b, c, d = tour[i], tour[i + 1], tour[j], tour[(j + 1) % n]
            best = max(best, dist[a, b] + dist[c, d] - dist[a, c] - dist[b, d])
    return best


def best_or_opt_gain(tour, dist) -> float:
    """Best gain of moving a stretch of 1..3 cities elsewhere, either way round."""
    n = len(tour)
    best = 0.0
    for k in (1, 2, 3):
        for start in range(n):
            seg = [tour[(start + q) % n] for q in range(k)]
            rest = [tour[(start + k + q) % n] for q in range(n - k)]
            base = length(np.array(seg + rest), dist)
            for cut in range(1, len(rest)):
                for piece in (seg, seg[::-1]):
                    candidate = np.array(rest[:cut] + piece + rest[cut:])
                    best = max(best, base - length(candidate, dist))
    return best


@pytest.mark.parametrize("seed", range(5))
def test_local_search_reaches_a_two_opt_and_or_opt_optimum(seed):
    dist, neighbours = instance(25, seed)
    tour = np.random.default_rng(seed).permutation(25).astype(np.int64)
    start_length = length(tour, dist)
    result = local_search(tour, dist, neighbours)
    assert sorted(tour.tolist()) == list(range(25))
    assert result == pytest.approx(length(tour, dist))
    assert result < start_length
    assert best_two_opt_gain(tour, dist) < 1e-7
    assert best_or_opt_gain(tour, dist) < 1e-7


def test_iterated_local_search_never_gets_worse_and_stays_a_tour():
    dist, _ = instance(120, 11)
    neighbours = neighbour_lists(dist, 10)
    tour = np.random.default_rng(0).permutation(120).astype(np.int64)
    after_descent = local_search(tour, dist, neighbours)
    after_ils = iterated_local_search(tour, dist, neighbours, 2000, 30, 3)
    assert sorted(tour.tolist()) == list(range(120))
    assert after_ils == pytest.approx(length(tour, dist))
    assert after_ils < after_descent


def test_iterated_local_search_is_reproducible_with_a_seed():
    dist, _ = instance(60, 12)
    tours = []
    for _ in range(2):
        tour = np.arange(60, dtype=np.int64)
        iterated_local_search(tour, dist, neighbour_lists(dist, 8), 500, 10, 42)
        tours.append(tour.tolist())
    assert tours[0] == tours[1]


def test_tour_length_kernel_matches_numpy():
    dist, _ = instance(30, 13)
    tour = np.random.default_rng(1).permutation(30).astype(np.int64)
    assert tour_length(tour, dist) == pytest.approx(length(tour, dist))


def test_neighbour_lists_are_the_nearest_other_nodes():
    dist, _ = instance(15, 14)
    lists = neighbour_lists(dist, 4)
    for node in range(15):
        assert node not in lists[node]
        assert np.all(np.diff(dist[node, lists[node]]) >= 0)
        others = np.delete(dist[node], node)
        assert dist[node, lists[node][-1]] <= np.sort(others)[3] + 1e-12
