"""The controller families and how one flight is flown and recorded, in the in-process lockstep harness.

Controllers (each family's gains for both loops follow from its design numbers and the airframe,
adrc_offboard.design; the shipped designs are adrc_offboard/gains/design.json, tuned by `python -m bench.tune`):
- "adrc": ADRC outer loop (adrc_offboard.outer_loop.AdrcOuterLoop) + ADRC inner loop (MC_ATT_CTRL = 1): the
  paper's cascade dual ADRC, in this project's form (no outer TD: the navigator's smooth reference and its
  derivatives are the TD's outputs; the measured velocity as the rate);
- "adrc_paper": the paper's literal cascade: the same loops with the TD in the outer loop and e2 from the ESO's z2;
- "pid": PID outer loop (PidOuterLoop) + the vehicle's PX4-style PID attitude loop (MC_ATT_CTRL = 0) at the PID
  family's design;
- "geometric": Lee, Leok and McClamroch's geometric tracking controller on SE(3) (2010), the reference most
  quadrotor simulators ship: adrc_offboard.geometric.GeometricOuterLoop + the vehicle's geometric attitude loop
  (MC_ATT_CTRL = 2), at the geometric family's design (no integral action: Lee's law has none);
- "px4": the vehicle's built-in PX4-default PID cascade, no offboard controller ("PX4 defaults", untuned).

`fly` flies the scenario's mission and records every outer-loop tick (`FlightRecorder`: with the outer ESO's
states and, for the ADRC inner loop, its three attitude ESOs'); `step_response` hovers at 5 m in still air (sensor
noise and D terms on) and then steps the reference 5 m east. Both take a `design` to fly instead of the shipped one
(the tuning's trials).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from adrc_offboard.adrc import P_B0, S_Z1, S_Z2, S_Z3
from adrc_offboard.adrc_attitude import AXES, L_ACTUATOR, L_THETA, AdrcAttitudeController
from adrc_offboard.design import Design, load_design, outer_loop_for, pid_attitude_gains
from adrc_offboard.outer_loop import AdrcOuterLoop
from bench.control.metrics import flight_metrics, step_metrics
from bench.control.scenario import OUTER_RATE_HZ, STEP_HOVER_S, STEP_M, STEP_WINDOW_S, Scenario, hover_mission
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.attitude_pid import PidAttitudeGains
from sitl_quad.config import AttitudeControllerKind, VehicleConfig
from sitl_quad.lockstep_harness import HarnessError, LockstepHarness
from sitl_quad.vehicle import TickRecord, Vehicle
from sitl_quad.wind import WindConfig
from uavcore.airframe import ModelParameterError
from uavcore.control import OuterLoopController
from uavcore.mission import MissionItem
from uavcore.rotation import euler_from_quat, heading
from uavcore.state import TrajectorySetpoint, VehicleState

CONTROLLERS = ("adrc", "adrc_paper", "pid", "geometric", "px4")
TUNED = ("adrc", "adrc_paper", "pid", "geometric")  # the families with a design (px4 flies the vehicle's defaults)
LABELS = {
    "adrc": "ADRC outer + ADRC inner (cascade dual ADRC)",
    "adrc_paper": "ADRC as in the paper (outer TD, ESO z2) + ADRC inner",
    "pid": "PID outer + PID inner",
    "px4": "PX4 defaults (built-in PID cascade)",
    "geometric": "Geometric SE(3) (Lee 2010), same attitude bandwidth",
}
INNER_LOOP = {  # MC_ATT_CTRL per family; others: the PID
    "adrc": AttitudeControllerKind.ADRC,
    "adrc_paper": AttitudeControllerKind.ADRC,
    "geometric": AttitudeControllerKind.GEOMETRIC,
}


def make_controller(kind: str, config: VehicleConfig, design: Design | None = None) -> OuterLoopController | None:
    """The offboard outer loop of controller `kind` for the airframe the controllers are designed for
    (config.controller_airframe: the true one unless the config names a design airframe) at `design` (the shipped
    one by default); None for "px4": the vehicle flies its own cascade."""
    if kind == "px4":
        return None
    return outer_loop_for(kind, config.controller_airframe, design, rate_hz=OUTER_RATE_HZ)


def configure_vehicle(kind: str, config: VehicleConfig, design: Design | None = None) -> VehicleConfig:
    """`config` with the inner loop of family `kind` selected (MC_ATT_CTRL) and, for the PID family, its designed
    attitude gains (the "px4" row keeps the vehicle's PX4 defaults)."""
    inner = INNER_LOOP.get(kind, AttitudeControllerKind.PID)
    config = replace(config, control=replace(config.control, attitude_controller=inner))
    if kind == "pid":
        design = design if design is not None else load_design("pid")
        gains = pid_attitude_gains(config.controller_airframe, design)
        config = replace(config, attitude_pid=PidAttitudeGains(**gains))
    return config


# the inner (attitude) loop's columns, per axis of adrc_attitude.AXES (roll, pitch, yaw), in rad, rad/s, rad/s^2:
INNER_COLUMNS = tuple(
    f"{name}_{axis}"
    for axis in AXES
    for name in (
        "att",  # the true Euler angle (ZYX; near level att_yaw equals the "yaw" column, the body x axis' heading)
        "att_ref",  # the attitude target's Euler angle (what the outer loop asked for)
        "rate",  # the true body rate p, q, r
        "iz1",  # the inner ADRC's ESO z1: estimate of its channel's angle (theta_i, below)
        "iz2",  # ... z2: estimate of the body rate
        "iz3",  # ... z3: estimate of the total disturbance f_i in theta_i'' = f_i + b0_i u_i (rad/s^2)
        "itheta",  # the channel's measured output theta_i: the body rate integrated (a bookkeeping angle)
        "iext",  # the true external angular acceleration: eq. 1's gyroscopic coupling + D_angular (any controller)
        "if",  # the true total disturbance z3 estimates: body angular acceleration - b0_i u_i (see below)
    )
)


class FlightRecorder:
    """Per-tick series of one flight (called by the harness after each vehicle tick, before the exchange).

    The outer loop's ESO columns (z1_x .. z3_z) are its states after its last update, which answered the
    previous tick. The inner ADRC's (iz1_roll .. if_yaw, INNER_COLUMNS) are sampled here, at the outer tick
    (50 Hz), from the attitude loop that runs at 250 Hz: the state after the last of the tick's five attitude
    steps; NaN when the vehicle flies its PID attitude loop. The true inner disturbance if_i is defined against
    the ESO's own model theta_i'' = f_i + b0_i u_i: f_i = (body angular acceleration) - b0_i u_i with the body's
    angular acceleration from the simulator at the end of the tick (external_angular_accel +
    rotor_angular_accel: gyroscopic coupling, D_angular and the torque the rotors deliver, per inertia) and u_i
    the torque the ESO believes the rotors deliver (its first-order actuator model's output). So if_i holds the
    D terms, the couplings and the model's error (the real motor lag, mixer saturation); iext_i the first two.
    """

    COLUMNS = (
        "t",
        "x",
        "y",
        "z",
        "yaw",
        "x_ref",
        "y_ref",
        "z_ref",
        "yaw_ref",
        "yaw_rate_ref",
        "seq",
        "thrust",
        "qw",
        "qx",
        "qy",
        "qz",
        "ext_x",
        "ext_y",
        "ext_z",
        "saturated",
        "offboard",
        "z1_x",
        "z1_y",
        "z1_z",
        "z2_x",
        "z2_y",
        "z2_z",
        "z3_x",
        "z3_y",
        "z3_z",
        "vx",
        "vy",
        "vz",
        *INNER_COLUMNS,
    )

    def __init__(self, harness: LockstepHarness) -> None:
        self.harness = harness
        self.rows: list[list[float]] = []
        self._saturated = harness.vehicle.saturated_ticks

    def __call__(self, record: TickRecord) -> None:
        vehicle = self.harness.vehicle
        truth, sp, target = record.truth, record.setpoint, record.target
        ext = record.disturbance.get("external_accel_ned", np.zeros(3))
        saturated = vehicle.saturated_ticks - self._saturated
        self._saturated = vehicle.saturated_ticks
        controller = self.harness.controller
        eso = controller.telemetry() if isinstance(controller, AdrcOuterLoop) else {}
        inner = self._inner(record, vehicle.loop.attitude)
        self.rows.append(
            [
                record.t,
                *truth.position,
                heading(truth.quaternion),
                *sp.position,
                sp.yaw,
                sp.yaw_rate,
                vehicle.navigator.current_seq,
                target.thrust,
                *target.quaternion,
                *ext,
                saturated,
                float(record.source == "offboard"),
                *(eso.get(f"{name}_{axis}", math.nan) for name in ("z1", "z2", "z3") for axis in "xyz"),
                *truth.velocity,
                *inner,
            ]
        )

    @staticmethod
    def _inner(record: TickRecord, attitude: object) -> list[float]:
        """INNER_COLUMNS' values for this tick (the class docstring)."""
        truth = record.truth
        true_angles = euler_from_quat(truth.quaternion)
        target_angles = euler_from_quat(record.target.quaternion)
        nan3 = np.full(3, math.nan)
        external = np.asarray(record.disturbance.get("external_angular_accel", nan3), dtype=float)
        rotors = np.asarray(record.disturbance.get("rotor_angular_accel", nan3), dtype=float)
        adrc = isinstance(attitude, AdrcAttitudeController)
        values = []
        for i in range(3):
            if adrc:
                state = attitude.channel_states[i]
                b0 = attitude.channel_params[i][P_B0]
                u = attitude.loop_state[L_ACTUATOR + i]
                eso = [state[S_Z1], state[S_Z2], state[S_Z3], attitude.loop_state[L_THETA + i]]
                true_f = external[i] + rotors[i] - b0 * u
            else:
                eso, true_f = [math.nan] * 4, math.nan
            values += [true_angles[i], target_angles[i], truth.angular_velocity[i], *eso, external[i], true_f]
        return [float(v) for v in values]

    def series(self) -> dict[str, np.ndarray]:
        data = np.asarray(self.rows, dtype=float)
        return {name: data[:, i] for i, name in enumerate(self.COLUMNS)}


def _lockstep(
    kind: str, config: VehicleConfig, scenario: Scenario, seed: int, design: Design | None
) -> LockstepHarness:
    config = configure_vehicle(kind, config, design)
    adrc_design = design if kind in ("adrc", "adrc_paper") else None
    loops = attitude_loops(adrc_design=adrc_design, geometric_design=design if kind == "geometric" else None)
    vehicle = Vehicle(config, scenario.home, seed=seed, outer_rate_hz=OUTER_RATE_HZ, attitude_loops=loops)
    return LockstepHarness(vehicle, make_controller(kind, config, design), outer_rate_hz=OUTER_RATE_HZ)


def fly(
    kind: str,
    seed: int,
    scenario: Scenario,
    paper_disturbance: bool = False,
    design: Design | None = None,
    items: list[MissionItem] | None = None,
    config: VehicleConfig | None = None,
    timeout_s: float = 900.0,
    observe: Callable[[TickRecord, LockstepHarness], None] | None = None,
) -> tuple[dict, dict[str, np.ndarray]]:
    """One mission (the scenario's, or `items`) at `design` (the family's shipped one by default), in the scenario's
    air or on `config`; returns (metrics, per-tick series). A flight still going timeout_s (simulated) after the
    mission start is cut there and counts as not completed. `observe`, if given, sees every tick's record with the
    harness after the recorder has it (what a caller wants beyond the metrics: the wind met, the vehicle's texts).

    Besides the metrics: `completed`, `mission_state` (the navigator's at the end) and `failure` (why a flight that
    did not complete ended: the harness's or the model's error, else the mission's state and the vehicle's last
    STATUSTEXT, a crash or a failsafe; empty when it completed)."""
    config = config if config is not None else scenario.config(paper_disturbance)
    harness = _lockstep(kind, config, scenario, seed, design)
    recorder = FlightRecorder(harness)
    texts: list[str] = []

    def on_tick(record: TickRecord) -> None:
        recorder(record)
        texts.extend(e.text for e in harness.last_events if e.kind == "text" and e.text)
        if observe is not None:
            observe(record, harness)

    failure = ""
    try:
        harness.fly_mission(items or scenario.items, idle_ticks=60, timeout_s=timeout_s, on_tick=on_tick)
    except (HarnessError, ModelParameterError) as exc:
        failure = f"{type(exc).__name__}: {exc}"[:200]
    vehicle = harness.vehicle
    state = vehicle.navigator.mission_state
    if not failure and state != "complete":  # ended without an error: say how (a crash, a failsafe)
        failure = f"mission {state}, vehicle {'armed' if vehicle.armed else 'disarmed'}" + (
            f": {texts[-1]}" if texts else ""
        )
    series = recorder.series()
    metrics = flight_metrics(series, scenario, len(items or scenario.items)) if recorder.rows else {}
    metrics.update(completed=not failure, mission_state=state, failure=failure)
    return metrics, series


class StepReference:
    """Stands in for the vehicle's navigator during the step experiment: a fixed position (a step from the
    hover point) with what the vehicle reads of a navigator in an active mission."""

    activity = "mission"
    is_landing = False
    mission_state = "active"

    def __init__(self, position: np.ndarray, yaw: float, current_seq: int) -> None:
        self.position, self.yaw, self.current_seq = position, yaw, current_seq

    def update(self, t: float, state: VehicleState) -> TrajectorySetpoint:
        return TrajectorySetpoint(position=self.position.copy(), yaw=self.yaw)

    def pop_events(self) -> list:
        return []


def step_response(
    kind: str,
    seed: int,
    scenario: Scenario,
    design: Design | None = None,
) -> tuple[dict, np.ndarray]:
    """Hover at 5 m in still air, then a 5 m step east; returns metrics and [t, east] after the step."""
    config = scenario.config()
    config.wind = WindConfig()
    harness = _lockstep(kind, config, scenario, seed, design)
    vehicle = harness.vehicle
    harness.upload_mission(hover_mission(scenario.home))
    harness.arm()
    for _ in range(60):
        harness.step()
    harness.start_mission()
    for _ in range(round(STEP_HOVER_S * OUTER_RATE_HZ)):
        harness.step()
    start = vehicle.setpoint.position.copy()
    vehicle.navigator = StepReference(start + np.array([0.0, STEP_M, 0.0]), 0.0, vehicle.navigator.current_seq)
    east = []
    for _ in range(round(STEP_WINDOW_S * OUTER_RATE_HZ)):
        record = harness.step()
        east.append(record.truth.position[1] - start[1])
    east = np.asarray(east)
    t = (np.arange(east.size) + 1) / OUTER_RATE_HZ
    return step_metrics(t, east), np.column_stack([t, east])
