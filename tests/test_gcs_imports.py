"""Buoy files: GeoJSON and CSV readers, with precise errors."""

import json

import pytest

from gcs.domain.buoy_files import BuoyFileError, buoys_from_csv, buoys_from_file, buoys_from_geojson


def point(lon, lat, **properties):
    return {"type": "Feature", "geometry": {"type": "Point", "coordinates": [lon, lat]}, "properties": properties}


def test_geojson_feature_collection_lon_lat_order_and_ids():
    document = {"type": "FeatureCollection", "features": [point(121.5, 38.9, id="A"), point(121.6, 38.8, name="B")]}
    buoys = buoys_from_geojson(document)
    assert [(b.lat, b.lon, b.id) for b in buoys] == [(38.9, 121.5, "A"), (38.8, 121.6, "B")]


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
    buoys = buoys_from_csv("name,longitude,latitude\nN1,121.5,38.9\nN2,121.6,38.8\n")
    assert [(b.lat, b.lon, b.id) for b in buoys] == [(38.9, 121.5, "N1"), (38.8, 121.6, "N2")]


def test_csv_without_header_is_lat_lon():
    buoys = buoys_from_csv("38.9,121.5\n\n38.8,121.6,X\n")
    assert [(b.lat, b.lon, b.id) for b in buoys] == [(38.9, 121.5, None), (38.8, 121.6, "X")]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no rows"),
        ("a,b\n1,2\n", "lat and lon"),
        ("lat,lon\n", "no buoys"),
        ("1,2\n3\n", "line 2"),
        ("lat,lon\n91,0\n", "line 2: latitude 91"),
    ],
)
def test_csv_errors(text, message):
    with pytest.raises(BuoyFileError, match=message):
        buoys_from_csv(text)


def test_file_format_from_name_type_or_content():
    geo = json.dumps({"type": "FeatureCollection", "features": [point(1.0, 2.0)]}).encode()
    assert buoys_from_file(geo, "buoys.geojson")[0].lat == 2.0
    assert buoys_from_file(geo, "", "application/geo+json")[0].lat == 2.0
    assert buoys_from_file(geo)[0].lat == 2.0
    assert buoys_from_file(b"lat,lon\n2,1\n", "b.csv")[0].lon == 1.0
    with pytest.raises(BuoyFileError, match="UTF-8"):
        buoys_from_file(b"\xff\xfe\x00", "b.csv")
    with pytest.raises(BuoyFileError, match="not valid JSON"):
        buoys_from_file(b"{nope", "b.geojson")
