"""The CHNN against eq. (14)-(16) written out element by element, its energy descent and its decoding."""

import dataclasses

import numpy as np
import pytest

from planner import chnn
from planner.chnn_ga import GAParameters, _chnn_children
from planner.distances import closed_tour_length, euclidean_matrix


def small_network(m: int, seed: int):
    rng = np.random.default_rng(seed)
    points = rng.uniform(0, 1, (m + 1, 2))
    dist = euclidean_matrix(points)
    return chnn.normalised(dist, np.arange(1, m + 1), 0, 0)


def weights_eq14(d, params, m):
    """w_xi,yj of eq. (14), with the visiting order running from the clamped start to the clamped end."""
    w = np.zeros((m, m, m, m))
    for x in range(m):
        for i in range(m):
            for y in range(m):
                for j in range(m):
                    w[x, i, y, j] = (
                        -params.A * (x == y) * (i != j)
                        - params.B * (i == j) * (x != y)
                        - params.C
                        - params.D * d[x, y] * ((j == i + 1) + (j == i - 1))
                    )
    return w


@pytest.mark.parametrize("params", [chnn.VALID_TOURS, chnn.HOPFIELD_TANK])
def test_gradient_is_minus_the_eq14_weights_times_v_minus_the_bias(params):
    m = 5
    d, d_start, d_end = small_network(m, 0)
    v = np.random.default_rng(1).uniform(0, 1, (1, m, m))
    w = weights_eq14(d, params, m)
    bias = np.full((m, m), params.C * params.n_bar(m))
    bias[:, 0] -= params.D * d_start
    bias[:, -1] -= params.D * d_end
    expected = -(np.einsum("xiyj,yj->xi", w, v[0]) + bias)
    assert chnn.energy_gradient(v, d, d_start, d_end, params)[0] == pytest.approx(expected, rel=1e-10)


def test_energy_is_the_sum_of_the_four_terms_of_eq15():
    m = 4
    d, d_start, d_end = small_network(m, 2)
    v = np.random.default_rng(3).uniform(0, 1, (1, m, m))[0]
    p = chnn.VALID_TOURS
    e1 = p.A / 2 * sum(v[x, i] * v[x, j] for x in range(m) for i in range(m) for j in range(m) if j != i)
    e2 = p.B / 2 * sum(v[x, i] * v[y, i] for i in range(m) for x in range(m) for y in range(m) if y != x)
    e3 = p.C / 2 * (v.sum() - p.n_bar(m)) ** 2
    # E4 of eq. (15) on the path depot -> position 0 .. position m-1 -> depot, each leg counted once
    padded = np.zeros((m + 2, m + 2))
    padded[1:-1, 1:-1] = v
    padded[0, 0] = padded[m + 1, m + 1] = 1.0  # the clamped start and end
    full = np.zeros((m + 2, m + 2))
    full[1:-1, 1:-1] = d
    full[0, 1:-1] = full[1:-1, 0] = d_start
    full[m + 1, 1:-1] = full[1:-1, m + 1] = d_end
    e4 = p.D * sum(
        full[x, y] * padded[x, i] * padded[y, i + 1] for x in range(m + 2) for y in range(m + 2) for i in range(m + 1)
    )
    terms = chnn.energy_terms(v[None], d, d_start, d_end, p)
    assert [float(terms[k][0]) for k in ("E1", "E2", "E3", "E4")] == pytest.approx([e1, e2, e3, e4], rel=1e-10)
    assert chnn.energy(v[None], d, d_start, d_end, p)[0] == pytest.approx(e1 + e2 + e3 + e4, rel=1e-10)


def test_on_a_tour_the_distance_term_is_the_tour_length():
    m = 6
    rng = np.random.default_rng(5)
    dist = euclidean_matrix(rng.uniform(0, 100, (m + 1, 2)))
    d, d_start, d_end = chnn.normalised(dist, np.arange(1, m + 1), 0, 0)
    order = rng.permutation(m)
    v = np.zeros((1, m, m))
    v[0, order, np.arange(m)] = 1.0
    e4 = chnn.energy_terms(v, d, d_start, d_end, chnn.VALID_TOURS)["E4"][0]
    scale = dist.max()
    assert e4 * scale == pytest.approx(closed_tour_length([0, *(order + 1)], dist) * chnn.VALID_TOURS.D)


def test_initial_state_follows_eq16():
    p = chnn.VALID_TOURS
    u = chnn.initial_state(50, 9, p, np.random.default_rng(0))
    centre = 0.5 * p.u0 * np.log(8)
    assert np.all(np.abs(u - centre) < p.init_noise)
    assert np.std(u) > 0.3 * p.init_noise  # really random, not constant
    assert chnn.activation(np.array([0.0]), p.u0)[0] == 0.5


@pytest.mark.parametrize("adaptive", [False, True])
def test_energy_never_increases(adaptive):
    """With a small fixed Euler step (the gradient flow's own property), and with the default step control."""
    m = 8
    d, d_start, d_end = small_network(m, 4)
    fixed_small = {"dt": 0.002, "adaptive_step": False}
    params = dataclasses.replace(chnn.VALID_TOURS, **({} if adaptive else fixed_small))
    run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(6, m, params, np.random.default_rng(0)))
    steps = np.diff(run.energy, axis=0)
    assert np.all(steps <= 1e-12 * np.abs(run.energy).max())
    assert np.all(run.energy[-1] < 0.5 * run.energy[0])


def test_a_large_fixed_step_can_raise_the_energy_which_the_step_control_prevents():
    m = 13
    d, d_start, d_end = small_network(m, 4)
    params = dataclasses.replace(chnn.VALID_TOURS, dt=0.1, adaptive_step=False)
    run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(6, m, params, np.random.default_rng(0)))
    assert np.any(np.diff(run.energy, axis=0) > 0)


def test_valid_tours_are_stable_corners_of_the_default_setting():
    """The corner conditions documented in planner.chnn: on a valid tour every on-neuron is pushed on and
    every off-neuron pushed off, for any tour, however long its legs."""
    m = 9
    d, d_start, d_end = small_network(m, 6)
    rng = np.random.default_rng(0)
    for _ in range(20):
        v = np.zeros((1, m, m))
        v[0, rng.permutation(m), np.arange(m)] = 1.0
        gradient = chnn.energy_gradient(v, d, d_start, d_end, chnn.VALID_TOURS)[0]
        assert np.all(gradient[v[0] == 1] < 0)
        assert np.all(gradient[v[0] == 0] > 0)


def test_decode_accepts_permutation_matrices_only():
    v = np.zeros((4, 4))
    v[[2, 0, 3, 1], [0, 1, 2, 3]] = 0.9
    assert chnn.decode(v).tolist() == [2, 0, 3, 1]
    v[1, 0] = 0.8  # two buoys in the first position
    assert chnn.decode(v) is None
    v = np.full((4, 4), 0.1)
    assert chnn.decode(v) is None  # nothing on


def test_the_default_network_alone_settles_on_valid_tours():
    m = 13
    d, d_start, d_end = small_network(m, 7)
    params = chnn.VALID_TOURS
    run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(16, m, params, np.random.default_rng(0)))
    valid = [chnn.decode(v) is not None for v in run.v]
    assert np.mean(valid) >= 0.9


def test_the_classic_hopfield_tank_setting_rarely_gives_valid_tours():
    m = 10
    d, d_start, d_end = small_network(m, 8)
    params = chnn.HOPFIELD_TANK
    run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(8, m, params, np.random.default_rng(0)))
    assert sum(chnn.decode(v) is not None for v in run.v) <= 2


def test_chnn_mutation_children_are_tours_that_keep_the_outside_of_the_window():
    rng = np.random.default_rng(9)
    n = 40
    dist = euclidean_matrix(rng.uniform(0, 1000, (n, 2)))
    parents = [rng.permutation(n).astype(np.int64) for _ in range(6)]
    children, energy = _chnn_children(parents, dist, GAParameters(window=10), chnn.VALID_TOURS, rng)
    assert len(energy) == GAParameters().chnn_steps + 1
    made = [c for c in children if c is not None]
    assert made
    for parent, child in zip(parents, children, strict=True):
        if child is None:
            continue
        assert sorted(child.tolist()) == list(range(n))
        assert np.sum(child != parent) <= 10  # only the 10-buoy window may change
