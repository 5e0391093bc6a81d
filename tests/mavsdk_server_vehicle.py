"""A vehicle nobody here wrote: an autopilot made of MAVSDK's server plugins, for testing the ground station.

MAVSDK (the native `mavsdk` 4 package, ctypes over the C library) answers the MAVLink protocols itself:
ServerComponent sends the autopilot heartbeat (MAVSDK's own: autopilot GENERIC, with our MAV_TYPE), MissionRawServer
runs the mission upload and MISSION_CURRENT / MISSION_ITEM_REACHED, ActionServer answers ARM and DO_SET_MODE (PX4
custom modes) and puts armed state and mode into the heartbeat, TelemetryServer sends what we publish
(GLOBAL_POSITION_INT, LOCAL_POSITION_NED, ATTITUDE, EXTENDED_SYS_STATE, HOME_POSITION, SYSTEM_TIME) and answers
SET_MESSAGE_INTERVAL, ParamServer serves parameters. This file only decides what the vehicle does: once armed in
mission mode it moves in a straight line at constant speed (wall-clock time, no dynamics) to each uploaded item,
marks it complete, and on the return-to-launch or land item comes down, lands and disarms.

    python tests/mavsdk_server_vehicle.py --connect udpout://127.0.0.1:PORT --items-out received.json

`udpout` to the ground station's `udpin` port is how PX4 SITL talks to QGroundControl on 14550. The items the
upload delivered are written to --items-out as JSON, one object of `uavcore.mission.MissionItem` fields each.
"""

from __future__ import annotations

import argparse
import ctypes
import dataclasses
import json
import math
import signal
import threading
import time
from pathlib import Path

from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.cmavsdk_loader import _cmavsdk_lib
from mavsdk.plugins.action_server import ActionServer, ActionServerResult, AllowableFlightModes, FlightMode
from mavsdk.plugins.mission_raw_server import MissionRawServer, MissionRawServerResult
from mavsdk.plugins.param_server import ParamServer
from mavsdk.plugins.telemetry_server import (
    AngularVelocityBody,
    EulerAngle,
    Heading,
    LandedState,
    Position,
    PositionNed,
    PositionVelocityNed,
    TelemetryServer,
    VelocityNed,
    VtolState,
)

from uavcore.geodesy import DEFAULT_HOME, LocalFrame
from uavcore.mission import MavCmd, MissionItem

MAV_TYPE_QUADROTOR = 2
TICK_S = 0.05  # telemetry and kinematics at 20 Hz
SLOW_TELEMETRY_S = 1.0  # home and unix time at 1 Hz
CLIMB_M_S = 5.0
DESCENT_M_S = 3.0
ARRIVED_M = 0.01  # the kinematics land exactly on the target; this only absorbs rounding


def set_mav_type(configuration: Configuration, mav_type: int) -> None:
    """MAVSDK's heartbeat carries the configured MAV_TYPE (GENERIC by default). The C library can set it
    (mavsdk_configuration_set_mav_type) but the Python wrapper does not offer it, so call the C function."""
    _cmavsdk_lib.mavsdk_configuration_set_mav_type.argtypes = [ctypes.c_void_p, ctypes.c_int]
    _cmavsdk_lib.mavsdk_configuration_set_mav_type.restype = None
    _cmavsdk_lib.mavsdk_configuration_set_mav_type(configuration._handle, mav_type)


class MavsdkServerVehicle:
    """The plugins, the vehicle's state, and the loop that flies and publishes it.

    MAVSDK calls the subscriptions from its own thread; they only record what was asked, under `lock`, and the
    main thread's loop (`run`) acts on it. The current mission item is MissionRawServer's: it announces each new
    one (after an upload, a MISSION_SET_CURRENT or our set_current_item_complete); after the last item it
    announces the last item again, so "current == the item we completed last" means nothing is left to fly.
    """

    def __init__(
        self, connection: str, home: tuple[float, float, float], speed_m_s: float, items_out: Path, unix_time: bool
    ) -> None:
        self.home = home
        self.frame = LocalFrame(*home)
        self.speed_m_s = speed_m_s
        self.items_out = items_out
        self.unix_time = unix_time
        self.lock = threading.Lock()
        self.stopping = threading.Event()
        # state the MAVSDK callbacks write
        self.items: list[MissionItem] = []
        self.current_seq: int | None = None
        self.armed = False
        self.mode = FlightMode.READY
        # state only the loop touches
        self.mission_flown: list[MissionItem] = []  # the mission completed_seq belongs to
        self.completed_seq: int | None = None
        self.north = self.east = self.down = 0.0
        self.velocity = (0.0, 0.0, 0.0)
        self.heading_deg = 0.0
        self.landed_state = LandedState.ON_GROUND
        self.dwell_until: float | None = None

        configuration = Configuration.create_with_component_type(ComponentType.AUTOPILOT)
        set_mav_type(configuration, MAV_TYPE_QUADROTOR)
        self.mavsdk = Mavsdk(configuration)
        result = self.mavsdk.add_any_connection(connection)
        if int(result) != 0:  # ConnectionResult.SUCCESS
            raise SystemExit(f"MAVSDK cannot open {connection}: {result!r}")
        component = self.mavsdk.server_component()
        self.telemetry = TelemetryServer(component)
        self.boot = time.monotonic()  # within milliseconds of the TelemetryServer's own boot clock
        self.params = ParamServer(component)
        self.action = ActionServer(component)
        self.mission = MissionRawServer(component)

        self.params.provide_param_float("MPC_XY_CRUISE", speed_m_s)
        self.params.provide_param_float("MIS_TAKEOFF_ALT", 5.0)
        self.action.set_armable(True, True)
        self.action.set_disarmable(True, True)
        self.action.set_allow_takeoff(True)
        self.action.set_allowable_flight_modes(
            AllowableFlightModes(can_auto_mode=True, can_guided_mode=True, can_stabilize_mode=True)
        )
        self.action.subscribe_arm_disarm(self._on_arm_disarm)
        self.action.subscribe_flight_mode_change(self._on_flight_mode_change)
        self.mission.subscribe_incoming_mission(self._on_incoming_mission)
        self.mission.subscribe_current_item_changed(self._on_current_item_changed)

    # ----- MAVSDK's callbacks (its thread)
    def _on_arm_disarm(self, result: ActionServerResult, arm_disarm, _user_data) -> None:
        if result == ActionServerResult.SUCCESS:
            with self.lock:
                self.armed = bool(arm_disarm.arm)
        print(f"arm/disarm request: arm={arm_disarm.arm} -> {result.name}", flush=True)

    def _on_flight_mode_change(self, result: ActionServerResult, mode: FlightMode, _user_data) -> None:
        if result == ActionServerResult.SUCCESS:
            with self.lock:
                self.mode = FlightMode(mode)
        print(f"flight mode request: {FlightMode(mode).name} -> {result.name}", flush=True)

    def _on_incoming_mission(self, result: MissionRawServerResult, plan, _user_data) -> None:
        print(f"incoming mission: {result.name}, {len(plan.mission_items)} items", flush=True)
        if result != MissionRawServerResult.SUCCESS:
            return
        items = [
            MissionItem(**{f.name: getattr(raw, f.name) for f in dataclasses.fields(MissionItem)})
            for raw in plan.mission_items
        ]
        with self.lock:
            self.items = items
        temporary = self.items_out.with_suffix(".tmp")
        temporary.write_text(json.dumps([dataclasses.asdict(item) for item in items], indent=1))
        temporary.replace(self.items_out)  # the test never reads half a file

    def _on_current_item_changed(self, item, _user_data) -> None:
        with self.lock:
            self.current_seq = item.seq

    # ----- the loop (main thread)
    def run(self) -> None:
        next_slow = 0.0
        while not self.stopping.is_set():
            self.step(TICK_S)
            self.publish_fast()
            if time.monotonic() >= next_slow:
                self.publish_slow()
                next_slow = time.monotonic() + SLOW_TELEMETRY_S
            time.sleep(TICK_S)

    def step(self, dt: float) -> None:
        """Fly the current mission item for dt seconds, if armed in mission mode."""
        with self.lock:
            armed, mode, items, seq = self.armed, self.mode, self.items, self.current_seq
        self.velocity = (0.0, 0.0, 0.0)
        if items is not self.mission_flown:  # a new upload: nothing of it is done yet
            self.mission_flown, self.completed_seq = items, None
        in_mission = armed and mode == FlightMode.MISSION and seq is not None and seq < len(items)
        if not in_mission or seq == self.completed_seq:
            return
        item = items[seq]
        if self.fly_item(item, dt):
            self.completed_seq = seq
            self.dwell_until = None
            self.mission.set_current_item_complete()

    def fly_item(self, item: MissionItem, dt: float) -> bool:
        """Move toward what the item asks; True once it is done."""
        if item.command == MavCmd.NAV_TAKEOFF:
            self.landed_state = LandedState.TAKING_OFF
            if self.move_to(self.north, self.east, -item.z, dt):
                self.landed_state = LandedState.IN_AIR
                return True
            return False
        if item.command == MavCmd.NAV_WAYPOINT:
            north, east, _ = self.frame.to_ned(item.lat, item.lon, self.home[2])
            if not self.move_to(north, east, -item.z, dt):
                return False
            return self.dwelt(item.param1)
        if item.command in (MavCmd.NAV_RETURN_TO_LAUNCH, MavCmd.NAV_LAND):
            north, east = (0.0, 0.0) if item.command == MavCmd.NAV_RETURN_TO_LAUNCH else (self.north, self.east)
            if item.has_position:
                north, east, _ = self.frame.to_ned(item.lat, item.lon, self.home[2])
            if not self.move_to(north, east, self.down, dt):
                return False
            self.landed_state = LandedState.LANDING
            if not self.move_to(north, east, 0.0, dt):
                return False
            self.landed_state = LandedState.ON_GROUND
            self.action.set_armed_state(False)
            with self.lock:
                self.armed = False
            return True
        return True  # DO_CHANGE_SPEED and the like: accepted, nothing to fly (this double keeps --speed)

    def move_to(self, north: float, east: float, down: float, dt: float) -> bool:
        """One straight-line step toward the target (horizontal at --speed, vertical at the climb or descent
        rate); True once there."""
        d_north, d_east, d_down = north - self.north, east - self.east, down - self.down
        horizontal = math.hypot(d_north, d_east)
        if horizontal > 0:
            self.heading_deg = math.degrees(math.atan2(d_east, d_north)) % 360.0
        scale = min(1.0, self.speed_m_s * dt / horizontal) if horizontal > 0 else 0.0
        vertical_rate = CLIMB_M_S if d_down < 0 else DESCENT_M_S
        step = (d_north * scale, d_east * scale, math.copysign(min(abs(d_down), vertical_rate * dt), d_down))
        self.north, self.east, self.down = self.north + step[0], self.east + step[1], self.down + step[2]
        self.velocity = (step[0] / dt, step[1] / dt, step[2] / dt)
        return math.dist((self.north, self.east, self.down), (north, east, down)) <= ARRIVED_M

    def dwelt(self, seconds: float) -> bool:
        """Hold at a waypoint for its hold time (param1, seconds; NaN means none)."""
        if not seconds > 0:
            return True
        if self.dwell_until is None:
            self.dwell_until = time.monotonic() + seconds
        return time.monotonic() >= self.dwell_until

    # ----- telemetry
    def publish_fast(self) -> None:
        lat, lon, alt = self.frame.from_ned(self.north, self.east, self.down)
        vn, ve, vd = self.velocity
        yaw_deg = self.heading_deg if self.heading_deg <= 180.0 else self.heading_deg - 360.0
        self.telemetry.publish_position(
            Position(float(lat), float(lon), float(alt), -self.down), VelocityNed(vn, ve, vd), Heading(self.heading_deg)
        )
        self.telemetry.publish_position_velocity_ned(
            PositionVelocityNed(PositionNed(self.north, self.east, self.down), VelocityNed(vn, ve, vd))
        )
        self.telemetry.publish_attitude(
            # ATTITUDE's time_boot_ms is our timestamp (the other messages carry MAVSDK's boot clock)
            EulerAngle(0.0, 0.0, yaw_deg, round((time.monotonic() - self.boot) * 1e6)),
            AngularVelocityBody(0.0, 0.0, 0.0),
        )
        self.telemetry.publish_extended_sys_state(VtolState.UNDEFINED, self.landed_state)

    def publish_slow(self) -> None:
        lat, lon, alt = self.home
        self.telemetry.publish_home(Position(lat, lon, alt, 0.0))
        if self.unix_time:  # MAVSDK 4.1 sends this SYSTEM_TIME with time_boot_ms 0 (a TODO in its source)
            self.telemetry.publish_unix_epoch_time(int(time.time() * 1e6))

    def close(self) -> None:
        self.mavsdk.destroy()


def parse_home(text: str) -> tuple[float, float, float]:
    lat, lon, alt = (float(part) for part in text.split(","))
    return lat, lon, alt


def main(argv: list[str] | None = None, vehicle_type: type[MavsdkServerVehicle] | None = None) -> int:
    """Run the double (or `vehicle_type`, a subclass taking the same arguments) until SIGTERM."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--connect", required=True, help="MAVSDK connection URL, e.g. udpout://127.0.0.1:14550")
    parser.add_argument("--items-out", type=Path, required=True, help="JSON file for the uploaded mission items")
    parser.add_argument("--home", type=parse_home, default=DEFAULT_HOME, help="lat,lon,alt (default %(default)s)")
    parser.add_argument(
        "--speed", type=float, default=30.0, help="horizontal speed, m/s (faster than planned: short test flights)"
    )
    parser.add_argument(
        "--unix-time", action="store_true", help="publish SYSTEM_TIME (TelemetryServer.publish_unix_epoch_time)"
    )
    args = parser.parse_args(argv)
    vehicle = (vehicle_type or MavsdkServerVehicle)(args.connect, args.home, args.speed, args.items_out, args.unix_time)
    signal.signal(signal.SIGTERM, lambda *_: vehicle.stopping.set())
    signal.signal(signal.SIGINT, lambda *_: vehicle.stopping.set())
    print(f"MAVSDK {vehicle.mavsdk.version()} autopilot on {args.connect}", flush=True)
    try:
        vehicle.run()
    finally:
        vehicle.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
