"""Tour improvement: 2-opt + Or-opt local search and an iterated local search (ILS) chain, compiled by numba.

This is the memetic repair of the CHNN-GA (Section V-C): the CHNN proposes tours, these kernels polish them.
A tour is an int64 array holding a cyclic permutation of the node indices; ``position[city]`` is its index.
Moves are tried only towards each city's K nearest neighbours (neighbour lists) and cities whose
surroundings did not change are skipped (don't-look bits, kept as a work queue), so a local search after a
small change costs a few microseconds instead of O(n^2).

All kernels are compiled on first use and cached on disk (``cache=True``); ``warm_up()`` forces the compile.
"""

from __future__ import annotations

import numpy as np

from uavcore.kernel_cache import cached_kernel

_EPS = 1e-9  # improvements smaller than this are rounding noise, not progress


def neighbour_lists(dist: np.ndarray, k: int) -> np.ndarray:
    """The k nearest other nodes of every node, nearest first: an (n, k) int64 array."""
    n = len(dist)
    k = max(1, min(k, n - 1))
    keyed = dist + np.diag(np.full(n, np.inf))  # a node is not its own neighbour
    nearest = np.argsort(keyed, axis=1, kind="stable")[:, :k]
    return np.ascontiguousarray(nearest, dtype=np.int64)


@cached_kernel
def tour_length(tour, dist):
    """Length of the closed tour."""
    n = len(tour)
    total = 0.0
    for i in range(n):
        total += dist[tour[i], tour[(i + 1) % n]]
    return total


@cached_kernel
def _reverse(tour, position, i, j):
    """Reverse the cyclic stretch of positions i..j; reverses the complement instead when that is shorter
    (the same cycle, read the other way round)."""
    n = len(tour)
    length = (j - i) % n + 1
    if 2 * length > n:
        i, j = (j + 1) % n, (i - 1) % n
        length = n - length
    for _ in range(length // 2):
        a, b = tour[i], tour[j]
        tour[i], tour[j] = b, a
        position[b], position[a] = i, j
        i = (i + 1) % n
        j = (j - 1) % n


@cached_kernel
def _move_segment(tour, position, start, k, target, reverse):
    """Or-opt move: take the k cities at positions start..start+k-1 and reinsert them between the city at
    position ``target`` and its successor (target outside the segment), optionally reversed. Shifts the
    shorter of the two stretches between the old and the new place."""
    n = len(tour)
    seg = np.empty(k, dtype=np.int64)
    for q in range(k):
        seg[q] = tour[(start + q) % n]
    if reverse:
        seg = seg[::-1].copy()
    forward = (target - (start + k - 1)) % n  # cities between the segment's end and the target, inclusive
    backward = n - k - forward  # cities from the target's successor to the segment's predecessor
    if forward <= backward:
        for q in range(forward):
            city = tour[(start + k + q) % n]
            tour[(start + q) % n] = city
            position[city] = (start + q) % n
        base = start + forward
    else:
        for q in range(backward - 1, -1, -1):
            city = tour[(target + 1 + q) % n]
            tour[(target + 1 + k + q) % n] = city
            position[city] = (target + 1 + k + q) % n
        base = target + 1
    for q in range(k):
        tour[(base + q) % n] = seg[q]
        position[seg[q]] = (base + q) % n


@cached_kernel
def _push(queue, queued, head_tail, city):
    """Append a city to the circular work queue unless it is already queued."""
    if not queued[city]:
        n = len(queue)
        queue[head_tail[1] % n] = city
        head_tail[1] += 1
        queued[city] = True


@cached_kernel
def _improve_city(a, tour, position, dist, neighbours, queue, queued, head_tail):
    """Try one improving 2-opt or Or-opt move around city a; apply the first found. Returns the gain."""
    n = len(tour)
    k = neighbours.shape[1]
    # 2-opt, both tour directions: replace edges (a, b) and (c, d) by (a, c) and (b, d).
    for direction in (1, -1):
        pa = position[a]
        b = tour[(pa + direction) % n]
        d_ab = dist[a, b]
        for t in range(k):
            c = neighbours[a, t]
            d_ac = dist[a, c]
            if d_ac >= d_ab:
                break
            pc = position[c]
            d = tour[(pc + direction) % n]
            if c == b or d == a:
                continue
            gain = d_ab + dist[c, d] - d_ac - dist[b, d]
            if gain > _EPS:
                if direction == 1:
                    _reverse(tour, position, (pa + 1) % n, pc)
                else:
                    _reverse(tour, position, pc, (pa - 1) % n)
                for city in (a, b, c, d):
                    _push(queue, queued, head_tail, city)
                return gain
    # Or-opt: move the segment of 1..3 cities that starts at a (going forward) next to a neighbour.
    for seg_len in range(1, 4):
        if seg_len + 2 >= n:
            break
        start = position[a]
        end_city = tour[(start + seg_len - 1) % n]
        prev_city = tour[(start - 1) % n]
        next_city = tour[(start + seg_len) % n]
        removal_gain = dist[prev_city, a] + dist[end_city, next_city] - dist[prev_city, next_city]
        if removal_gain <= _EPS:
            continue
        for end_pick in range(2):
            anchor = a if end_pick == 0 else end_city
            # no early exit on the neighbour's distance here: unlike 2-opt, an improving Or-opt move
            # need not start with a new edge shorter than the removal gain at this anchor
            for t in range(k):
                c = neighbours[anchor, t]
                pc = position[c]
                if (pc - start) % n < seg_len:
                    continue  # c lies inside the segment
                for side in (0, 1):
                    # insert between c and its successor (side 0) or its predecessor and c (side 1)
                    if side == 0:
                        left, right = c, tour[(pc + 1) % n]
                    else:
                        left, right = tour[(pc - 1) % n], c
                    if (position[left] - start) % n < seg_len or (position[right] - start) % n < seg_len:
                        continue  # that edge touches the segment: not a different place
                    forward_cost = dist[left, a] + dist[end_city, right]
                    reverse_cost = dist[left, end_city] + dist[a, right]
                    insert_cost = min(forward_cost, reverse_cost) - dist[left, right]
                    gain = removal_gain - insert_cost
                    if gain > _EPS:
                        _move_segment(tour, position, start, seg_len, position[left], reverse_cost < forward_cost)
                        for city in (a, end_city, prev_city, next_city, left, right):
                            _push(queue, queued, head_tail, city)
                        return gain
    return 0.0


@cached_kernel
def _local_search_queue(tour, position, dist, neighbours, queue, queued, head_tail):
    """Drain the work queue: each queued city is tried until it yields no improving move."""
    n = len(tour)
    total_gain = 0.0
    while head_tail[0] < head_tail[1]:
        a = queue[head_tail[0] % n]
        head_tail[0] += 1
        queued[a] = False
        gain = _improve_city(a, tour, position, dist, neighbours, queue, queued, head_tail)
        if gain > 0.0:
            total_gain += gain
            _push(queue, queued, head_tail, a)
    return total_gain


@cached_kernel
def local_search(tour, dist, neighbours):
    """2-opt + Or-opt to a local optimum, in place. Returns the tour length."""
    n = len(tour)
    position = np.empty(n, dtype=np.int64)
    for i in range(n):
        position[tour[i]] = i
    queue = np.empty(n, dtype=np.int64)
    queued = np.zeros(n, dtype=np.bool_)
    head_tail = np.zeros(2, dtype=np.int64)
    # Don't-look bits only wake the cities next to a change; a final sweep over every city confirms (or
    # continues from) the local optimum, so none of the moves tried is left improving.
    while True:
        for i in range(n):
            _push(queue, queued, head_tail, tour[i])
        if _local_search_queue(tour, position, dist, neighbours, queue, queued, head_tail) <= 0.0:
            break
    return tour_length(tour, dist)


@cached_kernel
def _double_bridge(tour, position, max_segment):
    """Segment-local double bridge: A B C D -> A C B D with B and C short stretches at a random place.
    Returns where B started and the two stretches' lengths (the changed edges sit around those cuts)."""
    n = len(tour)
    len_b = 1 + np.random.randint(0, max_segment)
    len_c = 1 + np.random.randint(0, max_segment)
    start = np.random.randint(0, n)
    buf = np.empty(len_b + len_c, dtype=np.int64)
    for q in range(len_c):
        buf[q] = tour[(start + len_b + q) % n]
    for q in range(len_b):
        buf[len_c + q] = tour[(start + q) % n]
    for q in range(len_b + len_c):
        tour[(start + q) % n] = buf[q]
        position[buf[q]] = (start + q) % n
    return start, len_b, len_c


@cached_kernel
def iterated_local_search(tour, dist, neighbours, n_kicks, max_segment, seed):
    """Iterated local search: double-bridge kick, local repair, keep the result unless it is longer.

    Works in place on a tour that is already a local optimum; returns its final length.
    """
    np.random.seed(seed)
    n = len(tour)
    if n < 8:
        return local_search(tour, dist, neighbours)
    max_segment = max(1, min(max_segment, (n - 2) // 3))
    position = np.empty(n, dtype=np.int64)
    for i in range(n):
        position[tour[i]] = i
    queue = np.empty(n, dtype=np.int64)
    queued = np.zeros(n, dtype=np.bool_)
    head_tail = np.zeros(2, dtype=np.int64)
    current = tour_length(tour, dist)
    saved = tour.copy()
    for _ in range(n_kicks):
        saved[:] = tour
        start, len_b, len_c = _double_bridge(tour, position, max_segment)
        before = tour[(start - 1) % n]
        after = tour[(start + len_b + len_c) % n]
        b_first = tour[(start + len_c) % n]
        c_last = tour[(start + len_c - 1) % n]
        delta = dist[before, tour[start]] + dist[c_last, b_first] + dist[tour[(start + len_b + len_c - 1) % n], after]
        b_last, c_first = saved[(start + len_b - 1) % n], saved[(start + len_b) % n]
        delta -= (
            dist[before, saved[start]] + dist[b_last, c_first] + dist[saved[(start + len_b + len_c - 1) % n], after]
        )
        for q in (-1, 0, len_c - 1, len_c, len_b + len_c - 1, len_b + len_c):
            _push(queue, queued, head_tail, tour[(start + q) % n])
        gain = _local_search_queue(tour, position, dist, neighbours, queue, queued, head_tail)
        candidate = current + delta - gain
        if candidate <= current + _EPS:
            current = candidate
        else:
            tour[:] = saved
            for i in range(n):
                position[tour[i]] = i
    return tour_length(tour, dist)


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every kernel on a tiny instance."""
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 1, (12, 2))
    dist = np.sqrt(((pts[:, None, :] - pts[None, :, :]) ** 2).sum(-1))
    neighbours = neighbour_lists(dist, 5)
    tour = np.arange(12, dtype=np.int64)
    local_search(tour, dist, neighbours)
    iterated_local_search(tour, dist, neighbours, 5, 3, 0)
