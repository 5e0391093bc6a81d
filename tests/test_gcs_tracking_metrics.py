"""Tracking figures (gcs.domain.tracking_metrics) on hand-built tracks whose answers are known geometrically."""

import numpy as np
import pytest

from gcs.domain import tracking_metrics
from gcs.domain.tracking_metrics import TrackPoint

# depot -> (100, 0) -> depot: two legs along the east axis
ROUTE = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 0.0]])


def test_distance_to_segment_perpendicular_and_beyond_ends():
    points = np.array([[50.0, 3.0], [-4.0, 3.0], [110.0, 0.0]])
    d = tracking_metrics.distance_to_segment(points, ROUTE[0], ROUTE[1])
    assert d == pytest.approx([3.0, 5.0, 10.0])


def test_leg_rms_and_max_of_a_constant_offset_and_a_mixed_leg():
    out = [TrackPoint(t, float(t), 2.0, True, 0) for t in range(0, 100, 10)]  # 2 m north of leg 0
    back = [TrackPoint(100 + t, 100.0 - t, s, True, 1) for t, s in ((10, 3.0), (20, -4.0))]
    legs = tracking_metrics.tracking_figures(ROUTE, 200.0, out + back)["legs"]
    assert legs[0]["samples"] == 10
    assert legs[0]["rms_cross_track_m"] == pytest.approx(2.0)
    assert legs[0]["max_cross_track_m"] == pytest.approx(2.0)
    assert legs[1]["rms_cross_track_m"] == pytest.approx(np.sqrt((9 + 16) / 2))
    assert legs[1]["max_cross_track_m"] == pytest.approx(4.0)


def test_samples_on_the_ground_or_without_a_leg_are_not_counted():
    track = [TrackPoint(0, 0, 50.0, False, 0), TrackPoint(1, 0, 50.0, True, None), TrackPoint(2, 10, 1.0, True, 0)]
    legs = tracking_metrics.tracking_figures(ROUTE, 200.0, track)["legs"]
    assert legs[0]["samples"] == 1 and legs[0]["max_cross_track_m"] == pytest.approx(1.0)
    assert legs[1]["samples"] == 0 and legs[1]["rms_cross_track_m"] is None


def test_buoy_closest_approach_reached_flag_and_arrival_time():
    buoys = np.array([[100.0, 0.0], [0.0, 500.0]])
    track = [TrackPoint(float(t), float(x), 1.5, True, 0) for t, x in enumerate(range(90, 111, 5))]
    result = tracking_metrics.buoy_figures(buoys, [2.0, 2.0], track, reached_at={})
    assert result[0]["closest_m"] == pytest.approx(1.5)
    assert result[0]["reached"] is True
    assert result[0]["arrival_s"] == pytest.approx(2.0)  # first sample inside 2 m: x = 100 at t = 2
    assert result[1]["reached"] is False and result[1]["arrival_s"] is None
    assert result[1]["closest_m"] == pytest.approx(np.hypot(90.0, 500.0 - 1.5))


def test_vehicle_reported_arrival_time_wins():
    track = [TrackPoint(5.0, 100.0, 0.0, True, 0)]
    result = tracking_metrics.buoy_figures(np.array([[100.0, 0.0]]), [1.0], track, reached_at={0: 4.2})
    assert result[0]["arrival_s"] == 4.2


def test_distance_flown_and_flight_time_use_airborne_samples_only():
    track = [
        TrackPoint(0.0, 0.0, 0.0, False, None),
        TrackPoint(1.0, 0.0, 0.0, True, 0),
        TrackPoint(2.0, 3.0, 4.0, True, 0),
        TrackPoint(3.0, 6.0, 8.0, True, 0),
        TrackPoint(9.0, 100.0, 100.0, False, None),
    ]
    assert tracking_metrics.distance_flown_m(track) == pytest.approx(10.0)
    assert tracking_metrics.flight_time_s(track) == pytest.approx(2.0)
    figures = tracking_metrics.tracking_figures(ROUTE, 200.0, track)
    assert figures["planned_length_m"] == 200.0
    assert figures["distance_flown_m"] == pytest.approx(10.0)
    assert len(figures["legs"]) == 2


def test_empty_track_gives_no_figures_rather_than_errors():
    figures = tracking_metrics.tracking_figures(ROUTE, 200.0, [])
    assert figures["rms_cross_track_m"] is None and figures["flight_time_s"] is None
    assert tracking_metrics.buoy_figures(np.array([[1.0, 1.0]]), [1.0], [], {})[0]["closest_m"] is None


# ----- a gust's effect: peak 3-D error after the onset and the time until it is back under 0.2 m for good
def test_gust_effect_on_a_synthetic_bump_peaks_and_recovers_when_the_error_stays_under_the_threshold():
    t = np.arange(0.0, 40.0, 0.1)
    onset = 20.0
    # 0.05 m before the gust; after it a bump peaking at 0.45 m 1 s in, over 0.2 m while |t - 21| < 0.99 s
    error = 0.05 + np.where(t >= onset, 0.4 * np.exp(-(((t - 21.0) / 1.0) ** 2)), 0.0)
    error[t > 35.0] = 0.9  # outside the 10 s window: does not count
    error[100] = 2.0  # before the onset (t = 10 s): does not count
    effect = tracking_metrics.gust_effect(t, error, onset)
    assert effect.peak_m == pytest.approx(0.45, abs=1e-9)
    last_above = t[(t >= onset) & (t <= onset + 10.0) & (error > 0.2)].max()
    assert effect.recovery_s == pytest.approx(last_above + 0.1 - onset)
    assert effect.recovery_s == pytest.approx(2.0)  # the first sample back under 0.2 m is t = 22.0 s


def test_gust_effect_never_above_is_zero_never_back_is_the_window_and_no_sample_is_nan():
    t = np.arange(0.0, 30.0, 0.5)
    calm = tracking_metrics.gust_effect(t, np.full(t.size, 0.1), 5.0)
    assert (calm.peak_m, calm.recovery_s) == (pytest.approx(0.1), 0.0)
    off_track = tracking_metrics.gust_effect(t, np.where(t >= 5.0, 0.3, 0.1), 5.0)
    assert off_track.recovery_s == tracking_metrics.GUST_WINDOW_S
    ends_above = tracking_metrics.gust_effect(
        t[t < 8.0], np.full((t < 8.0).sum(), 0.5), 5.0
    )  # the record ends off track
    assert ends_above.recovery_s == tracking_metrics.GUST_WINDOW_S
    gaps = np.where(t == 6.0, np.nan, 0.1)  # samples without a reference are left out
    assert tracking_metrics.gust_effect(t, gaps, 5.0).peak_m == pytest.approx(0.1)
    nothing = tracking_metrics.gust_effect(t, np.full(t.size, 0.1), 100.0)
    assert np.isnan(nothing.peak_m) and np.isnan(nothing.recovery_s)


def test_the_climb_starts_at_the_last_sample_before_the_reference_rises():
    t = np.arange(0.0, 3.0, 0.1)
    ref_down = np.where(t < 1.25, 0.03, 0.03 - 2.0 * (t - 1.25) ** 2)  # on the ground, then climbing
    assert tracking_metrics.climb_start_s(t, ref_down) == pytest.approx(1.2)
    assert tracking_metrics.climb_start_s(t, np.full(t.size, 0.03)) is None
