"""The benchmark's air and mission (the paper's Section VI, made concrete; every number is in control.json's
"scenario").

- Mission: `planner.scenario.reference_scenario()` (13 buoys, depot at home), optimal order
  (`plan_tour(method="exact")` through gcs.planning.make_plan), flown as the GCS would upload it
  (gcs.planning.mission_items: takeoff, DO_CHANGE_SPEED 10 m/s, one NAV_WAYPOINT per buoy at 5 m with a
  1 s inspection dwell and a 2 m acceptance radius, RTL), in-process lockstep (sitl_quad.lockstep_harness).
- Wind: 5 m/s mean crosswind perpendicular to the route's longest leg (blowing from its right-hand side).
- Gust: 1-cosine, 4 m/s along the crosswind, rise 1 s, starting when the navigator's reference is halfway
  along the longest leg (computed from the reference's own timeline, see `gust_start_time`). Like every
  wind time it counts on the flight's disturbance clock, which starts at the mission start command (the
  climb follows the vehicle's 1 s motor spool-up, so the gust meets the reference about 1 s before its
  midpoint: still mid-cruise on a 41 s leg; each flight's item at the onset is in per_seed). It holds
  10 s and falls back (gust_hold_s = 10): the onset is the step-like "sudden wind change" of the paper's
  Figure 6, and falling back keeps the rest of the mission at the 5 m/s mean.
- Turbulence: Dryden, MIL-F-8785C low-altitude form, W20 chosen so that sigma_u = sigma_v = 1.0 m/s at the
  5 m flight altitude (`dryden_w20_for_sigma`: W20 = 5.15 m/s, sigma_w = 0.52 m/s). W20 ~ 5 m/s is also
  consistent with the 5 m/s mean wind.
- Disturbance terms D (eq. 1-2): sitl_quad.disturbances' realistic default (variance 0.05 on every channel,
  held 0.5 s). The paper's variance 15 is a 0.4 g random push held half a second; `--paper-seeds N` flies
  N extra seeds with it and reports them apart.
- Sensor noise: sitl_quad.sensors defaults (2 cm, 5 cm/s, 0.3 deg, 0.01 rad/s).
- Seeds 0..N-1; a seed fixes wind, turbulence, D terms and sensor noise, so every controller meets the same
  air (paired design).

The step experiment flies `hover_mission` instead: a 5 m hover in still air (sensor noise and D terms on),
then a STEP_M lateral (east) position step (see flight.step_response).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gcs.planning import FIRST_BUOY_SEQ, FlightParams, make_plan, mission_items
from planner.scenario import ALTITUDE_M, CRUISE_SPEED_M_S, reference_scenario
from sitl_quad.config import AttitudeControllerKind, ControlConfig, VehicleConfig
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.navigator import Navigator, NavigatorConfig
from sitl_quad.wind import FEET, WindConfig
from uavcore.geodesy import LocalFrame
from uavcore.mission import MavCmd, MavFrame, MissionItem
from uavcore.rotation import quat_from_euler
from uavcore.state import VehicleState

OUTER_RATE_HZ = 50.0
DWELL_S = 1.0
ACCEPTANCE_RADIUS_M = 2.0
CROSSWIND_M_S = 5.0
GUST_M_S = 4.0
GUST_RISE_S = 1.0
GUST_HOLD_S = 10.0
TURBULENCE_SIGMA_M_S = 1.0
STEP_M = 5.0
STEP_HOVER_S = 12.0
STEP_WINDOW_S = 10.0


def dryden_w20_for_sigma(sigma_m_s: float, altitude_m: float) -> float:
    """W20 whose MIL-F-8785C low-altitude horizontal intensity at altitude_m is sigma_m_s:
    sigma_u = sigma_v = 0.1 W20 / (0.177 + 0.000823 h)^0.4, h in feet (clamped to 10..1000 ft as in sitl_quad.wind)."""
    h_ft = min(max(altitude_m / FEET, 10.0), 1000.0)
    return sigma_m_s * (0.177 + 0.000823 * h_ft) ** 0.4 / 0.1


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

    def config(self, kind: str, paper_disturbance: bool = False) -> VehicleConfig:
        """The vehicle for controller `kind`: ADRC inner loop for "adrc", the PID attitude loop otherwise."""
        inner = AttitudeControllerKind.ADRC if kind == "adrc" else AttitudeControllerKind.PID
        disturbance = DisturbanceConfig.paper() if paper_disturbance else self.disturbance
        return VehicleConfig(wind=self.wind, disturbance=disturbance, control=ControlConfig(attitude_controller=inner))


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
    legs = np.diff(np.asarray(waypoints), axis=0)
    longest = int(np.argmax(np.hypot(legs[:, 0], legs[:, 1]))) + 1
    bearing = math.degrees(math.atan2(legs[longest - 1, 1], legs[longest - 1, 0]))
    crosswind_from = (bearing + 90.0) % 360.0  # from the leg's right-hand side
    gust_start = gust_start_time(items, reference.home, longest)
    wind = WindConfig(
        speed_m_s=CROSSWIND_M_S,
        direction_from_deg=crosswind_from,
        gust_amplitude_m_s=GUST_M_S,
        gust_rise_time_s=GUST_RISE_S,
        gust_start_s=gust_start,
        gust_hold_s=GUST_HOLD_S,
        gust_direction_from_deg=crosswind_from,
        turbulence_w20_m_s=round(dryden_w20_for_sigma(TURBULENCE_SIGMA_M_S, ALTITUDE_M), 3),
    )
    return Scenario(reference.home, items, waypoints, float(plan.length_m), longest, crosswind_from, gust_start, wind)


def gust_start_time(items: list[MissionItem], home: tuple[float, float, float], leg: int) -> float:
    """Seconds from takeoff at which the navigator's reference is halfway along leg `leg` (its own timeline,
    flown by a vehicle that tracks it perfectly), rounded to 0.1 s."""
    navigator = Navigator(LocalFrame(*home), NavigatorConfig())
    navigator.set_mission(items)
    state = VehicleState()
    navigator.start_mission(0.0, state)
    dt, t = 1.0 / OUTER_RATE_HZ, 0.0
    seq, start, end = FIRST_BUOY_SEQ - 1 + leg, None, None
    while t < 3600.0:
        sp = navigator.update(t, state)
        moving = float(np.hypot(*sp.velocity[:2])) > 0.5
        if navigator.current_seq == seq and moving:
            start = t if start is None else start
            end = t
        elif start is not None and navigator.current_seq != seq:
            break
        state = VehicleState(
            t=t, position=sp.position, velocity=sp.velocity, quaternion=np.asarray(quat_from_euler(0.0, 0.0, sp.yaw))
        )
        t += dt
    if start is None or end is None:
        raise RuntimeError(f"the reference never flew leg {leg}")
    return round(0.5 * (start + end), 1)


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
