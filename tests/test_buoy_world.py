"""The simulated world's buoys (uavcore.buoy_world): the world file's contract and its errors, IALA appearance and
lights, the faults a buoy hides, its swing about its mooring, and the seeded benchmark worlds."""

import json
import math

import numpy as np
import pytest

from uavcore.buoy_world import (
    APPEARANCE,
    KINDS,
    LIGHT_RGB,
    PAINT_RGB,
    World,
    WorldBuoy,
    WorldFileError,
    appearance,
    check_kind_light,
    default_light,
    load_world,
)
from uavcore.light_character import COLOURS, parse

LAT, LON = 38.9210, 121.6630
DAY_S = np.arange(0.0, 600.0, 0.05)  # ten minutes at 20 Hz: every phase of every default light, several times


def feature(lon=LON, lat=LAT, **props):
    return {"type": "Feature", "geometry": {"type": "Point", "coordinates": [lon, lat]}, "properties": props}


def collection(*features):
    return {"type": "FeatureCollection", "features": list(features)}


def grid(n):
    """n buoys 100 m apart northwards, and their ids."""
    return np.column_stack([LAT + np.arange(n) * 0.0009, np.full(n, LON)]), [f"B{i}" for i in range(n)]


def flashes(b):
    """How many times the buoy's light comes on over DAY_S."""
    on = np.array([b.light_on(t) for t in DAY_S])
    return int(np.count_nonzero(on[1:] & ~on[:-1]))


def buoy(**props):
    return load_world(collection(feature(**{"id": "B1", "kind": "port", **props}))).buoys[0]


def test_load_reads_every_contract_field():
    world = load_world(
        collection(
            feature(121.5, 38.5, id="B1", kind="starboard", light="Fl(2) G 6s", swing_radius_m=8, shows="Iso G 4s",
                    offset_m=[3.0, -4.0]),
            feature(id="B2", kind="south"),
        )
    )  # fmt: skip
    full, bare = world.buoys
    assert (full.id, full.kind, full.charted, full.swing_radius_m) == ("B1", "starboard", (38.5, 121.5), 8.0)
    assert (full.light, full.actual_light, full.offset_m) == (parse("Fl(2) G 6s"), parse("Iso G 4s"), (3.0, -4.0))
    assert (bare.light, bare.actual_light, bare.swing_radius_m, bare.offset_m) == (None, None, 5.0, (0.0, 0.0))


def test_load_reads_a_path_and_text(tmp_path):
    text = json.dumps(collection(feature(id="B1", kind="north", light="Q W")))
    path = tmp_path / "world.geojson"
    path.write_text(text)
    assert load_world(path) == load_world(str(path)) == load_world(text)
    assert load_world(path).buoys[0].light == parse("Q W")


def test_shows_dark_puts_the_light_out():
    assert buoy(light="Fl R 4s", shows="dark").actual_light is None


ERRORS = [
    (feature(id="B4", kind="portt"), "feature 0 (B4): kind 'portt' is not one of port, starboard"),
    (feature(kind="port"), "feature 0: id must be a non-empty string"),
    (feature(id=7, kind="port"), "feature 0: id must be a non-empty string"),
    (feature(id="B4", kind="port", light="Fl(2) Z 6s"), "feature 0 (B4): light 'Fl(2) Z 6s': cannot read"),
    (feature(id="B4", kind="east", light="Q(3) W"), "feature 0 (B4): light 'Q(3) W' has no period"),
    (feature(id="B4", kind="port", light=4), "feature 0 (B4): light must be a light character"),
    (feature(id="B4", kind="port", shows="Blink"), "feature 0 (B4): shows 'Blink': no light class"),
    (feature(id="B4", kind="port", swing_radius_m=-1), "feature 0 (B4): swing_radius_m must be a finite number >= 0"),
    (feature(id="B4", kind="port", swing_radius_m=math.nan), "feature 0 (B4): swing_radius_m must be a finite"),
    (feature(id="B4", kind="port", swing_radius_m=True), "feature 0 (B4): swing_radius_m must be a finite"),
    (feature(id="B4", kind="port", offset_m=[1.0]), "feature 0 (B4): offset_m must be [north, east]"),
    (feature(id="B4", kind="port", offset_m=[1.0, math.inf]), "feature 0 (B4): offset_m must be [north, east]"),
    (feature(id="B4", kind="port", offset_m="1,2"), "feature 0 (B4): offset_m must be [north, east]"),
    (feature(id="B4", kind="port", offest_m=[9, 9]), "feature 0 (B4): properties offest_m unknown"),
    (feature(id="B4", kind="port", region="C"), "feature 0 (B4): region must be one of A, B"),
    (feature(LON, 91.0, id="B4", kind="port"), "feature 0 (B4): coordinates [lon, lat] = [121.663, 91.0]"),
    (feature(181.0, LAT, id="B4", kind="port"), "feature 0 (B4): coordinates [lon, lat] = [181.0, 38.921]"),
    (feature(math.nan, LAT, id="B4", kind="port"), "feature 0 (B4): coordinates must be [lon, lat] as finite numbers"),
    ({**feature(id="B4", kind="port"), "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 1]]}},
     "feature 0 (B4): geometry must be a Point"),
    ({**feature(id="B4", kind="port"), "type": "Point"}, "feature 0 (B4): type must be 'Feature'"),
    ({**feature(), "properties": None}, "feature 0: properties must be an object"),
]  # fmt: skip


@pytest.mark.parametrize(("bad", "message"), ERRORS)
def test_a_bad_feature_is_refused_naming_feature_and_field(bad, message):
    with pytest.raises(WorldFileError) as error:
        load_world(collection(bad))
    assert str(error.value).startswith(message)


def test_a_bad_feature_is_numbered_by_its_place():
    with pytest.raises(WorldFileError, match=r"^feature 2 \(B9\): kind"):
        load_world(collection(feature(id="B0", kind="port"), feature(id="B1", kind="port"), feature(id="B9", kind="x")))


def test_duplicate_ids_are_refused():
    with pytest.raises(WorldFileError, match=r"^feature 1 \(B0\): id 'B0' is already feature 0's"):
        load_world(collection(feature(id="B0", kind="port"), feature(id="B0", kind="starboard")))


@pytest.mark.parametrize(
    "bad", [[], {"type": "Feature"}, {"type": "FeatureCollection"}, {"type": "FeatureCollection", "features": {}}]
)
def test_not_a_feature_collection_is_refused(bad):
    with pytest.raises(WorldFileError, match="FeatureCollection"):
        World.from_geojson(bad)


@pytest.mark.parametrize(
    "text",
    ['{"type": "FeatureCollection", "features": [', '{"type": "FeatureCollection", "seed": 1.5, "features": []}'],
)
def test_bad_json_and_seed_are_refused(text):
    with pytest.raises(WorldFileError):
        load_world(text)


def test_nan_from_json_text_is_refused():
    text = json.dumps(collection(feature(id="B4", kind="port", swing_radius_m=math.nan)))
    assert "NaN" in text  # Python's json writes it, and reads it back as a float: the loader must refuse it
    with pytest.raises(WorldFileError, match="swing_radius_m"):
        load_world(text)


def test_a_dark_light_is_never_on():
    dark = buoy(light="Fl R 4s", shows="dark")
    assert not any(dark.light_on(t) for t in DAY_S)
    assert all(dark.light_colour(t) is None for t in DAY_S)


def test_an_unlit_buoy_is_never_on():
    assert not any(buoy().light_on(t) for t in DAY_S)


def test_another_character_shows_instead_of_the_charted_one():
    charted, faulty = buoy(light="Fl(2) R 6s"), buoy(light="Fl(2) R 6s", shows="Fl(3) R 6s")
    assert any(charted.light_on(t) != faulty.light_on(t) for t in DAY_S)
    # ten minutes of 6 s periods: 100 groups, of two flashes as charted, of three as the fault shows
    assert flashes(charted) in (199, 200, 201) and flashes(faulty) in (299, 300, 301)


def test_light_colour_is_the_actual_lights():
    faulty = buoy(light="Fl R 4s", shows="Fl G 4s")
    assert {faulty.light_colour(t) for t in DAY_S} == {None, "G"}


def test_faults_are_the_injected_ones():
    assert buoy(light="Fl R 4s").faults == []
    assert buoy(light="Fl R 4s", shows="dark").faults == ["light_out"]
    assert buoy(light="Fl R 4s", shows="Fl R 8s").faults == ["wrong_character"]
    assert buoy(light="Fl R 4s", shows="Fl R 4s").faults == []  # shows what is charted: no fault
    assert buoy(offset_m=[3.0, 4.0]).faults == []  # 5 m: the mooring still within its 5 m swing circle
    assert buoy(offset_m=[6.0, 0.0], shows="dark", light="Q W").faults == ["off_station", "light_out"]


WINDS_CURRENTS = [(0, 0, 0, 0), (270, 15, 0, 0), (0, 0, 90, 0.5), (45, 25, 200, 2.5), (180, 8, 0, 0.2)]


@pytest.mark.parametrize("environment", WINDS_CURRENTS)
def test_swing_never_leaves_the_circle_over_two_hours(environment):
    lat_lon, ids = grid(13)
    world = World.random(7, lat_lon, ids, fault_probability=0.5)
    radii = np.array([b.swing_radius_m for b in world.buoys])
    moorings = np.array([b.offset_m for b in world.buoys])
    worst = max(float(np.max(np.hypot(*(world.positions(t, *environment) - moorings).T) / radii)) for t in range(7200))
    assert worst <= 1.0
    assert worst > 0.1  # and it does swing


@pytest.mark.parametrize("current_to_deg", [0.0, 90.0, 225.0, 300.0])
def test_the_buoy_lies_downstream_of_the_current(current_to_deg):
    lat_lon, ids = grid(5)
    world = World.default(lat_lon, ids)
    # a 1 m/s current against a 10 m/s wind from downstream: the current still wins
    mean = np.mean([world.positions(t, current_to_deg, 10.0, current_to_deg, 1.0) for t in range(0, 600, 5)], axis=0)
    bearings = np.degrees(np.arctan2(mean[:, 1], mean[:, 0]))
    assert np.all(np.abs((bearings - current_to_deg + 180) % 360 - 180) < 10)
    assert np.all(np.hypot(*mean.T) > 0.5 * 5.0)


def test_the_wind_alone_pushes_the_buoy_downwind():
    lat_lon, ids = grid(3)
    mean = np.mean([World.default(lat_lon, ids).positions(t, 270.0, 20.0) for t in range(0, 600, 5)], axis=0)
    assert np.all(mean[:, 1] > 1.0) and np.all(np.abs(mean[:, 0]) < 0.5 * mean[:, 1])  # from the west: eastwards


def test_the_same_seed_gives_the_same_positions_another_seed_others():
    lat_lon, ids = grid(6)
    a, b, c = (World.random(seed, lat_lon, ids, fault_probability=0.0) for seed in (1, 1, 2))
    times = np.arange(0.0, 300.0, 7.3)
    assert all(np.array_equal(a.positions(t, 0, 5, 90, 0.3), b.positions(t, 0, 5, 90, 0.3)) for t in times)
    assert not any(np.allclose(a.positions(t, 0, 5, 90, 0.3), c.positions(t, 0, 5, 90, 0.3)) for t in times)


def test_positions_are_smooth_in_time():
    lat_lon, ids = grid(4)
    world = World.default(lat_lon, ids)
    steps = [np.hypot(*(world.positions(t + 0.1) - world.positions(t)).T).max() for t in np.arange(0, 600, 3.7)]
    assert max(steps) < 0.05  # under 0.5 m/s: a buoy drifts, it does not jump


def test_the_off_station_offset_moves_the_buoy():
    world = load_world(collection(feature(id="B1", kind="port", offset_m=[20.0, -10.0], swing_radius_m=4.0)))
    for t in range(0, 600, 10):
        assert math.dist(world.positions(t, 0, 5, 45, 0.5)[0], (20.0, -10.0)) <= 4.0
    lat, lon = world.positions_lat_lon(0.0)[0]
    assert abs((lat - LAT) * 111_000 - 20.0) < 5 and abs((lon - LON) * 111_000 * math.cos(math.radians(LAT)) + 10) < 5


def test_a_beacon_stands_where_it_is_built():
    # swing radius 0: a chart's beacon (BCNLAT, ...) on its pile, whatever the wind and current
    world = load_world(collection(feature(id="BN1", kind="starboard", swing_radius_m=0)))
    assert world.buoys[0].faults == []
    assert all(np.array_equal(world.positions(t, 270, 20, 90, 2.0), [[0.0, 0.0]]) for t in range(0, 600, 10))
    moved = load_world(collection(feature(id="BN1", kind="starboard", swing_radius_m=0, offset_m=[0.5, 0.0])))
    assert moved.buoys[0].faults == ["off_station"]  # a beacon moved at all is off its station


def test_random_world_fault_rate_is_about_p():
    lat_lon, ids = grid(2000)
    world = World.random(11, lat_lon, ids, fault_probability=0.2)
    faulty = [b.faults for b in world.buoys if b.faults]
    # binomial(2000, 0.2): mean 400, sd ~18; 5 sd either side
    assert 310 <= len(faulty) <= 490
    assert all(len(f) == 1 for f in faulty)  # one fault each
    counts = {name: sum(f == [name] for f in faulty) for name in ("off_station", "light_out", "wrong_character")}
    assert min(counts.values()) > len(faulty) / 5


def test_random_world_faults_are_of_the_stated_size():
    lat_lon, ids = grid(300)
    for b in World.random(5, lat_lon, ids, fault_probability=1.0).buoys:
        distance = math.hypot(*b.offset_m)
        assert distance == 0 or 2 * b.swing_radius_m <= distance <= 5 * b.swing_radius_m
        if b.faults == ["wrong_character"]:
            assert b.actual_light.colours == b.light.colours and b.actual_light.cycle_s is not None


def test_random_world_kinds_are_plausible():
    lat_lon, ids = grid(200)
    kinds = [b.kind for b in World.random(3, lat_lon, ids).buoys]
    assert kinds.count("safe_water") == kinds.count("isolated_danger") == 1
    assert kinds.count("port") + kinds.count("starboard") > len(kinds) / 2
    assert set(kinds) == set(KINDS)


def test_random_world_is_seeded():
    lat_lon, ids = grid(40)
    assert World.random(4, lat_lon, ids) == World.random(4, lat_lon, ids) != World.random(5, lat_lon, ids)


@pytest.mark.parametrize("seed", range(5))
def test_to_geojson_round_trips(seed):
    lat_lon, ids = grid(40)
    world = World.random(seed, lat_lon, ids, fault_probability=0.5)
    assert load_world(world.to_geojson()) == world
    assert load_world(json.dumps(world.to_geojson())) == world


def test_default_world_has_no_faults_and_default_lights():
    lat_lon, ids = grid(30)
    world = World.default(lat_lon, ids)
    assert world == World.default(lat_lon, ids)
    assert all(b.faults == [] and b.light == default_light(b.kind) for b in world.buoys)
    assert world.buoys[0].kind == "safe_water" and {b.kind for b in world.buoys} >= {"port", "starboard", "north"}


@pytest.mark.parametrize("kind", KINDS)
def test_default_lights_parse_and_fit_their_kind(kind):
    light = default_light(kind)
    assert light.cycle_s is not None
    assert check_kind_light(kind, light) == []


@pytest.mark.parametrize(
    ("kind", "text", "complaint"),
    [
        ("north", "Q R", "is R, IALA gives it W"),
        ("north", "Q(3) W 10s", "rhythm Q(3)"),
        ("east", "Q(3) W 15s", "period 15.0 s"),
        ("port", "Fl G 4s", "is G, IALA gives it R"),
        ("port", "Fl(2+1) R 10s", "rhythm Fl(2+1)"),
        ("safe_water", "Fl(2) W 5s", "rhythm Fl(2)"),
        ("special", "Fl W 4s", "IALA gives it Y"),
    ],
)
def test_check_kind_light_warns_of_a_contradiction(kind, text, complaint):
    warnings = check_kind_light(kind, parse(text))
    assert len(warnings) == 1 and complaint in warnings[0] and warnings[0].startswith(f"{kind} buoy: light {text}")


def test_check_kind_light_accepts_the_other_iala_forms_and_unlit():
    for kind, text in [
        ("north", "VQ W"),
        ("south", "VQ(6)+LFl W 10s"),
        ("safe_water", "Mo(A) W 6s"),
        ("port", "Iso R 4s"),
    ]:
        assert check_kind_light(kind, parse(text)) == []
    assert all(check_kind_light(kind, None) == [] for kind in KINDS)


def test_every_kind_has_an_appearance_in_the_palette():
    assert set(APPEARANCE) == set(KINDS)
    for look in APPEARANCE.values():
        assert set(look.colours) | {look.topmark_colour} <= set(PAINT_RGB)
        assert 1.0 <= look.height_m <= 3.5 and 1.0 <= look.diameter_m <= 2.0
    assert APPEARANCE["safe_water"].pattern == "vertical" and APPEARANCE["east"].colours == ("black", "yellow", "black")
    assert set(LIGHT_RGB) == set(COLOURS)
    assert all(0 <= c <= 255 for rgb in (*PAINT_RGB.values(), *LIGHT_RGB.values()) for c in rgb)


def test_a_world_buoy_built_in_code_equals_the_loaded_one():
    loaded = buoy(light="Fl R 4s")
    assert loaded == WorldBuoy("B1", "port", (LAT, LON), parse("Fl R 4s"), 5.0, parse("Fl R 4s"))


def test_in_region_b_a_lateral_mark_takes_the_other_colour_and_keeps_its_shape():
    for kind, colour_a, colour_b in (("port", "red", "green"), ("starboard", "green", "red")):
        a, b = appearance(kind), appearance(kind, "B")
        assert (a.colours, a.topmark_colour, b.colours, b.topmark_colour) == (
            (colour_a,),
            colour_a,
            (colour_b,),
            colour_b,
        )
        assert (a.shape, a.topmark) == (b.shape, b.topmark)  # port a can, starboard a cone, in both regions
    assert all(appearance(kind, "B") == APPEARANCE[kind] for kind in KINDS if kind not in ("port", "starboard"))
    assert (default_light("port", "B").abbreviation(), default_light("starboard", "B").abbreviation()) == (
        "Fl G 4s", "Fl R 4s"
    )  # fmt: skip
    assert check_kind_light("starboard", parse("Fl R 4s"), "B") == []
    assert "IALA gives it R" in check_kind_light("starboard", parse("Fl G 4s"), "B")[0]
    assert all(check_kind_light(kind, default_light(kind, "B"), "B") == [] for kind in KINDS)


def test_a_region_b_buoy_round_trips_through_its_world_file_and_is_drawn_in_its_colours():
    document = {"type": "FeatureCollection", "features": [feature(id="R2", kind="starboard", region="B"),
                                                          feature(id="G1", kind="port")]}  # fmt: skip
    world = World.from_geojson(document)
    assert [(b.region, b.appearance.colours) for b in world.buoys] == [("B", ("red",)), ("A", ("red",))]
    written = world.to_geojson()["features"]
    assert written[0]["properties"]["region"] == "B" and "region" not in written[1]["properties"]
    assert World.from_geojson(world.to_geojson()) == world
