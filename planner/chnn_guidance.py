"""The CHNN as a prior on edges: its converged activations read as edge frequencies, and what uses them.

Algorithm 2 uses the network's end states only after decoding them into tours. The same states say more:
v_xi v_y,i+1 is the product that eq. (15)'s E4 term weighs by d_xy, i.e. the network's belief that buoy y
follows buoy x. Summed over positions and over many networks it is the frequency with which the CHNN's local
minima use the edge (x, y). Two GA options read it (planner.chnn_ga): candidate lists for 2-opt / Or-opt that
include each node's likeliest CHNN partners (``guided_neighbour_lists``), and an edge crossover that prefers
those edges (planner.edge_crossover).

Where the networks come from: on a mission small enough for the whole-tour network (depot clamped, the
paper's setting) the initial population's K networks are reused, at no extra cost. On larger ones an
n^2-neuron network is too slow, so each of a set of neighbourhoods (a centre node and its ``size`` nearest
nodes, the centre clamped as the sub-tour's start and end) gets its own small network, all in one batch;
the centres are drawn until every node sits in some neighbourhood.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner import chnn
from planner.local_search import neighbour_lists


@dataclass(frozen=True)
class Windows:
    """The sub-problems of a batch of networks: network k orders free[k] between start[k] and end[k]."""

    free: np.ndarray  # (K, m) node indices, one neuron row each
    start: np.ndarray  # (K,) the clamped node before position 0
    end: np.ndarray  # (K,) the clamped node after position m - 1

    @classmethod
    def whole_tour(cls, n: int, batch: int) -> Windows:
        """K networks on the whole mission, the depot (node 0) clamped at both ends."""
        return cls(np.tile(np.arange(1, n), (batch, 1)), np.zeros(batch, np.int64), np.zeros(batch, np.int64))

    @classmethod
    def neighbourhoods(cls, dist: np.ndarray, size: int, rng: np.random.Generator) -> Windows:
        """One network per centre, on the centre's ``size`` nearest nodes; centres are drawn in random order
        until every node is in some window (a cover, not one window per node: fewer, cheaper networks)."""
        nearest = neighbour_lists(dist, size)
        covered = np.zeros(len(dist), dtype=bool)
        drawn = []
        for centre in rng.permutation(len(dist)):
            if not covered[centre]:
                drawn.append(centre)
                covered[centre] = True
                covered[nearest[centre]] = True
        centres = np.array(drawn, dtype=np.int64)
        return cls(nearest[centres], centres, centres)

    def distances(self, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each window's normalised distances (chnn.normalised), stacked: (K, m, m), (K, m), (K, m)."""
        parts = [chnn.normalised(dist, f, s, e) for f, s, e in zip(self.free, self.start, self.end, strict=True)]
        d, d_start, d_end = (np.stack(column) for column in zip(*parts, strict=True))
        return d, d_start, d_end


def expected_successors(v: np.ndarray) -> np.ndarray:
    """(K, m, m) activations -> (K, m, m) with [k, x, y] = sum_i v_xi v_y,i+1: how strongly network k puts
    buoy y right after buoy x (the product in eq. (15)'s E4 term, one direction)."""
    return v[..., :, :-1] @ np.swapaxes(v[..., :, 1:], -1, -2)


def edge_frequencies(v: np.ndarray, windows: Windows, n: int) -> np.ndarray:
    """(n, n) symmetric edge frequencies in [0, 1] from K networks' activations: the expected use of edge
    (x, y) summed over the networks whose window holds both ends, divided by the number of such networks.
    The clamped ends count as neighbours of positions 0 and m - 1. Zero where no window holds both ends."""
    use = np.zeros((n, n))
    seen = np.zeros((n, n))
    successors = expected_successors(v)
    for k, free in enumerate(windows.free):
        use[np.ix_(free, free)] += successors[k]
        use[windows.start[k], free] += v[k, :, 0]
        use[free, windows.end[k]] += v[k, :, -1]
        nodes = np.unique(np.concatenate([free, [windows.start[k], windows.end[k]]]))
        seen[np.ix_(nodes, nodes)] += 1.0
    use = use + use.T
    frequencies = np.divide(use, seen, out=np.zeros_like(use), where=seen > 0)
    np.fill_diagonal(frequencies, 0.0)
    return np.clip(frequencies, 0.0, 1.0)


def neighbourhood_edge_frequencies(
    dist: np.ndarray, size: int, params: chnn.CHNNParameters, rng: np.random.Generator
) -> np.ndarray:
    """Edge frequencies of a large mission from one batch of neighbourhood networks (eq. (14)-(16), run from
    the random initial state of eq. (16) for params.steps Euler steps)."""
    windows = Windows.neighbourhoods(dist, size, rng)
    d, d_start, d_end = windows.distances(dist)
    run = chnn.run_chnn(d, d_start, d_end, params, chnn.initial_state(len(d), d.shape[-1], params, rng))
    return edge_frequencies(run.v, windows, len(dist))


def guided_neighbour_lists(dist: np.ndarray, frequencies: np.ndarray, k: int, k_chnn: int) -> np.ndarray:
    """Candidate lists of k nodes: each node's (up to) k_chnn likeliest CHNN partners (frequency > 0, most
    frequent first), then its nearest nodes until the list is full; each row sorted nearest first, because
    the 2-opt kernel stops scanning a list at the first candidate farther than the edge it would remove."""
    n = len(dist)
    k = max(1, min(k, n - 1))
    nearest = neighbour_lists(dist, n - 1)
    lists = np.empty((n, k), dtype=np.int64)
    for x in range(n):
        likeliest = np.argsort(-frequencies[x], kind="stable")[:k_chnn]
        picked = [int(y) for y in likeliest if frequencies[x, y] > 0 and y != x]
        for y in nearest[x]:
            if len(picked) == k:
                break
            if y not in picked:
                picked.append(int(y))
        lists[x] = sorted(picked, key=lambda y: (dist[x, y], y))
    return lists
