"""The paper's weather for a route (planner.scenario): where the crosswind comes from, when the gust starts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs.domain.planning import FlightParams, Plan, mission_items
from planner.scenario import (
    CROSSWIND_M_S,
    GUST_HOLD_S,
    GUST_M_S,
    MissionTimeline,
    Weather,
    compass_bearing_deg,
    dryden_w20_for_sigma,
    paper_weather,
    rest_to_rest_s,
)
from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.rotation import quat_from_euler
from uavcore.state import VehicleState


def test_rest_to_rest_is_a_trapezoid_without_jerk_and_an_s_curve_with_it():
    assert rest_to_rest_s(300.0, 10.0, 3.0) == pytest.approx(30.0 + 10.0 / 3.0)  # cruise, plus one ramp's loss
    assert rest_to_rest_s(300.0, 10.0, 3.0, 4.0) == pytest.approx(30.0 + 10.0 / 3.0 + 0.75)
    assert rest_to_rest_s(12.0, 10.0, 3.0) == pytest.approx(2.0 * math.sqrt(12.0 / 3.0))  # a triangle
    threshold = 10.0 * (10.0 / 3.0 + 0.75)  # the shortest move that reaches cruise under the jerk limit
    assert rest_to_rest_s(threshold - 1e-9, 10.0, 3.0, 4.0) == pytest.approx(rest_to_rest_s(threshold, 10.0, 3.0, 4.0))
    assert rest_to_rest_s(0.0, 10.0, 3.0, 4.0) == 0.0


def test_the_crosswind_blows_across_the_longest_leg_from_its_right_and_the_gust_meets_its_middle():
    route = np.array([[0.0, 0.0], [0.0, 100.0], [300.0, 100.0], [300.0, 50.0]])  # [east, north]: N, E, S legs
    placed = paper_weather(route)
    assert placed.longest_leg == 2 and placed.leg_bearing_deg == pytest.approx(90.0)
    weather = placed.weather
    assert weather.wind_from_deg == pytest.approx(180.0)  # an eastbound leg's right-hand side is south
    assert weather.gust_from_deg == weather.wind_from_deg
    assert (weather.wind_m_s, weather.gust_m_s, weather.gust_hold_s) == (CROSSWIND_M_S, GUST_M_S, GUST_HOLD_S)
    # by hand: spool-up 1 s; climb 5 m at 2.5 m/s (a = 3, j = 4); no turn (it faces north); 100 m north;
    # dwell 1 s; a 90 deg turn (60 deg/s, 45 deg/s^2); then half of the 300 m leg
    climb = 5.0 / 2.5 + 2.5 / 3.0 + 0.75
    leg = lambda length: length / 10.0 + 10.0 / 3.0 + 0.75  # noqa: E731
    turn = 90.0 / 60.0 + 60.0 / 45.0
    onset = 1.0 + climb + leg(100.0) + 1.0 + turn + 0.5 * leg(300.0)
    assert weather.gust_start_s == pytest.approx(round(onset, 1))
    assert placed.leg_start_s + placed.leg_duration_s / 2 == pytest.approx(onset)


def test_the_turbulence_is_sigma_1_m_s_at_5_m_and_the_default_weather_is_still_air():
    w20 = dryden_w20_for_sigma(1.0, 5.0)
    h_ft = 5.0 / 0.3048
    assert 0.1 * w20 / (0.177 + 0.000823 * h_ft) ** 0.4 == pytest.approx(1.0)  # MIL-F-8785C's sigma_u
    assert paper_weather(np.array([[0.0, 0.0], [10.0, 0.0]])).weather.turbulence_w20_m_s == pytest.approx(5.152)
    calm = Weather()
    assert calm.wind_m_s == calm.gust_m_s == calm.turbulence_w20_m_s == 0.0


def test_turns_take_the_short_way_round():
    timeline = MissionTimeline(initial_heading_deg=350.0)
    # north-west then back: the first turn is 350 -> 315 (35 deg), not the long way
    (start, _), _ = timeline.legs(np.array([[0.0, 0.0], [-10.0, 10.0], [0.0, 0.0]]))
    assert compass_bearing_deg([0.0, 0.0], [-10.0, 10.0]) == pytest.approx(315.0)
    assert start == pytest.approx(timeline.spool_up_s + 3.5833333 + timeline.turn_duration_s(35.0), abs=1e-6)


def test_the_timeline_agrees_with_the_vehicles_navigator_to_a_fraction_of_a_second_a_leg():
    """The navigator's own reference (flown by a vehicle that tracks it perfectly) starts each leg's motion when
    the timeline says, less the spool-up (the navigator starts climbing at once)."""
    from sitl_quad.navigator import Navigator, NavigatorConfig

    route = np.array([[0.0, 0.0], [-80.0, 60.0], [250.0, 120.0], [240.0, 100.0]])  # [east, north]
    frame = LocalFrame(*DEFAULT_HOME)
    lat_lon = frame.unproject(route[1:])
    plan = Plan(
        (DEFAULT_HOME[0], DEFAULT_HOME[1]),
        ["a", "b", "c"],
        lat_lon.tolist(),
        route[1:].tolist(),
        [0, 1, 2],
        0.0,
        0.0,
        "given",
        0.0,
    )
    navigator = Navigator(frame, NavigatorConfig())
    navigator.set_mission(mission_items(plan, FlightParams(5.0, 10.0, 1.0, 2.0)))
    state = VehicleState()
    navigator.start_mission(0.0, state)
    starts, was_moving = [], False
    for tick in range(4000):
        t = tick / 50.0
        setpoint = navigator.update(t, state)
        moving = float(np.hypot(*setpoint.velocity[:2])) > 0.05
        if moving and not was_moving:
            starts.append(t)
        was_moving = moving
        state = VehicleState(
            t=t,
            position=setpoint.position,
            velocity=setpoint.velocity,
            quaternion=np.asarray(quat_from_euler(0.0, 0.0, setpoint.yaw)),
        )
    timeline = MissionTimeline()
    expected = [start - timeline.spool_up_s for start, _ in timeline.legs(route)]
    assert len(starts) >= 3 and np.allclose(starts[:3], expected, atol=0.3)


def test_an_inspection_timeline_stops_short_of_each_buoy_and_holds_there_before_the_next_leg():
    route = np.array([[0.0, 0.0], [0.0, 300.0], [400.0, 300.0]])  # north 300 m, then east 400 m
    plain = MissionTimeline()
    inspected = MissionTimeline(standoff_m=20.0, holds_s=(9.5, 21.5))
    (start_1, to_standoff_1), (start_2, to_standoff_2) = inspected.legs(route)
    (plain_start_1, leg_1), (plain_start_2, _) = plain.legs(route)
    assert start_1 == plain_start_1 and to_standoff_1 == pytest.approx(plain.leg_duration_s(280.0))
    assert to_standoff_2 == pytest.approx(plain.leg_duration_s(380.0))
    # the second leg starts after the first's stretch to the standoff, its hold and the last 20 m flown rest to rest
    expected = start_1 + to_standoff_1 + 9.5 + plain.leg_duration_s(20.0) + plain.dwell_s
    assert start_2 - expected == pytest.approx(plain_start_2 - (plain_start_1 + leg_1 + plain.dwell_s))
