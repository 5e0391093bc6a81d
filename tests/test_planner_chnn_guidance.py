"""The CHNN as a prior on edges (planner.chnn_guidance, planner.edge_crossover) and the GA options using it."""

import numpy as np
import pytest

from planner import chnn
from planner.chnn_ga import GAParameters, _candidate_lists, _edge_prior, chnn_ga
from planner.chnn_guidance import (
    Windows,
    edge_frequencies,
    guided_neighbour_lists,
    neighbourhood_edge_frequencies,
)
from planner.distances import euclidean_matrix
from planner.edge_crossover import edge_crossover
from planner.local_search import neighbour_lists


def points_dist(n: int, seed: int) -> np.ndarray:
    return euclidean_matrix(np.random.default_rng(seed).uniform(0, 1000, (n, 2)))


def tour_edges(tour) -> set[frozenset]:
    tour = list(tour)
    return {frozenset((a, b)) for a, b in zip(tour, tour[1:] + tour[:1], strict=True)}


def test_a_permutation_matrix_gives_frequency_one_on_its_tour_edges_and_zero_elsewhere():
    n = 7
    order = np.array([3, 0, 5, 1, 4, 2])  # row (buoy) visited in each position
    v = np.zeros((1, n - 1, n - 1))
    v[0, order, np.arange(n - 1)] = 1.0
    frequencies = edge_frequencies(v, Windows.whole_tour(n, 1), n)
    tour = [0, *(order + 1)]  # free rows are nodes 1..n-1, depot clamped at both ends
    expected = np.zeros((n, n))
    for edge in tour_edges(tour):
        a, b = tuple(edge)
        expected[a, b] = expected[b, a] = 1.0
    assert frequencies == pytest.approx(expected)


def test_frequencies_average_over_the_networks_that_see_the_edge():
    n = 5
    v = np.zeros((2, n - 1, n - 1))
    v[0, [0, 1, 2, 3], np.arange(4)] = 1.0  # tour 0 1 2 3 4
    v[1, [1, 0, 2, 3], np.arange(4)] = 1.0  # tour 0 2 1 3 4
    frequencies = edge_frequencies(v, Windows.whole_tour(n, 2), n)
    assert frequencies[1, 2] == pytest.approx(1.0)  # in both
    assert frequencies[0, 1] == pytest.approx(0.5) and frequencies[2, 3] == pytest.approx(0.5)
    assert frequencies[1, 3] == pytest.approx(0.5) and frequencies[0, 2] == pytest.approx(0.5)


def test_neighbourhood_windows_cover_every_node_and_clamp_their_centre():
    dist = points_dist(80, 1)
    windows = Windows.neighbourhoods(dist, 12, np.random.default_rng(0))
    assert set(np.concatenate([windows.free.ravel(), windows.start])) == set(range(80))
    assert np.array_equal(windows.start, windows.end)
    assert all(centre not in free for centre, free in zip(windows.start, windows.free, strict=True))
    assert len(windows.start) < 80  # a cover, not one network per node


def test_neighbourhood_frequencies_are_symmetric_probabilities_and_deterministic_per_seed():
    dist = points_dist(60, 2)
    first = neighbourhood_edge_frequencies(dist, 12, chnn.VALID_TOURS, np.random.default_rng(3))
    again = neighbourhood_edge_frequencies(dist, 12, chnn.VALID_TOURS, np.random.default_rng(3))
    assert np.array_equal(first, again)
    assert np.allclose(first, first.T) and first.min() >= 0.0 and first.max() <= 1.0
    assert np.all(np.diag(first) == 0.0)
    # a sub-tour through its window: every node is used by some network, with about two edges
    assert np.all(first.sum(axis=1) > 0.5)


def test_guided_lists_take_the_chnn_partner_even_when_it_is_not_near_and_stay_sorted_by_distance():
    n, k = 40, 6
    dist = points_dist(n, 4)
    nearest = neighbour_lists(dist, n - 1)
    frequencies = np.zeros((n, n))
    far = nearest[:, -1]  # every node's farthest node becomes its likeliest CHNN partner
    frequencies[np.arange(n), far] = 1.0
    lists = guided_neighbour_lists(dist, frequencies, k, k_chnn=2)
    for x in range(n):
        row = lists[x].tolist()
        assert far[x] in row and x not in row and len(set(row)) == k
        assert row[:-1] == nearest[x, : k - 1].tolist()  # the rest of the list: the nearest nodes
        assert np.all(np.diff(dist[x, row]) >= 0)
    assert np.array_equal(guided_neighbour_lists(dist, frequencies, k, k_chnn=0), neighbour_lists(dist, k))


def test_the_candidate_option_changes_the_lists_only_when_the_chnn_is_on():
    dist = points_dist(60, 5)
    rng = np.random.default_rng(0)
    on = GAParameters(chnn_candidates=5)
    prior = _edge_prior(dist, None, on, chnn.VALID_TOURS, rng)
    assert prior is not None
    assert not np.array_equal(_candidate_lists(dist, prior, on), neighbour_lists(dist, on.neighbours))
    assert _edge_prior(dist, None, GAParameters(), chnn.VALID_TOURS, rng) is None
    assert _edge_prior(dist, None, GAParameters(use_chnn=False, chnn_candidates=5), chnn.VALID_TOURS, rng) is None


def test_edge_crossover_of_a_tour_with_itself_keeps_its_edges():
    dist = points_dist(30, 6)
    parent = np.random.default_rng(7).permutation(30).astype(np.int64)
    child = edge_crossover(parent, parent, np.zeros_like(dist), dist, neighbour_lists(dist, 5), 11)
    assert child[0] == 11 and tour_edges(child) == tour_edges(parent)


def test_edge_crossover_follows_the_prior_where_the_parents_disagree():
    dist = points_dist(30, 8)
    rng = np.random.default_rng(9)
    first, second = (rng.permutation(30).astype(np.int64) for _ in range(2))
    prior = np.zeros_like(dist)
    for a, b in tour_edges(second):
        prior[a, b] = prior[b, a] = 1.0  # the prior believes the second parent
    neighbours = neighbour_lists(dist, 5)
    child = edge_crossover(first, second, prior, dist, neighbours, int(second[0]))
    assert sorted(child.tolist()) == list(range(30))
    assert tour_edges(child) == tour_edges(second)
    plain = edge_crossover(first, second, np.zeros_like(dist), dist, neighbours, int(second[0]))
    assert tour_edges(plain) != tour_edges(second)


@pytest.mark.parametrize(
    "ga",
    [
        GAParameters(p_chnn=0.0, chnn_candidates=5),
        GAParameters(p_chnn=0.0, edge_crossover=True),
        GAParameters(chnn_candidates=5, edge_crossover=True),
        GAParameters(use_chnn=False, edge_crossover=True),
    ],
)
@pytest.mark.parametrize("n", [14, 60])
def test_ga_options_give_valid_tours_and_are_deterministic_for_a_seed(ga, n):
    dist = points_dist(n, 10)
    runs = [chnn_ga(dist, seed=3, time_limit_s=30.0, ga=ga) for _ in range(2)]
    assert runs[0].order == runs[1].order
    assert [h["best_length"] for h in runs[0].history] == [h["best_length"] for h in runs[1].history]
    assert runs[0].order[0] == 0 and sorted(runs[0].order) == list(range(n))


def test_the_options_change_the_search():
    dist = points_dist(60, 11)

    def trace(ga: GAParameters) -> list[float]:
        return [h["mean_length"] for h in chnn_ga(dist, seed=1, time_limit_s=30.0, ga=ga).history]

    plain = trace(GAParameters(p_chnn=0.0))
    assert trace(GAParameters(p_chnn=0.0, chnn_candidates=5)) != plain
    assert trace(GAParameters(p_chnn=0.0, edge_crossover=True)) != plain


def test_a_target_length_stops_the_search_once_reached():
    dist = points_dist(60, 12)
    result = chnn_ga(dist, seed=0, time_limit_s=30.0, target_length=1e12)
    assert len(result.history) == 1  # the repaired initial population already beats it
    assert "cpu_s" in result.history[0]
