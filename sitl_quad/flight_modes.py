"""What each flight mode asks of the navigator, as PX4's navigator modes do.

The vehicle switches modes (commands, failsafes, arming in a mode); these functions say what a mode then
flies: a mission from an item, a vertical takeoff, a return to launch, a landing or a hold. A mode that
starts with a climb from the ground (`CLIMB_MODES`) first waits for the motors to spool up with a fresh
navigator (`flight_navigator`), see sitl_quad.arming.
"""

from __future__ import annotations

import math

from sitl_quad.navigator import Navigator, NavigatorConfig
from uavcore.geodesy import LocalFrame
from uavcore.mission import MissionItem
from uavcore.modes import FlightMode
from uavcore.state import VehicleState

CLIMB_MODES = (FlightMode.AUTO_MISSION, FlightMode.AUTO_TAKEOFF)  # on the ground these start a flight
# ORBIT holds until the vehicle's orbit command gives the navigator its circle (Vehicle.orbit)
HOLD_MODES = (FlightMode.AUTO_LOITER, FlightMode.POSCTL, FlightMode.AUTO_READY, FlightMode.ORBIT)
# PX4 refuses to arm in these (mode_req_prevent_arming), and a disarm returns to the last mode the user chose that
# neither prevents arming nor means a takeoff (UserModeIntention::onDisarm): home from a Return, the vehicle is
# back in, say, Mission, not left in a Return that arming would fly again
ARMING_PREVENTED_MODES = (FlightMode.AUTO_RTL, FlightMode.AUTO_LAND, FlightMode.ORBIT)


def kept_after_disarm(mode: FlightMode) -> bool:
    """Whether a mode the user chooses is the one a later disarm returns to (PX4's user mode intention)."""
    return mode not in ARMING_PREVENTED_MODES and mode != FlightMode.AUTO_TAKEOFF


def start_activity(
    navigator: Navigator,
    mode: FlightMode,
    t: float,
    est: VehicleState,
    first_seq: int | None,
    altitude: float | None,
    config: NavigatorConfig,
) -> None:
    """Tell the navigator what `mode` flies from now (time t, estimate est); OFFBOARD flies nothing new.

    first_seq: the mission item to start at (None: resume); altitude: the takeoff's (None: the configured one).
    """
    if mode == FlightMode.AUTO_MISSION:
        if navigator.mission_state == "complete" and first_seq is None:
            first_seq = 0  # re-arming after a finished mission flies it again, from the start
        navigator.start_mission(t, est, first_seq)
    elif mode == FlightMode.AUTO_TAKEOFF:
        navigator.start_takeoff(t, est, altitude or config.takeoff_altitude)
    elif mode == FlightMode.AUTO_RTL:
        navigator.start_rtl(t, est)
    elif mode == FlightMode.AUTO_LAND:
        navigator.start_land(t, est)
    elif mode in HOLD_MODES:
        navigator.hold(t, est)


def resume_seq(navigator: Navigator, first_seq: int | None) -> int | None:
    """The item a new flight starts at: the one asked for, else the current one of an unfinished mission."""
    if first_seq is None and navigator.mission_state != "complete":
        return navigator.current_seq
    return first_seq


def flight_navigator(
    frame: LocalFrame,
    config: NavigatorConfig,
    mission: list[MissionItem],
    rally_points: list[MissionItem],
    t: float,
    est: VehicleState,
) -> Navigator:
    """A fresh navigator for a new flight: the mission and rally points stored, holding where the vehicle
    stands."""
    navigator = Navigator(frame, config)
    navigator.set_mission(mission)
    navigator.set_rally_points(rally_points)
    navigator.hold(t, est)
    return navigator


def reposition_target(
    frame: LocalFrame, home_altitude: float, here: VehicleState, lat: float, lon: float, alt_amsl: float
) -> tuple[float, float, float] | None:
    """DO_REPOSITION's place in NED metres, or None if it is no place to go (not a latitude/longitude,
    below home). NaN keeps the coordinate of `here`."""
    north, east, down = (float(c) for c in here.position)
    if math.isfinite(lat) and math.isfinite(lon):
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            return None
        north, east, _ = (float(c) for c in frame.to_ned(lat, lon, 0.0))
    if math.isfinite(alt_amsl):
        down = -(alt_amsl - home_altitude)
        if down > 0:
            return None  # below home: into the water
    return north, east, down
