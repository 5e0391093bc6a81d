"""`python -m planner` run as a subprocess: round trips on every file format, and every bad input."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planner.distances import closed_tour_length, euclidean_matrix
from planner.exact import held_karp
from planner.scenario import reference_scenario
from planner.tsplib import parse_tsp
from uavcore.geodesy import LocalFrame

# Each test starts `python -m planner` (a fresh interpreter importing numpy and numba: about a second apiece).
pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[1]
TSPLIB = REPO / "tests" / "data" / "tsplib"


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "planner", *map(str, args)], capture_output=True, text=True, cwd=REPO, timeout=120
    )


def geojson(points, roles=None) -> str:
    features = []
    for i, (lat, lon) in enumerate(points):
        props = {"role": roles[i]} if roles and roles[i] else {}
        features.append(
            {"type": "Feature", "properties": props, "geometry": {"type": "Point", "coordinates": [lon, lat]}}
        )
    return json.dumps({"type": "FeatureCollection", "features": features})


def scenario_lat_lon(seed=3, n=9) -> np.ndarray:
    s = reference_scenario(seed=seed, n_buoys=n)
    return np.vstack([[s.home[0], s.home[1]], s.buoys_lat_lon])


def optimum_in_metres(lat_lon: np.ndarray) -> float:
    metres = LocalFrame(lat_lon[0, 0], lat_lon[0, 1]).project(lat_lon)
    return held_karp(euclidean_matrix(metres))[1]


def test_reference_example_round_trip():
    out = run(REPO / "examples" / "reference_buoys.geojson", "--method", "chnn-ga", "--seed", "1", "--json")
    assert out.returncode == 0, out.stderr
    plan = json.loads(out.stdout)
    assert set(plan) == {"order", "length", "method", "elapsed_s"}
    assert sorted(plan["order"]) == list(range(14)) and plan["order"][0] == 0
    data = json.loads((REPO / "examples" / "reference_buoys.geojson").read_text())
    assert data["features"][0]["properties"]["role"] == "depot"
    lat_lon = np.array([f["geometry"]["coordinates"][::-1] for f in data["features"]])
    assert plan["length"] == pytest.approx(optimum_in_metres(lat_lon), rel=1e-9)


def test_geojson_depot_is_the_marked_feature_and_order_indexes_the_input(tmp_path):
    lat_lon = scenario_lat_lon()
    # put the depot third in the file: node indices in the answer are the planner's (depot first)
    shuffled = [lat_lon[1], lat_lon[2], lat_lon[0], *lat_lon[3:]]
    roles = ["", "", "depot"] + [""] * (len(lat_lon) - 3)
    path = tmp_path / "mission.geojson"
    path.write_text(geojson(shuffled, roles))
    out = run(path, "--method", "exact", "--json")
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["length"] == pytest.approx(optimum_in_metres(lat_lon), rel=1e-9)


def test_csv_with_and_without_header_and_explicit_depot(tmp_path):
    lat_lon = scenario_lat_lon(seed=5, n=7)
    plain = tmp_path / "plain.csv"
    plain.write_text("\n".join(f"{lat},{lon}" for lat, lon in lat_lon))
    header = tmp_path / "header.csv"
    header.write_text("name,lon,lat\n" + "\n".join(f"b{i},{lon},{lat}" for i, (lat, lon) in enumerate(lat_lon)))
    buoys_only = tmp_path / "buoys.csv"
    buoys_only.write_text("\n".join(f"{lat},{lon}" for lat, lon in lat_lon[1:]))
    expected = optimum_in_metres(lat_lon)
    for args in ([plain], [header], [buoys_only, f"--depot={lat_lon[0, 0]},{lat_lon[0, 1]}"]):
        out = run(*args, "--method", "auto", "--json")
        assert out.returncode == 0, out.stderr
        plan = json.loads(out.stdout)
        assert plan["method"] == "exact"
        assert plan["length"] == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize(("name", "method"), [("burma14", "exact"), ("ulysses16", "auto"), ("ulysses22", "chnn-ga")])
def test_tsplib_lengths_use_tsplib_distances(name, method):
    out = run(TSPLIB / f"{name}.tsp", "--method", method, "--seed", "2", "--json")
    assert out.returncode == 0, out.stderr
    plan = json.loads(out.stdout)
    dist = parse_tsp((TSPLIB / f"{name}.tsp").read_text()).distance_matrix()
    assert isinstance(plan["length"], int)
    assert plan["length"] == closed_tour_length(plan["order"], dist)
    if method != "chnn-ga":
        assert plan["length"] == held_karp(dist)[1]


def test_human_summary_and_plot(tmp_path):
    png = tmp_path / "route.png"
    out = run(REPO / "examples" / "reference_buoys.geojson", "--seed", "1", "--plot", png)
    assert out.returncode == 0, out.stderr
    assert "closed tour" in out.stdout and "order: 0 " in out.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def bad(tmp_path, name: str, text: str | bytes) -> Path:
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("name", "content", "extra", "message"),
    [
        ("empty.geojson", geojson([]), [], "at least one buoy"),
        ("single.geojson", geojson([(38.9, 121.6)]), [], "at least one buoy"),
        ("dup.geojson", geojson([(38.9, 121.6), (38.91, 121.61), (38.91, 121.61)]), [], "same place"),
        ("range.geojson", geojson([(38.9, 121.6), (95.0, 121.6)]), [], "outside"),
        (
            "nan.geojson",
            '{"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": '
            '{"type": "Point", "coordinates": [NaN, 38.9]}}]}',
            [],
            "finite",
        ),
        ("broken.geojson", "{not json", [], "not valid JSON"),
        (
            "line.geojson",
            '{"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": '
            '{"type": "LineString", "coordinates": [[0, 0], [1, 1]]}}]}',
            [],
            "Point",
        ),
        ("two.geojson", geojson([(38.9, 121.6), (38.91, 121.6)], ["depot", "depot"]), [], "marked as depot"),
        ("empty.csv", "", [], "no rows"),
        ("text.csv", "38.9,121.6\n38.91,east\n", [], "not a number"),
        ("inf.csv", "38.9,121.6\n38.91,inf\n", [], "finite"),
        ("binary.csv", b"\xff\xfe\x00\x01garbage", [], "cannot read"),
        ("mission.txt", "38.9,121.6\n38.91,121.6\n", [], "unknown file type"),
        ("ok.csv", "38.9,121.6\n38.91,121.6\n", ["--depot", "38.9"], "LAT,LON"),
        ("ok2.csv", "38.9,121.6\n38.91,121.6\n", ["--time-limit", "-1"], "time limit"),
    ],
)
def test_bad_input_gives_a_message_and_non_zero_exit(tmp_path, name, content, extra, message):
    out = run(bad(tmp_path, name, content), *extra)
    assert out.returncode == 2
    assert message in out.stderr
    assert "Traceback" not in out.stderr
    assert out.stdout == ""


def test_missing_file_too_many_nodes_and_bad_options(tmp_path):
    missing = run(tmp_path / "nope.geojson")
    assert missing.returncode == 2 and "cannot read" in missing.stderr
    too_many = run(TSPLIB / "ulysses22.tsp", "--method", "exact")
    assert too_many.returncode == 2 and "at most 16" in too_many.stderr
    unknown = run(TSPLIB / "burma14.tsp", "--method", "annealing")
    assert unknown.returncode == 2 and "invalid choice" in unknown.stderr
    for out in (missing, too_many, unknown):
        assert "Traceback" not in out.stderr
