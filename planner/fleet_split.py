"""The exact min-max split of a giant tour among a fleet: the min-max analogue of planner/split.py.

Given the buoys in one order s_1..s_m and the vehicles in one order 1..K, every vehicle takes one stretch
s_i..s_j of it (possibly empty), vehicle 1 the first stretch, vehicle 2 the next one, and so on. A stretch
flown by vehicle k takes

    T_k(i, j) = f_k + (d(depot_k, s_i) + d(s_i..s_j) + d(s_j, depot_k)) / v_k + sum of dwell(s_i..s_j)

(take-off and landing f_k, speed v_k, the path length along the order) and an empty one takes 0. Bellman's
recursion over (vehicles used, buoys covered)

    F_0(0) = 0,  F_0(j > 0) = inf,  F_k(j) = min( F_{k-1}(j),  min over i < j of max(F_{k-1}(i), T_k(i+1, j)) )

gives the least makespan F_K(m) of any cut of that order (the min-max form of Prins' shortest path). The total
time breaks ties: a second pass with the same recursion, the sum in place of the max and only stretches within
the makespan allowed, gives the least total among the cuts that reach it, so the result is the lexicographic
optimum (makespan, then total) over all cuts of the order. Both passes take O(K m^2).
"""

from __future__ import annotations

import numpy as np

from uavcore.kernel_cache import cached_kernel

TOLERANCE = 1e-9  # relative: a stretch "within the makespan" allows this much rounding


@cached_kernel
def _stretch_time(k, i, j, order, D, path, dwell_sum, depot, inv_speed, fixed):
    """T_k of the stretch order[i..j-1] (0-based, j exclusive, i < j)."""
    first, last = order[i], order[j - 1]
    length = D[depot[k], first] + path[j - 1] - path[i] + D[last, depot[k]]
    return fixed[k] + length * inv_speed[k] + dwell_sum[j] - dwell_sum[i]


@cached_kernel
def split_kernel(order, D, dwell, depot, inv_speed, fixed):
    """Both passes of the recursion; returns (makespan, total, start) with start[k] the index in order where
    vehicle k's stretch begins (its stretch is order[start[k]:start[k + 1]], start[K] = m)."""
    m, K = len(order), len(depot)
    path = np.zeros(m)  # path[x] = length of order[0..x] along the order
    dwell_sum = np.zeros(m + 1)  # dwell_sum[x] = dwell of order[0..x-1]
    for x in range(m):
        if x > 0:
            path[x] = path[x - 1] + D[order[x - 1], order[x]]
        dwell_sum[x + 1] = dwell_sum[x] + dwell[order[x]]
    F = np.full((K + 1, m + 1), np.inf)
    F[0, 0] = 0.0
    for k in range(1, K + 1):
        for j in range(m + 1):
            best = F[k - 1, j]
            for i in range(j):
                if F[k - 1, i] >= best:
                    continue
                best = min(best, max(F[k - 1, i], _stretch_time(k - 1, i, j, order, D, path, dwell_sum, depot,
                                                                  inv_speed, fixed)))  # fmt: skip
            F[k, j] = best
    makespan = F[K, m]
    limit = makespan * (1.0 + TOLERANCE)
    G = np.full((K + 1, m + 1), np.inf)
    pred = np.zeros((K + 1, m + 1), dtype=np.int64)
    G[0, 0] = 0.0
    for k in range(1, K + 1):
        for j in range(m + 1):
            G[k, j] = G[k - 1, j]
            pred[k, j] = j
            for i in range(j):
                if G[k - 1, i] == np.inf:
                    continue
                t = _stretch_time(k - 1, i, j, order, D, path, dwell_sum, depot, inv_speed, fixed)
                if t <= limit and G[k - 1, i] + t < G[k, j]:
                    G[k, j] = G[k - 1, i] + t
                    pred[k, j] = i
    start = np.zeros(K + 1, dtype=np.int64)
    start[K] = m
    j = m
    for k in range(K, 0, -1):
        j = pred[k, j]
        start[k - 1] = j
    return makespan, G[K, m], start


def minmax_split(
    order, D: np.ndarray, dwell: np.ndarray, depot: np.ndarray, inv_speed: np.ndarray, fixed: np.ndarray
) -> tuple[list[list[int]], float, float]:
    """The lexicographically best cut (makespan, then total time) of the buoy order ``order`` among the
    vehicles in their given order: (one buoy list per vehicle, makespan, total time)."""
    order = np.ascontiguousarray(order, dtype=np.int64)
    makespan, total, start = split_kernel(order, D, dwell, depot, inv_speed, fixed)
    routes = [order[start[k] : start[k + 1]].tolist() for k in range(len(depot))]
    return routes, float(makespan), float(total)
