"""A buoy's light in camera frames: each frame's measurement of the lantern's spot, and the burst's reading of
its character from them. Pure computation.

The lantern is a small disc of its signal colour with a white-hot centre (the lamp saturates the sensor), at the
top of the body. One frame gives the spot's peak brightness and the colour of its bright saturated pixels; but a
bright patch behind the spot (the sky near the horizon, a whitecap) may pass for a lit lamp in one frame, while
over a burst a flashing light is a change: the burst decides on/off by splitting the spot's brightness into two
levels where the burst shows two (the widest gap a lamp's level bounds: `lamp_threshold`), and believes each
frame's own reading only where it does not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from skimage.filters import threshold_otsu

from gcs.domain.paint_segmentation import LIGHT_HUE_DEG, nearest_hue, to_lab
from uavcore.light_character import ObservedLight, read_sequence

LIT_LEVEL = 0.85  # peak luma (0-1) of a lamp in one frame: its white-hot centre; sea clutter behind stays below
MIN_LAMP_LEVEL = 0.75  # below it, a spot is sea or paint (clutter behind the spot reaches ~0.65)
MIN_LEVEL_SPREAD = 0.2  # a burst whose spot brightness spans less shows one level: steady on, or dark
LAMP_MIN_CHROMA = 25.0  # a coloured lamp's pixels, against its white centre and its halo
LAMP_MIN_L = 40.0
LAMP_HUE_TOLERANCE_DEG = 30.0


@dataclass(frozen=True)
class LightSpot:
    """One frame's measurement of the lantern's spot: peak luma (0-1) and the colour its lit pixels show."""

    centre_px: tuple[float, float]
    level: float
    colour: str  # W, R, G, Y or Bu: the lamp's colour were it lit (meaningless while dark)

    @property
    def lit(self) -> bool:
        """The frame's own reading: a lamp's white-hot centre is the brightest thing near the body's top."""
        return self.level >= LIT_LEVEL


def measure_spot(
    image: np.ndarray, centre_px: tuple[float, float], radius_px: float, body_top_v: float
) -> LightSpot | None:
    """The upper half of the spot of radius_px around centre_px (u, v), above the body's top edge (row body_top_v):
    the lamp sits on the body, whose paint may be as bright (white) or of the lamp's colour (yellow); the lamp's
    upper half and its halo show above it. None if no part of the spot lies in the frame."""
    u, v = centre_px
    height, width = image.shape[:2]
    r = int(np.ceil(radius_px))
    above_body = (
        math.floor(body_top_v - 1.5) + 1
    )  # rows whose centres lie 1.5 px or more above the edge: JPEG and a sub-pixel edge smear white paint a pixel up
    # and no lower than the lamp's centre row: the body's top is projected from the geotag, whose attitude error
    # (half a degree moves it by several pixels at 20 m) may put white paint inside the rows kept above it
    top, bottom = max(0, round(v) - r), min(height, round(v) + 1, above_body)
    left, right = max(0, round(u) - r), min(width, round(u) + r + 1)
    if top >= bottom or left >= right:
        return None
    patch = image[top:bottom, left:right].astype(float) / 255.0
    luma = patch @ np.array([0.299, 0.587, 0.114])  # ITU-R BT.601, JPEG's own luma
    level = float(luma.max())  # the sensor's noise is a few levels: one pixel of the lamp's centre suffices
    lab = to_lab(image[top:bottom, left:right])
    chroma = np.hypot(lab[..., 1], lab[..., 2])
    index, gap = nearest_hue(np.degrees(np.arctan2(lab[..., 2], lab[..., 1])), LIGHT_HUE_DEG)
    coloured = (lab[..., 0] >= LAMP_MIN_L) & (chroma >= LAMP_MIN_CHROMA) & (gap <= LAMP_HUE_TOLERANCE_DEG)
    white = (lab[..., 0] >= 85.0) & (chroma < LAMP_MIN_CHROMA)
    # a coloured lamp is mostly its colour round a small white centre; a white lamp is white throughout
    if coloured.sum() <= white.sum():
        colour = "W"
    else:
        names = list(LIGHT_HUE_DEG)
        colour = names[int(np.bincount(index[coloured], minlength=len(names)).argmax())]
    return LightSpot((u, v), level, colour)


def lit_frames(spots: Sequence[LightSpot]) -> list[bool]:
    """Whether the light showed in each frame: by the burst's two brightness levels when it has two, else by each
    frame's own reading."""
    levels = np.array([s.level for s in spots])
    # two levels, the upper a lamp's: a whitecap drifting behind the spot changes it too, but never to a lamp's
    if len(levels) >= 3 and np.ptp(levels) >= MIN_LEVEL_SPREAD and levels.max() >= LIT_LEVEL:
        return [bool(level > lamp_threshold(levels)) for level in levels]
    return [s.lit for s in spots]


def lamp_threshold(levels: np.ndarray) -> float:
    """The brightness that splits a burst's lit frames from its dark ones: the middle of the widest gap between
    the burst's levels whose upper side a lamp reaches, never below what only a lamp reaches. Dark frames are not
    one level: clutter behind the spot (a whitecap, the sky) makes a second, brighter one, and a split of all the
    levels in two (Otsu's) then falls between the two dark ones; the lamp's saturated centre stands apart above
    both. Otsu's split where no gap reaches a lamp's level."""
    ordered = np.sort(levels)
    gaps = np.diff(ordered)
    reaching = np.flatnonzero(ordered[1:] >= LIT_LEVEL)
    if reaching.size == 0:
        return max(float(threshold_otsu(levels)), MIN_LAMP_LEVEL)
    widest = reaching[np.argmax(gaps[reaching])]
    return max(float(ordered[widest] + ordered[widest + 1]) / 2, MIN_LAMP_LEVEL)


def read_light(times_s: Sequence[float], spots: Sequence[LightSpot]) -> ObservedLight:
    """The character a burst's spots show (uavcore.light_character.read_sequence); "unreadable" with under three."""
    if len(spots) < 3:
        return ObservedLight("unreadable")
    on = lit_frames(spots)
    return read_sequence(times_s, on, [s.colour if lit else None for s, lit in zip(spots, on, strict=True)])
