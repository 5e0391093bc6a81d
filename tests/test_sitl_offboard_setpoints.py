"""Offboard setpoints beyond attitude, as PX4 takes them: position/velocity/yaw targets flown by the built-in
position loop, body rates + thrust, the frames MAVSDK uses, OFFBOARD entry and loss, in-process and over UDP."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import pytest
from sitl_process import GroundStation
from test_sitl_vehicle import FRAME, HOME, fly_until

from sitl_quad.config import FailsafeAction, FailsafeConfig, VehicleConfig
from sitl_quad.offboard_setpoints import (
    PositionTarget,
    RatesTarget,
    SetpointError,
    local_position_target,
    wants_takeoff,
)
from sitl_quad.vehicle import CommandResult, LandedState, Vehicle
from uavcore.mavlink import mavlink
from uavcore.mission import MavFrame
from uavcore.modes import FlightMode, Px4MainMode
from uavcore.rotation import euler_from_quat, quat_from_euler
from uavcore.state import VehicleState

NAN3 = (math.nan, math.nan, math.nan)


@pytest.fixture
def vehicle() -> Vehicle:
    return Vehicle(VehicleConfig(failsafe=FailsafeConfig(offboard_loss_timeout_s=0.5)), home=HOME, seed=3)


def stream(vehicle: Vehicle, seconds: float, position: PositionTarget | None = None, rates: RatesTarget | None = None):
    """Send a setpoint before every tick for `seconds` of simulated time, as a 50 Hz offboard stream."""
    for _ in range(round(seconds / vehicle.outer_dt)):
        if position is not None:
            vehicle.set_offboard_position_target(position)
        if rates is not None:
            vehicle.set_offboard_rates_target(rates)
        vehicle.tick()


def heading(vehicle: Vehicle) -> float:
    return euler_from_quat(vehicle.truth.quaternion)[2]


def offboard_from_the_ground(vehicle: Vehicle, first: PositionTarget) -> None:
    assert vehicle.arm() == CommandResult.ACCEPTED
    assert vehicle.set_mode(FlightMode.OFFBOARD) == CommandResult.TEMPORARILY_REJECTED  # no stream yet
    vehicle.set_offboard_position_target(first)
    assert vehicle.set_mode(FlightMode.OFFBOARD) == CommandResult.ACCEPTED


def test_position_targets_take_off_fly_turn_and_land(vehicle):
    """MAVSDK's offboard_position_ned: on the ground until a setpoint asks to climb, then to each point."""
    ground = PositionTarget(position=(0.0, 0.0, 0.0), yaw=0.0)
    offboard_from_the_ground(vehicle, ground)
    stream(vehicle, 2.0, ground)
    assert vehicle.source == "idle" and vehicle.sim.on_ground  # a ground setpoint does not take off (PX4)
    stream(vehicle, 8.0, PositionTarget(position=(0.0, 0.0, -5.0), yaw=0.0))
    assert np.allclose(vehicle.truth.position, (0.0, 0.0, -5.0), atol=0.3)
    assert vehicle.landed_state == LandedState.IN_AIR
    stream(vehicle, 10.0, PositionTarget(position=(5.0, 0.0, -5.0), yaw=math.pi / 2))
    assert np.allclose(vehicle.truth.position, (5.0, 0.0, -5.0), atol=0.3)
    assert abs(heading(vehicle) - math.pi / 2) < 0.05
    stream(vehicle, 10.0, PositionTarget(position=(5.0, 10.0, -5.0), yaw=math.pi))
    assert abs(heading(vehicle)) > math.pi - 0.05
    stream(vehicle, 10.0, PositionTarget(position=(5.0, 10.0, 0.0), yaw=math.pi))
    assert not vehicle.armed  # down on the ground: the land detector disarms, in OFFBOARD as in any mode
    assert np.allclose(vehicle.truth.position[:2], (5.0, 10.0), atol=0.3)


def test_velocity_and_yaw_rate_targets(vehicle):
    """Velocity with a yaw rate alone: the yaw reference turns at that rate; no yaw command holds the heading."""
    offboard_from_the_ground(vehicle, PositionTarget(velocity=(0.0, 0.0, 0.0)))
    stream(vehicle, 1.5, PositionTarget(velocity=(0.0, 0.0, 0.0)))
    assert vehicle.sim.on_ground  # a zero velocity does not take off
    stream(vehicle, 4.0, PositionTarget(velocity=(0.0, 0.0, -1.0), yaw_rate=math.radians(30)))
    assert 2.5 < -vehicle.truth.position[2] < 4.5
    start = heading(vehicle)
    stream(vehicle, 3.0, PositionTarget(velocity=(2.0, 0.0, 0.0), yaw_rate=math.radians(30)))
    assert abs(vehicle.truth.velocity[0] - 2.0) < 0.3
    turned = (heading(vehicle) - start) % (2 * math.pi)
    assert abs(turned - math.radians(90)) < math.radians(8)
    held = heading(vehicle)
    stream(vehicle, 2.0, PositionTarget(velocity=(0.0, 0.0, 0.0)))
    assert abs(heading(vehicle) - held) < math.radians(3)


def test_body_frame_velocity_turns_with_the_vehicle():
    """BODY_NED velocity (MAVSDK's set_velocity_body) is rotated by the heading when it arrives (PX4)."""
    facing_east = VehicleState(position=np.array([1.0, 2.0, -3.0]), quaternion=quat_from_euler(0.0, 0.0, math.pi / 2))
    target = local_position_target(MavFrame.BODY_NED, NAN3, (5.0, 0.0, -1.0), NAN3, math.nan, 0.5, facing_east)
    assert target.velocity == pytest.approx((0.0, 5.0, -1.0), abs=1e-12)
    offset = local_position_target(
        MavFrame.BODY_OFFSET_NED, (2.0, 0.0, 0.0), NAN3, NAN3, math.nan, math.nan, facing_east
    )
    assert offset.position == pytest.approx((1.0, 4.0, -3.0), abs=1e-12)
    local_offset = local_position_target(
        MavFrame.LOCAL_OFFSET_NED, (2.0, 0.0, 0.0), NAN3, NAN3, math.nan, math.nan, facing_east
    )
    assert local_offset.position == pytest.approx((3.0, 2.0, -3.0), abs=1e-12)
    with pytest.raises(SetpointError):
        local_position_target(MavFrame.GLOBAL_INT, (0.0, 0.0, 0.0), NAN3, NAN3, 0.0, 0.0, facing_east)
    with pytest.raises(SetpointError):
        PositionTarget(yaw=0.0)  # nothing controlled: not a setpoint


def test_takeoff_trigger_is_pxs():
    on_ground = VehicleState()
    assert not wants_takeoff(PositionTarget(position=(0.0, 0.0, -0.1)), on_ground)
    assert wants_takeoff(PositionTarget(position=(0.0, 0.0, -0.3)), on_ground)
    assert not wants_takeoff(PositionTarget(velocity=(0.0, 0.0, -0.2)), on_ground)
    assert wants_takeoff(PositionTarget(velocity=(0.0, 0.0, -0.5)), on_ground)


def test_body_rates_and_thrust_fly_the_attitude_loop(vehicle):
    rates = RatesTarget((0.0, 0.0, 0.0), 0.0)
    assert vehicle.arm() == CommandResult.ACCEPTED
    vehicle.set_offboard_rates_target(rates)
    assert vehicle.set_mode(FlightMode.OFFBOARD) == CommandResult.ACCEPTED
    stream(vehicle, 1.5, rates=RatesTarget((0.0, 0.0, 0.0), 0.6))
    assert vehicle.source == "offboard" and -vehicle.truth.position[2] > 0.2  # spooled up, then lifted off
    start = heading(vehicle)
    stream(vehicle, 2.0, rates=RatesTarget((0.0, 0.0, 0.5), 0.45))
    assert abs((heading(vehicle) - start) % (2 * math.pi) - 1.0) < 0.1  # 0.5 rad/s for 2 s


def test_position_stream_loss_triggers_offb_loss_act_in_simulated_time():
    config = VehicleConfig(
        failsafe=FailsafeConfig(offboard_loss_timeout_s=0.5, offboard_loss_action=FailsafeAction.LAND)
    )
    vehicle = Vehicle(config, home=HOME, seed=3)
    offboard_from_the_ground(vehicle, PositionTarget(position=(0.0, 0.0, -4.0)))
    stream(vehicle, 6.0, PositionTarget(position=(0.0, 0.0, -4.0)))
    last = vehicle.t
    events = fly_until(vehicle, lambda v: v.mode != FlightMode.OFFBOARD, 5.0)
    assert vehicle.mode == FlightMode.AUTO_LAND
    assert vehicle.t - last == pytest.approx(0.5 + vehicle.outer_dt, abs=1e-9)  # the first tick past OFFB_LOSS_T
    assert any("offboard setpoints lost" in e.text for e in events)
    fly_until(vehicle, lambda v: not v.armed, 30.0)
    assert not vehicle.armed and -vehicle.truth.position[2] < 0.1


@pytest.mark.integration
def test_position_targets_over_udp(start_sitl):
    """SET_POSITION_TARGET_LOCAL_NED then _GLOBAL_INT from a ground station, as MAVSDK sends them."""
    # OFFB_LOSS_T is simulated time: at 4x a 0.5 s one is 0.125 s of the stream's wall clock, which a loaded
    # machine's scheduler can leave between two setpoints (or between the first one and OFFBOARD's ack).
    vehicle = start_sitl(speed=4.0, extra_args=("--param", "OFFB_LOSS_T=4"))
    gcs = GroundStation(vehicle.port)
    try:
        gcs.connect()
        ignore_acceleration = (
            mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
        )
        velocity_ignored = (
            mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
            | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE
        )
        mask = ignore_acceleration | velocity_ignored

        def send_local(north: float, east: float, down: float) -> None:
            gcs.mav.set_position_target_local_ned_send(
                0, 1, 1, mavlink.MAV_FRAME_LOCAL_NED, mask, north, east, down, 0, 0, 0, 0, 0, 0, 0.0, 0.0
            )

        def send_global(lat: float, lon: float, altitude: float) -> None:
            gcs.mav.set_position_target_global_int_send(
                0, 1, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mask, round(lat * 1e7), round(lon * 1e7),
                altitude, 0, 0, 0, 0, 0, 0, 0.0, 0.0,
            )  # fmt: skip

        def stream_until_at(send: Callable[[], None], target: tuple[float, float, float], tolerance: float) -> None:
            """Stream the setpoint at 20 Hz wall clock, as MAVSDK does, until the vehicle holds the target (the
            vehicle's pace on a loaded machine decides how long that takes: the deadline is only a backstop)."""
            deadline, held, position = time.monotonic() + 60.0, 0, None
            while held < 10:  # the latest position inside the tolerance at ten sends in a row (0.5 s wall)
                assert time.monotonic() < deadline, f"never held {target}: last {position}"
                send()
                time.sleep(0.05)
                while (message := gcs.conn.recv_match(type="LOCAL_POSITION_NED", blocking=False)) is not None:
                    position = message
                if position is not None:
                    inside = math.dist((position.x, position.y, position.z), target) < tolerance
                    held = held + 1 if inside else 0

        assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        send_local(0.0, 0.0, -6.0)
        ack = gcs.set_mode(Px4MainMode.OFFBOARD)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        stream_until_at(lambda: send_local(0.0, 0.0, -6.0), (0.0, 0.0, -6.0), 0.5)
        lat, lon, _ = (float(c) for c in FRAME.from_ned(8.0, 0.0, 0.0))
        stream_until_at(lambda: send_global(lat, lon, 6.0), (8.0, 0.0, -6.0), 0.7)
        heartbeat = gcs.wait_heartbeat(lambda m: (m.custom_mode >> 16) & 0xFF != Px4MainMode.OFFBOARD, timeout=60)
        assert heartbeat is not None  # the stream stopped: OFFB_LOSS_ACT (hold) took over
    finally:
        gcs.close()
