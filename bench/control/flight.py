"""The three controllers and how one flight is flown and recorded, in the in-process lockstep harness.

Controllers:
- "adrc": ADRC outer loop (adrc_offboard.outer_loop.AdrcOuterLoop) + ADRC inner loop (MC_ATT_CTRL = 1,
  gains/attitude_adrc.json): the paper's cascade dual ADRC.
- "pid": PID outer loop (PidOuterLoop) + the vehicle's PID attitude loop (MC_ATT_CTRL = 0).
  Both outer loops fly gains bench/tune_control.py found (results/control_tuning.json, rebuilt by
  outer_loop.matched_gains), at two operating points (__main__'s --tunings): one shared bandwidth with each
  controller's free parameter tuned with the same budget, and each controller's own best tuning;
  --shipped-gains flies adrc_offboard/gains/outer_*.json instead.
- "px4": the vehicle's built-in PX4-default PID cascade, no offboard controller ("PX4 defaults").

`fly` flies the scenario's mission and records every outer-loop tick (`FlightRecorder`); `step_response`
hovers at 5 m in still air (sensor noise and D terms on) and then steps the reference 5 m east.
"""

from __future__ import annotations

import math

import numpy as np

from adrc_offboard.outer_loop import AdrcOuterGains, AdrcOuterLoop, PidOuterGains, PidOuterLoop
from bench.control.metrics import flight_metrics, step_metrics
from bench.control.scenario import OUTER_RATE_HZ, STEP_HOVER_S, STEP_M, STEP_WINDOW_S, Scenario, hover_mission
from sitl_quad.attitude_loops import attitude_loops
from sitl_quad.config import VehicleConfig
from sitl_quad.lockstep_harness import HarnessError, LockstepHarness
from sitl_quad.vehicle import TickRecord, Vehicle
from sitl_quad.wind import WindConfig
from uavcore.mission import MissionItem
from uavcore.rotation import heading
from uavcore.state import TrajectorySetpoint, VehicleState

CONTROLLERS = ("adrc", "pid", "px4")
LABELS = {
    "adrc": "ADRC outer + ADRC inner (cascade dual ADRC)",
    "pid": "PID outer + PID inner, same bandwidth",
    "px4": "PX4 defaults (built-in PID cascade)",
}


def make_controller(
    kind: str, config: VehicleConfig, adrc_gains: AdrcOuterGains | None = None, pid_gains: PidOuterGains | None = None
) -> AdrcOuterLoop | PidOuterLoop | None:
    """The offboard outer loop of controller `kind` (None for "px4": the vehicle flies its own cascade), designed
    for config.controller_airframe (the true airframe unless the config names a design airframe)."""
    af = config.controller_airframe
    if kind == "adrc":
        return AdrcOuterLoop(af.mass, af.g, af.max_thrust_n, gains=adrc_gains, rate_hz=OUTER_RATE_HZ)
    if kind == "pid":
        return PidOuterLoop(af.mass, af.g, af.max_thrust_n, gains=pid_gains, rate_hz=OUTER_RATE_HZ)
    return None


class FlightRecorder:
    """Per-tick series of one flight (called by the harness after each vehicle tick, before the exchange)."""

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
            ]
        )

    def series(self) -> dict[str, np.ndarray]:
        data = np.asarray(self.rows, dtype=float)
        return {name: data[:, i] for i, name in enumerate(self.COLUMNS)}


def _lockstep(
    kind: str,
    config: VehicleConfig,
    scenario: Scenario,
    seed: int,
    adrc_gains: AdrcOuterGains | None,
    pid_gains: PidOuterGains | None,
) -> LockstepHarness:
    vehicle = Vehicle(config, scenario.home, seed=seed, outer_rate_hz=OUTER_RATE_HZ, attitude_loops=attitude_loops())
    controller = make_controller(kind, config, adrc_gains, pid_gains)
    return LockstepHarness(vehicle, controller, outer_rate_hz=OUTER_RATE_HZ)


def fly(
    kind: str,
    seed: int,
    scenario: Scenario,
    paper_disturbance: bool = False,
    adrc_gains: AdrcOuterGains | None = None,
    pid_gains: PidOuterGains | None = None,
    items: list[MissionItem] | None = None,
) -> tuple[dict, dict[str, np.ndarray]]:
    """One mission (the scenario's, or `items`); returns (metrics, per-tick series)."""
    harness = _lockstep(kind, scenario.config(kind, paper_disturbance), scenario, seed, adrc_gains, pid_gains)
    recorder = FlightRecorder(harness)
    completed = True
    try:
        harness.fly_mission(items or scenario.items, idle_ticks=60, on_tick=recorder)
    except HarnessError:
        completed = False
    completed = completed and harness.vehicle.navigator.mission_state == "complete"
    series = recorder.series()
    metrics = flight_metrics(series, scenario, len(items or scenario.items))
    metrics["completed"] = completed
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
    adrc_gains: AdrcOuterGains | None = None,
    pid_gains: PidOuterGains | None = None,
) -> tuple[dict, np.ndarray]:
    """Hover at 5 m in still air, then a 5 m step east; returns metrics and [t, east] after the step."""
    config = scenario.config(kind)
    config.wind = WindConfig()
    harness = _lockstep(kind, config, scenario, seed, adrc_gains, pid_gains)
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
