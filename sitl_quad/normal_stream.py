"""Unit normal draws served in slices of a pre-drawn block.

The physics asks for a few rows of noise at every 250 Hz attitude step; a numpy Generator call costs about
as much as the RK4 steps themselves, so rows are drawn 4096 at a time. The sequence is the same however it
is sliced (numpy's Generator fills rows in order), which keeps seeded runs identical.
"""

from __future__ import annotations

import numpy as np

BLOCK_ROWS = 4096


class NormalStream:
    def __init__(self, rng: np.random.Generator, width: int) -> None:
        self.rng = rng
        self.width = width
        self._block = np.empty((0, width))
        self._next = 0

    def take(self, rows: int) -> np.ndarray:
        """The next `rows` rows of unit normals, shape (rows, width)."""
        if self._next + rows > len(self._block):
            rest = self._block[self._next :]
            self._block = np.concatenate([rest, self.rng.standard_normal((max(BLOCK_ROWS, rows), self.width))])
            self._next = 0
        out = self._block[self._next : self._next + rows]
        self._next += rows
        return out


class Zeros:
    """take(rows) of an inactive source: zeros, without allocating each time."""

    def __init__(self, width: int) -> None:
        self._zeros = np.zeros((BLOCK_ROWS, width))

    def take(self, rows: int) -> np.ndarray:
        return self._zeros[:rows] if rows <= BLOCK_ROWS else np.zeros((rows, self._zeros.shape[1]))
