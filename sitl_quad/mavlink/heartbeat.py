"""HEARTBEAT at 1 Hz of wall-clock time, so tools stay connected at any simulation speed."""

from __future__ import annotations

from sitl_quad.vehicle import Vehicle
from uavcore.mavlink import mavlink

HEARTBEAT_PERIOD_S = 1.0


def heartbeat_message(vehicle: Vehicle):
    base_mode = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED  # MAVSDK decodes the mode only with this bit
    if vehicle.armed:
        base_mode |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    base_mode |= mavlink.MAV_MODE_FLAG_AUTO_ENABLED | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
    base_mode |= mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
    status = mavlink.MAV_STATE_ACTIVE if vehicle.armed else mavlink.MAV_STATE_STANDBY
    return mavlink.MAVLink_heartbeat_message(
        mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, base_mode, vehicle.mode.custom_mode, status, 3
    )


class Heartbeat:
    def __init__(self, vehicle: Vehicle, send) -> None:
        self.vehicle = vehicle
        self.send = send
        self.next_due = 0.0

    def poll(self, now: float) -> None:
        """Called with the wall clock (time.monotonic()) on every loop pass."""
        if now >= self.next_due:
            self.next_due = max(self.next_due + HEARTBEAT_PERIOD_S, now)
            self.send(heartbeat_message(self.vehicle))
