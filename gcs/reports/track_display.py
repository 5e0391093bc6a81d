"""The flown track for display (pure): a long recorded track cut to a point budget, with a known deviation.

A 2-hour flight is 72 000 samples at 10 Hz: megabytes of JSON and a polyline no map needs. `simplify_track`
keeps at most `max_points` of them by Ramer-Douglas-Peucker refinement taken greedily, the worst-fitting
segment first (Douglas & Peucker 1973, with a heap so a budget rather than a tolerance stops it): start from the
points that must stay (the first, the last, each buoy arrival), then repeatedly split the segment whose farthest
recorded point lies farthest from it, at that point. When the budget is spent, every point left out lies within
`tolerance_m` of the segment between the two kept points around it, hence within `tolerance_m` of the displayed
polyline. Coordinates are local metres (east, north), so the tolerance is in metres.

The exports (track.geojson, the telemetry) keep every sample; this is only what the page draws.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

RESOLUTION_M = 0.01  # a point closer than this to the polyline is never worth drawing (nor is rounding noise)


@dataclass(frozen=True)
class SimplifiedTrack:
    indices: np.ndarray  # the kept samples' indices, increasing
    tolerance_m: float  # every left-out sample lies within this distance of the kept polyline


def segment_distances(points: np.ndarray, start: int, end: int) -> np.ndarray:
    """Distances of points[start + 1 : end] to the segment points[start] - points[end] (metres, shape (m,))."""
    a, b = points[start], points[end]
    inner = points[start + 1 : end]
    ab = b - a
    length2 = float(ab @ ab)
    if length2 == 0.0:  # a hover: the segment is a point
        return np.hypot(*(inner - a).T)
    t = np.clip((inner - a) @ ab / length2, 0.0, 1.0)
    return np.hypot(*(inner - (a + t[:, None] * ab)).T)


def simplify_track(points: np.ndarray, max_points: int, keep: Iterable[int] = ()) -> SimplifiedTrack:
    """At most max(max_points, the points that must stay) of `points` (shape (n, 2), local metres), keeping the
    first, the last and every index in `keep`, chosen to minimise the largest deviation greedily (see above); it
    stops early once every point left out is within RESOLUTION_M."""
    n = len(points)
    if n <= max(max_points, 2):
        return SimplifiedTrack(np.arange(n), 0.0)
    anchors = sorted({0, n - 1, *(int(i) for i in keep if 0 <= i < n)})
    kept = set(anchors)
    heap: list[tuple[float, int, int, int]] = []  # (-deviation, start, end, farthest point)

    def push(start: int, end: int) -> None:
        if end - start > 1:
            distances = segment_distances(points, start, end)
            farthest = int(np.argmax(distances))
            heapq.heappush(heap, (-float(distances[farthest]), start, end, start + 1 + farthest))

    for start, end in itertools.pairwise(anchors):
        push(start, end)
    while heap and len(kept) < max_points and -heap[0][0] > RESOLUTION_M:
        _, start, end, split = heapq.heappop(heap)
        kept.add(split)
        push(start, split)
        push(split, end)
    tolerance = -heap[0][0] if heap else 0.0
    return SimplifiedTrack(np.array(sorted(kept)), tolerance)


def evenly_spaced(n: int, count: int) -> np.ndarray:
    """At most `count` indices of n samples spread evenly over them, the first and the last included."""
    if n <= count:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max(count, 2)).round().astype(int))


def extremes_per_bucket(values: np.ndarray, count: int) -> np.ndarray:
    """At most `count` indices of a series for a chart: the first, the last, and the series cut into
    (count - 2) / 2 consecutive buckets, in each the sample with the lowest and the one with the highest value
    (NaN: no value; a bucket without any gives its first sample). Taking every k-th sample instead would alias an
    oscillation faster than k samples into a slow wave of the wrong amplitude; the extremes keep its envelope, as
    a chart of every sample draws it."""
    n = len(values)
    if n <= count or count < 4:
        return evenly_spaced(n, count)
    kept = [0, n - 1]
    for bucket in np.array_split(np.arange(n), (count - 2) // 2):
        inside = values[bucket]
        if np.isnan(inside).all():
            kept.append(int(bucket[0]))
        else:
            kept += [int(bucket[np.nanargmin(inside)]), int(bucket[np.nanargmax(inside)])]
    return np.unique(kept)


def arrival_indices(times_s: np.ndarray, arrivals_s: Iterable[float]) -> list[int]:
    """For each arrival time, the index of the first sample at or after it (times_s increasing)."""
    found = np.searchsorted(times_s, np.fromiter(arrivals_s, dtype=float))
    return [int(i) for i in found if i < len(times_s)]
