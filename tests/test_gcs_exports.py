"""Mission files: QGC .plan and WPL 110 round trips, and the flown track as GeoJSON."""

import json
import math

import pytest

from gcs.domain.planning import FlightParams, make_plan, mission_items
from gcs.domain.schemas import FenceZoneIn
from gcs.reports import exports
from planner.scenario import reference_scenario
from uavcore.mission import MavCmd

HOME = (38.9210, 121.6630, 0.0)
FLIGHT = FlightParams(altitude_m=5.0, speed_m_s=10.0, dwell_s=1.5, acceptance_radius_m=2.0)


@pytest.fixture(scope="module")
def items():
    scenario = reference_scenario(1)
    ids = [f"B{i}" for i in range(len(scenario.buoys_lat_lon))]
    plan = make_plan(HOME[:2], [tuple(p) for p in scenario.buoys_lat_lon], ids, method="exact")
    return mission_items(plan, FLIGHT)


def same_item(a, b) -> bool:
    params_a = [a.param1, a.param2, a.param3, a.param4, a.z]
    params_b = [b.param1, b.param2, b.param3, b.param4, b.z]
    same_params = all((math.isnan(x) and math.isnan(y)) or x == y for x, y in zip(params_a, params_b, strict=True))
    return same_params and (a.seq, a.frame, a.command, a.x, a.y, a.autocontinue) == (
        b.seq,
        b.frame,
        b.command,
        b.x,
        b.y,
        b.autocontinue,
    )


def test_mission_layout(items):
    assert [i.command for i in items[:2]] == [MavCmd.NAV_TAKEOFF, MavCmd.DO_CHANGE_SPEED]
    assert [i.command for i in items[2:-1]] == [MavCmd.NAV_WAYPOINT] * 13
    assert items[-1].command == MavCmd.NAV_RETURN_TO_LAUNCH
    assert [i.seq for i in items] == list(range(len(items)))
    assert all(i.param1 == 1.5 and i.param2 == 2.0 and i.z == 5.0 for i in items[2:-1])
    assert items[1].param2 == 10.0


def test_waypoints_round_trip(items):
    text = exports.waypoints_text(items, HOME)
    lines = text.splitlines()
    assert lines[0] == "QGC WPL 110"
    assert lines[1].split("\t")[:4] == ["0", "1", "0", "16"]  # line 0 is home
    assert all(len(line.split("\t")) == 12 for line in lines[1:])
    home, back = exports.read_waypoints(text)
    assert home == pytest.approx(HOME)
    assert len(back) == len(items)
    assert all(same_item(a, b) for a, b in zip(items, back, strict=True))


def test_qgc_plan_round_trip_and_format(items):
    document = exports.qgc_plan(items, HOME, cruise_speed=10.0, hover_speed=5.0)
    assert document["fileType"] == "Plan" and document["version"] == 1
    mission = document["mission"]
    assert (mission["version"], mission["firmwareType"], mission["vehicleType"]) == (2, 12, 2)
    assert all(len(item["params"]) == 7 and item["type"] == "SimpleItem" for item in mission["items"])
    assert mission["items"][0]["params"][0] is None  # NaN is written as null
    text = json.dumps(document)  # strict JSON: no NaN
    assert "NaN" not in text
    home, back = exports.read_qgc_plan(text)
    assert home == pytest.approx(HOME)
    assert all(same_item(a, b) for a, b in zip(items, back, strict=True))


@pytest.mark.parametrize(
    "text",
    ["", "QGC WPL 120\n", "QGC WPL 110\n0\t1\t0\n", "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\tx\t1\t1\t1\n"],
)
def test_bad_waypoints_files_raise_typed_errors(text):
    with pytest.raises(exports.MissionFileError):
        exports.read_waypoints(text)


@pytest.mark.parametrize("text", ["{", "{}", json.dumps({"fileType": "Plan", "mission": {"items": []}})])
def test_bad_plan_files_raise_typed_errors(text):
    with pytest.raises(exports.MissionFileError):
        exports.read_qgc_plan(text)


def test_track_geojson_is_lon_lat_alt_and_skips_samples_without_fix():
    samples = [
        {"lat": 1.0, "lon": 2.0, "alt_m": 5.0},
        {"lat": None, "lon": None},
        {"lat": 1.5, "lon": 2.5, "alt_m": None},
    ]
    feature = exports.track_geojson(samples, {"mission": 3})
    assert feature["type"] == "Feature" and feature["geometry"]["type"] == "LineString"
    assert feature["geometry"]["coordinates"] == [[2.0, 1.0, 5.0], [2.5, 1.5, 0.0]]
    assert feature["properties"] == {"mission": 3}


def test_qgc_plan_carries_the_fence_and_rally_points_as_qgroundcontrol_writes_them(items):
    keep_in = FenceZoneIn(kind="circle", inclusion=True, center={"lat": 38.92, "lon": 121.66}, radius_m=900.0)
    keep_out = FenceZoneIn(
        kind="polygon", inclusion=False,
        vertices=[{"lat": 38.925, "lon": 121.665}, {"lat": 38.926, "lon": 121.665}, {"lat": 38.926, "lon": 121.667}],
    )  # fmt: skip
    rally = [[38.9215, 121.6635, 10.0]]
    document = exports.qgc_plan(items, HOME, 10.0, 5.0, [keep_in, keep_out], rally)
    assert document["geoFence"] == {
        "version": 2,
        "circles": [{"version": 1, "inclusion": True, "circle": {"center": [38.92, 121.66], "radius": 900.0}}],
        "polygons": [{"version": 1, "inclusion": False, "polygon": [[38.925, 121.665], [38.926, 121.665],
                                                                    [38.926, 121.667]]}],
    }  # fmt: skip
    assert document["rallyPoints"] == {"version": 2, "points": rally}
    zones, points = exports.read_qgc_fence_and_rally(json.dumps(document))
    assert zones == [keep_in, keep_out] and points == rally
    bare = exports.qgc_plan(items, HOME, 10.0, 5.0)
    assert exports.read_qgc_fence_and_rally(json.dumps(bare)) == ([], [])


@pytest.mark.parametrize(
    "plan",
    [
        {"geoFence": {"circles": [{"inclusion": True, "circle": {"center": [1.0], "radius": 5.0}}]}},
        {"geoFence": {"polygons": [{"inclusion": True, "polygon": [[1.0, 2.0]]}]}},  # fewer than 3 vertices
        {"rallyPoints": {"points": [[1.0, 2.0]]}},
        {"rallyPoints": {"points": "x"}},
    ],
)
def test_a_plan_whose_fence_or_rally_points_do_not_read_raises_a_typed_error(plan):
    with pytest.raises(exports.MissionFileError, match=r"fence or rally points|rally point is"):
        exports.read_qgc_fence_and_rally(json.dumps({"fileType": "Plan", **plan}))
