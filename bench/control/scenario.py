"""The benchmark's air and mission (the paper's Section VI, made concrete; every number is in control.json's
"scenario").

- Mission: `planner.scenario.reference_scenario()` (13 buoys, depot at home), optimal order
  (`plan_tour(method="exact")` through gcs.domain.planning.make_plan), flown as the GCS would upload it
  (gcs.domain.planning.mission_items: takeoff, DO_CHANGE_SPEED 10 m/s, one NAV_WAYPOINT per buoy at 5 m with a
  1 s inspection dwell and a 2 m acceptance radius, RTL), in-process lockstep (sitl_quad.lockstep_harness).
- Weather: `planner.scenario.paper_weather` for the route, the one definition the demo (`buoy-gcs up --demo`)
  flies too: 5 m/s mean crosswind perpendicular to the route's longest leg (blowing from its right-hand side);
  a 1-cosine gust, 4 m/s along the crosswind, rise 1 s, starting at the instant the route's kinematic timeline
  (`planner.scenario.MissionTimeline`: spool-up, climb, turns, S-curve legs, dwells) has the vehicle halfway
  along the longest leg. Like every wind time it counts on the flight's disturbance clock, which starts at the
  mission start command. Where the navigator's reference really was then is recorded (`gust_leg_fraction`,
  from its own timeline, flown by a vehicle that tracks it perfectly); each flight's item at the onset is in
  per_seed. It holds 10 s and falls back (gust_hold_s = 10): the onset is the step-like "sudden wind change" of
  the paper's Figure 6, and falling back keeps the rest of the mission at the 5 m/s mean. Dryden turbulence,
  MIL-F-8785C low-altitude form, W20 chosen so that sigma_u = sigma_v = 1.0 m/s at the 5 m flight altitude
  (`dryden_w20_for_sigma`: W20 = 5.15 m/s, sigma_w = 0.52 m/s); W20 ~ 5 m/s is also consistent with the 5 m/s
  mean wind.
- Disturbance terms D (eq. 1-2): the weather's variance 0.05 on every channel (sitl_quad.disturbances' realistic
  default), held 0.5 s. The paper's variance 15 is a 0.4 g random push held half a second; `--paper-seeds N` flies
  N extra seeds with it and reports them apart.
- Sensor noise: sitl_quad.sensors defaults (2 cm, 5 cm/s, 0.3 deg, 0.01 rad/s).
- Seeds 0..N-1; a seed fixes wind, turbulence, D terms and sensor noise, so every controller meets the same
  air (paired design).

The step experiment flies `hover_mission` instead: a 5 m hover in still air (sensor noise and D terms on),
then a STEP_M lateral (east) position step (see flight.step_response).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cache

import numpy as np

from gcs.domain.planning import FIRST_BUOY_SEQ, FlightParams, make_plan, mission_items
from planner.scenario import (
    ALTITUDE_M,
    CRUISE_SPEED_M_S,
    MissionTimeline,
    Weather,
    paper_weather,
    reference_scenario,
)
from sitl_quad.config import VehicleConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.navigator import Navigator, NavigatorConfig
from sitl_quad.wind import WindConfig
from uavcore.geodesy import LocalFrame
from uavcore.mission import MavCmd, MavFrame, MissionItem
from uavcore.rotation import quat_from_euler
from uavcore.state import VehicleState

OUTER_RATE_HZ = 50.0
DWELL_S = 1.0
ACCEPTANCE_RADIUS_M = 2.0
STEP_M = 5.0
STEP_HOVER_S = 12.0
STEP_WINDOW_S = 10.0


@dataclass
class Scenario:
    home: tuple[float, float, float]
    items: list[MissionItem]
    waypoints_ne: list[list[float]]  # takeoff point, then the buoys in visiting order: [north, east] m
    route_length_m: float
    longest_leg: int  # index into waypoints_ne of the longest leg's end (1 = first buoy)
    crosswind_from_deg: float
    gust_start_s: float
    wind: WindConfig
    disturbance: DisturbanceConfig = field(default_factory=DisturbanceConfig)
    gust_leg_fraction: float = math.nan  # how far along the longest leg the navigator's reference was at the onset

    def config(self, paper_disturbance: bool = False) -> VehicleConfig:
        """The vehicle in this scenario's air (each controller's inner loop: flight.configure_vehicle)."""
        disturbance = DisturbanceConfig.paper() if paper_disturbance else self.disturbance
        return VehicleConfig(wind=self.wind, disturbance=disturbance)


def wind_config(weather: Weather) -> WindConfig:
    """The vehicle's wind model for a weather."""
    return WindConfig(
        speed_m_s=weather.wind_m_s,
        direction_from_deg=weather.wind_from_deg,
        gust_amplitude_m_s=weather.gust_m_s,
        gust_rise_time_s=weather.gust_rise_s,
        gust_start_s=weather.gust_start_s,
        gust_hold_s=weather.gust_hold_s,
        gust_direction_from_deg=weather.gust_from_deg,
        turbulence_w20_m_s=weather.turbulence_w20_m_s,
    )


def build_scenario() -> Scenario:
    reference = reference_scenario()
    plan = make_plan(
        reference.depot_lat_lon,
        [tuple(p) for p in reference.buoys_lat_lon.tolist()],
        [f"buoy-{i}" for i in range(len(reference.buoys_lat_lon))],
        method="exact",
    )
    items = mission_items(
        plan, FlightParams(ALTITUDE_M, CRUISE_SPEED_M_S, DWELL_S, ACCEPTANCE_RADIUS_M), reference.depot_lat_lon
    )
    frame = LocalFrame(*reference.home)
    waypoints = [[0.0, 0.0]]
    for it in items[FIRST_BUOY_SEQ : FIRST_BUOY_SEQ + len(plan.order)]:
        north, east, _ = frame.to_ned(it.lat, it.lon, frame.alt0)
        waypoints.append([float(north), float(east)])
    placed = paper_weather(np.asarray(waypoints)[:, ::-1])
    weather = placed.weather
    variance = weather.disturbance_variance
    fraction = reference_leg_fraction(items, reference.home, waypoints, placed.longest_leg, weather.gust_start_s)
    return Scenario(
        reference.home,
        items,
        waypoints,
        float(plan.length_m),
        placed.longest_leg,
        weather.wind_from_deg,
        weather.gust_start_s,
        wind_config(weather),
        DisturbanceConfig(*[variance] * 6),
        gust_leg_fraction=fraction,
    )


def reference_leg_fraction(
    items: list[MissionItem], home: tuple[float, float, float], waypoints_ne: list[list[float]], leg: int, t: float
) -> float:
    """How far along leg `leg` of waypoints_ne (0 = its start, 1 = its end) the navigator's reference is t seconds
    after the mission start, on its own timeline flown by a vehicle that tracks it perfectly (the climb starting after
    MissionTimeline's motor spool-up); NaN if it is then on another item."""
    navigator = Navigator(LocalFrame(*home), NavigatorConfig())
    navigator.set_mission(items)
    state = VehicleState()
    navigator.start_mission(0.0, state)
    dt, now = 1.0 / OUTER_RATE_HZ, 0.0
    t_reference = t - MissionTimeline().spool_up_s
    while now < t_reference:
        sp = navigator.update(now, state)
        state = VehicleState(
            t=now, position=sp.position, velocity=sp.velocity, quaternion=np.asarray(quat_from_euler(0.0, 0.0, sp.yaw))
        )
        now += dt
    if navigator.current_seq != FIRST_BUOY_SEQ - 1 + leg:
        return math.nan
    a, b = np.asarray(waypoints_ne[leg - 1]), np.asarray(waypoints_ne[leg])
    return float((state.position[:2] - a) @ (b - a) / float((b - a) @ (b - a)))


def hover_mission(home: tuple[float, float, float]) -> list[MissionItem]:
    """Take off to ALTITUDE_M over home and loiter there (an hour: longer than any step experiment)."""
    lat, lon = round(home[0] * 1e7), round(home[1] * 1e7)
    return [
        MissionItem(
            seq=0,
            frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
            command=MavCmd.NAV_TAKEOFF,
            current=1,
            x=lat,
            y=lon,
            z=ALTITUDE_M,
        ),
        MissionItem(
            seq=1,
            frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
            command=MavCmd.NAV_LOITER_TIME,
            param1=3600.0,
            param2=0.0,
            param3=0.0,
            x=lat,
            y=lon,
            z=ALTITUDE_M,
        ),
    ]


SHORT_LEGS = 2


def short_scenario(base: Scenario) -> Scenario:
    """The longest leg and the next, translated to start at home; gust halfway along the first."""
    waypoints = np.asarray(base.waypoints_ne)
    legs = np.diff(waypoints, axis=0)[base.longest_leg - 1 : base.longest_leg - 1 + SHORT_LEGS]
    points = np.vstack([[0.0, 0.0], np.cumsum(legs, axis=0)])
    frame = LocalFrame(*base.home)
    takeoff, speed = base.items[0], base.items[1]
    items = [takeoff, speed]
    for north, east in points[1:]:
        lat, lon, _ = frame.from_ned(float(north), float(east), 0.0)
        items.append(
            MissionItem(
                seq=len(items),
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                command=MavCmd.NAV_WAYPOINT,
                param1=base.items[FIRST_BUOY_SEQ].param1,
                param2=base.items[FIRST_BUOY_SEQ].param2,
                param3=0.0,
                x=round(float(lat) * 1e7),
                y=round(float(lon) * 1e7),
                z=takeoff.z,
            )
        )
    last = items[-1]
    items.append(
        MissionItem(
            seq=len(items), frame=MavFrame.GLOBAL_RELATIVE_ALT_INT, command=MavCmd.NAV_LAND, x=last.x, y=last.y, z=0.0
        )
    )
    start, duration = MissionTimeline().legs(points[:, ::-1])[0]  # points are [north, east]
    gust = round(start + 0.5 * duration, 1)
    return replace(
        base,
        items=items,
        waypoints_ne=points.tolist(),
        longest_leg=1,
        gust_start_s=gust,
        wind=replace(base.wind, gust_start_s=gust),
    )


@cache
def short_reference_scenario() -> Scenario:
    """short_scenario of the reference scenario: the tuning's, the robustness sweeps' and the campaign benchmark's
    flight, built once per process (a Scenario is not changed after it is built: variants are `replace`d copies)."""
    return short_scenario(build_scenario())
