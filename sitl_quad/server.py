"""The vehicle process's main loop: pace simulated time, tick the vehicle, talk MAVLink.

Simulated time advances in outer-loop ticks. `--speed N` paces ticks to N times the wall clock;
`--lockstep` waits after each tick until the offboard controller's SET_ATTITUDE_TARGET answers the state
just sent (its time_boot_ms), and runs freely while no offboard controller streams. The SIM_SPEEDUP parameter
(settable in flight) caps either: N > 0 holds a tick also until its pacing's due time at N times the wall clock
(lockstep then still waits for the answer, but never runs faster than N; paced, N replaces --speed); 0 lifts the
cap. Heartbeats, command acknowledgements and mission-transfer timers run on the wall clock whatever the pacing.
"""

from __future__ import annotations

import csv
import logging
import math
import time
from pathlib import Path

from sitl_quad.ais_out import AisOut
from sitl_quad.camera import Environment
from sitl_quad.flight_logs import FlightLogs
from sitl_quad.mavlink.camera import CameraComponent
from sitl_quad.mavlink.commands import Commands
from sitl_quad.mavlink.failure_injection import FailureInjection
from sitl_quad.mavlink.ftp import CAMERA_COMPID, FileTransfer
from sitl_quad.mavlink.gimbal import GimbalManager
from sitl_quad.mavlink.heartbeat import Heartbeat, heartbeat_message
from sitl_quad.mavlink.link import UdpLink
from sitl_quad.mavlink.log_transfer import LogTransfer
from sitl_quad.mavlink.mission import MissionProtocol
from sitl_quad.mavlink.offboard import Offboard
from sitl_quad.mavlink.parameters import Parameters
from sitl_quad.mavlink.payload import Payload
from sitl_quad.mavlink.telemetry import Telemetry
from sitl_quad.pacing import WallPacing
from sitl_quad.params import ParameterTable
from sitl_quad.vehicle import CommandResult, TickRecord, Vehicle, VehicleEvent
from uavcore.buoy_world import World
from uavcore.mavlink import mavlink
from uavcore.rotation import euler_from_quat

log = logging.getLogger(__name__)

MAX_WAIT_SLICE_S = 0.005  # never sleep longer than this without looking at the socket and wall timers


class VehicleServer:
    def __init__(
        self,
        vehicle: Vehicle,
        params: ParameterTable,
        link: UdpLink,
        speed: float = 1.0,
        lockstep: bool = False,
        flight_log: Path | None = None,
        log_dir: Path | None = None,
        on_params_changed=None,
        ftp_root: Path | None = None,
        ftp_component: int = CAMERA_COMPID,
        image_dir: Path | None = None,
        world: World | None = None,
        current: Environment | None = None,
        ais_out: AisOut | None = None,
    ) -> None:
        """image_dir: the camera's (None: no camera and no gimbal); world: what it sees; current: the water's;
        ais_out: the world's AIS reports, sent as simulated time reaches them (their buoys move in the current);
        flight_log: the CSV of every tick (--log); log_dir: the ULog flight logs, one per arming (--log-dir), served
        over the MAVLink log protocol (none kept without it)."""
        self.vehicle = vehicle
        vehicle.wall_clock = time.monotonic  # protocol-facing timers also respect the wall clock
        self.params = params
        self.link = link
        self.lockstep = lockstep
        self.running = True
        self.speed = speed  # paced mode's pace while SIM_SPEEDUP is 0
        self.pacing = WallPacing(speed, time.monotonic(), vehicle.t)
        self.paced = not lockstep  # ticks wait for the pacing's due time (lockstep too while SIM_SPEEDUP caps it)
        self._follow_speedup()
        self._arrived_at = 0.0  # when the message being handled reached the socket (wall clock)
        self._setpoint_arrived_at = 0.0  # when the newest offboard setpoint did
        if not lockstep:  # a setpoint read late belongs to the simulated time it arrived at (sitl_quad.pacing)
            vehicle.arrival_step = self.arrival_step
        self.handler_errors = 0
        self.tick_lateness_s: list[float] = []  # paced mode: how late each tick started (for --stats)
        self.armed_lateness_s: list[float] = []  # the same, of the ticks flown armed (a fleet's start-ups excluded)
        self.telemetry = Telemetry(vehicle, link)
        self.heartbeat = Heartbeat(vehicle, self.send)
        self.parameters = Parameters(params, self.send, self._param_changed)
        self.on_params_changed = on_params_changed
        self.commands = Commands(vehicle, self.send)
        self.commands.vehicle_sysid = link.sysid
        self.commands.before_ack = self._publish_events
        self.mission = MissionProtocol(vehicle, self.send, link.sysid, link.compid)
        self.offboard = Offboard(vehicle)
        self.file_transfer = FileTransfer(link, ftp_root, ftp_component)
        self.failure_injection = FailureInjection(vehicle, link, self.commands)
        self.flight_logs = FlightLogs(log_dir, params, self.telemetry.boot_unix_us) if log_dir is not None else None
        self.log_transfer = LogTransfer(self.flight_logs, self.send) if self.flight_logs is not None else None
        home_id = mavlink.MAVLINK_MSG_ID_HOME_POSITION
        version_id = mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION
        self.commands.register(mavlink.MAV_CMD_REQUEST_MESSAGE, lambda p: self._request_message(p[0]))
        self.commands.register(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, lambda p: self.telemetry.set_interval(p[0], p[1]))
        self.commands.register(mavlink.MAV_CMD_GET_HOME_POSITION, lambda p: self.telemetry.request_message(home_id))
        self.commands.register(
            mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, lambda p: self.telemetry.request_message(version_id)
        )
        self.commands.register(mavlink.MAV_CMD_REQUEST_PROTOCOL_VERSION, lambda p: CommandResult.UNSUPPORTED)
        self.dispatch: dict = {}
        capabilities = [
            self.parameters, self.commands, self.mission, self.offboard, self.file_transfer, self.failure_injection
        ]  # fmt: skip
        if self.log_transfer is not None:
            capabilities.append(self.log_transfer)
        for capability in capabilities:
            self.dispatch.update(capability.handlers())
        self._setpoint_types = set(self.offboard.handlers())
        # ----- the camera on its gimbal: the gimbal manager is the autopilot's, the camera its own component
        self.payload: Payload | None = None
        self.gimbal: GimbalManager | None = None
        self.camera: CameraComponent | None = None
        if image_dir is not None:
            boot_unix_us = self.telemetry.boot_unix_us
            # paced, frames are made in a worker process so the ticks stay on time; lockstep, in the loop (exact)
            self.payload = Payload(
                vehicle, link, self.commands, image_dir, world, current, boot_unix_us=boot_unix_us,
                frames_in_loop=lockstep,
            )  # fmt: skip
            self.gimbal, self.camera = self.payload.gimbal, self.payload.camera
            self.dispatch.update(self.gimbal.handlers())
        self._log_file = None
        self._log_writer = None
        if flight_log is not None:
            self._open_log(flight_log)
        self._last_mission_seq = -1
        self.ais_out = ais_out
        self._current = current or Environment()

    # ----- sending and receiving
    def send(self, msg, peer=None) -> None:
        self.link.send(msg, peer)

    def handle_incoming(self) -> None:
        for peer, msg, at in self.link.receive():
            if self.camera is not None and self.camera.handles(msg):
                handler = self.camera.command
            else:
                handler = self.dispatch.get(msg.get_type())
            if handler is None:
                continue
            self._arrived_at = at  # for arrival_step()
            if msg.get_type() in self._setpoint_types:
                self._setpoint_arrived_at = at
            try:
                handler(peer, msg)
            except Exception:  # a bug in one handler must not take the vehicle down mid-flight
                self.handler_errors += 1
                log.exception("handler for %s failed", msg.get_type())

    def poll_wall_timers(self) -> None:
        now = time.monotonic()
        self.heartbeat.poll(now)
        self.mission.poll(now)
        self.parameters.poll()
        self.file_transfer.poll()
        self.failure_injection.poll(now)
        if self.log_transfer is not None:
            self.log_transfer.poll(now)
        if self.camera is not None:
            self.camera.poll(now)

    def _param_changed(self, section: str) -> None:
        self.vehicle.apply_config(section)
        if section == "simulation":
            self._follow_speedup()
        if self.on_params_changed is not None:
            self.on_params_changed()

    def pace(self) -> float | None:
        """Simulated seconds per wall second the ticks are held to: SIM_SPEEDUP when set, else --speed when
        paced; None for lockstep uncapped (as fast as the controller answers)."""
        speedup = self.params.config.simulation.speedup
        if speedup > 0:
            return speedup
        return None if self.lockstep else self.speed

    def _follow_speedup(self) -> None:
        """Take up SIM_SPEEDUP's pace from this tick on: re-anchored now, so a change is neither sprinted
        through (a slower pace measured from an old anchor would owe nothing for a while: a stall) nor owed."""
        pace = self.pace()
        self.paced = pace is not None
        if pace is not None:
            self.pacing.speed = pace
        self.pacing.resync(time.monotonic(), self.vehicle.t)

    # ----- the loop
    def run(self, duration_s: float | None = None) -> None:
        """Run until stop() or until `duration_s` of simulated time has passed."""
        self.pacing.resync(time.monotonic(), self.vehicle.t)
        end = None if duration_s is None else self.vehicle.t + duration_s
        while self.running and (end is None or self.vehicle.t < end - 1e-9):
            self._wait_for_next_tick()
            if not self.running:
                break
            if not self.lockstep:
                self.tick_lateness_s.append(self.pacing.behind_s(time.monotonic(), self.vehicle.t))
                if self.vehicle.armed:
                    self.armed_lateness_s.append(self.tick_lateness_s[-1])
            record = self.vehicle.tick()
            self._publish_events()
            if self.flight_logs is not None:
                self.flight_logs.tick(self.vehicle, record)
            if self.payload is not None:
                self.payload.tick()
            self.telemetry.publish_due()
            if self.ais_out is not None:
                self._send_ais_due()
            if self._log_writer is not None:
                self._write_log(record)
        self.close()

    def stop(self) -> None:
        self.running = False

    def _send_ais_due(self) -> None:
        """The AIS reports due at this tick, from the buoys as they float in the vehicle's mean wind and the current,
        stamped with the simulated clock (SYSTEM_TIME's)."""
        assert self.ais_out is not None
        wind, current, t = self.vehicle.config.wind, self._current, self.vehicle.t
        unix_s = self.telemetry.boot_unix_us / 1e6 + t
        self.ais_out.poll(
            t, unix_s, wind.direction_from_deg, wind.speed_m_s, current.current_to_deg, current.current_speed_m_s
        )

    def _request_message(self, msg_id: float) -> CommandResult:
        answered = self.gimbal.request_message(int(msg_id)) if self.gimbal and math.isfinite(msg_id) else None
        return answered if answered is not None else self.telemetry.request_message(msg_id)

    def arrival_step(self) -> int:
        """Paced mode: the physics step the message being handled arrived at (sitl_quad.pacing)."""
        sim = self.vehicle.sim
        ahead_s = self.pacing.arrival_time(self._arrived_at, time.monotonic(), sim.t) - sim.t
        return sim.step_index + int(ahead_s / sim.dt)  # rounded down: a setpoint is never made younger than it is

    def _wait_for_next_tick(self) -> None:
        while self.running:
            self.handle_incoming()
            self.poll_wall_timers()
            now = time.monotonic()
            if self.lockstep and not self._answered(now):
                self.link.wait(MAX_WAIT_SLICE_S)
                continue
            if not self.paced:  # lockstep without SIM_SPEEDUP: the answer is all a tick waits for
                return
            due = self.pacing.due(self.vehicle.t)
            if now >= due:
                if self.pacing.must_resync(now, self.vehicle.t):  # e.g. the process was suspended: don't sprint
                    self.pacing.resync(now, self.vehicle.t)
                return
            self.link.wait(min(due - now, MAX_WAIT_SLICE_S))

    def _answered(self, now: float) -> bool:
        """Lockstep: the offboard controller answered this tick's state, or none streams (the vehicle runs on)."""
        return not self.offboard.streaming(now) or self.offboard.answered(self.vehicle.time_boot_ms)

    def _publish_events(self) -> None:
        vehicle = self.vehicle
        events, vehicle.events = vehicle.events, []
        for event in events:
            self._publish_event(event)

    def _publish_event(self, event: VehicleEvent) -> None:
        if event.kind == "offboard_lost":
            self._report_offboard_loss()
            return
        if event.kind == "payload_item":
            if self.payload is not None:
                self.payload.run_mission_item(event.seq)
            return
        if event.kind == "text" or (event.kind in ("armed", "mission_complete") and event.text):
            self.send(mavlink.MAVLink_statustext_message(event.severity, event.text.encode()[:50]))
            if self.flight_logs is not None:
                self.flight_logs.text(event.severity, event.text, self.vehicle.t)
        if event.kind in ("mode", "armed"):
            self.send(heartbeat_message(self.vehicle))  # tools learn mode and arming changes at once
        if event.kind == "mode":
            self.send(mavlink.MAVLink_statustext_message(6, f"Mode: {event.text}".encode()[:50]))
        if event.kind in ("mission_current", "mission_complete", "item_reached"):
            self.send(self.telemetry.mission_current())
        if event.kind == "item_reached":
            self.send(mavlink.MAVLink_mission_item_reached_message(event.seq))

    def _report_offboard_loss(self) -> None:
        """Why the stream counted as lost, for whoever reads the vehicle's messages (a debug STATUSTEXT, as
        SITL diagnostics go) and its log: the newest setpoint's age in simulated time (what OFFB_LOSS_T is
        measured in) and on the wall clock since it reached the socket, and how far behind the wall clock the
        vehicle itself is. A wall age under OFFB_LOSS_T / speed means the simulator, not the stream, fell behind."""
        now = time.monotonic()
        behind = 0.0 if self.lockstep else max(0.0, self.pacing.behind_s(now, self.vehicle.t))
        text = (
            f"OFFB lost: last {self.vehicle.offboard_age_s:.2f}s sim "
            f"{now - self._setpoint_arrived_at:.2f}s wall lag {behind:.2f}s"
        )
        log.warning("%s", text)
        self.send(mavlink.MAVLink_statustext_message(mavlink.MAV_SEVERITY_DEBUG, text.encode()[:50]))

    # ----- flight log (CSV: one row per outer tick)
    LOG_COLUMNS = (
        "t",
        "mode",
        "armed",
        "source",
        "x",
        "y",
        "z",
        "vx",
        "vy",
        "vz",
        "roll",
        "pitch",
        "yaw",
        "x_est",
        "y_est",
        "z_est",
        "vx_est",
        "vy_est",
        "vz_est",
        "roll_est",
        "pitch_est",
        "yaw_est",
        "x_ref",
        "y_ref",
        "z_ref",
        "vx_ref",
        "vy_ref",
        "vz_ref",
        "ax_ref",
        "ay_ref",
        "az_ref",
        "yaw_ref",
        "qw_cmd",
        "qx_cmd",
        "qy_cmd",
        "qz_cmd",
        "thrust_cmd",
        "wind_n",
        "wind_e",
        "wind_d",
        "ext_acc_n",
        "ext_acc_e",
        "ext_acc_d",
        "mission_seq",
        "offboard_age",
    )

    def _open_log(self, path: Path) -> None:
        self._log_file = open(path, "w", newline="")  # noqa: SIM115 (closed in close())
        self._log_writer = csv.writer(self._log_file)
        self._log_writer.writerow(self.LOG_COLUMNS)

    def _write_log(self, r: TickRecord) -> None:
        v = self.vehicle
        truth, est, sp, target = r.truth, r.estimate, r.setpoint, r.target
        dist = r.disturbance
        row = [round(r.t, 4), v.mode.label, int(v.armed), r.source]
        row += [*truth.position, *truth.velocity, *euler_from_quat(truth.quaternion)]
        row += [*est.position, *est.velocity, *euler_from_quat(est.quaternion)]
        row += [*sp.position, *sp.velocity, *sp.acceleration, sp.yaw]
        row += [*target.quaternion, target.thrust]
        row += [*dist.get("wind_ned", (0, 0, 0)), *dist.get("external_accel_ned", (0, 0, 0))]
        row += [v.navigator.current_seq, min(v.offboard_age_s, 1e6)]
        self._log_writer.writerow([f"{x:.5g}" if isinstance(x, float) else x for x in row])

    def stats(self) -> dict:
        """Counters for --stats: ticks, pacing, link drops, mission transfers."""

        def percentiles(lateness_s: list[float]) -> dict[str, float | None]:
            ms = sorted(x * 1000 for x in lateness_s)

            def percentile(q: float) -> float | None:
                return ms[min(len(ms) - 1, int(q * len(ms)))] if ms else None

            return {"p50": percentile(0.5), "p99": percentile(0.99), "max": percentile(1.0)}

        link = self.link.stats
        return {
            "simulated_s": self.vehicle.t,
            "ticks": round(self.vehicle.t / self.vehicle.outer_dt),
            "tick_lateness_ms": percentiles(self.tick_lateness_s[50:]),  # skip start-up
            "tick_lateness_armed_ms": percentiles(self.armed_lateness_s),
            "link": {k: v for k, v in vars(link).items() if k != "by_type"} | {"dropped": link.dropped},
            "received_by_type": dict(link.by_type),
            "handler_errors": self.handler_errors,
            "mission_uploads": {"completed": self.mission.transfers_completed, "failed": self.mission.transfers_failed},
            "offboard_setpoints": self.vehicle.offboard.count,
            "log_data_sent": self.log_transfer.pieces_sent if self.log_transfer is not None else None,
            "motor_saturated_ticks": self.vehicle.saturated_ticks,
            "camera": self.camera.stats() if self.camera is not None else None,
            "ais": self.ais_out.stats() if self.ais_out is not None else None,
        }

    def close(self) -> None:
        if self.flight_logs is not None:
            self.flight_logs.close()
        if self.payload is not None:
            self.payload.close()
        if self._log_file is not None:
            self._log_file.close()
            self._log_file = self._log_writer = None
        if self.ais_out is not None:
            self.ais_out.close()
        self.link.close()
