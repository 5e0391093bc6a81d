"""plan_tour: tour invariants, the distance-matrix path, reproducibility, and every bad input."""

import itertools

import numpy as np
import pytest

from planner import PlanResult, plan_tour
from planner.distances import closed_tour_length, euclidean_matrix, is_valid_tour
from planner.errors import InputError, TooLargeError
from planner.scenario import reference_scenario


def mission(seed: int, n_buoys: int = 13) -> np.ndarray:
    return np.vstack([[0.0, 0.0], reference_scenario(seed=seed, n_buoys=n_buoys).buoys_local])


@pytest.mark.parametrize("method", ["chnn-ga", "chnn", "exact", "auto"])
def test_every_method_returns_a_closed_tour_from_the_depot(method):
    points = mission(4)
    result = plan_tour(points, method=method, seed=1)
    assert isinstance(result, PlanResult)
    assert is_valid_tour(result.order, len(points))
    assert result.length == pytest.approx(closed_tour_length(result.order, euclidean_matrix(points)))
    assert result.elapsed_s > 0
    assert result.method == ("exact" if method == "auto" else method)


def test_history_records_best_length_per_generation_and_chnn_energy():
    result = plan_tour(mission(2), method="chnn-ga", seed=3)
    best = [h["best_length"] for h in result.history]
    assert len(best) >= 2
    assert all(b2 <= b1 for b1, b2 in itertools.pairwise(best))  # the best never gets worse
    assert best[-1] == pytest.approx(result.length)
    assert len(result.history[0]["energy"]) > 10  # the initial population's CHNN energy trace


def test_the_same_seed_gives_the_same_route_and_another_seed_can_differ():
    points = mission(0, n_buoys=30)
    first = plan_tour(points, seed=5, time_limit_s=20.0)
    second = plan_tour(points, seed=5, time_limit_s=20.0)
    assert first.order == second.order
    assert [h["best_length"] for h in first.history] == [h["best_length"] for h in second.history]
    pure = [plan_tour(mission(1), method="chnn", seed=s).order for s in range(4)]
    assert len({tuple(o) for o in pure}) > 1


def test_a_distance_matrix_defines_the_lengths():
    rng = np.random.default_rng(1)
    dist = np.rint(euclidean_matrix(rng.uniform(0, 100, (20, 2))))
    result = plan_tour(distance=dist, seed=0)
    assert is_valid_tour(result.order, 20)
    assert result.length == closed_tour_length(result.order, dist)


def test_two_nodes_is_the_smallest_mission():
    result = plan_tour([[0.0, 0.0], [3.0, 4.0]], method="chnn-ga")
    assert result.order == [0, 1]
    assert result.length == pytest.approx(10.0)


@pytest.mark.parametrize(
    ("points", "message"),
    [
        ([], "at least one buoy"),
        ([[0.0, 0.0]], "at least one buoy"),
        ([[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]], "same place"),
        ([[0.0, 0.0], [np.nan, 1.0]], "non-finite"),
        ([[0.0, 0.0], [np.inf, 1.0]], "non-finite"),
        ([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], r"\(n, 2\)"),
        ([["a", "b"], ["c", "d"]], "numbers"),
    ],
)
def test_bad_points_raise_input_error(points, message):
    with pytest.raises(InputError, match=message):
        plan_tour(points)


def test_bad_options_and_matrices_raise_typed_errors():
    points = mission(0)
    with pytest.raises(InputError, match="unknown method"):
        plan_tour(points, method="simulated-annealing")
    with pytest.raises(InputError, match="time limit"):
        plan_tour(points, time_limit_s=0)
    with pytest.raises(InputError, match="square"):
        plan_tour(distance=np.zeros((3, 4)))
    with pytest.raises(InputError, match="negative"):
        plan_tour(distance=-np.ones((3, 3)))
    with pytest.raises(InputError, match="points or a distance"):
        plan_tour()
    with pytest.raises(TooLargeError, match="Held-Karp"):
        plan_tour(mission(0, n_buoys=16), method="exact")
    with pytest.raises(TooLargeError, match="pure CHNN"):
        plan_tour(np.random.default_rng(0).uniform(0, 1, (80, 2)), method="chnn")


def test_chnn_ga_is_anytime_it_returns_its_best_tour_when_time_runs_out():
    points = np.random.default_rng(3).uniform(0, 5000, (200, 2))
    result = plan_tour(points, method="chnn-ga", seed=0, time_limit_s=0.05)
    assert is_valid_tour(result.order, 200)
    # stopped by the clock, long before the stall rule (60 generations without progress at 200 nodes)
    assert len(result.history) - 1 < 60
    assert result.length == pytest.approx(min(h["best_length"] for h in result.history))
