"""Arming, the motors' spool-up before a takeoff, and the land detector with its automatic disarms.

`ArmingState` holds whether the vehicle is armed, its MAV_LANDED_STATE and the timers around them, as
PX4's commander and land detector do:
- a takeoff or mission command on the ground waits SPOOLUP_S (COM_SPOOLUP_TIME) with the rotors at idle
  before the climb starts (`schedule_climb` / `due_climb`);
- armed on the ground without taking off for PREFLIGHT_DISARM_S (COM_DISARM_PRFLT) -> disarm;
- down on the ground for TOUCHDOWN_CONFIRM_S after a flight or during a landing -> landed, disarm.
`update` runs once per tick after the physics and tells the vehicle which of those disarms is due; the
vehicle does the disarming (rotors, events), this class only keeps the books.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum, IntEnum

from sitl_quad.navigator import Navigator
from uavcore.modes import FlightMode
from uavcore.state import VehicleState

TOUCHDOWN_CONFIRM_S = 1.0  # on the ground this long while landing -> landed, disarm
SPOOLUP_S = 1.0  # from a takeoff or mission command on the ground to the climb (PX4's COM_SPOOLUP_TIME)
PREFLIGHT_DISARM_S = 10.0  # armed on the ground without taking off this long -> disarm (COM_DISARM_PRFLT)
FORCE_DISARM_MAGIC = 21196  # COMPONENT_ARM_DISARM param2 that disarms even in the air
AIRBORNE_ALTITUDE_M = 0.5  # above this height the vehicle has flown (a later touchdown is a landing)
CLIMBING_ACTIVITIES = ("takeoff", "mission", "rtl")  # navigator activities that leave the ground


class LandedState(IntEnum):
    """Same numbers as MAV_LANDED_STATE."""

    UNDEFINED = 0
    ON_GROUND = 1
    IN_AIR = 2
    TAKEOFF = 3
    LANDING = 4


class AutoDisarm(Enum):
    """A disarm the land detector asks for."""

    LANDED = "landed"  # touchdown confirmed
    NO_TAKEOFF = "no takeoff"  # armed on the ground too long


@dataclass(frozen=True)
class PendingClimb:
    """A takeoff or mission start waiting for the motors to spool up."""

    climb_at: float  # the flight clock's time at which the climb starts
    mode: FlightMode
    first_seq: int | None
    altitude: float | None


def touching_ground(on_ground: bool, truth: VehicleState) -> bool:
    """Land detector: in contact, or hovering within a few cm of the ground without vertical motion.

    Contact alone flickers when a controller presses with about the vehicle's weight (as an ESO that
    learned the ground reaction does), so a near-ground, near-still state also counts.
    """
    return on_ground or (-truth.position[2] < 0.05 and abs(truth.velocity[2]) < 0.3)


class ArmingState:
    """Armed or not, the landed state, and the spool-up, pre-flight and touchdown timers."""

    def __init__(self) -> None:
        self.armed = False
        self.landed_state = LandedState.ON_GROUND
        self.was_airborne = False  # has flown since arming (a touchdown is then a landing)
        self.pending_climb: PendingClimb | None = None
        self.spooled_up = False  # a climb's spool-up has run since arming (OFFBOARD may then leave the ground)
        # Wall clock for the pre-flight disarm timer (the server passes time.monotonic): a ground station's
        # command retries run on the wall clock, so at lockstep speeds 10 s of simulated time can pass between
        # its ARM and a MISSION_START that had to be resent. None: simulated time only (tests, benchmarks).
        self.wall_clock: Callable[[], float] | None = None
        self._armed_at = 0.0
        self._armed_at_wall = 0.0
        self._ground_since: float | None = None

    @property
    def in_air(self) -> bool:
        return self.landed_state in (LandedState.IN_AIR, LandedState.TAKEOFF, LandedState.LANDING)

    def arm(self, t: float) -> None:
        """Armed at simulated time t, on the ground."""
        self.armed = True
        self._armed_at = t
        self._armed_at_wall = self.wall_clock() if self.wall_clock is not None else 0.0
        self.was_airborne = False
        self.spooled_up = False
        self.landed_state = LandedState.ON_GROUND

    def disarm(self) -> None:
        self.armed = False
        self.landed_state = LandedState.ON_GROUND

    def schedule_climb(self, climb: PendingClimb) -> None:
        self.pending_climb = climb

    def due_climb(self, clock: float) -> PendingClimb | None:
        """The pending climb once its time has come (then no longer pending), else None."""
        pending = self.pending_climb
        if pending is None or clock + 1e-9 < pending.climb_at:
            return None
        self.pending_climb = None
        self.spooled_up = True
        return pending

    def idling(self, on_ground: bool, navigator: Navigator) -> bool:
        """Rotors at idle: on the ground since arming and no climb under way yet."""
        climbing = navigator.activity in CLIMBING_ACTIVITIES and not navigator.is_landing
        return on_ground and not self.was_airborne and not climbing

    def _preflight_timed_out(self, t: float) -> bool:
        """Armed on the ground without a takeoff for PREFLIGHT_DISARM_S, in simulated and in wall time."""
        if t - self._armed_at <= PREFLIGHT_DISARM_S:
            return False
        return self.wall_clock is None or self.wall_clock() - self._armed_at_wall > PREFLIGHT_DISARM_S

    def update(
        self, touching: bool, altitude: float, clock: float, t: float, navigator: Navigator
    ) -> AutoDisarm | None:
        """The landed state after a tick; which automatic disarm is due, if any.

        touching: `touching_ground` of the truth; altitude: the truth's height above home (m); clock: the
        flight's clock (the touchdown timer); t: simulated time (the pre-flight timer).
        """
        if not self.armed:
            self.landed_state = LandedState.ON_GROUND
            return None
        if not touching:
            self.was_airborne = self.was_airborne or altitude > AIRBORNE_ALTITUDE_M
        if navigator.is_landing or (self.was_airborne and touching):
            self.landed_state = LandedState.LANDING
            if not touching:
                self._ground_since = None
                return None
            self._ground_since = clock if self._ground_since is None else self._ground_since
            if clock - self._ground_since >= TOUCHDOWN_CONFIRM_S - 1e-9:
                self._ground_since = None
                return AutoDisarm.LANDED
            return None
        if touching and not self.was_airborne:
            climbing = navigator.activity in CLIMBING_ACTIVITIES
            # while the motors spool up the vehicle is still on the ground (an offboard controller resets then)
            self.landed_state = LandedState.TAKEOFF if climbing else LandedState.ON_GROUND
            spooling = self.pending_climb is not None
            if not climbing and not spooling and self._preflight_timed_out(t):
                return AutoDisarm.NO_TAKEOFF
            return None
        self.landed_state = LandedState.TAKEOFF if navigator.activity == "takeoff" else LandedState.IN_AIR
        return None
