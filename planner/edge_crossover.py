"""Edge crossover guided by a prior on edges (the CHNN's edge frequencies, planner.chnn_guidance).

Order crossover (OX) keeps positions of one parent and the relative order of the other; for a tour what
matters is its edges. This operator builds the child city by city from a random start and, at each city,
takes the next one among the unvisited cities adjacent to it in either parent, scored by
    (number of parents with that edge) + weight[current, next]
so edges both parents share come first, then parent edges the prior believes in; ties go to the shorter
edge. When every parent neighbour is visited it takes the best unvisited candidate-list node by the same
weight, else the nearest unvisited city. With a zero weight it is a plain greedy edge recombination: the
control that tells the prior's share from the operator's.
"""

from __future__ import annotations

import numpy as np

from uavcore.kernel_cache import cached_kernel


@cached_kernel
def _parent_neighbours(first, second):
    """(n, 4): each city's predecessor and successor in the first parent, then in the second."""
    n = len(first)
    adjacent = np.empty((n, 4), dtype=np.int64)
    for i in range(n):
        adjacent[first[i], 0] = first[(i - 1) % n]
        adjacent[first[i], 1] = first[(i + 1) % n]
        adjacent[second[i], 2] = second[(i - 1) % n]
        adjacent[second[i], 3] = second[(i + 1) % n]
    return adjacent


@cached_kernel
def _nearest_unvisited(current, dist, visited):
    best, best_d = -1, np.inf
    for y in range(len(visited)):
        if not visited[y] and dist[current, y] < best_d:
            best, best_d = y, dist[current, y]
    return best


@cached_kernel
def edge_crossover(first, second, weight, dist, neighbours, start):
    """A child tour (int64 permutation) of the two parents, built from city ``start`` (see the module doc)."""
    n = len(first)
    adjacent = _parent_neighbours(first, second)
    visited = np.zeros(n, dtype=np.bool_)
    child = np.empty(n, dtype=np.int64)
    current = start
    child[0] = current
    visited[current] = True
    for position in range(1, n):
        best, best_score, best_d = -1, -np.inf, np.inf
        for q in range(4):
            y = adjacent[current, q]
            if visited[y]:
                continue
            shared = 0
            for r in range(4):
                if adjacent[current, r] == y:
                    shared += 1
            score = shared + weight[current, y]  # shared = how many parents have the edge (current, y)
            if score > best_score or (score == best_score and dist[current, y] < best_d):
                best, best_score, best_d = y, score, dist[current, y]
        if best < 0:
            for t in range(neighbours.shape[1]):
                y = neighbours[current, t]
                if visited[y]:
                    continue
                score = weight[current, y]
                if score > best_score or (score == best_score and dist[current, y] < best_d):
                    best, best_score, best_d = y, score, dist[current, y]
        if best < 0:
            best = _nearest_unvisited(current, dist, visited)
        child[position] = best
        visited[best] = True
        current = best
    return child
