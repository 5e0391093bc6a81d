"""Take-offs and landings in turn at a shared depot (planner.fleet_schedule) and the fleet's time model
(planner.fleet_time): the zone, when a vehicle leaves and re-enters it, and a schedule whose depot windows never
overlap."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from planner.energy import EnergyModel, RouteFlight, WindForecast, leg_durations_s, route_energy
from planner.fleet import check_fleet, plan_fleet
from planner.fleet_schedule import (
    LAUNCH_LATENCY_S,
    depot_zones,
    margin_s,
    schedule,
    split_offsets,
    zone_entry_s,
    zone_exit_s,
)
from planner.fleet_time import fleet_time_terms, share_timeline
from planner.scenario import rest_to_rest_s
from uavcore.motion_profiles import rest_to_rest_spans

MODEL = EnergyModel.load()
PADS = np.array([[0.0, 0.0], [3.0, 0.0], [6.0, 0.0]])  # stack.children: pads 3 m apart, west to east


def test_pads_close_together_share_a_zone_reaching_the_separation_beyond_the_farthest_pad():
    zones = depot_zones(np.vstack([PADS, [[900.0, 400.0]]]), separation_m=5.0)
    assert [z.vehicles for z in zones] == [[0, 1, 2], [3]]
    assert zones[0].centre_en == pytest.approx([3.0, 0.0])
    assert zones[0].radius_m == pytest.approx(3.0 + 5.0)
    assert zones[1].radius_m == pytest.approx(5.0)


def test_leg_durations_are_the_navigators_s_curves_long_and_short():
    nav = MODEL.navigator
    lengths = np.array([0.0, 0.5, 5.0, 20.0, 40.0, 41.0, 300.0])
    exact = [sum(s[0] for s in rest_to_rest_spans(d, 10.0, nav.acceleration_m_s2, nav.jerk_m_s3)) for d in lengths]
    assert leg_durations_s(lengths, 10.0, nav) == pytest.approx(exact, abs=1e-9)
    # the closed form the mission timeline uses agrees where the acceleration limit is reached
    assert leg_durations_s(300.0, 10.0, nav) == pytest.approx(rest_to_rest_s(300.0, 10.0, 3.0, 4.0))


def test_a_share_timeline_is_route_energys_duration_and_its_legs_follow_one_another():
    route = np.array([[0.0, 0.0], [120.0, 40.0], [-60.0, 200.0], [10.0, -90.0]])
    timeline = share_timeline(route, 8.0, 10.0, 1.0, MODEL)
    flown = route_energy(route, RouteFlight(8.0, 10.0, 1.0), WindForecast(6.0, 30.0), MODEL).time_s
    assert timeline.time_s == pytest.approx(flown, rel=1e-9)  # ground speeds: the wind changes no duration
    assert [tuple(leg.end_en) for leg in timeline.legs] == [tuple(p) for p in [*route[1:], route[0]]]
    starts = [leg.start_s for leg in timeline.legs]
    assert all(b >= a + leg.duration_s for a, b, leg in zip(starts, starts[1:], timeline.legs, strict=False))


def test_the_vehicle_leaves_the_zone_on_its_first_leg_and_enters_it_on_its_way_home():
    zone = depot_zones(PADS, 5.0)[0]
    route = np.array([PADS[0], [0.0, 200.0], [150.0, 200.0]])
    timeline = share_timeline(route, 5.0, 10.0, 1.0, MODEL)
    first = timeline.legs[0]  # due north from the westmost pad: out of the circle 8 m about (3, 0) at y = sqrt(55)
    spans = rest_to_rest_spans(200.0, 10.0, 3.0, 4.0)
    s_out = math.sqrt(8.0**2 - 3.0**2)
    exit_s = zone_exit_s(timeline, zone, MODEL, 10.0)
    assert first.start_s < exit_s < first.start_s + first.duration_s
    covered = _distance_after(spans, exit_s - first.start_s)
    assert covered == pytest.approx(s_out, abs=1e-6)
    home = timeline.legs[-1]
    entry_s = zone_entry_s(timeline, zone, MODEL, 10.0)
    assert home.start_s < entry_s < home.start_s + home.duration_s
    assert timeline.time_s - entry_s > 10.0  # the last metres, the descent from 10 m and the touchdown


def _distance_after(spans, t: float) -> float:
    s = v = 0.0
    for duration, a0, jerk in spans:
        h = min(duration, t)
        s += v * h + a0 * h * h / 2 + jerk * h**3 / 6
        v += a0 * h + jerk * h * h / 2
        t -= h
        if t <= 0:
            break
    return s


@pytest.mark.parametrize("separation", [5.0, 20.0])
def test_the_depot_windows_of_a_schedule_never_overlap(separation):
    zone = depot_zones(PADS, separation)[0]
    rng = np.random.default_rng(3)
    # a long share and two short ones that would come home a take-off's interval apart: too close, one waits
    routes = {
        0: np.vstack([PADS[0], rng.uniform(-300.0, 300.0, (6, 2))]),
        1: np.array([PADS[1], [0.0, 150.0]]),
        2: np.array([PADS[2], [6.0, 140.0]]),
    }
    timelines = {k: share_timeline(r, 5.0 + 3.0 * k, 10.0, 1.0, MODEL) for k, r in routes.items()}
    slots = schedule([zone], timelines, MODEL, 10.0)
    assert [slots[k].after for k in range(3)] == [None, 0, 1]  # in the vehicles' order
    for k in (1, 2):  # each starts when the one before has left the zone (and the service has seen it)
        ahead = slots[k - 1]
        assert slots[k].start_s == pytest.approx(ahead.start_s + ahead.exit_s + LAUNCH_LATENCY_S)
    windows = [(slots[k].start_s, slots[k].start_s + slots[k].exit_s) for k in range(3)]
    for k, slot in slots.items():
        end = slot.start_s + timelines[k].time_s + slot.hold_s
        windows.append((slot.start_s + slot.hold_s + slot.entry_s - margin_s(end), end + margin_s(end)))
    windows.sort()
    assert all(b[0] >= a[1] - 1e-9 for a, b in itertools.pairwise(windows)), windows
    assert any(slot.hold_s > 0 for slot in slots.values())  # the short shares were held


def test_the_split_leaves_the_later_departures_less_time_and_the_plan_stays_balanced():
    zones = depot_zones(PADS, 5.0)
    offsets = split_offsets(zones, PADS, lambda k: 5.0 + 3.0 * k, 10.0, 1.0, MODEL)
    assert (
        offsets[0] > 0 and offsets[2] > 0
    )  # the first waits for the landings after its own, the last for the take-offs
    rng = np.random.default_rng(0)
    points = np.vstack([PADS, rng.uniform(-400.0, 400.0, (24, 2))])
    terms = fleet_time_terms(points, [0, 1, 2], [5.0, 8.0, 11.0], 10.0, 1.0, MODEL)
    plan = plan_fleet(
        points, [0, 1, 2], 10.0, terms.dwell_s, terms.fixed_s + offsets, seed=0, time_limit_s=30.0,
        max_iterations=200, leg_time_s=terms.leg_time_s,
    )  # fmt: skip
    fleet = check_fleet(points, [0, 1, 2], 10.0, terms.dwell_s, terms.fixed_s + offsets, terms.leg_time_s)
    assert plan.makespan_s == pytest.approx(max(fleet.route_time(k, r.buoys) for k, r in enumerate(plan.routes)))
    flight = [fleet.route_time(k, r.buoys) - offsets[k] for k, r in enumerate(plan.routes)]
    # the min-max balances flight + room: a vehicle with more room to leave flies less
    assert (
        max(f + o for f, o in zip(flight, offsets, strict=True))
        - min(f + o for f, o in zip(flight, offsets, strict=True))
        < 0.5 * (max(flight) - min(flight)) + 30.0
    )


def test_leg_times_must_be_a_symmetric_matrix_of_the_nodes():
    points = [[0.0, 0.0], [100.0, 0.0], [0.0, 100.0]]
    with pytest.raises(Exception, match=r"leg_time_s must be a finite non-negative \(3, 3\) matrix"):
        check_fleet(points, [0], 10.0, 1.0, 20.0, np.zeros((2, 2)))
    skew = np.array([[0.0, 1.0, 2.0], [3.0, 0.0, 1.0], [2.0, 1.0, 0.0]])
    with pytest.raises(Exception, match="leg_time_s must be symmetric"):
        check_fleet(points, [0], 10.0, 1.0, 20.0, skew)
