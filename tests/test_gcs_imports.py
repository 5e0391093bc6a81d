"""Buoy files: GeoJSON and CSV readers, with precise errors."""

import json
from pathlib import Path

import pytest

from gcs.domain.buoy_files import BuoyFileError, buoys_from_csv, buoys_from_file, buoys_from_geojson

REPO = Path(__file__).resolve().parents[1]


def point(lon, lat, **properties):
    return {"type": "Feature", "geometry": {"type": "Point", "coordinates": [lon, lat]}, "properties": properties}


def test_geojson_feature_collection_lon_lat_order_and_ids():
    document = {"type": "FeatureCollection", "features": [point(121.5, 38.9, id="A"), point(121.6, 38.8, name="B")]}
    file = buoys_from_geojson(document)
    assert [(b.lat, b.lon, b.id) for b in file.buoys] == [(38.9, 121.5, "A"), (38.8, 121.6, "B")]
    assert file.depot is None  # no point says it is the depot: the first is a buoy (the planner CLI's differs)


def test_geojson_role_depot_is_the_depot_not_a_buoy_and_role_buoy_a_buoy():
    features = [point(121.5, 38.9, id="A", role="buoy"), point(121.0, 38.0, role="Depot"), point(121.6, 38.8, id="B")]
    file = buoys_from_geojson({"type": "FeatureCollection", "features": features})
    assert [b.id for b in file.buoys] == ["A", "B"] and file.depot == (38.0, 121.0)


@pytest.mark.parametrize(
    ("roles", "where"),
    [(["depot", "buoy", "depot"], r"features\[2\]: a second depot \(the first is features\[0\]\)"),
     (["buoy", "dock"], r"features\[1\].properties.role: role 'dock' is neither depot nor buoy")],
)  # fmt: skip
def test_geojson_roles_that_cannot_be_flown_are_refused(roles, where):
    features = [point(121.0 + i / 100, 38.0, role=role) for i, role in enumerate(roles)]
    with pytest.raises(BuoyFileError, match=where):
        buoys_from_geojson({"type": "FeatureCollection", "features": features})


def test_the_example_geojson_is_13_buoys_and_a_depot():
    file = buoys_from_file((REPO / "examples" / "reference_buoys.geojson").read_bytes(), "reference_buoys.geojson")
    mission = json.loads((REPO / "examples" / "reference_mission.json").read_text())
    assert len(file.buoys) == 13 and file.depot == (mission["depot"]["lat"], mission["depot"]["lon"])


@pytest.mark.parametrize(
    ("document", "where"),
    [
        ({"type": "Polygon"}, "FeatureCollection"),
        ({"type": "FeatureCollection", "features": "x"}, "list"),
        (
            {"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": {"type": "LineString"}}]},
            "features[0].geometry",
        ),
        ({"type": "FeatureCollection", "features": [point(200.0, 10.0)]}, "longitude 200.0"),
        ({"type": "FeatureCollection", "features": [point(10.0, "a")]}, "numbers"),
        ({"type": "FeatureCollection", "features": [point(10.0, 10.0), point(10.0, -95.0)]}, "features[1]"),
    ],
)
def test_geojson_errors_name_the_place(document, where):
    with pytest.raises(BuoyFileError, match=where.replace("[", r"\[").replace("]", r"\]")):
        buoys_from_geojson(document)


def test_csv_with_header_in_any_column_order():
    file = buoys_from_csv("name,longitude,latitude\nN1,121.5,38.9\nN2,121.6,38.8\n")
    assert [(b.lat, b.lon, b.id) for b in file.buoys] == [(38.9, 121.5, "N1"), (38.8, 121.6, "N2")]


def test_csv_role_column_names_the_depot():
    file = buoys_from_csv("lat,lon,role\n38.0,121.0,depot\n38.9,121.5,\n38.8,121.6,buoy\n")
    assert file.depot == (38.0, 121.0) and [(b.lat, b.lon) for b in file.buoys] == [(38.9, 121.5), (38.8, 121.6)]
    with pytest.raises(BuoyFileError, match="CSV line 3: a second depot"):
        buoys_from_csv("lat,lon,role\n38.0,121.0,depot\n38.9,121.5,DEPOT\n")


def test_csv_without_header_is_lat_lon():
    file = buoys_from_csv("38.9,121.5\n\n38.8,121.6,X\n")
    assert [(b.lat, b.lon, b.id) for b in file.buoys] == [(38.9, 121.5, None), (38.8, 121.6, "X")]


def test_csv_lines_may_end_in_a_lone_carriage_return():
    # old Mac files; a lone CR once raised the csv module's error from inside the reader (HTTP 500 on /imports)
    file = buoys_from_csv("lat,lon,id\r38.9,121.5,A\r38.8,121.6,B\r")
    assert [(b.lat, b.lon, b.id) for b in file.buoys] == [(38.9, 121.5, "A"), (38.8, 121.6, "B")]
    with pytest.raises(BuoyFileError, match="the header needs columns named lat and lon"):
        buoys_from_csv("\r\x17\xb9")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no rows"),
        ("a,b\n1,2\n", "lat and lon"),
        ("lat,lon\n", "no buoys"),
        ("1,2\n3\n", "line 2"),
        ("lat,lon\n91,0\n", "line 2: latitude 91"),
        ("lat,lon\n" + "1" * 200_000 + ",2\n", "CSV: field larger than field limit"),
    ],
)
def test_csv_errors(text, message):
    with pytest.raises(BuoyFileError, match=message):
        buoys_from_csv(text)


def test_file_format_from_name_type_or_content():
    geo = json.dumps({"type": "FeatureCollection", "features": [point(1.0, 2.0)]}).encode()
    assert buoys_from_file(geo, "buoys.geojson").buoys[0].lat == 2.0
    assert buoys_from_file(geo, "", "application/geo+json").buoys[0].lat == 2.0
    assert buoys_from_file(geo).buoys[0].lat == 2.0
    assert buoys_from_file(b"lat,lon\n2,1\n", "b.csv").buoys[0].lon == 1.0
    with pytest.raises(BuoyFileError, match="UTF-8"):
        buoys_from_file(b"\xff\xfe\x00", "b.csv")
    with pytest.raises(BuoyFileError, match="not valid JSON"):
        buoys_from_file(b"{nope", "b.geojson")
