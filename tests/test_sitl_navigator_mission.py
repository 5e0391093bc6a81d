"""The navigator flying missions and modes against a kinematic vehicle that follows its reference.

Most tests use a "perfect tracker": at each 50 Hz tick the vehicle is where the reference was one tick
before (and never below the ground). Acceptance logic is checked with followers that are noisy, offset or
stuck.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from gcs.domain.planning import FlightParams, Plan, mission_items
from planner.scenario import reference_scenario
from sitl_quad.navigator import NavEvent, NavigationError, Navigator, NavigatorConfig
from uavcore.geodesy import LocalFrame
from uavcore.mission import MavCmd, MavFrame, MissionItem, rally_point_items
from uavcore.rotation import quat_from_euler, wrap_pi
from uavcore.state import TrajectorySetpoint, VehicleState

DT = 0.02  # the outer-loop period
REL = MavFrame.GLOBAL_RELATIVE_ALT_INT
HOME = (38.9210, 121.6630, 0.0)
CONFIG = dict(
    cruise_speed=10.0,
    max_acceleration=3.0,
    max_jerk=4.0,
    climb_speed=2.5,
    descent_speed=1.5,
    land_speed=0.7,
    yaw_rate=math.radians(60),
    acceptance_radius=2.0,
    altitude_acceptance=1.0,
    rtl_altitude=10.0,
    takeoff_altitude=5.0,
)

Follower = Callable[[float, TrajectorySetpoint], VehicleState]


def state_at(position, yaw: float = 0.0, velocity=(0.0, 0.0, 0.0), t: float = 0.0) -> VehicleState:
    return VehicleState(
        t=t,
        position=np.array(position, dtype=float),
        velocity=np.array(velocity, dtype=float),
        quaternion=quat_from_euler(0.0, 0.0, yaw),
    )


def perfect_tracker(t: float, setpoint: TrajectorySetpoint) -> VehicleState:
    position = setpoint.position.copy()
    position[2] = min(position[2], 0.0)  # the ground stops it
    return state_at(position, setpoint.yaw, setpoint.velocity, t)


@dataclass
class Flight:
    """What the navigator published, tick by tick, and the events with the time they were popped."""

    times: list[float] = field(default_factory=list)
    position: list[np.ndarray] = field(default_factory=list)
    velocity: list[np.ndarray] = field(default_factory=list)
    acceleration: list[np.ndarray] = field(default_factory=list)
    yaw: list[float] = field(default_factory=list)
    yaw_rate: list[float] = field(default_factory=list)
    events: list[tuple[float, NavEvent]] = field(default_factory=list)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (np.array(self.times), np.array(self.position), np.array(self.velocity), np.array(self.acceleration))

    def kinds(self) -> list[tuple[str, int]]:
        return [(e.kind, e.seq) for _, e in self.events]

    def time_of(self, kind: str, seq: int) -> float:
        return next(t for t, e in self.events if e.kind == kind and e.seq == seq)

    def index_at(self, t: float) -> int:
        return int(np.searchsorted(np.array(self.times), t - 1e-9))


def fly(
    nav: Navigator,
    t0: float,
    state: VehicleState,
    duration: float,
    follower: Follower = perfect_tracker,
    until: Callable[[Navigator], bool] | None = None,
) -> tuple[Flight, float, VehicleState]:
    """Call update every DT for `duration` seconds (or until `until(nav)`); returns (flight, t, last state)."""
    flight = Flight()
    for k in range(round(duration / DT)):
        t = t0 + k * DT  # multiplied, not accumulated, so tick times are exact
        setpoint = nav.update(t, state)
        flight.times.append(t)
        flight.position.append(setpoint.position)
        flight.velocity.append(setpoint.velocity)
        flight.acceleration.append(setpoint.acceleration)
        flight.yaw.append(setpoint.yaw)
        flight.yaw_rate.append(setpoint.yaw_rate)
        flight.events.extend((t, event) for event in nav.pop_events())
        state = follower(t, setpoint)
        if until is not None and until(nav):
            break
    return flight, t + DT, state


def item(
    seq: int,
    command: int,
    north: float = 0.0,
    east: float = 0.0,
    alt: float = 5.0,
    frame: int = REL,
    here: bool = False,
    **params: float,
) -> MissionItem:
    """A mission item at local (north, east) metres from HOME, or with lat/lon 0,0 when `here`."""
    x = y = 0
    if not here:
        lat, lon, _ = LocalFrame(*HOME).from_ned(north, east, 0.0)
        x, y = round(lat * 1e7), round(lon * 1e7)
    return MissionItem(seq=seq, frame=frame, command=command, x=x, y=y, z=alt, **params)


def renumber(items: list[MissionItem]) -> list[MissionItem]:
    return [MissionItem(**{**vars(it), "seq": i}) for i, it in enumerate(items)]


def navigator(home=HOME, **overrides: float) -> Navigator:
    return Navigator(LocalFrame(*home), NavigatorConfig(**{**CONFIG, **overrides}))


def horizontal_speed(velocity: np.ndarray) -> np.ndarray:
    return np.hypot(velocity[:, 0], velocity[:, 1])


# ---- the 13-buoy reference mission -------------------------------------------------------------------------


def reference_mission() -> tuple[list[MissionItem], list[tuple[float, float]]]:
    """TAKEOFF, DO_CHANGE_SPEED 10, one WAYPOINT per buoy (dwell 1 s, acceptance 2 m, 5 m), RTL.

    The buoys of reference_scenario(1) are visited in nearest-neighbour order from the depot (the route
    planner's order is not needed to test the navigator).
    """
    scenario = reference_scenario(1)
    left = list(range(len(scenario.buoys_local)))
    here = np.zeros(2)
    order = []
    while left:
        nearest = min(left, key=lambda k: float(np.linalg.norm(scenario.buoys_local[k] - here)))
        order.append(nearest)
        left.remove(nearest)
        here = scenario.buoys_local[nearest]
    items = [
        MissionItem(0, REL, MavCmd.NAV_TAKEOFF, z=5.0),
        MissionItem(1, MavFrame.MISSION, MavCmd.DO_CHANGE_SPEED, param1=1.0, param2=10.0, param3=-1.0),
    ]
    north_east = []
    for k in order:
        lat, lon = scenario.buoys_lat_lon[k]
        items.append(
            MissionItem(
                len(items),
                REL,
                MavCmd.NAV_WAYPOINT,
                param1=1.0,
                param2=2.0,
                x=round(lat * 1e7),
                y=round(lon * 1e7),
                z=5.0,
            )
        )
        east, north = scenario.buoys_local[k]
        north_east.append((float(north), float(east)))
    items.append(MissionItem(len(items), REL, MavCmd.NAV_RETURN_TO_LAUNCH))
    return items, north_east


def fly_reference_mission(config: dict | None = None) -> tuple[Navigator, Flight]:
    items, _ = reference_mission()
    nav = navigator(home=reference_scenario(1).home, **(config or {}))
    nav.set_mission(items)
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)
    # run on a little after completion so the landing reference is seen settling under the ground
    flight, t, state = fly(nav, 0.0, state, 2000.0, until=lambda n: n.mission_state == "complete")
    tail, _, _ = fly(nav, t, state, 5.0)
    flight.times += tail.times
    flight.position += tail.position
    flight.velocity += tail.velocity
    flight.acceleration += tail.acceleration
    flight.yaw += tail.yaw
    flight.yaw_rate += tail.yaw_rate
    flight.events += tail.events
    return nav, flight


@pytest.fixture(scope="module")
def reference_flight() -> tuple[Navigator, Flight]:
    return fly_reference_mission()


def test_reference_mission_sequences_to_complete_with_events_in_order(reference_flight) -> None:
    nav, flight = reference_flight
    items, _ = reference_mission()
    last = len(items) - 1
    expected = []
    for seq in range(last):
        expected += [("current", seq), ("reached", seq)]
    expected += [("current", last), ("landing", last), ("reached", last), ("complete", last)]
    assert flight.kinds() == expected
    assert nav.mission_state == "complete"
    assert nav.is_landing
    assert nav.activity == "land"
    times = [t for t, _ in flight.events]
    assert times == sorted(times)
    # DO_CHANGE_SPEED runs at once: current and reached in the same tick as the takeoff's arrival
    assert flight.time_of("reached", 0) == flight.time_of("current", 1) == flight.time_of("reached", 1)


def test_reference_mission_reaches_every_buoy_where_it_is(reference_flight) -> None:
    _, flight = reference_flight
    _, buoys = reference_mission()
    _, position, velocity, _ = flight.arrays()
    for k, (north, east) in enumerate(buoys):
        i = flight.index_at(flight.time_of("reached", k + 2))
        # the mission stores lat/lon in degE7: about 1 cm of quantisation
        assert position[i] == pytest.approx([north, east, -5.0], abs=0.02)
        assert np.linalg.norm(velocity[i]) == pytest.approx(0.0, abs=1e-9)


def test_reference_never_exceeds_the_speed_limits(reference_flight) -> None:
    _, flight = reference_flight
    _, _, velocity, _ = flight.arrays()
    assert horizontal_speed(velocity).max() <= 10.0 + 1e-9
    assert horizontal_speed(velocity).max() >= 10.0 - 1e-9  # the long legs do cruise
    assert -velocity[:, 2].min() <= 2.5 + 1e-9  # climb
    assert velocity[:, 2].max() <= 1.5 + 1e-9  # descent


def test_reference_is_continuous_and_acceleration_limited_by_finite_differences(reference_flight) -> None:
    _, flight = reference_flight
    _, position, velocity, acceleration = flight.arrays()
    speed = np.linalg.norm(velocity, axis=1)
    steps = np.linalg.norm(np.diff(position, axis=0), axis=1)
    # within a tick the speed can exceed both ends' speeds only by the acceleration limit times the tick
    fastest_within_tick = np.maximum(speed[:-1], speed[1:]) + 3.0 * DT
    assert np.all(steps <= fastest_within_tick * DT + 1e-9), "no jumps between updates"
    differenced = np.linalg.norm(np.diff(velocity, axis=0), axis=1) / DT
    assert differenced.max() <= 3.0 + 1e-6
    assert np.linalg.norm(acceleration, axis=1).max() <= 3.0 + 1e-9
    jerk = np.linalg.norm(np.diff(acceleration, axis=0), axis=1) / DT
    assert jerk.max() <= 4.0 + 1e-6


def test_velocity_and_acceleration_feed_forward_match_the_position_derivatives(reference_flight) -> None:
    _, flight = reference_flight
    _, position, velocity, acceleration = flight.arrays()
    central_velocity = (position[2:] - position[:-2]) / (2 * DT)
    # a cubic's central difference is off by jerk dt^2 / 6; across a jerk switch by at most J dt
    assert np.abs(central_velocity - velocity[1:-1]).max() <= 4.0 * DT
    central_acceleration = (velocity[2:] - velocity[:-2]) / (2 * DT)
    assert np.abs(central_acceleration - acceleration[1:-1]).max() <= 4.0 * DT


def test_yaw_turns_at_the_limited_rate_while_hovering_then_flies_facing_the_buoy(reference_flight) -> None:
    _, flight = reference_flight
    _, position, velocity, _ = flight.arrays()
    yaw = np.array(flight.yaw)
    yaw_rate = np.array(flight.yaw_rate)
    assert np.all((yaw >= -math.pi) & (yaw < math.pi))
    yaw_steps = np.array([wrap_pi(b - a) for a, b in itertools.pairwise(yaw)])
    assert np.abs(yaw_steps).max() <= math.radians(60) * DT + 1e-9
    assert np.abs(yaw_rate).max() <= math.radians(60) + 1e-9
    speed = np.linalg.norm(velocity, axis=1)
    turning = np.abs(yaw_rate) > 1e-9
    assert turning.any()
    assert np.all(speed[turning] == 0.0), "turns happen hovering over the previous waypoint"
    moving = horizontal_speed(velocity) > 0.1
    for i in np.flatnonzero(moving):
        heading = math.atan2(velocity[i, 1], velocity[i, 0])
        assert wrap_pi(yaw[i] - heading) == pytest.approx(0.0, abs=1e-9)
    # each mission leg is preceded by a turn whose end faces the buoy the leg flies to
    _, buoys = reference_mission()
    for seq in range(2, len(buoys) + 2):
        start = flight.index_at(flight.time_of("current", seq))
        depart = start + int(np.argmax(speed[start:] > 0.0))
        here = position[depart - 1]
        north, east, _ = position[flight.index_at(flight.time_of("reached", seq))]
        assert np.all(speed[start:depart] == 0.0)
        assert wrap_pi(yaw[depart] - math.atan2(east - here[1], north - here[0])) == pytest.approx(0.0, abs=1e-9)


def test_dwell_is_respected_at_each_buoy(reference_flight) -> None:
    _, flight = reference_flight
    _, position, velocity, _ = flight.arrays()
    _, buoys = reference_mission()
    for k in range(len(buoys)):
        seq = k + 2
        reached = flight.time_of("reached", seq)
        advanced = flight.time_of("current", seq + 1)
        assert 1.0 - 1e-9 <= advanced - reached < 1.0 + DT + 1e-9
        held = slice(flight.index_at(reached), flight.index_at(advanced))
        assert np.all(np.linalg.norm(velocity[held], axis=1) == 0.0)
        assert np.ptp(position[held], axis=0).max() == 0.0


def test_reference_mission_duration_is_reported_and_plausible(reference_flight) -> None:
    _, flight = reference_flight
    _, buoys = reference_mission()
    # the mission's corners: up from home to 5 m, every buoy at 5 m, up to the 10 m return altitude, home, down
    climb = [(0.0, 0.0, 0.0), (0.0, 0.0, -5.0)]
    visits = [(north, east, -5.0) for north, east in buoys]
    back = [(*buoys[-1], -10.0), (0.0, 0.0, -10.0), (0.0, 0.0, 0.0)]
    path = np.array([*climb, *visits, *back])
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    duration = flight.time_of("complete", len(reference_mission()[0]) - 1)
    # lower bound: the whole path at cruise plus the dwells; each of the 14 horizontal legs adds at least the
    # S-curve's ramp overhead V/A + A/J
    assert duration >= length / 10.0 + 13 * 1.0 + 14 * (10.0 / 3.0 + 3.0 / 4.0) * 0.5
    print(f"\nreference mission: path {length:.0f} m, reference duration to touchdown {duration:.1f} s")


# ---- speed changes, acceptance -----------------------------------------------------------------------------


def two_leg_mission(speed_change: float) -> list[MissionItem]:
    return renumber(
        [
            item(0, MavCmd.NAV_TAKEOFF, here=True, alt=5.0),
            item(0, MavCmd.NAV_WAYPOINT, 200.0, 0.0, param1=0.0),
            item(0, MavCmd.DO_CHANGE_SPEED, param1=1.0, param2=speed_change, frame=MavFrame.MISSION, here=True),
            item(0, MavCmd.NAV_WAYPOINT, 200.0, 200.0, param1=0.0),
        ]
    )


def leg_peak_speeds(speed_change: float) -> tuple[float, float]:
    nav = navigator()
    nav.set_mission(two_leg_mission(speed_change))
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 200.0, until=lambda n: n.mission_state == "complete")
    _, _, velocity, _ = flight.arrays()
    speed = horizontal_speed(velocity)
    split = flight.index_at(flight.time_of("current", 3))
    return float(speed[:split].max()), float(speed[split:].max())


def test_do_change_speed_slows_the_following_legs() -> None:
    first, second = leg_peak_speeds(4.0)
    assert first == pytest.approx(10.0)
    assert second == pytest.approx(4.0)


@pytest.mark.parametrize("no_change", [-1.0, math.nan])
def test_do_change_speed_minus_one_or_nan_keeps_the_speed(no_change: float) -> None:
    assert leg_peak_speeds(no_change) == pytest.approx((10.0, 10.0))


def hover_then_waypoint(radius: float = 2.0) -> tuple[Navigator, VehicleState]:
    nav = navigator()
    nav.set_mission([item(0, MavCmd.NAV_WAYPOINT, 60.0, 0.0, param1=0.0, param2=radius)])
    state = state_at((0.0, 0.0, -5.0))
    nav.start_mission(0.0, state)
    return nav, state


def test_a_vehicle_that_never_arrives_is_never_reported_reached() -> None:
    nav, state = hover_then_waypoint()
    stuck = state_at((45.0, 0.0, -5.0))
    flight, _, _ = fly(nav, 0.0, state, 60.0, follower=lambda t, sp: stuck)
    assert flight.kinds() == [("current", 0)]
    assert nav.mission_state == "active"
    assert flight.position[-1] == pytest.approx([60.0, 0.0, -5.0], abs=0.02)  # degE7 quantisation


@pytest.mark.parametrize(("radius", "reached"), [(2.0, False), (5.0, True)])
def test_acceptance_radius_parameter_decides_arrival(radius: float, reached: bool) -> None:
    nav, state = hover_then_waypoint(radius)

    def offset_by_three_metres(t: float, setpoint: TrajectorySetpoint) -> VehicleState:
        return state_at(setpoint.position + np.array([0.0, 3.0, 0.0]), setpoint.yaw, setpoint.velocity, t)

    flight, _, _ = fly(nav, 0.0, state, 60.0, follower=offset_by_three_metres)
    assert (("reached", 0) in flight.kinds()) is reached


def test_altitude_tolerance_is_part_of_arrival() -> None:
    nav, state = hover_then_waypoint(10.0)

    def two_metres_low(t: float, setpoint: TrajectorySetpoint) -> VehicleState:
        return state_at(setpoint.position + np.array([0.0, 0.0, 2.0]), setpoint.yaw, setpoint.velocity, t)

    flight, _, _ = fly(nav, 0.0, state, 60.0, follower=two_metres_low)
    assert ("reached", 0) not in flight.kinds()


def test_noisy_follower_is_reached_only_once_the_reference_has_arrived() -> None:
    rng = np.random.default_rng(7)
    items, _ = reference_mission()
    nav = navigator(home=reference_scenario(1).home)
    nav.set_mission(items[:6])  # takeoff, speed, four buoys
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)

    vehicle: list[np.ndarray] = []

    def noisy(t: float, setpoint: TrajectorySetpoint) -> VehicleState:
        lag = setpoint.position - setpoint.velocity * 0.3  # a tracking lag plus noise
        vehicle.append(lag + rng.normal(0.0, 0.3, 3))
        return state_at(vehicle[-1], setpoint.yaw, setpoint.velocity, t)

    flight, _, _ = fly(nav, 0.0, state, 600.0, follower=noisy, until=lambda n: n.mission_state == "complete")
    assert [kind for kind, _ in flight.kinds()].count("reached") == 6
    _, position, velocity, _ = flight.arrays()
    for seq in range(2, 6):
        i = flight.index_at(flight.time_of("reached", seq))
        target = position[i]
        assert np.linalg.norm(velocity[i]) == 0.0, "reached only once the reference has arrived"
        # the vehicle state passed at tick j is vehicle[j - 1]; it was inside the radius before the reference
        # arrived, and that alone did not count
        leg_start = flight.index_at(flight.time_of("current", seq))
        inside = [
            j
            for j in range(leg_start + 1, i)
            if np.hypot(*(vehicle[j - 1][:2] - target[:2])) <= 2.0 and abs(vehicle[j - 1][2] - target[2]) <= 1
        ]
        assert inside, "the vehicle was within the acceptance radius while the reference still moved"
        assert np.linalg.norm(velocity[inside[0]]) > 0.0


# ---- landing, return, takeoff, hold, resume ----------------------------------------------------------------


def test_rtl_climbs_to_return_altitude_flies_home_and_lands() -> None:
    nav = navigator()
    state = state_at((120.0, -80.0, -5.0), yaw=1.0)
    nav.hold(0.0, state)
    _, t, state = fly(nav, 0.0, state, 1.0)
    nav.start_rtl(t, state)
    assert nav.activity == "rtl" and not nav.is_landing
    flight, _, _ = fly(nav, t, state, 200.0)
    _, position, velocity, _ = flight.arrays()
    # climb first, straight up
    climbing = position[:, 2] > -10.0 + 1e-9
    first_at_altitude = int(np.argmin(climbing))
    assert np.allclose(position[:first_at_altitude, :2], [120.0, -80.0], rtol=0, atol=1e-9)
    # home at the return altitude, then straight down
    over_home = np.flatnonzero(np.all(np.abs(position[:, :2]) < 1e-9, axis=1))[0]
    assert position[over_home, 2] == pytest.approx(-10.0)
    assert np.all(np.abs(position[over_home:, :2]) < 1e-9)
    assert [kind for kind, _ in flight.kinds()] == ["landing"]
    assert nav.is_landing
    assert position[-1, 2] == pytest.approx(0.5), "the reference ends pressing half a metre under the ground"
    at_ground = np.argmin(np.abs(position[over_home:, 2])) + over_home
    assert velocity[at_ground, 2] == pytest.approx(0.7, abs=1e-3)
    assert velocity[over_home:, 2].max() == pytest.approx(1.5)


def test_a_sortie_given_rally_points_lands_at_its_depot_and_not_at_a_closer_rally_point() -> None:
    """The service's items (gcs.domain.planning.mission_items) against the vehicle's return: a NAV_RETURN_TO_LAUNCH
    item is PX4's RTL, which (RTL_TYPE 0) lands at the closest of home and the rally points, here the rally point
    100 m past the buoy; a plan given rally points ends instead with a waypoint at its depot and NAV_LAND there, so
    the sortie lands where the next one takes off (a fleet share's second sortie failed when it landed elsewhere)."""
    frame = LocalFrame(*HOME)
    buoy, rally = (140.0, 0.0), (240.0, -40.0)  # north, east m from home, the depot: the rally is 108 m from the buoy
    buoy_lat, buoy_lon, _ = frame.from_ned(*buoy, 0.0)
    rally_lat, rally_lon, _ = frame.from_ned(*rally, 0.0)
    plan = Plan(HOME[:2], ["B1"], [[buoy_lat, buoy_lon]], [[buoy[1], buoy[0]]], [0], 280.0, 280.0, "given", 0.0)
    flight_params = FlightParams(altitude_m=5.0, speed_m_s=10.0, dwell_s=0.0, acceptance_radius_m=2.0)

    def landed_at(plan: Plan) -> np.ndarray:
        nav = navigator()
        nav.set_rally_points(rally_point_items([(rally_lat, rally_lon, 15.0)]))
        nav.set_mission(mission_items(plan, flight_params, HOME[:2]))
        state = state_at((0.0, 0.0, 0.0))
        nav.start_mission(0.0, state)
        flight, _, _ = fly(nav, 0.0, state, 300.0, until=lambda n: n.mission_state == "complete")
        assert nav.mission_state == "complete"
        return flight.arrays()[1][-1]

    without_rally = landed_at(plan)  # ends with NAV_RETURN_TO_LAUNCH: the vehicle's RTL picks the rally point
    assert np.allclose(without_rally[:2], rally, atol=0.05), without_rally  # 1e-7 deg items: cm
    with_rally = landed_at(replace(plan, rally_points=[[rally_lat, rally_lon, 15.0]]))
    assert np.allclose(with_rally[:2], (0.0, 0.0), atol=0.05), with_rally


def test_rtl_outside_a_mission_emits_landing_with_seq_minus_one() -> None:
    nav = navigator()
    state = state_at((1.0, 0.0, -3.0))
    nav.start_rtl(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 30.0)
    assert flight.kinds() == [("landing", -1)]


def test_nav_land_descends_at_land_speed_at_its_position_and_completes() -> None:
    nav = navigator()
    nav.set_mission(
        renumber(
            [
                item(0, MavCmd.NAV_TAKEOFF, here=True),
                item(0, MavCmd.NAV_WAYPOINT, 30.0, 0.0, param1=0.0),
                item(0, MavCmd.NAV_LAND, 30.0, 40.0, alt=0.0),
            ]
        )
    )
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)
    flight, _t, _ = fly(nav, 0.0, state, 200.0, until=lambda n: n.mission_state == "complete")
    assert flight.kinds()[-4:] == [("current", 2), ("landing", 2), ("reached", 2), ("complete", 2)]
    _, position, velocity, _ = flight.arrays()
    descending = slice(flight.index_at(flight.time_of("landing", 2)), None)
    assert np.allclose(position[descending, :2], position[descending.start, :2], rtol=0, atol=1e-12)
    assert position[descending.start, :2] == pytest.approx([30.0, 40.0], abs=0.02)  # degE7 quantisation
    assert velocity[descending, 2].max() == pytest.approx(0.7)  # from 5 m it is all at land speed
    assert position[-1, 2] >= 0.0  # reached when the reference got to the ground


def test_land_item_without_position_lands_here() -> None:
    nav = navigator()
    nav.set_mission(
        renumber(
            [
                item(0, MavCmd.NAV_WAYPOINT, 20.0, 20.0, alt=4.0, param1=0.0),
                item(0, MavCmd.NAV_LAND, here=True, alt=0.0),
            ]
        )
    )
    state = state_at((0.0, 0.0, -4.0))
    nav.start_mission(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 120.0, until=lambda n: n.mission_state == "complete")
    assert flight.position[-1][:2] == pytest.approx([20.0, 20.0], abs=0.02)  # degE7 quantisation
    assert flight.kinds()[-1] == ("complete", 1)


def test_start_land_brakes_then_descends_here() -> None:
    nav, state = hover_then_waypoint()
    flight, t, state = fly(nav, 0.0, state, 8.0)
    moving = flight.velocity[-1]
    assert np.linalg.norm(moving) > 1.0
    nav.start_land(t, state)
    assert nav.mission_state == "paused" and nav.activity == "land"
    landing, _, _ = fly(nav, t, state, 40.0)
    _, position, velocity, acceleration = landing.arrays()
    assert np.linalg.norm(acceleration, axis=1).max() <= 3.0 + 1e-9
    assert np.linalg.norm(np.diff(position, axis=0), axis=1).max() <= 10.0 * DT
    assert position[-1, 2] == pytest.approx(0.5)
    assert np.all(velocity[-10:] == 0.0)


def test_mission_without_landing_holds_at_the_last_waypoint() -> None:
    nav = navigator()
    nav.set_mission(
        renumber([item(0, MavCmd.NAV_TAKEOFF, here=True), item(0, MavCmd.NAV_WAYPOINT, 0.0, 50.0, param1=2.0)])
    )
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)
    flight, t, state = fly(nav, 0.0, state, 100.0, until=lambda n: n.mission_state == "complete")
    assert flight.kinds()[-2:] == [("reached", 1), ("complete", 1)]
    assert flight.time_of("complete", 1) - flight.time_of("reached", 1) >= 2.0 - 1e-9
    assert nav.activity == "hold" and not nav.is_landing
    later, _, _ = fly(nav, t, state, 10.0)
    assert np.allclose(later.position, flight.position[-1], rtol=0, atol=0)
    assert later.position[-1] == pytest.approx([0.0, 50.0, -5.0], abs=0.02)  # degE7 quantisation
    assert later.events == []


def test_takeoff_climbs_vertically_then_holds() -> None:
    nav = navigator()
    state = state_at((3.0, 4.0, 0.0), yaw=0.5)
    nav.start_takeoff(0.0, state, 7.0)
    assert nav.activity == "takeoff"
    flight, _, _ = fly(nav, 0.0, state, 15.0)
    _, position, velocity, _ = flight.arrays()
    assert np.allclose(position[:, :2], [3.0, 4.0], rtol=0, atol=1e-12)
    assert -velocity[:, 2].min() == pytest.approx(2.5)
    assert position[-1, 2] == pytest.approx(-7.0)
    assert nav.activity == "hold"
    assert flight.yaw[-1] == pytest.approx(0.5)


def test_takeoff_item_with_a_position_climbs_first_then_flies_there() -> None:
    nav = navigator()
    nav.set_mission([item(0, MavCmd.NAV_TAKEOFF, 40.0, 0.0, alt=6.0)])
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 60.0, until=lambda n: n.mission_state == "complete")
    _, position, _, _ = flight.arrays()
    left_home = int(np.argmax(position[:, 0] > 1e-9))
    assert position[left_home - 1, 2] == pytest.approx(-6.0)
    assert flight.kinds() == [("current", 0), ("reached", 0), ("complete", 0)]
    assert position[-1] == pytest.approx([40.0, 0.0, -6.0], abs=0.02)  # degE7 quantisation


def test_waypoint_yaw_parameter_sets_the_heading_in_degrees() -> None:
    nav = navigator()
    nav.set_mission([item(0, MavCmd.NAV_WAYPOINT, 30.0, 0.0, param1=0.0, param4=90.0)])
    state = state_at((0.0, 0.0, -5.0))
    nav.start_mission(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 30.0)
    _, _, velocity, _ = flight.arrays()
    moving = np.linalg.norm(velocity, axis=1) > 0
    assert np.all(np.array(flight.yaw)[moving] == pytest.approx(math.pi / 2))


def test_yaw_wraps_across_plus_minus_pi_the_short_way() -> None:
    # south-south-west then south-south-east: the heading goes from -160 deg to +160 deg through 180
    nav = navigator()
    nav.set_mission(
        renumber(
            [
                item(
                    0,
                    MavCmd.NAV_WAYPOINT,
                    -30.0 * math.cos(math.radians(20)),
                    -30.0 * math.sin(math.radians(20)),
                    param1=0.0,
                ),
                item(0, MavCmd.NAV_WAYPOINT, -60.0 * math.cos(math.radians(20)), 0.0, param1=0.0),
            ]
        )
    )
    state = state_at((0.0, 0.0, -5.0), yaw=math.radians(-160))
    nav.start_mission(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 60.0, until=lambda n: n.mission_state == "complete")
    turn = slice(flight.index_at(flight.time_of("current", 1)), None)
    yaw = np.array(flight.yaw[turn])
    swept = sum(wrap_pi(b - a) for a, b in itertools.pairwise(yaw))
    assert swept == pytest.approx(math.radians(-40), abs=1e-3)  # degE7 quantisation of the waypoints
    assert np.abs(np.array(flight.yaw_rate[turn])).max() <= math.radians(60) + 1e-9
    assert yaw.max() > math.radians(170) and yaw.min() < math.radians(-170), "it passed through 180 degrees"


def test_amsl_frames_subtract_home_altitude() -> None:
    home = (38.9210, 121.6630, 20.0)
    frame = LocalFrame(*home)
    lat, lon, _ = frame.from_ned(50.0, -30.0, 0.0)
    x, y = round(lat * 1e7), round(lon * 1e7)
    north, east, _ = frame.to_ned(x * 1e-7, y * 1e-7, home[2])
    for amsl_frame in (MavFrame.GLOBAL, MavFrame.GLOBAL_INT):
        nav = navigator(home=home)
        nav.set_mission([MissionItem(0, amsl_frame, MavCmd.NAV_WAYPOINT, param1=0.0, x=x, y=y, z=25.0)])
        relative = navigator(home=home)
        relative.set_mission([MissionItem(0, REL, MavCmd.NAV_WAYPOINT, param1=0.0, x=x, y=y, z=5.0)])
        ends = []
        for flown in (nav, relative):
            state = state_at((50.0, -30.0, -20.0))
            flown.start_mission(0.0, state)
            flight, _, _ = fly(flown, 0.0, state, 30.0, until=lambda n: n.mission_state == "complete")
            ends.append(flight.position[-1])
        assert ends[0] == pytest.approx([north, east, -5.0], abs=1e-9)
        assert ends[1] == pytest.approx(ends[0], abs=1e-9)


def test_hold_mid_leg_brakes_smoothly_and_pauses_the_mission_then_resumes() -> None:
    items, _ = reference_mission()
    nav = navigator(home=reference_scenario(1).home)
    nav.set_mission(items[:5])
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)
    first, t, state = fly(nav, 0.0, state, 14.0)
    assert nav.current_seq == 2 and np.linalg.norm(first.velocity[-1]) > 5.0
    nav.hold(t, state)
    assert nav.mission_state == "paused" and nav.activity == "hold"
    held, t, state = fly(nav, t, state, 10.0)
    _, position, velocity, acceleration = held.arrays()
    assert np.linalg.norm(position[0] - first.position[-1]) <= 10.0 * DT
    assert np.linalg.norm(acceleration, axis=1).max() <= 3.0 + 1e-9
    assert np.all(velocity[-50:] == 0.0)
    assert held.events == []
    nav.start_mission(t, state)
    resumed, _, _ = fly(nav, t, state, 300.0, until=lambda n: n.mission_state == "complete")
    assert resumed.kinds()[0] == ("current", 2)
    assert resumed.kinds()[-1] == ("complete", 4)
    assert np.linalg.norm(resumed.position[0] - position[-1]) < 1e-9


def test_resume_from_a_mid_mission_seq_keeps_earlier_speed_changes() -> None:
    nav = navigator()
    nav.set_mission(two_leg_mission(4.0))
    state = state_at((200.0, 0.0, -5.0))
    nav.start_mission(0.0, state, from_seq=3)
    flight, _, _ = fly(nav, 0.0, state, 120.0, until=lambda n: n.mission_state == "complete")
    assert flight.kinds() == [("current", 3), ("reached", 3), ("complete", 3)]
    assert horizontal_speed(np.array(flight.velocity)).max() == pytest.approx(4.0)


def test_mission_from_the_ground_at_a_waypoint_climbs_before_the_leg() -> None:
    nav = navigator()
    nav.set_mission([item(0, MavCmd.NAV_WAYPOINT, 40.0, 0.0, param1=0.0)])
    state = state_at((0.0, 0.0, 0.0))
    nav.start_mission(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 60.0, until=lambda n: n.mission_state == "complete")
    _, position, _, _ = flight.arrays()
    left = int(np.argmax(position[:, 0] > 1e-9))
    assert position[left - 1, 2] == pytest.approx(-5.0)


def test_a_stale_reference_restarts_from_the_vehicle() -> None:
    nav, state = hover_then_waypoint()
    _, t, _ = fly(nav, 0.0, state, 3.0)
    elsewhere = state_at((-20.0, 10.0, -8.0))
    nav.hold(t + 30.0, elsewhere)  # the navigator was not updated for 30 s
    setpoint = nav.update(t + 30.0, elsewhere)
    assert setpoint.position == pytest.approx([-20.0, 10.0, -8.0])


def test_bad_requests_raise_navigation_errors() -> None:
    with pytest.raises(NavigationError, match="cruise_speed"):
        NavigatorConfig(cruise_speed=0.0)
    with pytest.raises(NavigationError, match="max_acceleration"):
        NavigatorConfig(max_acceleration=math.nan)
    NavigatorConfig(max_jerk=math.inf)  # a trapezoidal profile is allowed
    nav = navigator()
    state = state_at((0.0, 0.0, 0.0))
    with pytest.raises(NavigationError, match="no mission"):
        nav.start_mission(0.0, state)
    nav.set_mission(two_leg_mission(4.0))
    with pytest.raises(NavigationError, match="cannot start at 9"):
        nav.start_mission(0.0, state, from_seq=9)
    with pytest.raises(NavigationError, match="altitude"):
        nav.start_takeoff(0.0, state, -3.0)
    with pytest.raises(NavigationError, match="frame 7"):
        nav.set_mission([MissionItem(0, 7, MavCmd.NAV_WAYPOINT, x=1, y=1, z=5.0)])


def test_mission_state_and_current_item_bookkeeping() -> None:
    nav = navigator()
    assert nav.mission_state == "no_mission" and nav.activity == "idle"
    nav.set_mission(two_leg_mission(4.0))
    assert nav.mission_state == "not_started" and nav.current_seq == 0
    nav.set_current(0.0, state_at((0.0, 0.0, 0.0)), 2)
    assert nav.current_seq == 2 and nav.pop_events() == [NavEvent("current", 2)]
    nav.set_mission([])
    assert nav.mission_state == "no_mission"


def test_loiter_time_holds_at_its_position_for_its_time() -> None:
    nav = navigator()
    nav.set_mission(
        renumber(
            [
                item(0, MavCmd.NAV_LOITER_TIME, 0.0, 30.0, param1=3.0),
                item(0, MavCmd.NAV_WAYPOINT, 0.0, 60.0, param1=0.0),
            ]
        )
    )
    state = state_at((0.0, 0.0, -5.0))
    nav.start_mission(0.0, state)
    flight, _, _ = fly(nav, 0.0, state, 60.0, until=lambda n: n.mission_state == "complete")
    reached, advanced = flight.time_of("reached", 0), flight.time_of("current", 1)
    assert 3.0 - 1e-9 <= advanced - reached < 3.0 + DT + 1e-9
    held = np.array(flight.position[flight.index_at(reached) : flight.index_at(advanced)])
    assert np.ptp(held, axis=0).max() == 0.0
    assert held[0] == pytest.approx([0.0, 30.0, -5.0], abs=0.02)  # degE7 quantisation


def test_hold_at_a_given_point_and_yaw() -> None:
    nav = navigator()
    state = state_at((0.0, 0.0, -5.0))
    nav.hold(0.0, state, position=(20.0, -10.0, -8.0), yaw=math.radians(-90))
    flight, _, _ = fly(nav, 0.0, state, 30.0)
    assert nav.activity == "hold" and flight.events == []
    assert flight.position[-1] == pytest.approx([20.0, -10.0, -8.0])
    assert flight.yaw[-1] == pytest.approx(math.radians(-90))
    _, _, velocity, _ = flight.arrays()
    assert np.linalg.norm(velocity, axis=1).max() <= math.hypot(10.0, 2.5) + 1e-9


def test_a_completed_mission_starts_again_from_the_first_item() -> None:
    nav = navigator()
    nav.set_mission([item(0, MavCmd.NAV_WAYPOINT, 10.0, 0.0, param1=0.0)])
    state = state_at((0.0, 0.0, -5.0))
    nav.start_mission(0.0, state)
    _, t, state = fly(nav, 0.0, state, 30.0, until=lambda n: n.mission_state == "complete")
    nav.hold(t, state, position=(0.0, 0.0, -5.0))
    _, t, state = fly(nav, t, state, 20.0)
    nav.start_mission(t, state)
    again, _, _ = fly(nav, t, state, 30.0, until=lambda n: n.mission_state == "complete")
    assert again.kinds() == [("current", 0), ("reached", 0), ("complete", 0)]
