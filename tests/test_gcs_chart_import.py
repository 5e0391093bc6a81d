"""The chart import: buoys and beacons from NOAA's ENC US4MD81M (a real S-57 cell, tests/data/enc/README.md) through
gcs.charts, POST /imports and `python -m gcs chart`; the S-57 mapping on hand-made objects where the real cell has
no example (a missing CATLAM, an unknown code, several lights on one structure, region A).

The fixtures are the cell itself and copies of it made here: cut short, overwritten, a PNG named .000, and the cell
without its buoy, beacon and light records (whole ISO 8211 records dropped: what is left is still a valid cell).
"""

from __future__ import annotations

import json
import random
from collections import Counter
from pathlib import Path

import pytest
from test_gcs_api import errors_of, make_client

import stack.cli
from gcs.charts import is_cell, read_cell, read_upload
from gcs.cli import main
from gcs.domain.areas import AreaError, parse_area
from gcs.domain.chart_basemap import feature_collection
from gcs.domain.charted_marks import (
    CellInfo,
    ChartContents,
    ChartError,
    NothingInAreaError,
    S57Object,
    SystemArea,
    read_marks,
    world_of,
)
from gcs.domain.schemas import BuoyIn, MissionRequest
from uavcore.buoy_world import load_world
from uavcore.light_character import parse

CELL = Path(__file__).parent / "data" / "enc" / "US4MD81M" / "US4MD81M.000"
ANNAPOLIS = "-76.47,38.93,-76.40,38.99"  # the harbour's approach: 3 buoys, 6 beacons
ANNAPOLIS_IDS = {
    "0226525A78F0270F", "022601ED565CFB20", "02261D3BF8B707EE", "02260002734A0001", "02260002734E0001",
    "0226000268610001", "0226000273500001", "0226000273550001", "02266E4A56DD270F",
}  # fmt: skip
EMPTY_WATER = "-76.35,38.45,-76.34,38.46"  # inside the cell, no mark in it
PNG = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(64)
# S-57 object class codes (OBJL) of the marks and of LIGHTS
MARK_OBJL = {"BCNCAR": 5, "BCNISD": 6, "BCNLAT": 7, "BCNSAW": 8, "BCNSPP": 9, "BOYCAR": 14, "BOYISD": 16,
             "BOYLAT": 17, "BOYSAW": 18, "BOYSPP": 19, "LIGHTS": 75}  # fmt: skip
MARK_OBJL_COUNTS = {"BOYLAT": 71, "BOYSAW": 2, "BOYSPP": 19, "BCNLAT": 194, "BCNSPP": 30, "LIGHTS": 151}


@pytest.fixture(scope="module")
def cell_bytes() -> bytes:
    return CELL.read_bytes()


@pytest.fixture(scope="module")
def chart():
    return read_cell(CELL)


@pytest.fixture
def client(tmp_path):
    with make_client(tmp_path) as c:
        yield c


def by_name(chart, name):
    (mark,) = [m for m in chart.marks if m.name == name]
    return mark


# ----- the real cell
def test_the_cell_gives_its_buoys_and_beacons_of_several_kinds(chart):
    assert (chart.cell.name, chart.cell.edition, chart.cell.update, chart.cell.issued) == (
        "US4MD81M", "31", "0", "20250722",
    )  # fmt: skip
    buoys = Counter(m.kind for m in chart.marks if not m.beacon)
    beacons = Counter(m.kind for m in chart.marks if m.beacon)
    assert buoys == {"port": 37, "starboard": 34, "special": 19, "safe_water": 2}
    assert beacons == {"port": 104, "starboard": 90, "special": 30}
    assert Counter(m.object_class for m in chart.marks) == {
        "BOYLAT": 71, "BOYSAW": 2, "BOYSPP": 19, "BCNLAT": 194, "BCNSPP": 30,
    }  # fmt: skip
    assert len({m.id for m in chart.marks}) == len(chart.marks) == 316  # LNAMs: unique
    assert all(m.swing_radius_m == (0.0 if m.beacon else None) for m in chart.marks)
    assert chart.warnings == ()  # a clean cell: every attribute mapped


def test_every_light_reads_with_the_projects_parser(chart):
    lit = [m for m in chart.marks if m.light is not None]
    assert len(lit) == 141 and sum(not m.beacon for m in lit) == 38
    for mark in lit:
        assert parse(mark.light).abbreviation() == mark.light
    assert not any(m.other_lights for m in chart.marks)  # one light a structure in this cell


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        # LITCHR 2 (Fl), SIGGRP (1), SIGPER 2.5, COLOUR 3 (red); CATLAM 2; BOYSHP 4 (pillar)
        ("Annapolis Harbor Lighted Buoy 2",
         {"id": "0226525A78F0270F", "object_class": "BOYLAT", "kind": "starboard", "light": "Fl R 2.5s",
          "colours": ("red",), "colour_pattern": "solid", "shape": "pillar", "lat": 38.9418108, "lon": -76.4261103}),
        # BOYSAW, LITCHR 12 (Mo), SIGGRP (A), SIGPER 8, COLOUR 1; COLOUR 3,1 COLPAT 2 (vertical stripes)
        ("Chesapeake Channel Mid-Channel Lighted Buoy CP",
         {"kind": "safe_water", "light": "Mo(A) W 8s", "colours": ("red", "white"), "colour_pattern": "vertical"}),
        # LITCHR 4 (Q), SIGPER 1, COLOUR 3
        ("Choptank River Lighted Buoy 8", {"kind": "starboard", "light": "Q R 1s", "colours": ("red",)}),
        # CATLAM 3: preferred channel to starboard, a port-hand mark, green-red-green bands; unlit can
        ("South River Junction Buoy SR",
         {"kind": "port", "preferred_channel": "starboard", "colours": ("green", "red", "green"),
          "colour_pattern": "horizontal", "shape": "can", "light": None}),
        # CATLAM 4 on a beacon: Fl(2+1) R 6s, fixed
        ("Saunders Point Shoal Junction Light",
         {"object_class": "BCNLAT", "kind": "starboard", "preferred_channel": "port", "light": "Fl(2+1) R 6s",
          "swing_radius_m": 0.0, "shape": "stake"}),
        ("Triton Light", {"kind": "port", "light": "Fl(4+5) G 30s", "beacon": True}),
        ("NOAA Lighted Data Buoy AN", {"object_class": "BOYSPP", "kind": "special", "light": "Fl Y 4s"}),
        # COLOUR 1,11: white and orange, horizontal bands (a US regulatory buoy)
        ("Scraping Limit Buoy A", {"kind": "special", "colours": ("white", "orange"), "light": None}),
    ],
)  # fmt: skip
def test_real_marks_are_what_the_cell_says(chart, name, expected):
    mark = by_name(chart, name)
    assert {key: getattr(mark, key) for key in expected} == expected


def test_the_region_is_the_charts_and_the_colours_are_as_charted(chart):
    assert (chart.region, chart.region_source) == ("B", "chart")  # M_NSYS MARSYS 2
    assert {m.region for m in chart.marks} == {"B"}
    plain_lateral = [m for m in chart.marks if m.object_class.endswith("LAT") and m.preferred_channel is None]
    # region B: port green, starboard red; the charted COLOUR, not uavcore.buoy_world.APPEARANCE's region A
    assert {(m.kind, m.colours) for m in plain_lateral} == {("port", ("green",)), ("starboard", ("red",))}
    # a region asked for is the fallback: the chart's own MARSYS wins
    assert read_cell(CELL, region="A", area=parse_area(ANNAPOLIS)).region == "B"


def test_an_area_takes_the_marks_inside_it(chart):
    assert {m.id for m in read_cell(CELL, area=parse_area(ANNAPOLIS)).marks} == ANNAPOLIS_IDS
    west, south, east, north = -76.47, 38.93, -76.40, 38.99
    triangle = {"type": "Polygon", "coordinates": [[[west, south], [east, south], [west, north], [west, south]]]}
    inside = read_cell(CELL, area=parse_area(json.dumps({"type": "Feature", "geometry": triangle}))).marks
    assert {m.id for m in inside} < ANNAPOLIS_IDS
    assert all((m.lon - west) / (east - west) + (m.lat - south) / (north - south) <= 1 for m in inside)
    assert len(inside) == len(read_cell(CELL, area=parse_area(json.dumps(triangle))).marks) > 0


@pytest.mark.parametrize(
    ("area", "message"),
    [
        ("1,1,2,2", "US4MD81M: the area 1.00000,1.00000,2.00000,2.00000 lies outside the cell, which covers -76.58"),
        (
            EMPTY_WATER,
            "US4MD81M: no buoys or beacons in the area -76.35000,38.45000,-76.34000,38.46000; the cell's 316",
        ),
    ],
)
def test_an_area_without_marks_says_where_they_are(area, message):
    with pytest.raises(NothingInAreaError) as raised:
        read_cell(CELL, area=parse_area(area))
    assert str(raised.value).startswith(message)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1,2,3", "expected west,south,east,north"),
        ("3,2,1,4", "needs west < east and south < north"),
        ("-200,1,2,3", "is not a [lon, lat] position"),
        ("{nope", "not JSON"),
        ('{"type": "LineString", "coordinates": [[0, 0], [1, 1]]}', "expected a GeoJSON Polygon"),
        ('{"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [1, 0], [0, 1], [0, 0]]]}', "Self-intersection"),
        ('{"type": "Polygon", "coordinates": [[[0, 0], [1]]]}', "cannot be read"),
        ('{"type": "Polygon", "coordinates": [[[0, 95], [1, 95], [1, 96], [0, 95]]]}', "is not a [lon, lat]"),
    ],
)
def test_a_bad_area_is_refused_naming_why(text, message):
    with pytest.raises(AreaError, match=message.replace("[", r"\[")):
        parse_area(text)


# ----- bad files
def records(data: bytes) -> list[bytes]:
    """The cell's ISO 8211 records: each starts with its length in five digits."""
    found, offset = [], 0
    while offset < len(data):
        length = int(data[offset : offset + 5])
        found.append(data[offset : offset + length])
        offset += length
    return found


def object_class_code(record: bytes) -> int | None:
    """A feature record's OBJL (its FRID field: RCNM, RCID, PRIM, GRUP, then OBJL, two bytes little-endian)."""
    base = int(record[12:17])  # where the fields start
    length_digits, position_digits, tag_chars = record[20] - 48, record[21] - 48, 4  # the leader's entry map
    entry_size = tag_chars + length_digits + position_digits
    entry = 24
    while record[entry] != 0x1E:  # the directory: tag, field length, field position each; then a field terminator
        if record[entry : entry + tag_chars] == b"FRID":
            position = int(record[entry + tag_chars + length_digits : entry + entry_size])
            return int.from_bytes(record[base + position + 7 : base + position + 9], "little")
        entry += entry_size
    return None


def without_marks(data: bytes) -> bytes:
    """The cell without its buoy, beacon and light records: a real cell holding no marks."""
    return b"".join(r for r in records(data) if object_class_code(r) not in MARK_OBJL.values())


def damaged(data: bytes, seed: int) -> bytes:
    """The cell with a span overwritten by random bytes (seeded)."""
    rng = random.Random(seed)
    start, length = rng.randrange(len(data) - 4096), rng.choice([1, 16, 4096])
    return data[:start] + rng.randbytes(length) + data[start + length :]


def test_the_cell_is_known_by_its_name_or_its_leader(cell_bytes):
    assert is_cell(cell_bytes) and is_cell(b"anything", "US4MD81M.000") and is_cell(cell_bytes, "chart.bin")
    assert not is_cell(b"lat,lon\n38.9,-76.4\n", "b.csv") and not is_cell(PNG, "x.png")


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda data: data[:100_000], "upload.000: not a readable S-57 cell: "),
        (lambda data: data[:10], "upload.000: not an S-57 cell: it does not start with an ISO 8211 record leader"),
        (lambda data: b"", "upload.000: not an S-57 cell"),
        (lambda data: PNG, "upload.000: not an S-57 cell"),
        (lambda data: data[:5] + b"9" + data[6:], "upload.000: not a readable S-57 cell: "),  # the leader's level
        (without_marks, "US4MD81M: the cell has no buoys or beacons (BOYLAT, BOYCAR, BOYISD, BOYSAW, BOYSPP, BCNLAT"),
    ],
    ids=["truncated", "a leader cut short", "empty", "a PNG", "a bad leader", "no marks"],
)
def test_a_file_that_gives_no_buoys_is_a_chart_error_naming_why(cell_bytes, make, message):
    with pytest.raises(ChartError) as raised:
        read_upload(make(cell_bytes), "upload.000")
    assert str(raised.value).startswith(message)


def test_the_cell_without_marks_still_reads_as_a_cell(cell_bytes):
    stripped = without_marks(cell_bytes)
    assert len(records(stripped)) == len(records(cell_bytes)) - sum(MARK_OBJL_COUNTS.values())
    assert stripped[:5].isdigit()  # the same leader


def test_a_damaged_cell_that_still_reads_keeps_its_marks_and_says_what_it_lost(cell_bytes):
    result = read_upload(damaged(cell_bytes, 10), "damaged.000")  # 16 bytes overwritten in a LIGHTS record
    assert len(result.marks) == 316
    assert result.warnings[0].startswith("GDAL: ") and "attribute" in result.warnings[0]  # GDAL skipped one
    assert result.warnings[1] == (
        "BOYLAT 'Choptank River Lighted Buoy 5' (0226000F79FEFB1B): light S-57 SIGGRP (1), SIGPER 2.5, COLOUR 4 "
        "not read (LITCHR missing is no light character): kept as charted in other_lights"
    )
    buoy5 = next(m for m in result.marks if m.id == "0226000F79FEFB1B")
    assert (buoy5.kind, buoy5.light, buoy5.other_lights) == ("port", None, ("S-57 SIGGRP (1), SIGPER 2.5, COLOUR 4",))


@pytest.mark.parametrize("seed", range(4))
def test_a_damaged_cell_gives_marks_or_a_chart_error_never_another_error(cell_bytes, seed):
    try:
        result = read_upload(damaged(cell_bytes, seed), "damaged.000")
    except ChartError as error:
        assert "damaged.000" in str(error) or "US4MD81M" in str(error)
    else:
        assert all(isinstance(m.id, str) for m in result.marks)


# ----- POST /imports
def test_post_imports_takes_the_cell_and_answers_buoys_for_a_mission(client, cell_bytes):
    answer = client.post("/imports?filename=US4MD81M.000", content=cell_bytes)
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert len(body["buoys"]) == len(body["chart"]["marks"]) == 316 and body["warnings"] == []
    assert all(set(b) == set(BuoyIn.model_fields) for b in body["buoys"])
    MissionRequest.model_validate({"buoys": body["buoys"][:100]})  # as POST /missions takes them
    buoy2 = next(i for i, m in enumerate(body["chart"]["marks"]) if m["name"] == "Annapolis Harbor Lighted Buoy 2")
    assert body["buoys"][buoy2] == {
        "id": "0226525A78F0270F", "lat": 38.9418108, "lon": -76.4261103, "kind": "starboard", "light": "Fl R 2.5s",
        "swing_radius_m": None, "register_id": None, "charted": None, "region": "B",
    }  # fmt: skip
    mark = body["chart"]["marks"][buoy2]
    assert (mark["colours"], mark["region"], mark["beacon"], mark["object_class"]) == (["red"], "B", False, "BOYLAT")
    chart = {k: v for k, v in body["chart"].items() if k != "marks"}
    assert chart == {"cell": "US4MD81M", "edition": "31", "update": "0", "issued": "20250722", "region": "B",
                     "region_source": "chart"}  # fmt: skip


def test_post_imports_filters_by_area_and_knows_a_cell_by_its_leader(client, cell_bytes):
    polygon = {"type": "Polygon", "coordinates": [[[-76.47, 38.93], [-76.40, 38.93], [-76.40, 38.99],
                                                   [-76.47, 38.99], [-76.47, 38.93]]]}  # fmt: skip
    for area in (ANNAPOLIS, json.dumps(polygon)):
        answer = client.post("/imports", params={"area": area, "region": "A"}, content=cell_bytes)
        assert answer.status_code == 200, answer.text
        assert {b["id"] for b in answer.json()["buoys"]} == ANNAPOLIS_IDS
        assert answer.json()["chart"]["region"] == "B"


@pytest.mark.parametrize(
    ("make", "params", "where", "message"),
    [
        (lambda data: data[:100_000], {}, ["body"], "x.000: not a readable S-57 cell"),
        (lambda data: PNG, {}, ["body"], "x.000: not an S-57 cell"),
        (without_marks, {}, ["body"], "US4MD81M: the cell has no buoys or beacons"),
        (lambda data: data, {"area": EMPTY_WATER}, ["query", "area"], "US4MD81M: no buoys or beacons in the area"),
        (lambda data: data, {"area": "1,1,2,2"}, ["query", "area"], "US4MD81M: the area 1.00000,1.00000,2.00000"),
        (lambda data: data, {"area": "1,2,3"}, ["query", "area"], "'1,2,3': expected west,south,east,north"),
    ],
    ids=["truncated", "a PNG", "no marks", "empty water", "outside the cell", "a bad area"],
)
def test_post_imports_answers_a_bad_cell_with_422_naming_it_and_stores_nothing(
    client, cell_bytes, make, params, where, message
):
    answer = client.post("/imports", params={"filename": "x.000"} | params, content=make(cell_bytes))
    [(loc, msg)] = errors_of(answer)
    assert loc == where and msg.startswith(message), msg
    assert client.get("/missions").json() == []


def test_post_imports_answers_a_damaged_cell_with_422_or_the_marks_and_warnings(client, cell_bytes):
    errors = errors_of(client.post("/imports?filename=damaged.000", content=damaged(cell_bytes, 0)))
    assert errors == [(["body"], "damaged.000: not a readable S-57 cell: ISO8211 record leader appears to be corrupt.")]
    answer = client.post("/imports?filename=damaged.000", content=damaged(cell_bytes, 10)).json()
    assert len(answer["buoys"]) == 316 and len(answer["warnings"]) == 2


def test_area_and_region_belong_to_a_cell(client):
    errors = errors_of(client.post("/imports?filename=b.csv&area=1,2,3,4&region=B", content=b"lat,lon\n1,2\n"))
    assert [loc for loc, _ in errors] == [["query", "area"], ["query", "region"]]
    assert "a GeoJSON or CSV file is taken whole" in errors[0][1]
    assert errors_of(client.post("/imports?filename=x.000&region=C", content=PNG))[0][0] == ["query", "region"]


def test_a_cell_may_be_larger_than_other_bodies_up_to_its_own_limit(tmp_path, cell_bytes):
    with make_client(tmp_path, max_chart_bytes=1 << 20) as c:
        answer = c.post("/imports?filename=x.000", content=cell_bytes)
        assert answer.status_code == 413
        assert answer.json() == {
            "detail": [
                {"type": "too_large", "loc": ["body"], "msg": f"the request body is larger than {1 << 20} bytes"}
            ]
        }
    with make_client(tmp_path, max_body_bytes=4096) as c:
        assert c.post("/imports?filename=x.000", content=cell_bytes).status_code == 200  # 3.5 MB: under 5 MiB
        csv = b"lat,lon\n" + b"38.9,-76.4\n" * 500
        assert c.post("/imports?filename=b.csv", content=csv).json() == {
            "detail": [{"type": "too_large", "loc": ["body"], "msg": "the request body is larger than 4096 bytes"}]
        }


# ----- the command line
def test_the_cli_prints_the_marks_and_writes_a_world_file_both_readers_take(tmp_path, capsys, client):
    out = tmp_path / "annapolis.geojson"
    assert main(["chart", str(CELL), f"--area={ANNAPOLIS}", "--geojson", str(out)]) == 0
    printed = capsys.readouterr()
    assert "0226525A78F0270F  starboard  buoy    Fl R 2.5s  red" in printed.out
    assert "Annapolis Harbor Lighted Buoy 2" in printed.out
    assert "US4MD81M (edition 31, update 0, issued 20250722), IALA region B (the chart's): 9 marks" in printed.out
    assert printed.err == ""
    world = load_world(out)  # sitl-quad --world's reader
    assert {b.id for b in world.buoys} == ANNAPOLIS_IDS
    beacon = next(b for b in world.buoys if b.id == "0226000268610001")  # Annapolis Harbor Entrance Light 4
    assert (beacon.kind, beacon.light, beacon.swing_radius_m) == ("starboard", parse("Fl R 6s"), 0.0)
    imported = client.post("/imports?filename=annapolis.geojson", content=out.read_bytes()).json()["buoys"]
    from_cell = client.post(f"/imports?filename=x.000&area={ANNAPOLIS}", content=CELL.read_bytes()).json()["buoys"]
    assert [(b["id"], b["kind"], b["light"]) for b in imported] == [(b["id"], b["kind"], b["light"]) for b in from_cell]


def test_the_world_file_leaves_out_what_the_simulator_cannot_fly_and_says_why(tmp_path, capsys):
    out = tmp_path / "cell.geojson"
    assert stack.cli.main(["chart", str(CELL), "--geojson", str(out)]) == 0  # buoy-gcs chart: the same
    err = capsys.readouterr().err.splitlines()
    # two unnamed special beacons carry an aero light (CATLIT 5) charted without a period
    assert len(err) == 2 and all("not in the world file: its light Fl R has no period" in line for line in err)
    assert len(load_world(out).buoys) == 314


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.000"], "missing.000: cannot be read: No such file or directory"),
        (["png.000"], "png.000: not an S-57 cell"),
        (["cut.000"], "cut.000: not a readable S-57 cell"),
        ([str(CELL), "--area", "1,2,3"], "'1,2,3': expected west,south,east,north"),
        ([str(CELL), f"--area={EMPTY_WATER}"], "US4MD81M: no buoys or beacons in the area"),
        ([str(CELL), "--geojson", "no/such/folder/out.geojson"], "cannot write no/such/folder/out.geojson"),
    ],
)
def test_the_cli_exits_2_with_a_message_on_bad_input(tmp_path, monkeypatch, capsys, args, message):
    monkeypatch.chdir(tmp_path)
    Path("png.000").write_bytes(PNG)
    Path("cut.000").write_bytes(CELL.read_bytes()[:50_000])
    assert main(["chart", *args]) == 2
    assert capsys.readouterr().err.startswith(f"buoy-gcs: chart: {message}")


def test_the_cli_reads_an_area_from_a_file(tmp_path, capsys):
    west, south, east, north = (float(v) for v in ANNAPOLIS.split(","))
    ring = [[west, south], [east, south], [east, north], [west, north], [west, south]]
    area = tmp_path / "area.geojson"
    area.write_text(json.dumps({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [ring]}}))
    assert main(["chart", str(CELL), "--area", str(area)]) == 0
    assert ": 9 marks, 3 buoys and 6 beacons, 8 lit" in capsys.readouterr().out


# ----- the mapping, on objects made here (what the real cell has no example of)
def point(object_class, lat=38.9, lon=-76.4, **attributes):
    return S57Object(object_class, {"LNAM": f"L{object_class}{lat}{lon}"} | attributes, lat, lon)


def read(*marks, lights=(), systems=(), region="A"):
    result = read_marks(ChartContents(CellInfo("TEST"), marks, lights, systems), region)
    return result.marks, result.warnings


@pytest.mark.parametrize(
    ("region", "colour", "kind"),
    [("A", "3", "port"), ("A", "4", "starboard"), ("B", "3", "starboard"), ("B", "4", "port")],
)
def test_a_lateral_mark_without_catlam_takes_its_side_from_its_colour_in_its_region(region, colour, kind):
    (mark,), (warning,) = read(point("BOYLAT", OBJNAM="X 1", COLOUR=[colour]), region=region)
    assert (mark.kind, mark.region) == (kind, region)
    assert warning.startswith("BOYLAT 'X 1' (LBOYLAT38.9-76.4): CATLAM missing: kind " + kind)


def test_what_cannot_be_mapped_is_left_out_and_named():
    (mark,), warnings = read(point("BCNLAT", CATLAM=11, COLOUR=["3", "4", "99", "x"], BCNSHP=42, RCID=7, LNAM=None))
    assert (mark.id, mark.kind, mark.colours, mark.shape, mark.beacon) == ("RCID7", None, ("red", "green"), None, True)
    assert warnings == (
        "BCNLAT (RCID 7): COLOUR 99, x not an S-57 value this import knows: left out",
        "BCNLAT (RCID 7): CATLAM 11 not a side this maps, and its colours red/green do not tell the side: kind unknown",
        "BCNLAT (RCID 7): BCNSHP 42 not an S-57 value this import knows: left out",
    )


@pytest.mark.parametrize(("catcam", "kind"), [(1, "north"), (2, "east"), (3, "south"), (4, "west"), (None, None)])
def test_cardinal_marks_take_their_quadrant(catcam, kind):
    (mark,), warnings = read(point("BOYCAR", CATCAM=catcam, COLOUR=["2", "6"], COLPAT=["1"]))
    assert (mark.kind, mark.colours, mark.colour_pattern) == (kind, ("black", "yellow"), "horizontal")
    assert len(warnings) == (kind is None)


@pytest.mark.parametrize(
    ("object_class", "kind"),
    [("BOYISD", "isolated_danger"), ("BCNISD", "isolated_danger"), ("BCNSAW", "safe_water"), ("BCNSPP", "special")],
)
def test_the_other_classes_are_their_kind(object_class, kind):
    assert read(point(object_class))[0][0].kind == kind


def test_the_main_light_is_the_navigation_light_and_the_others_are_kept():
    mark = point("BOYCAR", CATCAM=1, LNAM_REFS=["AERO", "MAIN", "ODD"])
    aero = point("LIGHTS", LNAM="AERO", LITCHR=2, SIGPER=1.5, COLOUR=["3"], CATLIT=["5"], VALNMR=20.0)
    main = point("LIGHTS", LNAM="MAIN", LITCHR=4, COLOUR=["1"], VALNMR=5.0)
    odd = point("LIGHTS", LNAM="ODD", LITCHR=13, SIGPER=5.0, COLOUR=["1"])  # 13: fixed and flashing, not read
    (found,), warnings = read(mark, lights=(aero, odd, main))
    # in rank order: the aero light, though it reaches further, comes last
    assert (found.light, found.other_lights) == ("Q W", ("S-57 LITCHR 13, SIGPER 5.0, COLOUR 1", "Fl R 1.5s"))
    assert warnings == (
        "BOYCAR (LBOYCAR38.9-76.4): light S-57 LITCHR 13, SIGPER 5.0, COLOUR 1 not read (S-57 LITCHR 13 COLOUR "
        "'1': not a character this module reads): kept as charted in other_lights",
    )


def test_a_light_belongs_to_its_linked_mark_or_to_the_nearest_within_a_metre():
    near, far = point("BOYLAT", CATLAM=1), point("BOYLAT", lat=38.9001, CATLAM=2, LNAM_REFS=["LINKED"])
    linked = point("LIGHTS", LNAM="LINKED", LITCHR=2, SIGPER=4.0, COLOUR=["3"])  # 11 m from `far`, linked to it
    close = point("LIGHTS", lat=38.900005, LNAM="CLOSE", LITCHR=2, SIGPER=4.0, COLOUR=["4"])  # 0.6 m from `near`
    away = point("LIGHTS", lat=38.90002, LNAM="AWAY", LITCHR=7, SIGPER=2.0)  # 2.2 m: on no mark
    marks, _ = read(near, far, lights=(linked, close, away))
    assert [(m.light, m.other_lights) for m in marks] == [("Fl G 4s", ()), ("Fl R 4s", ())]


def test_the_marks_own_marsys_beats_its_area_and_a_system_that_is_no_region_gives_none():
    from shapely.geometry import box

    systems = (SystemArea(box(-77, 38, -76, 39), 2), SystemArea(box(-80, 38, -77, 39), 11))
    marks, warnings = read(
        point("BOYLAT", CATLAM=1),  # in the region B area
        point("BOYLAT", lat=38.5, CATLAM=1, MARSYS=1),  # says A itself
        point("BOYLAT", lon=-78.0, COLOUR=["3"]),  # in a CEVNI area: no region, so no side from its colour
        point("BOYLAT", lat=40.0, COLOUR=["3"]),  # in no area: the fallback, A
        systems=systems,
    )
    assert [(m.region, m.kind) for m in marks] == [("B", "port"), ("A", "port"), (None, None), ("A", "port")]
    assert warnings[0] == "M_NSYS: MARSYS 11 is no IALA region: its marks' colours are read in none"
    result = read_marks(ChartContents(CellInfo("T"), (point("BOYSPP"),), systems=systems))
    assert (result.region, result.region_source) == ("A", "default")  # two systems: the cell names no one region
    result = read_marks(ChartContents(CellInfo("T"), (point("BOYSPP"),), systems=systems[:1]))
    assert (result.region, result.region_source) == ("B", "chart")


def test_a_cell_without_region_takes_the_fallback():
    result = read_marks(ChartContents(CellInfo("T"), (point("BOYLAT", CATLAM=2),)), "B")
    assert (result.region, result.region_source, result.marks[0].region) == ("B", "default", "B")


def test_the_world_file_holds_the_marks_with_a_kind_and_a_flashable_light():
    marks, _ = read(
        point("BOYLAT", CATLAM=1, LNAM="A"),
        point("BCNLAT", lat=38.91, CATLAM=2, LNAM="B"),
        point("BOYLAT", lat=38.92, LNAM="C"),  # no CATLAM, no colour: no kind
        point("BOYSPP", lat=38.93, LNAM="D", LNAM_REFS=["L"]),
        lights=(point("LIGHTS", lat=38.93, LNAM="L", LITCHR=4, COLOUR=["6"], SIGGRP="(3)"),),  # Q(3) Y: no period
    )
    world, left_out = world_of(marks)
    assert [(b.id, b.kind, b.swing_radius_m) for b in world.buoys] == [("A", "port", 5.0), ("B", "starboard", 0.0)]
    assert left_out == [
        "BOYLAT (C): not in the world file: its kind is unknown",
        "BOYSPP (D): not in the world file: its light Q(3) Y has no period",
    ]
    assert load_world(world.to_geojson()) == world


def test_the_base_map_joins_the_cells_feature_lists_into_one_collection():
    document = json.loads(feature_collection(["[]", '[{"x": 1}]', "[]", '[{"y": 2}, {"z": 3}]']))
    assert document == {"type": "FeatureCollection", "features": [{"x": 1}, {"y": 2}, {"z": 3}]}
    assert json.loads(feature_collection([])) == {"type": "FeatureCollection", "features": []}
