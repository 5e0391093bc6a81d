"""What the vehicle answers and reports: command results, events for the outside world, one tick's record.

Plain data shared by the vehicle's parts and its users (the MAVLink handlers, the server's flight log, the
lockstep harness, benchmarks); the numbers of `CommandResult` equal MAV_RESULT's so a handler can send them
as they are.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState


class CommandResult(IntEnum):
    """Same numbers as MAV_RESULT."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4


@dataclass
class VehicleEvent:
    # "text" | "mission_current" | "item_reached" | "mission_complete" | "mode" | "armed" | "offboard_lost"
    # | "payload_item" (a camera or gimbal mission item reached: seq)
    kind: str
    text: str = ""
    severity: int = 6  # MAV_SEVERITY for "text": 6 info, 4 warning, 3 error
    seq: int = -1


@dataclass
class TickRecord:
    """What one outer tick did, for logs and benchmarks."""

    t: float
    truth: VehicleState
    estimate: VehicleState
    setpoint: TrajectorySetpoint
    target: AttitudeTarget
    source: str  # "offboard" | "builtin" | "idle" | "off"
    disturbance: dict = field(default_factory=dict)
