"""The offboard controller process: vehicle state in, SET_ATTITUDE_TARGET out, once per outer-loop tick.

The vehicle sends LOCAL_POSITION_NED, ATTITUDE_QUATERNION and POSITION_TARGET_LOCAL_NED stamped with the
same time_boot_ms every tick; as soon as all three of a tick have arrived the node runs the outer loop
and answers with a SET_ATTITUDE_TARGET carrying that time_boot_ms (which is what a lockstep vehicle waits
for): attitude, thrust and the reference's yaw rate as body-rate feed-forward (R^T e_z yaw_rate in the
target's body axes). It asks for OFFBOARD as soon as the vehicle is armed in mission (or takeoff) mode, keeps its
observers reset whenever it is not in control (disarmed, another mode) or the vehicle restarted, and
publishes the ESO's total-disturbance estimates z3 as DEBUG_VECT "ESO_Z3" (x, y, z, m/s^2) at 10 Hz.
"""

from __future__ import annotations

import logging
import math
import select
import socket
import time
from dataclasses import dataclass, field

import numpy as np

from uavcore.mavlink import (
    AUTOPILOT_COMPID,
    ONBOARD_COMPUTER_COMPID,
    VEHICLE_SYSID,
    Encoder,
    mavlink,
    new_parser,
    parse_datagram,
)
from uavcore.modes import Px4AutoSubMode, Px4MainMode, px4_main_sub
from uavcore.state import AttitudeTarget, TrajectorySetpoint, VehicleState

log = logging.getLogger(__name__)

ENGAGE_RETRY_TICKS = 25  # outer-loop ticks between DO_SET_MODE attempts (0.5 s at 50 Hz)
HEARTBEAT_S = 1.0
ESO_PUBLISH_EVERY = 5  # ticks (10 Hz at 50 Hz)


@dataclass
class VehicleView:
    """What the node knows about the vehicle, from its messages."""

    sysid: int = VEHICLE_SYSID  # the vehicle's system id (the node follows the first autopilot it hears)
    armed: bool = False
    main_mode: int = 0
    sub_mode: int = 0
    landed_state: int = 0  # MAV_LANDED_STATE
    last_heartbeat: float = -math.inf
    last_time_ms: int = -1
    pending: dict[int, dict[str, object]] = field(default_factory=dict)  # time_boot_ms -> messages

    @property
    def in_offboard(self) -> bool:
        return self.main_mode == Px4MainMode.OFFBOARD

    @property
    def flying_mission(self) -> bool:
        return self.main_mode == Px4MainMode.AUTO and self.sub_mode in (Px4AutoSubMode.MISSION, Px4AutoSubMode.TAKEOFF)


def state_from_messages(local, attitude) -> VehicleState:
    return VehicleState(
        t=local.time_boot_ms / 1000.0,
        position=np.array([local.x, local.y, local.z]),
        velocity=np.array([local.vx, local.vy, local.vz]),
        quaternion=np.array([attitude.q1, attitude.q2, attitude.q3, attitude.q4]),
        angular_velocity=np.array([attitude.rollspeed, attitude.pitchspeed, attitude.yawspeed]),
    )


def setpoint_from_message(target) -> TrajectorySetpoint:
    return TrajectorySetpoint(
        position=np.array([target.x, target.y, target.z]),
        velocity=np.array([target.vx, target.vy, target.vz]),
        acceleration=np.array([target.afx, target.afy, target.afz]),
        yaw=target.yaw,
        yaw_rate=target.yaw_rate,
    )


STATE_MESSAGES = ("LOCAL_POSITION_NED", "ATTITUDE_QUATERNION", "POSITION_TARGET_LOCAL_NED")
IGNORE_BODY_RATES = (
    mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
    | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE
    | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE
)


def attitude_target_message(t_ms: int, target: AttitudeTarget):
    """SET_ATTITUDE_TARGET for the tick stamped t_ms: attitude, thrust and, when the target has them, body rates
    as feed-forward (the yaw-rate feed-forward of the outer loops); without them the rate bits say ignore."""
    w, x, y, z = (float(c) for c in target.quaternion)
    if target.body_rates is None:
        type_mask, rates = IGNORE_BODY_RATES, (0.0, 0.0, 0.0)
    else:
        type_mask, rates = 0, tuple(float(r) for r in target.body_rates)
    return mavlink.MAVLink_set_attitude_target_message(
        t_ms, 1, 1, type_mask, [w, x, y, z], *rates, float(target.thrust)
    )


def _autopilot_heartbeat(msg) -> bool:
    return msg.get_type() == "HEARTBEAT" and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID


class OffboardProtocol:
    """The node's side of the MAVLink conversation without its socket: `handle(msg)` takes one message from the
    vehicle and returns the messages to send back, in order. The in-process lockstep harness
    (sitl_quad.lockstep_harness) drives the same object, so both fly by exactly the same decisions."""

    def __init__(self, controller, outer_rate_hz: float = 50.0, engage: bool = True) -> None:
        self.controller = controller
        self.dt = 1.0 / outer_rate_hz
        self.engage = engage
        self.vehicle = VehicleView()
        self.ticks_answered = 0
        self.engage_requests = 0
        self._next_engage_tick = 0

    def handle(self, msg) -> list:
        kind = msg.get_type()
        v = self.vehicle
        if kind == "HEARTBEAT":
            v.last_heartbeat = time.monotonic()
            v.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            v.main_mode, v.sub_mode = px4_main_sub(msg.custom_mode)
        elif kind == "EXTENDED_SYS_STATE":
            v.landed_state = msg.landed_state
        elif kind in STATE_MESSAGES:
            return self._collect(msg)
        return []

    def _collect(self, msg) -> list:
        v = self.vehicle
        t_ms = msg.time_boot_ms
        if t_ms < v.last_time_ms:  # time went backwards: the vehicle restarted
            log.warning("vehicle time went back from %d to %d ms: restart, observers reset", v.last_time_ms, t_ms)
            v.pending.clear()
            v.last_time_ms = -1
            self.controller.reset()
        slot = v.pending.setdefault(t_ms, {})
        slot[msg.get_type()] = msg
        if len(slot) == len(STATE_MESSAGES):
            del v.pending[t_ms]
            for stale in [k for k in v.pending if k < t_ms]:  # a lost datagram leaves an incomplete tick
                del v.pending[stale]
            v.last_time_ms = t_ms
            return self._answer(t_ms, slot)
        return []

    def _answer(self, t_ms: int, slot: dict) -> list:
        v = self.vehicle
        out = []
        estimate = state_from_messages(slot["LOCAL_POSITION_NED"], slot["ATTITUDE_QUATERNION"])
        setpoint = setpoint_from_message(slot["POSITION_TARGET_LOCAL_NED"])
        if self.engage and v.armed and v.flying_mission and self.ticks_answered >= self._next_engage_tick:
            # Decided on this tick's heartbeat and sent before the answer, so a lockstep vehicle switches at
            # the same tick in every run. Takeoff included: the ADRC flies the whole mission.
            self._next_engage_tick = self.ticks_answered + ENGAGE_RETRY_TICKS
            self.engage_requests += 1
            base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_SAFETY_ARMED
            out.append(
                mavlink.MAVLink_command_long_message(
                    v.sysid,
                    AUTOPILOT_COMPID,
                    mavlink.MAV_CMD_DO_SET_MODE,
                    0,
                    base,
                    Px4MainMode.OFFBOARD,
                    0,
                    0,
                    0,
                    0,
                    0,
                )
            )
        if not (v.armed and v.in_offboard and v.landed_state != mavlink.MAV_LANDED_STATE_ON_GROUND):
            self.controller.reset()  # not in control, or idling on the ground: start fresh at the climb
        target = self.controller.update(setpoint, estimate, self.dt)
        out.append(attitude_target_message(t_ms, target))
        self.ticks_answered += 1
        if self.ticks_answered % ESO_PUBLISH_EVERY == 0:
            z3 = self.controller.disturbance_estimates()
            if z3:
                out.append(
                    mavlink.MAVLink_debug_vect_message(
                        b"ESO_Z3", t_ms * 1000, z3.get("x", 0.0), z3.get("y", 0.0), z3.get("z", 0.0)
                    )
                )
        return out


class OffboardNode:
    """`OffboardProtocol` on a UDP socket, with a 1 Hz wall-clock heartbeat."""

    def __init__(
        self,
        controller,
        vehicle_address: tuple[str, int],
        outer_rate_hz: float = 50.0,
        engage: bool = True,
        sysid: int | None = None,
        compid: int = ONBOARD_COMPUTER_COMPID,
        signing_key: bytes | None = None,
    ) -> None:
        """sysid: the vehicle's system id, which the node shares as its companion computer; None follows the
        first autopilot heartbeat heard."""
        self.protocol = OffboardProtocol(controller, outer_rate_hz, engage)
        self.follow_sysid = sysid is None
        sysid = VEHICLE_SYSID if sysid is None else sysid
        self.protocol.vehicle.sysid = sysid
        self.vehicle_address = vehicle_address
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.encoder = Encoder(sysid, compid, signing_key)
        self.parser = new_parser(sysid, compid, signing_key)
        self.running = True
        self._next_heartbeat = 0.0

    @property
    def controller(self):
        return self.protocol.controller

    @property
    def vehicle(self) -> VehicleView:
        return self.protocol.vehicle

    # ----- transport
    def send(self, msg) -> None:
        buf = self.encoder.pack(msg)
        try:
            self.sock.sendto(buf, self.vehicle_address)
        except OSError as exc:  # vehicle not up yet (ICMP refused): keep going, it will come
            log.debug("send failed: %s", exc)

    def receive(self, timeout: float) -> list:
        ready, _, _ = select.select([self.sock], [], [], timeout)
        if not ready:
            return []
        out = []
        while True:
            try:
                data, _ = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                return out
            except OSError:
                continue
            try:
                msgs = parse_datagram(self.parser, data)
            except Exception:  # hostile or broken datagram: ignore it
                continue
            for m in msgs:
                if isinstance(m, mavlink.MAVLink_bad_data) or m.get_srcComponent() != AUTOPILOT_COMPID:
                    continue
                if self.follow_sysid and _autopilot_heartbeat(m):
                    self._follow(m.get_srcSystem())
                if m.get_srcSystem() == self.vehicle.sysid:
                    out.append(m)

    def _follow(self, sysid: int) -> None:
        """Become the companion of the vehicle with this system id (one vehicle per node)."""
        log.info("following vehicle system %d", sysid)
        self.follow_sysid = False
        self.vehicle.sysid = sysid
        self.encoder.mav.srcSystem = sysid

    # ----- the loop
    def run(self, duration_s: float | None = None) -> None:
        end = None if duration_s is None else time.monotonic() + duration_s
        while self.running and (end is None or time.monotonic() < end):
            self._wall_timers(time.monotonic())
            for msg in self.receive(0.05):
                self.handle(msg)
        self.sock.close()

    def stop(self) -> None:
        self.running = False

    def _wall_timers(self, now: float) -> None:
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + HEARTBEAT_S
            self.send(
                mavlink.MAVLink_heartbeat_message(
                    mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                    mavlink.MAV_AUTOPILOT_INVALID,
                    0,
                    0,
                    mavlink.MAV_STATE_ACTIVE,
                    3,
                )
            )

    def handle(self, msg) -> None:
        for reply in self.protocol.handle(msg):
            self.send(reply)
