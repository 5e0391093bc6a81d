"""Which pixels of a frame are a buoy's paint: colour classes in CIELAB, where a colour's hue and chroma survive
the camera's vignetting and JPEG's chroma subsampling far better than its RGB. Pure computation (numpy, scipy,
scikit-image).

The sea and the sky of a marine frame are blue, grey or white (whitecaps are grey-white, never saturated), so the
saturated paints (red, green, yellow: every IALA kind has one) anchor a search; black and white are believed only
next to them. Class tests, in CIELAB (L* 0-100, chroma C* = hypot(a*, b*), hue angle h = atan2(b*, a*)):
- saturated paint: C* >= MIN_CHROMA and h within HUE_TOLERANCE_DEG of the paint's own hue;
- black: L* < BLACK_MAX_L, C* < NEUTRAL_MAX_CHROMA and b* > -NEUTRAL_MAX_CHROMA / 2 (the darkest sea troughs
  are as dark, but bluish: b* about -7);
- white: L* > WHITE_MIN_L and C* < NEUTRAL_MAX_CHROMA (a whitecap passes too: hence "only next to an anchor").
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from skimage import color

from uavcore.buoy_world import LIGHT_RGB, PAINT_RGB

SATURATED = ("red", "green", "yellow")
NEUTRAL = ("black", "white")
MIN_CHROMA = 22.0
HUE_TOLERANCE_DEG = 22.0  # red's and yellow's hues are 42 deg apart
BLACK_MAX_L = 16.0
WHITE_MIN_L = 80.0
NEUTRAL_MAX_CHROMA = 8.0
# A quick RGB pre-filter finds where paint may be, so that CIELAB is computed only there: max - min of the
# channels (a crude saturation) at least this, and blue not the largest (the sky and the sea always have it so).
MIN_RGB_SPREAD = 40


def to_lab(rgb: np.ndarray) -> np.ndarray:
    """CIELAB (H, W, 3) of an sRGB uint8 image."""
    return color.rgb2lab(rgb)


def _hue_deg(rgb: tuple[int, int, int]) -> float:
    _, a, b = to_lab(np.array([[rgb]], dtype=np.uint8))[0, 0]
    return math.degrees(math.atan2(b, a))


PAINT_HUE_DEG = {name: _hue_deg(PAINT_RGB[name]) for name in SATURATED}
LIGHT_HUE_DEG = {name: _hue_deg(rgb) for name, rgb in LIGHT_RGB.items() if name != "W"}


def nearest_hue(hue_deg: np.ndarray, hues: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Index into `hues` of the nearest hue for each angle, and the angular distance (deg)."""
    reference = np.array(list(hues.values()))
    gap = np.abs((hue_deg[..., None] - reference + 180.0) % 360.0 - 180.0)
    index = gap.argmin(axis=-1)
    return index, np.take_along_axis(gap, index[..., None], axis=-1)[..., 0]


def paint_labels(lab: np.ndarray, colours: tuple[str, ...]) -> np.ndarray:
    """Per pixel: 1 + the index in `colours` (PAINT_RGB names) of the paint it is, 0 for none of them."""
    lightness, a, b = lab[..., 0], lab[..., 1], lab[..., 2]
    chroma = np.hypot(a, b)
    labels = np.zeros(lab.shape[:2], dtype=np.int8)
    index, gap = nearest_hue(np.degrees(np.arctan2(b, a)), PAINT_HUE_DEG)
    saturated = (chroma >= MIN_CHROMA) & (gap <= HUE_TOLERANCE_DEG)
    grey = chroma < NEUTRAL_MAX_CHROMA
    for k, name in enumerate(colours):
        if name in SATURATED:
            mask = saturated & (index == SATURATED.index(name))
        elif name == "black":
            mask = grey & (lightness < BLACK_MAX_L) & (b > -NEUTRAL_MAX_CHROMA / 2)
        else:
            mask = grey & (lightness > WHITE_MIN_L)
        labels[mask & (labels == 0)] = k + 1
    return labels


def paint_boxes(rgb: np.ndarray, min_pixels: int) -> list[tuple[slice, slice]]:
    """Bounding boxes (row, column slices) of the blobs of saturated, not-blue pixels (MIN_RGB_SPREAD) with at
    least min_pixels: where a buoy's saturated paint may be. The RGB test is a cheap superset of the CIELAB one."""
    red, green, blue = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    # element-wise over the three planes: 3x faster than max/min along the last axis (a reduction over 3 values)
    top = np.maximum(np.maximum(red, green), blue)
    warm = (top - np.minimum(np.minimum(red, green), blue) >= MIN_RGB_SPREAD) & (blue < top)  # top >= min: no wrap
    labels, _ = ndimage.label(ndimage.binary_dilation(warm, iterations=2))
    sizes = ndimage.sum_labels(warm, labels, index=np.arange(1, labels.max() + 1))
    return [box for box, size in zip(ndimage.find_objects(labels), sizes, strict=True) if box and size >= min_pixels]
