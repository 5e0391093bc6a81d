"""The flown track for display: the simplification (gcs.reports.track_display) and GET /missions/{id}/track on a stored
two-hour mission (72 000 samples at 10 Hz), whose exports stay at full resolution."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from fastapi.testclient import TestClient

from bench.long_mission import SAMPLES, store_long_mission
from bench.processes import free_udp_port
from gcs.api.app import create_app
from gcs.domain.schemas import TelemetrySample
from gcs.reports.track_display import arrival_indices, evenly_spaced, extremes_per_bucket, simplify_track
from gcs.settings import Settings
from gcs.storage import open_storage

DISPLAY_TOLERANCE_M = 1.0  # the page draws the 2-hour track within this of every recorded position


def deviations(points: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Each point's distance to the kept polyline's segment spanning it (an upper bound of its distance to the
    polyline), computed here independently of the module under test."""
    result = np.zeros(len(points))
    for start, end in itertools.pairwise(kept):
        a, b, inner = points[start], points[end], points[start : end + 1]
        ab = b - a
        t = np.zeros(len(inner)) if not ab.any() else np.clip((inner - a) @ ab / (ab @ ab), 0, 1)
        result[start : end + 1] = np.linalg.norm(inner - (a + t[:, None] * ab), axis=1)
    return result


# ----- the simplification
def wandering_track(n: int, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(0.0, 1.0, (n, 2)), axis=0)


@pytest.mark.parametrize("max_points", [2, 10, 100, 1000])
def test_the_kept_points_respect_the_budget_and_the_reported_tolerance(max_points):
    points = wandering_track(5000)
    keep = [1234, 2500, 4000]
    track = simplify_track(points, max_points, keep)
    kept = track.indices
    assert len(kept) <= max(max_points, len(keep) + 2)
    assert {0, len(points) - 1, *keep} <= set(kept.tolist())
    assert np.all(np.diff(kept) > 0)
    assert deviations(points, kept).max() <= track.tolerance_m + 1e-9


def test_more_points_fit_the_track_more_closely():
    points = wandering_track(5000)
    tolerances = [simplify_track(points, n).tolerance_m for n in (50, 200, 800, 3200)]
    assert tolerances == sorted(tolerances, reverse=True) and tolerances[-1] < tolerances[0] / 10


def test_a_straight_flight_is_its_two_ends_and_a_short_track_is_kept_whole():
    line = np.column_stack([np.linspace(0, 100, 1001), np.linspace(0, 50, 1001)])
    track = simplify_track(line, 100)
    assert track.indices.tolist() == [0, 1000] and track.tolerance_m == pytest.approx(0.0, abs=1e-9)
    hover = np.zeros((500, 2))
    assert simplify_track(hover, 10).indices.tolist() == [0, 499]
    short = wandering_track(50)
    assert simplify_track(short, 100).indices.tolist() == list(range(50))


def test_the_chart_series_keeps_a_fast_oscillation_s_envelope():
    t = np.arange(72_000) * 0.1
    wobble = 0.4 * np.sin(2 * np.pi * t / 15.0)  # 150 samples a period, far faster than 72 per chart point
    kept = extremes_per_bucket(wobble, 1000)
    assert len(kept) <= 1000 and kept[0] == 0 and kept[-1] == 71_999
    assert wobble[kept].max() == wobble.max() and wobble[kept].min() == wobble.min()
    # every stretch of ~144 samples holds a crest and a trough: each is drawn, none aliased away
    crests = wobble[kept] > 0.39
    assert crests.sum() >= len(kept) / 2 - 2
    gaps = np.full(5000, np.nan)
    gaps[2500:] = 1.0
    assert len(extremes_per_bucket(gaps, 100)) <= 100


def test_evenly_spaced_and_arrival_indices():
    assert evenly_spaced(5, 10).tolist() == [0, 1, 2, 3, 4]
    spread = evenly_spaced(72_000, 1000)
    assert len(spread) == 1000 and spread[0] == 0 and spread[-1] == 71_999
    times = np.arange(100) * 0.1
    assert arrival_indices(times, [0.0, 0.25, 5.0, 99.0]) == [0, 3, 50]  # after the last sample: none


# ----- the endpoint on a stored 2-hour mission
# Storing its 72 000 samples takes 2 to 3 s and the track and export tests read them all (1.5 to 5.6 s each), so
# they are slow; so is the test that needs the mission only for an id, which alone would pay for storing it.
@pytest.fixture(scope="module")
def long_mission(tmp_path_factory):
    """A client of a service whose database holds a completed 72 000-sample mission, and the mission's id."""
    path = tmp_path_factory.mktemp("long") / "gcs.sqlite"
    storage = open_storage(path)
    mission_id = store_long_mission(storage)
    storage.close()
    settings = Settings(db_path=path, vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    with TestClient(create_app(settings)) as client:
        yield client, mission_id


@pytest.mark.slow
def test_the_display_track_of_a_two_hour_mission(long_mission):
    client, mission_id = long_mission
    mission = client.get(f"/missions/{mission_id}").json()
    answer = client.get(f"/missions/{mission_id}/track")
    assert answer.status_code == 200
    track = answer.json()
    assert track["samples"] == SAMPLES
    assert 100 < len(track["points"]) <= 2000
    assert 0.0 < track["tolerance_m"] <= DISPLAY_TOLERANCE_M
    series = track["series"]
    assert len(series) <= 1000 and series[0]["t_s"] == 0.0 and series[-1]["t_s"] == (SAMPLES - 1) * 0.1
    assert all(b["t_s"] > a["t_s"] for a, b in itertools.pairwise(series))

    # the points are recorded positions, in flight order, and every recorded position lies within the reported
    # tolerance of the polyline they draw
    samples = client.get(f"/missions/{mission_id}/telemetry").json()
    assert len(samples) == SAMPLES  # the export keeps every sample, streamed as the response model describes
    assert all(TelemetrySample.model_validate(s).model_dump() == s for s in samples[::997])
    largest_error = max(s["cross_track_m"] for s in samples)
    assert max(s["cross_track_m"] for s in series) == largest_error  # the charts show the worst of it
    recorded = np.array([(s["lat"], s["lon"]) for s in samples])
    kept, cursor = [], 0
    for point in track["points"]:
        while tuple(recorded[cursor]) != tuple(point):
            cursor += 1
        kept.append(cursor)
    assert kept[0] == 0 and kept[-1] == SAMPLES - 1
    frame = client.portal.call(client.app.state.service.get, mission_id).plan.frame
    local = frame.project(recorded)
    assert deviations(local, np.array(kept)).max() <= track["tolerance_m"] + 1e-6

    # every buoy arrival is a vertex of the drawn track
    times = np.array([s["t_s"] for s in samples])
    arrivals = [r["arrival_s"] for r in mission["buoy_results"]]
    assert len(arrivals) == 13 and set(arrival_indices(times, arrivals)) <= set(kept)


def test_the_display_track_is_cached_until_a_sample_is_added(tmp_path):
    storage = open_storage(tmp_path / "gcs.sqlite")
    mission_id = store_long_mission(storage, 3000)
    settings = Settings(db_path=tmp_path / "gcs.sqlite", vehicle_url=f"udpout:127.0.0.1:{free_udp_port()}")
    with TestClient(create_app(settings)) as client:
        url = f"/missions/{mission_id}/track?max_points=500"
        first = client.get(url)
        assert len(first.json()["points"]) <= 500
        documents = client.app.state.service.documents
        misses = documents.misses
        assert client.get(url).content == first.content
        assert documents.misses == misses  # served from the cache

        # a sample stored (by another storage object, as a second instance recording the flight would) is in
        # the next answer: the mission's version does not count samples, the track's does
        last = storage.telemetry(mission_id)[-1]
        storage.add_telemetry(mission_id, [{**last, "t_s": last["t_s"] + 0.1, "lat": last["lat"] + 1e-4}])
        after = client.get(url).json()
        assert after["samples"] == 3001 and after["points"][-1][0] == pytest.approx(last["lat"] + 1e-4)
    storage.close()


@pytest.mark.slow
def test_the_track_export_keeps_every_sample(long_mission):
    client, mission_id = long_mission
    geojson = client.get(f"/missions/{mission_id}/track.geojson").json()
    assert len(geojson["geometry"]["coordinates"]) == SAMPLES


@pytest.mark.slow
def test_the_track_of_an_unknown_mission_and_bad_budgets(long_mission):
    client, mission_id = long_mission
    assert client.get("/missions/999999/track").status_code == 404
    for bad in ("1", "0", "100001", "x"):
        answer = client.get(f"/missions/{mission_id}/track?max_points={bad}")
        assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["query", "max_points"]
