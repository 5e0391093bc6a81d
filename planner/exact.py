"""Exact oracle: Held-Karp dynamic programming (Bellman 1962; Held & Karp 1962), vectorised with numpy.

cost[S, j] = shortest path from the depot (node 0) through every node of the set S, ending at j in S.
Sets S are bit masks over the n - 1 other nodes and are processed in layers of equal size, so each layer is
a handful of array operations: O(2^n n^2) work and O(2^n n) memory, about 0.1 s at n = 16.
"""

from __future__ import annotations

import numpy as np

from planner.errors import TooLargeError

EXACT_MAX_NODES = 16  # 2^15 x 15 states; one more node doubles time and memory


def held_karp(dist: np.ndarray) -> tuple[list[int], float]:
    """Optimal closed tour from node 0: (order starting with 0, length). TooLargeError past 16 nodes."""
    n = len(dist)
    if n > EXACT_MAX_NODES:
        raise TooLargeError(
            f"the exact method (Held-Karp) takes at most {EXACT_MAX_NODES} nodes; got {n}. "
            "Use --method chnn-ga or auto."
        )
    if n <= 3:
        order = list(range(n))
        return order, float(sum(dist[order[i], order[(i + 1) % n]] for i in range(n)))
    m = n - 1  # the nodes other than the depot, bit b stands for node b + 1
    inner = dist[1:, 1:]
    n_sets = 1 << m
    cost = np.full((n_sets, m), np.inf)
    parent = np.full((n_sets, m), -1, dtype=np.int8)
    singles = 1 << np.arange(m)
    cost[singles, np.arange(m)] = dist[0, 1:]
    masks = np.arange(n_sets)
    popcount = np.zeros(n_sets, dtype=np.int64)
    for b in range(m):
        popcount += (masks >> b) & 1
    for size in range(2, m + 1):
        layer = masks[popcount == size]
        for j in range(m):
            sets = layer[(layer >> j) & 1 == 1]
            previous = sets ^ (1 << j)
            candidates = cost[previous] + inner[:, j]  # (sets, m): arrive at j from each k in previous
            best = np.argmin(candidates, axis=1)
            cost[sets, j] = candidates[np.arange(len(sets)), best]
            parent[sets, j] = best
    full = n_sets - 1
    closing = cost[full] + dist[1:, 0]
    last = int(np.argmin(closing))
    length = float(closing[last])
    order = []
    mask = full
    while last >= 0:
        order.append(last + 1)
        previous = int(parent[mask, last])
        mask ^= 1 << last
        last = previous
    order.append(0)
    order.reverse()
    return order, length
