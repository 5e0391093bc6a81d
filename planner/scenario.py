"""The paper's reference scenario (Section VI), generated reproducibly.

13 buoys uniform at random in a 1200 m x 700 m area whose south-west corner is the area origin, depot at
(269 m, 293 m) in that area, flight altitude 5 m, cruise 10 m/s. The depot is the vehicle's home, so local
coordinates used elsewhere are relative to the depot: ``local = area - DEPOT_IN_AREA``.

The paper's weather for a route (`paper_weather`): a crosswind across the longest leg, a 1-cosine gust halfway
along it at an instant estimated from the route (`MissionTimeline`), and Dryden turbulence; pure data that the
demo (`buoy-gcs up`) hands the vehicle as parameters and the benchmark (bench.control) as its wind configuration.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from uavcore.geodesy import DEFAULT_HOME, LocalFrame

AREA_SIZE_M = (1200.0, 700.0)  # east x north extent of the area
DEPOT_IN_AREA_M = (269.0, 293.0)
ALTITUDE_M = 5.0
CRUISE_SPEED_M_S = 10.0
N_BUOYS = 13


@dataclass(frozen=True)
class Scenario:
    """Depot and buoys in local ENU metres relative to the depot, and as WGS84 degrees."""

    buoys_local: np.ndarray  # (n, 2) [east, north] metres from the depot
    buoys_lat_lon: np.ndarray  # (n, 2) [lat, lon]
    home: tuple[float, float, float]

    @property
    def depot_lat_lon(self) -> tuple[float, float]:
        return self.home[0], self.home[1]


def random_area_points(n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniform in the area, as [east, north] metres relative to the depot."""
    area = rng.uniform((0.0, 0.0), AREA_SIZE_M, size=(n, 2))
    return area - np.asarray(DEPOT_IN_AREA_M)


def reference_scenario(seed: int = 1, n_buoys: int = N_BUOYS, home=DEFAULT_HOME) -> Scenario:
    """The reference scenario for a seed: the same seed always gives the same buoys."""
    rng = np.random.default_rng(seed)
    local = random_area_points(n_buoys, rng)
    frame = LocalFrame(*home)
    return Scenario(buoys_local=local, buoys_lat_lon=frame.unproject(local), home=tuple(home))


# ----- the paper's weather (Section VI, made concrete): one definition for the demo (buoy-gcs up) and the benchmark
CROSSWIND_M_S = 5.0  # mean wind across the route's longest leg
GUST_M_S = 4.0  # 1-cosine gust added along the crosswind: the "sudden wind change" of the paper's Figure 6
GUST_RISE_S = 1.0
GUST_HOLD_S = 10.0  # at full strength, then it falls back (mirrored), so the rest of the flight meets the mean
TURBULENCE_SIGMA_M_S = 1.0  # Dryden horizontal intensity sigma_u = sigma_v at the flight altitude
DISTURBANCE_VARIANCE = 0.05  # the Gaussian terms D of eq. 1-2 on every channel (sitl_quad.disturbances' default)
FEET_M = 0.3048


@dataclass(frozen=True)
class Weather:
    """The air a flight meets, in the vehicle's terms: a mean wind, one 1-cosine gust and Dryden turbulence.
    Directions are compass degrees the air comes FROM; times are seconds after the mission's start command
    (the vehicle's disturbance clock). The default is still air."""

    wind_m_s: float = 0.0
    wind_from_deg: float = 0.0
    gust_m_s: float = 0.0
    gust_from_deg: float = 0.0
    gust_start_s: float = 0.0
    gust_rise_s: float = GUST_RISE_S
    gust_hold_s: float = math.inf  # inf: the gust stays (MIL-F-8785C's discrete gust)
    turbulence_w20_m_s: float = 0.0
    disturbance_variance: float = DISTURBANCE_VARIANCE


@dataclass(frozen=True)
class PaperWeather:
    """The paper's weather for one route, and where on the route it was placed."""

    weather: Weather
    longest_leg: int  # the longest leg runs from route point longest_leg - 1 to route point longest_leg
    leg_bearing_deg: float  # compass bearing of the longest leg
    leg_start_s: float  # the timeline's instant the vehicle starts moving along the longest leg
    leg_duration_s: float


@dataclass(frozen=True)
class MissionTimeline:
    """A kinematic estimate of when a mission's vehicle is where, with PX4's mission defaults (the vehicle's
    navigator mirrors them): the motors spool up, the vehicle climbs vertically, then before each leg it turns on
    the spot toward the next buoy (yaw rate and yaw acceleration limited), flies the leg rest to rest (speed,
    acceleration and jerk limited) and dwells at the buoy. It ignores the few control ticks of each hand-over
    (about 0.3 s a leg) and how far the vehicle lags its reference: good to a few seconds after ten legs, enough
    to put a gust in the middle of a 30-40 s leg."""

    spool_up_s: float = 1.0
    altitude_m: float = ALTITUDE_M
    climb_m_s: float = 2.5
    yaw_rate_deg_s: float = 60.0
    yaw_acceleration_deg_s2: float = 45.0
    cruise_m_s: float = CRUISE_SPEED_M_S
    acceleration_m_s2: float = 3.0
    jerk_m_s3: float = 4.0
    dwell_s: float = 1.0
    initial_heading_deg: float = 0.0  # the vehicle stands facing north
    # An inspection mission stops `standoff_m` short of each buoy on the way in and holds there holds_s[k] (the k-th
    # buoy's camera burst), then flies on to the buoy; none: every leg is flown straight to its buoy.
    standoff_m: float = 0.0
    holds_s: tuple[float, ...] = ()

    def leg_duration_s(self, length_m: float) -> float:
        return rest_to_rest_s(length_m, self.cruise_m_s, self.acceleration_m_s2, self.jerk_m_s3)

    def turn_duration_s(self, angle_deg: float) -> float:
        return rest_to_rest_s(abs(angle_deg), self.yaw_rate_deg_s, self.yaw_acceleration_deg_s2)

    def legs(self, route_en: np.ndarray) -> list[tuple[float, float]]:
        """(start, duration) in seconds after the mission start of each leg's motion along route_en ([east, north]
        metres, the takeoff point first); an inspected leg's: its motion to the standoff."""
        route = np.asarray(route_en, dtype=float).reshape(-1, 2)
        t = self.spool_up_s + rest_to_rest_s(self.altitude_m, self.climb_m_s, self.acceleration_m_s2, self.jerk_m_s3)
        heading = self.initial_heading_deg
        out: list[tuple[float, float]] = []
        for start, end in itertools.pairwise(route):
            bearing = compass_bearing_deg(start, end)
            t += self.turn_duration_s((bearing - heading + 180.0) % 360.0 - 180.0)
            length = float(np.hypot(*(end - start)))
            if len(out) < len(self.holds_s):  # an inspection: to the standoff, its hold, then on to the buoy
                standoff = min(self.standoff_m, 0.5 * length)
                duration = self.leg_duration_s(length - standoff)
                out.append((t, duration))
                t += duration + self.holds_s[len(out) - 1] + self.leg_duration_s(standoff)
            else:
                duration = self.leg_duration_s(length)
                out.append((t, duration))
                t += duration
            t += self.dwell_s
            heading = bearing
        return out


def rest_to_rest_s(distance: float, speed: float, acceleration: float, jerk: float = math.inf) -> float:
    """Time to move `distance` from rest to rest under speed, acceleration and jerk limits (an S-curve; a
    trapezoid with jerk = inf). Each of the speed ramps takes speed/acceleration + acceleration/jerk, so a move
    long enough to cruise takes distance/speed + speed/acceleration + acceleration/jerk; a shorter one peaks at
    the speed v with v (v/acceleration + acceleration/jerk) = distance (exact while the acceleration limit is
    still reached, i.e. v >= acceleration^2/jerk: moves of a few metres or more)."""
    ramp = acceleration / jerk
    if distance >= speed * (speed / acceleration + ramp):
        return distance / speed + speed / acceleration + ramp
    peak = 0.5 * acceleration * (math.sqrt(ramp * ramp + 4.0 * distance / acceleration) - ramp)
    return distance / peak + peak / acceleration + ramp if peak > 0.0 else 0.0


def compass_bearing_deg(start_en: np.ndarray, end_en: np.ndarray) -> float:
    """Compass bearing (degrees clockwise from north, 0..360) from one [east, north] point to another."""
    east, north = np.asarray(end_en, dtype=float) - np.asarray(start_en, dtype=float)
    return math.degrees(math.atan2(east, north)) % 360.0


def dryden_w20_for_sigma(sigma_m_s: float, altitude_m: float) -> float:
    """W20 whose MIL-F-8785C low-altitude horizontal intensity at altitude_m is sigma_m_s:
    sigma_u = sigma_v = 0.1 W20 / (0.177 + 0.000823 h)^0.4, h in feet clamped to 10..1000 ft (as the vehicle's
    turbulence model does)."""
    h_ft = min(max(altitude_m / FEET_M, 10.0), 1000.0)
    return sigma_m_s * (0.177 + 0.000823 * h_ft) ** 0.4 / 0.1


def paper_weather(route_en: np.ndarray, timeline: MissionTimeline | None = None) -> PaperWeather:
    """The paper's weather placed on a route: route_en is the takeoff point (the depot) then the buoys in
    visiting order, [east, north] metres (the return home flies at the return altitude and does not count).

    - a CROSSWIND_M_S mean wind perpendicular to the longest leg, blowing from its right-hand side;
    - a GUST_M_S 1-cosine gust along the crosswind, rising in GUST_RISE_S, held GUST_HOLD_S then falling back,
      starting when the timeline has the vehicle halfway along the longest leg (a trapezoid is symmetric: half
      its time is half its length), rounded to 0.1 s;
    - Dryden turbulence with sigma_u = sigma_v = TURBULENCE_SIGMA_M_S at the flight altitude (W20 = 5.15 m/s at
      5 m, consistent with the 5 m/s mean wind);
    - the D terms at DISTURBANCE_VARIANCE."""
    timeline = timeline or MissionTimeline()
    route = np.asarray(route_en, dtype=float).reshape(-1, 2)
    if len(route) < 2:
        raise ValueError("a route needs the takeoff point and at least one buoy")
    lengths = np.hypot(*np.diff(route, axis=0).T)
    leg = int(np.argmax(lengths))
    bearing = compass_bearing_deg(route[leg], route[leg + 1])
    crosswind_from = (bearing + 90.0) % 360.0
    start, duration = timeline.legs(route)[leg]
    weather = Weather(
        wind_m_s=CROSSWIND_M_S,
        wind_from_deg=crosswind_from,
        gust_m_s=GUST_M_S,
        gust_from_deg=crosswind_from,
        gust_start_s=round(start + 0.5 * duration, 1),
        gust_rise_s=GUST_RISE_S,
        gust_hold_s=GUST_HOLD_S,
        turbulence_w20_m_s=round(dryden_w20_for_sigma(TURBULENCE_SIGMA_M_S, timeline.altitude_m), 3),
        disturbance_variance=DISTURBANCE_VARIANCE,
    )
    return PaperWeather(weather, leg + 1, bearing, start, duration)
