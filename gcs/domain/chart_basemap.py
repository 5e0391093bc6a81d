"""The offline base map from chart cells: land, shoreline constructions and depth contours. Pure.

The map page needs something to look at without a network: the cells the register imports already carry the
harbour's land (S-57 LNDARE), piers and breakwaters (SLCONS) and depth contours (DEPCNT, with their VALDCO depth),
as charted. Each object becomes a GeoJSON feature with `layer` (land, shoreline_construction, depth_contour) and,
for a contour, `depth_m`; a cell's features are kept together, under the cell's name, so a newer edition replaces
its own. The coastline (COALNE) is left out: it is the land areas' outline, which the page draws, and would double
the size.

Size: geometries are simplified within SIMPLIFY_DEG (about 2 m, a harbour chart's own drawing accuracy at its
1:20 000-1:50 000 scales) and their coordinates rounded to 1e-5 degrees (about 1 m): the test cell (US4MD81M,
3.5 MB) gives 2.0 MB of GeoJSON, 0.5 MB as the service sends it (gzip). Point objects (an islet charted as an
LNDARE point) are left out: there is no area or line to draw.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

import shapely
from shapely.geometry.base import BaseGeometry

BasemapLayer = Literal["land", "shoreline_construction", "depth_contour"]
BASEMAP_CLASSES: dict[str, BasemapLayer] = {
    "LNDARE": "land",
    "SLCONS": "shoreline_construction",
    "DEPCNT": "depth_contour",
}
SIMPLIFY_DEG = 2e-5
COORDINATE_DECIMALS = 5


@dataclass(frozen=True)
class BasemapFeature:
    layer: BasemapLayer
    geometry: BaseGeometry
    depth_m: float | None = None  # a depth contour's VALDCO


def basemap_feature(
    object_class: str, attributes: Mapping[str, Any], geometry: BaseGeometry | None
) -> BasemapFeature | None:
    """A chart object as a base map feature; None for a class the base map does not draw, or a point or empty
    geometry."""
    layer = BASEMAP_CLASSES.get(object_class)
    if layer is None or geometry is None or geometry.is_empty or geometry.geom_type in ("Point", "MultiPoint"):
        return None
    # drawn, never tested for containment: a ring the rounding made touch itself need not be made valid
    simplified = shapely.set_precision(geometry.simplify(SIMPLIFY_DEG), 10**-COORDINATE_DECIMALS)
    if simplified.is_empty:
        return None
    depth = attributes.get("VALDCO")
    depth_m = float(depth) if isinstance(depth, int | float) and math.isfinite(depth) else None
    return BasemapFeature(layer, simplified, depth_m if layer == "depth_contour" else None)


def basemap_features(features: Iterable[BasemapFeature]) -> list[dict[str, Any]]:
    """GeoJSON features, land first (drawn under the lines)."""
    order = list(BASEMAP_CLASSES.values())
    out = []
    for feature in sorted(features, key=lambda f: order.index(f.layer)):
        properties: dict[str, Any] = {"layer": feature.layer}
        if feature.depth_m is not None:
            properties["depth_m"] = feature.depth_m
        out.append(
            {"type": "Feature", "geometry": shapely.geometry.mapping(feature.geometry), "properties": properties}
        )
    return out


def feature_collection(cells: Iterable[str]) -> str:
    """The base map: the stored cells' features (each a JSON list, as stored) in one FeatureCollection, encoded."""
    return '{"type": "FeatureCollection", "features": [' + ",".join(c[1:-1] for c in cells if c != "[]") + "]}"


def encoded_features(features: Iterable[BasemapFeature]) -> str:
    """A cell's features as stored: a JSON list, compact."""
    return json.dumps(basemap_features(features), separators=(",", ":"))
