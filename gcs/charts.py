"""S-57 ENC cells: the buoys and beacons of a harbour authority's chart, read with GDAL's S57 driver.

The cell's objects are read here and mapped in gcs.domain.charted_marks (pure): which classes, which attributes
and codes, how a light finds its mark.

Why pyogrio: its wheels bundle GDAL (3.12 with pyogrio 0.13) with the S57 driver and its object and attribute
tables, so `pip install` is the whole set-up on any host the service runs on, and it reads a layer in one call
into NumPy arrays. Fiona also bundles GDAL but hands features over one Python mapping at a time. Debian's
python3-gdal is tied to the system's GDAL and Python, lives outside the virtual environment, and is what it takes
to WRITE a cell (the issue's note: its 287 predefined layers), which an import never does.

GDAL reads files: an upload is written to a temporary directory, read and removed. (pyogrio can read bytes through
/vsimem, but the S57 driver then refuses to look for updates under the name pyogrio gives it unless told to
ignore them, and every layer read copies the bytes again: 1.0 s against 0.46 s for the 3.5 MB test cell.) A cell
read from a path has its update files (.001, .002, ... beside it) applied, as GDAL does; an upload is the base
cell alone. Every layer read parses the whole cell again (about 60 ms for the test cell): only the layers present
are read.

Damaged input: GDAL's ISO 8211 reader answers a truncated or damaged cell with an error (DataSourceError), which
becomes ChartError; 120 randomly damaged copies of the test cell (cut short, bytes changed, spans overwritten)
gave an error or readable objects, never a crash. GDAL releases the GIL while it reads (the longest pause of a
thread beside it: 23 ms), so the service reads cells in a worker thread.
"""

from __future__ import annotations

import math
import tempfile
import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pyogrio
import shapely
from pyogrio.errors import DataLayerError, DataSourceError
from pyogrio.raw import read
from shapely.geometry.base import BaseGeometry

from gcs.domain.chart_basemap import BASEMAP_CLASSES, basemap_feature
from gcs.domain.charted_marks import (
    MARK_CLASSES,
    CellInfo,
    ChartContents,
    ChartError,
    ChartImport,
    Region,
    S57Object,
    SystemArea,
    object_label,
    read_marks,
)

CELL_SUFFIX = ".000"  # a base cell; .001, .002, ... are its updates
_READING = threading.Lock()  # one cell at a time (see _gdal_warnings); it also bounds the memory reading takes
_PYOGRIO = str(Path(pyogrio.__file__).parent)
LEADER_BYTES = 24
GDAL_MESSAGE_CHARS = 200


def is_cell(data: bytes, filename: str = "") -> bool:
    """Whether an upload is meant as an S-57 cell: named .000, or starting with an ISO 8211 leader."""
    return filename.lower().endswith(CELL_SUFFIX) or _has_iso8211_leader(data[:LEADER_BYTES])


def _has_iso8211_leader(head: bytes) -> bool:
    """An ISO/IEC 8211 record leader, as every S-57 file starts: the record length in 5 digits, the leader
    identifier "L" at 6, the field area's address in 5 digits at 12."""
    return len(head) == LEADER_BYTES and head[:5].isdigit() and head[6:7] == b"L" and head[12:17].isdigit()


def read_cell(path: Path, region: Region = "A", area: BaseGeometry | None = None) -> ChartImport:
    """The buoys and beacons of the cell at `path` (with its update files), in `area` when given; `region` is the
    IALA region of marks the chart places in none. ChartError for a file that gives none."""
    try:
        with path.open("rb") as file:
            head = file.read(LEADER_BYTES)
    except OSError as error:  # missing, a directory, not readable
        raise ChartError(f"{path}: cannot be read: {error.strerror}") from None
    return read_marks(_contents(path, head, path.name, updates=True), region, area)


def read_upload(
    data: bytes, filename: str = "", region: Region = "A", area: BaseGeometry | None = None, basemap: bool = False
) -> ChartImport:
    """read_cell for an uploaded cell (the base cell alone: an upload carries no update files); `basemap`: also its
    land, piers and depth contours (ChartImport.basemap: the register keeps them; about a second more for a
    harbour cell, which an import of its marks alone does not pay)."""
    name = Path(filename).name or "the upload"
    with tempfile.TemporaryDirectory(prefix="buoy-gcs-chart-") as folder:
        path = Path(folder) / f"cell{CELL_SUFFIX}"  # a name of ours: the upload's could be anything
        path.write_bytes(data)
        return read_marks(_contents(path, data[:LEADER_BYTES], name, updates=False, basemap=basemap), region, area)


def _contents(path: Path, head: bytes, name: str, updates: bool, basemap: bool = False) -> ChartContents:
    if not _has_iso8211_leader(head):
        raise ChartError(f"{name}: not an S-57 cell: it does not start with an ISO 8211 record leader")
    options = {"UPDATES": "APPLY" if updates else "IGNORE", "LNAM_REFS": "ON"}  # LNAM_REFS: a mark's lights
    gdal_warnings: list[str] = []
    try:
        with _gdal_warnings(gdal_warnings):
            layers = {str(row[0]) for row in pyogrio.list_layers(path)}
            if "DSID" not in layers:
                raise ChartError(f"{name}: an ISO 8211 file but not an S-57 cell (it has no data set record, DSID)")
            contents = _read_contents(path, name, layers, options, basemap)
    except (DataSourceError, DataLayerError, shapely.errors.ShapelyError) as error:  # GDAL's, or a geometry's
        raise ChartError(f"{name}: not a readable S-57 cell: {_gdal_message(error)}") from None
    return replace(contents, warnings=(*gdal_warnings, *contents.warnings))


@contextmanager
def _gdal_warnings(into: list[str]) -> Iterator[None]:
    """GDAL's warnings while a cell is read (a damaged record's attribute skipped, ...), as import warnings.

    pyogrio raises them as Python RuntimeWarnings, and warnings.catch_warnings is process-wide: cells are read one
    at a time, and a warning of another thread caught meanwhile is issued again."""
    with _READING, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for warning in caught:
        if warning.filename.startswith(_PYOGRIO):
            into.append(f"GDAL: {_gdal_message(warning.message)}")
        else:
            warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)


def _gdal_message(error: Exception | Warning | str) -> str:
    lines = str(error).strip().splitlines() or ["(no message)"]
    return lines[0][:GDAL_MESSAGE_CHARS]


def _read_contents(
    path: Path, name: str, layers: set[str], options: dict[str, str], basemap: bool = False
) -> ChartContents:
    dsid = _layer(path, "DSID", options)  # one record, no geometry
    cell = _cell_info(dsid[0][0] if dsid else {}, name)
    left_out: list[str] = []
    marks = [
        obj
        for object_class in MARK_CLASSES
        if object_class in layers
        for obj in _points(path, object_class, options, left_out)
    ]
    lights = _points(path, "LIGHTS", options, left_out) if "LIGHTS" in layers else []
    systems = [
        SystemArea(geometry, _integer(attributes.get("MARSYS")))
        for attributes, geometry in _areas(path, "M_NSYS", layers, options)
    ]
    base_map = [
        feature
        for object_class in (BASEMAP_CLASSES if basemap else ())
        if object_class in layers
        for attributes, geometry in _layer(path, object_class, options)
        if (feature := basemap_feature(object_class, attributes, geometry)) is not None
    ]
    return ChartContents(cell, marks, lights, systems, _coverage(path, layers, options), left_out, base_map)


def _cell_info(dsid: dict[str, Any], name: str) -> CellInfo:
    dataset = dsid.get("DSID_DSNM")
    return CellInfo(
        name=Path(str(dataset)).stem if dataset else Path(name).stem,
        edition=_optional_text(dsid.get("DSID_EDTN")),
        update=_optional_text(dsid.get("DSID_UPDN")),
        issued=_optional_text(dsid.get("DSID_ISDT")),
    )


def _areas(path: Path, layer: str, layers: set[str], options: dict[str, str]) -> list[tuple[dict, BaseGeometry]]:
    """A meta layer's areas (M_NSYS, M_COVR), made valid: a damaged cell's ring could otherwise break a test of
    whether a mark lies inside."""
    if layer not in layers:
        return []
    return [(attributes, shapely.make_valid(g)) for attributes, g in _layer(path, layer, options) if g is not None]


def _coverage(path: Path, layers: set[str], options: dict[str, str]) -> BaseGeometry | None:
    """The area the cell covers: its M_COVR areas with coverage (CATCOV 1)."""
    covered = [
        geometry for attributes, geometry in _areas(path, "M_COVR", layers, options) if attributes.get("CATCOV") == 1
    ]
    return shapely.union_all(covered) if covered else None


def _points(path: Path, object_class: str, options: dict[str, str], left_out: list[str]) -> list[S57Object]:
    """A layer's point objects; an object of another geometry is left out with a warning."""
    objects = []
    for attributes, geometry in _layer(path, object_class, options):
        if not isinstance(geometry, shapely.Point) or geometry.is_empty:
            kind = "no geometry" if geometry is None else f"a {geometry.geom_type}"
            left_out.append(f"{object_label(object_class, attributes)}: {kind}, not a point: left out")
            continue
        objects.append(S57Object(object_class, attributes, lat=geometry.y, lon=geometry.x))
    return objects


def _layer(path: Path, layer: str, options: dict[str, str]) -> list[tuple[dict[str, Any], BaseGeometry | None]]:
    """Every object of a layer: its attributes as plain Python values, and its geometry."""
    meta, _, wkb, columns = read(path, layer=layer, **options)
    names = [str(name) for name in meta["fields"]]
    count = len(columns[0]) if columns else (0 if wkb is None else len(wkb))
    geometries: Sequence[BaseGeometry | None] = [None] * count if wkb is None else shapely.from_wkb(wkb)
    return [
        ({name: value for name, column in zip(names, columns, strict=True) if (value := _plain(column[i])) is not None},
         geometries[i])
        for i in range(count)
    ]  # fmt: skip


def _plain(value: Any) -> Any:
    """A NumPy cell as a Python value, None where the cell gives none (NaN, an empty string or list)."""
    if isinstance(value, np.ndarray):  # a list attribute: COLOUR, LNAM_REFS, ...
        return value.tolist() or None
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, str) and not value.strip():
        return None
    return value


def _integer(value: Any) -> int | None:
    return int(value) if isinstance(value, int | float) and float(value).is_integer() else None


def _optional_text(value: Any) -> str | None:
    return None if value is None else str(value)
