"""SITL physics benchmark: speed of the simulated quadrotor, and its channels against the paper's Table 1.

    .venv/bin/python -m bench.sitl_physics       # prints the tables, writes bench/results/sitl_physics.json

Speed (simulated seconds per wall-clock second, best of 3; the machine is shared, so the load average is
recorded next to the figures):
- numba kernels: first-import compile time with an empty cache, and the cache-load time after it
- physics alone with wind (mean + gust + Dryden), the paper's D terms and sensor noise: RK4 steps in 50 Hz
  blocks of 20 (the lockstep tick) with one measurement each; target >= 40x real time
- what the vehicle runs: 250 Hz PID attitude loop + mixer + measurement, 50 Hz position loop, 1 kHz physics
Channels: from hover, a small step in each of the paper's inputs (U1 for altitude, U2 roll, U3 pitch, U4 yaw,
in newtons as eq. 3 defines them) drives the open-loop simulated body; two low-order models are fitted to the
response by least squares and compared with the paper's transfer functions (eq. 8, Table 1).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from sitl_quad.attitude_pid import PidAttitudeController
from sitl_quad.disturbances import DisturbanceConfig
from sitl_quad.position_control import PidPositionController
from sitl_quad.rotors import Mixer
from sitl_quad.sensors import SensorNoise
from sitl_quad.simulator import Simulator
from sitl_quad.wind import WindConfig
from uavcore.airframe import Airframe
from uavcore.rotation import euler_from_quat
from uavcore.state import TrajectorySetpoint

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
AIRFRAME = Airframe.table2()
WINDY = dict(
    wind=WindConfig(8.0, 270.0, gust_amplitude_m_s=4.0, gust_rise_time_s=0.1, gust_start_s=5.0, turbulence_w20_m_s=8.0),
    disturbance=DisturbanceConfig(),
    sensor_noise=SensorNoise(),
)
SIM_SECONDS = 20.0

# The paper's channel models, (numerator, denominator) coefficients, highest power first.
PAPER = {
    "roll (phi)": ((215.0, 593.0), (82.95, 4425.0, 0.0)),
    "pitch (theta)": ((301.4, 768.5), (86.0, 4488.0, 0.0)),
    "yaw (psi)": ((130.0,), (1.0, 435.0, 0.0)),
    "altitude (z up)": ((1.83,), (1.0, 4.0, 0.0)),
}


def import_and_compile_seconds() -> dict:
    """Wall time of `import numba` and of importing the simulator + first step, in fresh processes:
    once with an empty numba cache (compile) and once more with the cache it left (load)."""
    code = (
        "import time; t0 = time.perf_counter(); import numba; t1 = time.perf_counter(); "
        "from sitl_quad.simulator import Simulator; Simulator().step(1); "
        "print(t1 - t0, time.perf_counter() - t1)"
    )
    runs = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold_compile", "cached"):
            out = subprocess.run(
                [sys.executable, "-c", code], env=env, cwd=REPO, capture_output=True, text=True, check=True
            ).stdout.split()
            runs[label] = {"import_numba_s": float(out[0]), "simulator_ready_s": float(out[1])}
    return runs


def physics_alone(block: int) -> dict:
    """Simulated s per wall s for RK4 in blocks of `block` steps with wind, D terms and a measurement each."""
    best = math.inf
    for _ in range(3):
        sim = Simulator(AIRFRAME, seed=1, position=(0.0, 0.0, -5.0), rotor_speed=AIRFRAME.hover_rotor_speed, **WINDY)
        sim.set_rotor_commands(np.full(4, AIRFRAME.hover_rotor_speed))
        ticks = round(SIM_SECONDS / (block * sim.dt))
        started = time.perf_counter()
        for _ in range(ticks):
            sim.step(block)
            sim.measure()
        best = min(best, time.perf_counter() - started)
    steps = ticks * block
    return {"block_steps": block, "real_time_factor": SIM_SECONDS / best, "us_per_rk4_step": best / steps * 1e6}


def vehicle_loop() -> dict:
    """Simulated s per wall s of the vehicle's loop: 50 Hz position, 250 Hz attitude + mixer, 1 kHz RK4."""
    best, saturated = math.inf, 0.0
    setpoint = TrajectorySetpoint(position=np.array([0.0, 0.0, -5.0]))
    for _ in range(3):
        sim = Simulator(AIRFRAME, seed=1, position=(0.0, 0.0, -5.0), rotor_speed=AIRFRAME.hover_rotor_speed, **WINDY)
        attitude, position, mixer = PidAttitudeController(), PidPositionController(AIRFRAME), Mixer(AIRFRAME)
        started = time.perf_counter()
        target = None
        for k in range(round(SIM_SECONDS * 250)):
            if k % 5 == 0:
                target = position.update(setpoint, sim.measure(), 0.02)
            torque = attitude.update(target, sim.measure(), 0.004)
            sim.set_rotor_commands(mixer.rotor_commands(target.thrust * AIRFRAME.max_thrust_n, torque))
            sim.step(4)
        best = min(best, time.perf_counter() - started)
        saturated = mixer.saturated_steps / mixer.calls
    return {
        "real_time_factor": SIM_SECONDS / best,
        "us_per_attitude_tick": best / (SIM_SECONDS * 250) * 1e6,
        "motor_saturation_fraction": saturated,
    }


# ---------------------------------------------------------------- channel identification
def step_response(channel: str, size: float, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop response (rad, or m up) to a step of `size` N in the channel's U from exact hover."""
    sim = Simulator(AIRFRAME, position=(0.0, 0.0, -100.0), rotor_speed=AIRFRAME.hover_rotor_speed)
    arm, weight = AIRFRAME.arm_length, AIRFRAME.mass * AIRFRAME.g
    thrust, torque = weight, np.zeros(3)
    if channel == "altitude (z up)":
        thrust += size
    else:
        torque[["roll (phi)", "pitch (theta)", "yaw (psi)"].index(channel)] = arm * size  # moment = L U, eq. (1)
    sim.set_rotor_commands(Mixer(AIRFRAME).rotor_commands(thrust, torque))
    times, outputs = [], []
    for _ in range(round(seconds / sim.dt)):
        sim.step(1)
        state = sim.state
        value = (
            -state.position[2] - 100.0
            if channel == "altitude (z up)"
            else euler_from_quat(state.quaternion)[["roll (phi)", "pitch (theta)", "yaw (psi)"].index(channel)]
        )
        times.append(sim.t)
        outputs.append(value)
    return np.array(times), np.array(outputs) / size


def paper_structure_step(t: np.ndarray, b1: float, b0: float, a: float) -> np.ndarray:
    """Unit-step response of (b1 s + b0) / (s (s + a)), the form of every Table 1 entry."""
    return b0 / a * t + (b1 / a - b0 / a**2) * (1.0 - np.exp(-a * t))


def lagged_double_integrator_step(t: np.ndarray, k: float, tau: float) -> np.ndarray:
    """Unit-step response of k / (s^2 (tau s + 1)), eq. (1) behind a first-order motor."""
    return k * (t**2 / 2.0 - tau * t + tau**2 * (1.0 - np.exp(-t / tau)))


def fit_paper_structure(t: np.ndarray, y: np.ndarray, poles=None) -> dict:
    """Least-squares (b1, b0) for each candidate pole a (a grid unless given); the best one."""
    best = None
    for a in np.geomspace(0.01, 2000.0, 800) if poles is None else poles:
        basis = np.column_stack([(1.0 - np.exp(-a * t)) / a, t / a - (1.0 - np.exp(-a * t)) / a**2])
        (b1, b0), *_ = np.linalg.lstsq(basis, y, rcond=None)
        error = float(np.sqrt(np.mean((basis @ [b1, b0] - y) ** 2)))
        if best is None or error < best["rms_error"]:
            best = {"b1": float(b1), "b0": float(b0), "pole": float(-a), "rms_error": error}
    best["relative_rms_error"] = best["rms_error"] / float(np.sqrt(np.mean(y**2)))
    return best


def fit_lagged_double_integrator(t: np.ndarray, y: np.ndarray) -> dict:
    best = None
    for tau in np.geomspace(1e-4, 1.0, 800):
        shape = lagged_double_integrator_step(t, 1.0, tau)
        k = float(shape @ y / (shape @ shape))
        error = float(np.sqrt(np.mean((k * shape - y) ** 2)))
        if best is None or error < best["rms_error"]:
            best = {"k": k, "tau_s": float(tau), "rms_error": error}
    best["relative_rms_error"] = best["rms_error"] / float(np.sqrt(np.mean(y**2)))
    return best


FREQUENCIES = (1.0, 10.0, 50.0)  # rad/s


def magnitude(numerator, denominator, omega: float) -> float:
    s = 1j * omega
    return float(abs(np.polyval(numerator, s) / np.polyval(denominator, s)))


def channels() -> list[dict]:
    rows = []
    expected_k = {
        "roll (phi)": AIRFRAME.arm_length / AIRFRAME.ixx,
        "pitch (theta)": AIRFRAME.arm_length / AIRFRAME.iyy,
        "yaw (psi)": AIRFRAME.arm_length / AIRFRAME.izz,
        "altitude (z up)": 1.0 / AIRFRAME.mass,
    }
    for channel, (numerator, denominator) in PAPER.items():
        seconds = 1.0 if channel == "altitude (z up)" else 0.5
        t, y = step_response(channel, 0.5 if channel == "altitude (z up)" else 0.05, seconds)
        physical = fit_lagged_double_integrator(t, y)
        paper_form = fit_paper_structure(t, y)
        c2 = denominator[0]
        paper = {
            "b1": numerator[0] / c2 if len(numerator) == 2 else 0.0,
            "b0": numerator[-1] / c2,
            "pole": -denominator[1] / c2,
        }
        paper_pole_form = fit_paper_structure(t, y, poles=[-paper["pole"]])
        paper_step = paper_structure_step(t, paper["b1"], paper["b0"], -paper["pole"])
        rows.append(
            {
                "channel": channel,
                "expected_k_from_eq1": expected_k[channel],
                "motor_time_constant_s": AIRFRAME.motor_time_constant,
                "fit_k_over_s2_lag": physical,
                "fit_paper_form": paper_form,
                "fit_paper_form_with_paper_pole": paper_pole_form,
                "paper": paper,
                "response_at_end_per_newton": {
                    "simulated": float(y[-1]),
                    "paper_tf": float(paper_step[-1]),
                    "window_s": seconds,
                },
                "magnitude_at_rad_s": {
                    str(w): {
                        "paper": magnitude(numerator, denominator, w),
                        "simulated_fit": magnitude([physical["k"]], [physical["tau_s"], 1.0, 0.0, 0.0], w),
                    }
                    for w in FREQUENCIES
                },
            }
        )
    return rows


def prose(rows: list[dict]) -> str:
    """What the figures say, written from the measured numbers."""

    def name(row: dict) -> str:
        return row["channel"].split()[0]

    def ratios(w: str) -> str:
        cells = [(name(r), r["magnitude_at_rad_s"][w]) for r in rows]
        return ", ".join(f"{n} {c['simulated_fit'] / c['paper']:.2g}" for n, c in cells)

    k_error = max(abs(r["fit_k_over_s2_lag"]["k"] / r["expected_k_from_eq1"] - 1) for r in rows[:3])
    pinned = ", ".join(f"{name(r)} {r['fit_paper_form_with_paper_pole']['relative_rms_error']:.0%}" for r in rows)

    def free_pole(row: dict) -> str:  # 0.01 is the search grid's lower end: the pole would go lower still
        a = -row["fit_paper_form"]["pole"]
        return "<= 0.01" if a <= 0.0101 else f"{a:.2g}"

    free = ", ".join(f"{name(r)} {free_pole(r)}" for r in rows)
    return (
        "Table 1 models every channel as (b1 s + b0) / (s (s + a)): one free integrator and a fast real pole "
        "(a = 53 rad/s roll, 52 pitch, 435 yaw, 4 altitude), so the angle's rate follows the input like a "
        "first-order lag. The paper builds them as G_m G_e (eq. 5-8): the rigid body L/(I s^2) times "
        "G_e = k_D s / (tau_D s + 1), a filtered differentiator that cancels one integrator. The simulator "
        "integrates eq. (1)-(3) directly, so from the paper's inputs U (newtons, eq. 3) to angle it is a double "
        "integrator behind the motor lag: the open-loop step responses fit k / (s^2 (tau s + 1)) with "
        f"k within {k_error:.1%} of L/I and tau = the 0.02 s motor constant (altitude: 1/m, lowered a little by "
        "the vertical drag over the 1 s window). Fitting the paper's form with its own pole leaves relative "
        f"residuals of {pinned}; left free, that pole goes to {free} rad/s, i.e. the form only fits by turning "
        "into the double integrator (for altitude, the pole of the vertical drag, c_z / m = "
        f"{AIRFRAME.drag_linear_z / AIRFRAME.mass:.2f} rad/s). Magnitude ratios simulated/paper at 1 rad/s: "
        f"{ratios('1.0')}; at 10 rad/s: {ratios('10.0')}; at 50 rad/s: {ratios('50.0')}. So near the "
        "attitude loops' crossover (10-25 rad/s) the simulated roll, pitch and yaw channels have about the "
        "paper's gain, but below it they have one more integrator (much larger low-frequency gain, 90 deg more "
        "phase lag), and above it the 0.02 s motor lag instead of the paper's 2.3 ms filter. The simulator "
        "follows the paper's equations of motion and Table 2, not its Table 1 channel models."
    )


def main() -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()
    compile_times = import_and_compile_seconds()
    speed = {
        "physics_50hz_blocks": physics_alone(20),
        "physics_250hz_blocks": physics_alone(4),
        "vehicle_loop": vehicle_loop(),
    }
    channel_rows = channels()
    result = {
        "machine_load_average_1_5_15": load,
        "import_and_compile": compile_times,
        "speed": speed,
        "speed_targets": {"physics_real_time_factor_min": 40.0, "rk4_step_budget_us": 15.0},
        "channels": channel_rows,
        "channels_vs_paper": prose(channel_rows),
    }
    (RESULTS / "sitl_physics.json").write_text(json.dumps(result, indent=2) + "\n")

    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} (2 cores, shared)")
    print("\nnumba kernels              import numba   simulator ready")
    for label, run in compile_times.items():
        print(f"  {label:24s} {run['import_numba_s']:10.2f} s {run['simulator_ready_s']:12.2f} s")
    print("\nspeed                                   x real time   us per unit")
    p50, p250, loop = speed["physics_50hz_blocks"], speed["physics_250hz_blocks"], speed["vehicle_loop"]
    print(
        f"  physics, 20-step blocks + measure     {p50['real_time_factor']:8.1f}   "
        f"{p50['us_per_rk4_step']:6.2f} per RK4 step"
    )
    print(
        f"  physics, 4-step blocks + measure      {p250['real_time_factor']:8.1f}   "
        f"{p250['us_per_rk4_step']:6.2f} per RK4 step"
    )
    print(
        f"  vehicle loop (PID 250 Hz + mixer)     {loop['real_time_factor']:8.1f}   "
        f"{loop['us_per_attitude_tick']:6.2f} per 4 ms tick"
    )
    print("\nchannel          eq.1 k   fit k/(s^2(tau s+1))      fit (b1 s+b0)/(s(s+a))        paper Table 1")
    print("                           k       tau    rel.err    b1      b0      a    rel.err   b1      b0      a")
    for row in channel_rows:
        f, g, p = row["fit_k_over_s2_lag"], row["fit_paper_form"], row["paper"]
        print(
            f"  {row['channel']:15s} {row['expected_k_from_eq1']:6.3f} {f['k']:7.3f} {f['tau_s']:7.4f} "
            f"{f['relative_rms_error']:8.4f} {g['b1']:7.3f} {g['b0']:7.2f} {-g['pole']:6.1f} "
            f"{g['relative_rms_error']:7.3f} {p['b1']:7.3f} {p['b0']:7.3f} {-p['pole']:6.1f}"
        )
    print("\n|G(jw)|         " + "".join(f"  w={w:<4g} sim    paper" for w in FREQUENCIES))
    for row in channel_rows:
        cells = [row["magnitude_at_rad_s"][str(w)] for w in FREQUENCIES]
        print(f"  {row['channel']:15s}" + "".join(f"  {c['simulated_fit']:9.4f} {c['paper']:7.4f}" for c in cells))
    print("\n" + result["channels_vs_paper"])
    print(f"\nwrote {RESULTS / 'sitl_physics.json'}")


if __name__ == "__main__":
    main()
