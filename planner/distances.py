"""Input checks and distance matrices for planar points (metres on the local tangent plane)."""

from __future__ import annotations

import numpy as np

from planner.errors import InputError


def check_points(points) -> np.ndarray:
    """Return points as an (n, 2) float array, or raise InputError: fewer than 2 nodes (a depot and at least
    one buoy), a wrong shape, non-finite values or two points at the same place."""
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"points must be numbers: {exc}") from None
    if pts.size == 0:
        raise InputError("need a depot and at least one buoy (2 points); got none")
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InputError(f"points must be an (n, 2) array of x, y; got shape {pts.shape}")
    if len(pts) < 2:
        raise InputError(f"need a depot and at least one buoy (2 points); got {len(pts)}")
    if not np.all(np.isfinite(pts)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(pts), axis=1))[0])
        raise InputError(f"point {bad} has a non-finite coordinate: {pts[bad].tolist()}")
    _check_duplicates(pts)
    return pts


def _check_duplicates(pts: np.ndarray) -> None:
    _, first, counts = np.unique(pts, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup = pts[first[np.argmax(counts > 1)]]
        where = np.flatnonzero(np.all(pts == dup, axis=1)).tolist()
        raise InputError(f"points {where} are at the same place {dup.tolist()}: a buoy is listed twice")


def check_distance_matrix(distance) -> np.ndarray:
    """Return a square, finite, non-negative distance matrix as float, or raise InputError."""
    try:
        dist = np.asarray(distance, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"distance matrix must be numbers: {exc}") from None
    if dist.ndim != 2 or dist.shape[0] != dist.shape[1]:
        raise InputError(f"distance matrix must be square; got shape {dist.shape}")
    if len(dist) < 2:
        raise InputError(f"need a depot and at least one buoy (2 nodes); got {len(dist)}")
    if not np.all(np.isfinite(dist)):
        raise InputError("distance matrix has non-finite entries")
    if np.any(dist < 0):
        raise InputError("distance matrix has negative entries")
    return dist


def euclidean_matrix(points: np.ndarray) -> np.ndarray:
    """Pairwise straight-line distances of an (n, 2) array."""
    diff = points[:, None, :] - points[None, :, :]
    return np.sqrt((diff**2).sum(axis=-1))


def closed_tour_length(order, dist: np.ndarray) -> float:
    """Length of the closed tour visiting ``order`` and returning to its first node."""
    order = np.asarray(order)
    return float(dist[order, np.roll(order, -1)].sum())


def is_valid_tour(order, n: int) -> bool:
    """True when order is a permutation of range(n) that starts at the depot 0."""
    order = np.asarray(order)
    return len(order) == n and n > 0 and order[0] == 0 and np.array_equal(np.sort(order), np.arange(n))
