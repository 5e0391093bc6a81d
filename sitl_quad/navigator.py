"""The vehicle's navigator: sequences the stored mission and produces the reference the position loop follows.

Called by the vehicle at the outer-loop rate (50 Hz) with its state estimate; answers a TrajectorySetpoint
(POSITION_TARGET_LOCAL_NED) that is smooth and flyable: every motion is a straight leg that starts and ends at
rest, speed-, acceleration- and jerk-limited (sitl_quad.trajectory), and every change of heading is a
rate-limited turn on the spot before the leg, so the drone turns toward the next buoy while still holding over
the last one (the paper's Figure 11 shows such 2-3 s yaw turns at the 7th, 9th and 12th buoys).

Sequencing follows PX4's navigator: an item is reached when the reference has arrived AND the vehicle is
within the acceptance radius horizontally and within the altitude tolerance vertically; the navigator then
dwells for the item's hold time and makes the next item current. DO_ items run at once (a camera or gimbal
item is reported for the vehicle's payload to execute, as PX4 re-issues it as a command). A LAND or RTL item
ends the mission with a landing; a mission that ends otherwise holds over its last waypoint. Outside a
mission it flies hold, takeoff, return-to-launch and land. A return goes to the closest of home and the rally
points, as PX4's RTL with RTL_TYPE 0 picks its destination among home and the safe points, and lands there.

Pure computation: no I/O, no clocks. Times are the vehicle's simulated seconds; positions are NED metres in
the local frame whose origin is home (altitude above home h is z = -h); the ground is taken as flat at home's
altitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Literal

import numpy as np

from sitl_quad.orbit import Orbit, OrbitSegment
from sitl_quad.trajectory import (
    MotionLimits,
    NavigationError,
    ReferenceSample,
    Trajectory,
    Vector3,
    bearing,
)
from uavcore.geodesy import LocalFrame
from uavcore.mission import ITEM_FRAMES, PAYLOAD_COMMANDS, MavCmd, MavFrame, MissionItem
from uavcore.rotation import euler_from_quat
from uavcore.state import TrajectorySetpoint, VehicleState

__all__ = ["NavEvent", "NavigationError", "Navigator", "NavigatorConfig"]

GROUND_DOWN_M = 0.0  # the ground (and the sea) is flat at home's altitude
# A reference not sampled for this long is stale: a new activity then starts from the vehicle's own state
# (the vehicle flew something else meanwhile, e.g. OFFBOARD or position control).
STALE_REFERENCE_S = 0.5
# A reference (or vehicle) slower than this is at rest; faster, a new activity first brakes it to rest.
AT_REST_M_S = 0.05

NAV_COMMANDS = frozenset(
    {MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_TIME, MavCmd.NAV_TAKEOFF, MavCmd.NAV_LAND, MavCmd.NAV_RETURN_TO_LAUNCH}
)
AMSL_FRAMES = frozenset({MavFrame.GLOBAL, MavFrame.GLOBAL_INT})

# DO_CHANGE_SPEED param1 (speed type) and param2 special values, as in MAVLink/PX4
SPEED_TYPE_CLIMB = 2
SPEED_TYPE_DESCENT = 3
SPEED_RESET_TO_DEFAULT = -2

Activity = Literal["idle", "takeoff", "mission", "hold", "rtl", "land", "orbit"]
MissionState = Literal["no_mission", "not_started", "active", "paused", "complete"]


@dataclass
class NavigatorConfig:
    """The navigator's limits as plain floats (SI units, radians), each with the PX4 parameter it mirrors."""

    cruise_speed: float = 10.0  # MPC_XY_CRUISE, horizontal m/s
    max_acceleration: float = 3.0  # MPC_ACC_HOR, m/s^2 along any leg
    max_jerk: float = 4.0  # MPC_JERK_AUTO, m/s^3; math.inf gives a trapezoidal velocity profile
    climb_speed: float = 2.5  # MPC_Z_VEL_MAX_UP
    descent_speed: float = 1.5  # MPC_Z_VEL_MAX_DN
    land_speed: float = 0.7  # MPC_LAND_SPEED, the final part of every landing
    land_slowdown_altitude: float = 5.0  # MPC_LAND_ALT2: below this height a landing descends at land_speed
    land_target_depth: float = 0.5  # the landing reference ends this far under the ground, so the position
    # loop keeps pressing the vehicle down until the vehicle detects touchdown and disarms
    yaw_rate: float = math.radians(60.0)  # MPC_YAWRAUTO_MAX, rad/s
    # rad/s^2, smooths the start and end of each turn; within the airframe's yaw authority (Table 2's kf and
    # 500 rad/s rotors give about 63 deg/s^2), so a turn asks for no more than the rotors can do
    yaw_acceleration: float = math.radians(45.0)
    acceptance_radius: float = 2.0  # NAV_ACC_RAD, horizontal m
    altitude_acceptance: float = 1.0  # NAV_MC_ALT_RAD, vertical m
    rtl_altitude: float = 10.0  # RTL_RETURN_ALT, m above home
    takeoff_altitude: float = 5.0  # MIS_TAKEOFF_ALT, m above home

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise NavigationError unless every limit is a positive number (max_jerk may be infinite)."""
        for item in fields(self):
            value = getattr(self, item.name)
            lowest_ok = 0.0 if item.name == "land_target_depth" else math.nextafter(0.0, 1.0)
            if not isinstance(value, int | float) or math.isnan(value) or value < lowest_ok:
                raise NavigationError(f"navigator {item.name} must be a positive number, got {value!r}")
            if math.isinf(value) and item.name != "max_jerk":
                raise NavigationError(f"navigator {item.name} must be finite, got {value!r}")


@dataclass(frozen=True)
class NavEvent:
    """Something the vehicle reports: MISSION_CURRENT ("current"), MISSION_ITEM_REACHED ("reached"), the
    mission's end ("complete"), the start of a landing descent ("landing"; seq -1 outside a mission), or a
    camera or gimbal item reached ("payload": the vehicle's payload executes it)."""

    kind: Literal["current", "reached", "complete", "landing", "payload"]
    seq: int


@dataclass(frozen=True)
class _Goal:
    """What the current trajectory must achieve before its item counts as reached."""

    position: Vector3
    radius: float
    landing: bool = False  # arrival = the reference has reached the ground and the vehicle is down there
    dwell: float = 0.0  # seconds to hold after arrival


class Navigator:
    """Mission sequencing and reference generation; see the module docstring."""

    def __init__(self, frame: LocalFrame, config: NavigatorConfig) -> None:
        self.frame = frame
        self.config = config
        self.current_seq = 0
        self.mission_state: MissionState = "no_mission"
        self.activity: Activity = "idle"
        self.is_landing = False
        self.orbit: Orbit | None = None  # the circle flown while the activity is "orbit"
        self._items: list[MissionItem] = []
        self._targets: list[tuple[tuple[float, float] | None, float | None]] = []
        self._events: list[NavEvent] = []
        self._trajectory: Trajectory | None = None
        self._last_update: float | None = None
        self._goal: _Goal | None = None
        self._phase: Literal["enroute", "dwell", "done"] = "done"
        self._dwell_until = 0.0
        self._descent_start: float | None = None
        self._ground_time: float | None = None
        self._mission_speed: float | None = None  # DO_CHANGE_SPEED overrides; None = the configured limit
        self._mission_climb: float | None = None
        self._mission_descent: float | None = None
        self._rally_points: list[tuple[float, float]] = []  # north, east m: where a return may go besides home

    # ---- mission storage -------------------------------------------------------------------------------

    def set_rally_points(self, items: list[MissionItem]) -> None:
        """The rally points (MAV_CMD_NAV_RALLY_POINT items) a return may go to instead of home."""
        points = []
        for item in items:
            north, east, _ = self.frame.to_ned(item.lat, item.lon, self.frame.alt0)
            points.append((float(north), float(east)))
        self._rally_points = points

    def return_destination(self, north: float, east: float) -> tuple[float, float]:
        """Where a return from (north, east) goes: the closest of home and the rally points (PX4's RTL,
        RTL_TYPE 0: RtlDirect's destination is the closest safe point or home; home wins a tie)."""
        return min([(0.0, 0.0), *self._rally_points], key=lambda p: math.hypot(p[0] - north, p[1] - east))

    def set_mission(self, items: list[MissionItem]) -> None:
        """Replace the stored mission (already validated by the mission protocol).

        An active mission stops sequencing: the vehicle finishes the current leg and holds at its end.
        """
        targets = [self._item_target(item) for item in items]
        self._items = list(items)
        self._targets = targets
        self.current_seq = next((i for i, item in enumerate(items) if item.current), 0)
        self.mission_state = "not_started" if items else "no_mission"
        if self.activity == "mission":
            self.activity = "hold"
            self._goal = None
            self._phase = "done"

    def _item_target(self, item: MissionItem) -> tuple[tuple[float, float] | None, float | None]:
        """(north, east) of the item or None for "here"; its down coordinate or None for "keep altitude"."""
        if item.command not in NAV_COMMANDS or item.command == MavCmd.NAV_RETURN_TO_LAUNCH:
            return None, None
        if item.frame not in ITEM_FRAMES:
            raise NavigationError(f"mission item {item.seq}: frame {item.frame} is not supported")
        horizontal = None
        if item.has_position:
            # horizontal from the tangent plane; altitude handled apart so a 5 m waypoint 1 km away stays at
            # z = -5 (the ellipsoid's curvature would otherwise put it 8 cm lower)
            north, east, _ = self.frame.to_ned(item.lat, item.lon, self.frame.alt0)
            horizontal = (float(north), float(east))
        if item.command == MavCmd.NAV_LAND:
            return horizontal, GROUND_DOWN_M
        if not math.isfinite(item.z):
            return horizontal, None
        altitude = item.z - self.frame.alt0 if item.frame in AMSL_FRAMES else item.z
        return horizontal, -altitude

    # ---- commands from the vehicle -----------------------------------------------------------------------

    def start_mission(self, t: float, state: VehicleState, from_seq: int | None = None) -> None:
        """Fly the mission from `from_seq`, or resume at the current item (from the start once complete)."""
        if not self._items:
            raise NavigationError("no mission stored")
        if from_seq is None:
            from_seq = 0 if self.mission_state == "complete" else self.current_seq
        if not 0 <= from_seq < len(self._items):
            raise NavigationError(f"mission has items 0..{len(self._items) - 1}, cannot start at {from_seq}")
        self._replay_speed_changes(from_seq)
        trajectory = self._fresh_trajectory(t, state)
        self.current_seq = from_seq
        self.activity = "mission"
        self.mission_state = "active"
        self._begin_item(t, trajectory)

    def set_current(self, t: float, state: VehicleState, seq: int) -> None:
        """MISSION_SET_CURRENT: jump to `seq` (flying there now if the mission is active)."""
        if not 0 <= seq < len(self._items):
            raise NavigationError(f"mission has {len(self._items)} items, no item {seq}")
        if self.activity == "mission":
            self.start_mission(t, state, seq)
            return
        self.current_seq = seq
        if self.mission_state == "complete":
            self.mission_state = "not_started"
        self._emit("current", seq)

    def start_takeoff(self, t: float, state: VehicleState, altitude: float) -> None:
        """Climb vertically here to `altitude` metres above home, then hold."""
        if not (math.isfinite(altitude) and altitude > 0):
            raise NavigationError(f"takeoff altitude must be a positive number of metres, got {altitude!r}")
        trajectory = self._fresh_trajectory(t, state)
        here = trajectory.end_position
        target = (here[0], here[1], -altitude)
        trajectory.line_to(target, self._limits(mission=False))
        self._switch_activity("takeoff", trajectory, _Goal(target, self.config.acceptance_radius))

    def start_rtl(self, t: float, state: VehicleState) -> None:
        """Return to launch: climb to the return altitude if lower, fly home (or to a closer rally point), land."""
        trajectory = self._fresh_trajectory(t, state)
        self._switch_activity("rtl", trajectory, self._plan_return(trajectory, mission=False))

    def start_land(self, t: float, state: VehicleState) -> None:
        """Land here."""
        trajectory = self._fresh_trajectory(t, state)
        self._switch_activity("land", trajectory, self._plan_landing(trajectory, mission=False))

    def hold(self, t: float, state: VehicleState, position: Vector3 | None = None, yaw: float | None = None) -> None:
        """Loiter: stop smoothly where the reference is, or fly to `position` (NED m); then face `yaw`."""
        trajectory = self._fresh_trajectory(t, state)
        if position is not None:
            self._fly_to(trajectory, (float(position[0]), float(position[1]), float(position[2])), None, mission=False)
        if yaw is not None:
            trajectory.turn_to(yaw, self.config.yaw_rate, self.config.yaw_acceleration)
        self._switch_activity("hold", trajectory, None)

    def start_orbit(self, t: float, state: VehicleState, orbit: Orbit) -> None:
        """Fly straight to the nearest point of the circle, face as the orbit's yaw behaviour asks, then circle
        until something else is asked (sitl_quad.orbit)."""
        initial_heading = _yaw_of(state)
        trajectory = self._fresh_trajectory(t, state)
        here = trajectory.end_position
        angle = orbit.angle_of(here[0], here[1])
        self._fly_to(trajectory, orbit.point_at(angle), None, mission=False)
        segment = OrbitSegment(orbit, angle, initial_heading, self.config.max_acceleration / 2)
        trajectory.turn_to(segment.end_yaw, self.config.yaw_rate, self.config.yaw_acceleration)
        trajectory.append(segment)
        self._switch_activity("orbit", trajectory, None)
        self.orbit = orbit

    def release(self, t: float) -> None:
        """Fly nothing: something else (an offboard stream) sets the reference. A mission under way pauses; the
        next activity starts from the vehicle's own state."""
        self._descent_start = self._ground_time = None
        self.is_landing = False
        if self.mission_state == "active":
            self.mission_state = "paused"
        self.activity = "idle"
        self.orbit = None
        self._trajectory = self._goal = None
        self._phase = "done"
        self._last_update = t

    def update(self, t: float, state: VehicleState) -> TrajectorySetpoint:
        """The reference at time t; also detects arrival, dwells and advances the mission."""
        if self._trajectory is None or self.activity == "idle":
            self._last_update = t
            return TrajectorySetpoint(position=np.array(state.position, dtype=float), yaw=_yaw_of(state))
        self._sequence(t, state)
        sample = self._trajectory.sample(t)
        self._last_update = t
        return TrajectorySetpoint(
            position=np.array(sample.position),
            velocity=np.array(sample.velocity),
            acceleration=np.array(sample.acceleration),
            yaw=sample.yaw,
            yaw_rate=sample.yaw_rate,
        )

    def pop_events(self) -> list[NavEvent]:
        """Events since the last call, oldest first."""
        events, self._events = self._events, []
        return events

    # ---- sequencing ---------------------------------------------------------------------------------------

    def _sequence(self, t: float, state: VehicleState) -> None:
        if self._descent_start is not None and not self.is_landing and t >= self._descent_start:
            self.is_landing = True
            self._emit("landing", self.current_seq if self.activity == "mission" else -1)
        goal = self._goal
        if goal is None or self._phase == "done":
            return
        if self._phase == "enroute" and self._arrived(t, state, goal):
            if self.activity == "takeoff":
                self.activity = "hold"
                self._phase = "done"
                return
            if self.activity != "mission":
                self._phase = "done"
                return
            self._emit("reached", self.current_seq)
            if goal.landing:
                self._complete(landing=True)
                return
            self._phase = "dwell"
            self._dwell_until = t + goal.dwell
        if self._phase == "dwell" and t >= self._dwell_until:
            self.current_seq += 1
            # the reference is at rest at the reached item, so the next leg starts from it
            self._begin_item(t, Trajectory(t, self._trajectory.end_position, self._trajectory.end_yaw))

    def _arrived(self, t: float, state: VehicleState, goal: _Goal) -> bool:
        if goal.landing:
            if self._ground_time is None or t < self._ground_time:
                return False
        elif not self._trajectory.finished(t):
            return False
        north, east, down = (float(c) for c in state.position)
        horizontal = math.hypot(north - goal.position[0], east - goal.position[1])
        return horizontal <= goal.radius and abs(down - goal.position[2]) <= self.config.altitude_acceptance

    def _begin_item(self, t: float, trajectory: Trajectory) -> None:
        """Make current_seq current; run DO_ items at once; plan the leg of the first NAV item."""
        while self.current_seq < len(self._items):
            item = self._items[self.current_seq]
            self._emit("current", self.current_seq)
            if item.command in NAV_COMMANDS:
                self._switch_activity("mission", trajectory, self._plan_item(trajectory, item))
                return
            self._run_do_item(item)
            if item.command in PAYLOAD_COMMANDS:  # the camera's and gimbal's: the vehicle hands them on
                self._emit("payload", self.current_seq)
            self._emit("reached", self.current_seq)
            self.current_seq += 1
        self.current_seq = len(self._items) - 1
        self._switch_activity("mission", trajectory, None)
        self._complete(landing=False)

    def _complete(self, landing: bool) -> None:
        self.mission_state = "complete"
        self._emit("complete", self.current_seq)
        self._phase = "done"
        self.activity = "land" if landing else "hold"

    def _switch_activity(self, activity: Activity, trajectory: Trajectory, goal: _Goal | None) -> None:
        if self.mission_state == "active" and activity != "mission":
            self.mission_state = "paused"
        self.activity = activity
        self.orbit = None
        self._trajectory = trajectory
        self._goal = goal
        self._phase = "enroute" if goal is not None else "done"

    def _run_do_item(self, item: MissionItem) -> None:
        if item.command != MavCmd.DO_CHANGE_SPEED:
            return  # other DO_ commands have nothing to do in this vehicle
        speed = item.param2
        if speed == SPEED_RESET_TO_DEFAULT:
            speed = None
        elif not (math.isfinite(speed) and speed > 0):
            return  # -1 / NaN: no change
        if item.param1 == SPEED_TYPE_CLIMB:
            self._mission_climb = speed
        elif item.param1 == SPEED_TYPE_DESCENT:
            self._mission_descent = speed
        else:
            self._mission_speed = speed

    def _replay_speed_changes(self, seq: int) -> None:
        """A mission resumed at `seq` flies at the speeds its earlier DO_CHANGE_SPEED items set."""
        self._mission_speed = self._mission_climb = self._mission_descent = None
        for item in self._items[:seq]:
            self._run_do_item(item)

    # ---- planning -----------------------------------------------------------------------------------------

    def _fresh_trajectory(self, t: float, state: VehicleState) -> Trajectory:
        """An empty trajectory starting where the reference is now, at rest (braking first if it moves).

        Starts from the vehicle itself when there is no live reference, so the hand-over is smooth.
        """
        self._descent_start = None
        self._ground_time = None
        self.is_landing = False
        live = (
            self._trajectory is not None
            and self.activity != "idle"
            and self._last_update is not None
            and t - self._last_update <= STALE_REFERENCE_S
        )
        if live:
            now: ReferenceSample = self._trajectory.sample(t)
            position, velocity, yaw = now.position, now.velocity, now.yaw
        else:
            position = tuple(float(c) for c in state.position)
            velocity = tuple(float(c) for c in state.velocity)
            yaw = _yaw_of(state)
        trajectory = Trajectory(t, position, yaw)
        if math.sqrt(sum(v * v for v in velocity)) > AT_REST_M_S:
            trajectory.brake(velocity, self.config.max_acceleration)
        return trajectory

    def _limits(self, mission: bool) -> MotionLimits:
        config = self.config
        return MotionLimits(
            horizontal_speed=(self._mission_speed if mission and self._mission_speed else config.cruise_speed),
            climb_speed=(self._mission_climb if mission and self._mission_climb else config.climb_speed),
            descent_speed=(self._mission_descent if mission and self._mission_descent else config.descent_speed),
            acceleration=config.max_acceleration,
            jerk=config.max_jerk,
        )

    def _takeoff_down(self, down: float | None) -> float:
        """The item's altitude when it gives one above home, else the configured takeoff altitude."""
        return down if down is not None and down < GROUND_DOWN_M else -self.config.takeoff_altitude

    def _plan_item(self, trajectory: Trajectory, item: MissionItem) -> _Goal:
        horizontal, down = self._targets[self.current_seq]
        here = trajectory.end_position
        north, east = horizontal if horizontal is not None else (here[0], here[1])
        if item.command == MavCmd.NAV_TAKEOFF:
            altitude = self._takeoff_down(down)
            trajectory.line_to((here[0], here[1], altitude), self._limits(mission=True))
            target = (north, east, altitude)
            self._fly_to(trajectory, target, None, mission=True)
            return _Goal(target, self.config.acceptance_radius)
        if item.command == MavCmd.NAV_RETURN_TO_LAUNCH:
            return self._plan_return(trajectory, mission=True)
        if item.command == MavCmd.NAV_LAND:
            trajectory_yaw = _yaw_param(item.param4)
            self._fly_to(trajectory, (north, east, here[2]), trajectory_yaw, mission=True)
            return self._plan_landing(trajectory, mission=True)
        # NAV_WAYPOINT and NAV_LOITER_TIME
        target = (north, east, here[2] if down is None else down)
        yaw = _yaw_param(item.param4) if item.command == MavCmd.NAV_WAYPOINT else None
        self._fly_to(trajectory, target, yaw, mission=True)
        radius = self.config.acceptance_radius
        if item.command == MavCmd.NAV_WAYPOINT and math.isfinite(item.param2) and item.param2 > 0:
            radius = item.param2
        dwell = item.param1 if math.isfinite(item.param1) and item.param1 > 0 else 0.0
        return _Goal(target, radius, dwell=dwell)

    def _fly_to(self, trajectory: Trajectory, target: Vector3, yaw: float | None, mission: bool) -> None:
        """Turn toward the target (or to `yaw`) on the spot, then fly a straight leg to it.

        Near the ground the vehicle first climbs vertically to the target's altitude, so no leg scrapes along
        the ground (or the sea) from a standing start.
        """
        limits = self._limits(mission)
        start = trajectory.end_position
        if start[2] > GROUND_DOWN_M - self.config.altitude_acceptance and target[2] < start[2]:
            trajectory.line_to((start[0], start[1], target[2]), limits)
        heading = yaw if yaw is not None else bearing(trajectory.end_position, target)
        if heading is not None:
            trajectory.turn_to(heading, self.config.yaw_rate, self.config.yaw_acceleration)
        trajectory.line_to(target, limits)

    def _plan_return(self, trajectory: Trajectory, mission: bool) -> _Goal:
        """Climb to the return altitude if lower, fly to the return destination (home or the closest rally
        point) at it, land. Close to it, just land there."""
        here = trajectory.end_position
        home = self.return_destination(here[0], here[1])
        if math.hypot(here[0] - home[0], here[1] - home[1]) > self.config.acceptance_radius:
            cruise_down = min(here[2], -self.config.rtl_altitude)
            trajectory.line_to((here[0], here[1], cruise_down), self._limits(mission))
            self._fly_to(trajectory, (home[0], home[1], cruise_down), None, mission)
        else:
            trajectory.line_to((home[0], home[1], here[2]), self._limits(mission))
        return self._plan_landing(trajectory, mission)

    def _plan_landing(self, trajectory: Trajectory, mission: bool) -> _Goal:
        """Descend where the trajectory ends: fast down to the slow-down height, then at land speed."""
        config = self.config
        limits = self._limits(mission)
        self._descent_start, self._ground_time = trajectory.descend(
            GROUND_DOWN_M,
            config.land_target_depth,
            limits.descent_speed,
            min(config.land_speed, limits.descent_speed),
            config.land_slowdown_altitude,
            config.max_acceleration,
            config.max_jerk,
        )
        here = trajectory.end_position
        return _Goal((here[0], here[1], GROUND_DOWN_M), config.acceptance_radius, landing=True)

    def _emit(self, kind: str, seq: int) -> None:
        self._events.append(NavEvent(kind, seq))


def _yaw_of(state: VehicleState) -> float:
    return euler_from_quat(state.quaternion)[2]


def _yaw_param(degrees: float) -> float | None:
    """MAVLink's yaw parameter (degrees, NaN = the navigator chooses) in radians."""
    return math.radians(degrees) if math.isfinite(degrees) else None
