"""The vehicle's inner loop with the PID attitude controller, compiled as one numba kernel.

One outer tick (50 Hz) holds several attitude steps (250 Hz), each: measure the state (sensor noise), the PID
attitude law, the mixer, clip the rotor commands, then several RK4 physics steps with wind and disturbances.
Stepping that from Python costs ~70 us per attitude step in call overhead; here it is one call per tick.
Every law is the kernel its own module defines (add_sensor_noise, pid_attitude_torque, mix, advance): this
module only orders the calls, exactly as Vehicle.tick() does step by step, so both paths give the same
numbers. Simulator.run_pid_attitude_steps prepares the random draws and keeps the books.

numba's on-disk cache is invalidated by edits to a kernel's own file only, not to the kernels it calls from
other modules: after changing one of those, delete sitl_quad/__pycache__/*.nbi (tests/test_sitl_fused_loop.py
fails on a stale cache, as the step-by-step path then runs newer code).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sitl_quad.attitude_pid import pid_attitude_torque
from sitl_quad.rigid_body import STATE_SIZE, advance
from sitl_quad.rotors import mix
from sitl_quad.sensors import add_sensor_noise
from uavcore.airframe import P_OMEGA_MAX, P_OMEGA_MIN


@njit(cache=True)
def disturbance_samples_due(first: int, steps: int, steps_per_sample: int) -> int:
    """How many new disturbance samples steps physics steps from step number first take: the multiples of
    steps_per_sample in [first, first + steps)."""
    return (first + steps - 1) // steps_per_sample - (first - 1) // steps_per_sample


@njit(cache=True)
def pid_inner_loop(
    state: np.ndarray,
    omega_cmd: np.ndarray,
    params: np.ndarray,
    wind_params: np.ndarray,
    turbulence: np.ndarray,
    turbulence_noise: np.ndarray,
    disturbance: np.ndarray,
    disturbance_samples: np.ndarray,
    steps_per_sample: int,
    step_index: int,
    dt: float,
    info: np.ndarray,
    sensor_noise: np.ndarray,
    gains: np.ndarray,
    pid_state: np.ndarray,
    qd: np.ndarray,
    feedforward: np.ndarray,
    attitude_dt: float,
    thrust_n: float,
    apply_torque: bool,
    attitude_steps: int,
    physics_steps: int,
    saturated: np.ndarray,
) -> tuple[int, bool]:
    """Run attitude_steps attitude steps of physics_steps physics steps each, from step number step_index.

    The arguments are advance()'s (turbulence_noise and disturbance_samples covering all the steps),
    sensor_noise (one row per attitude step, see Sensors.noise), the PID's gains and state and the target
    quaternion qd with feed-forward rates, the collective thrust thrust_n (N), and apply_torque: False
    mixes zero torque (the PID still runs, its output unused). saturated[k] is set to whether the mixer
    saturated at step k. Returns (attitude steps completed, whether the body ends on the ground): a step stops
    the loop, before its rotor commands and physics, when the mixer's input is not finite.
    """
    measured = np.empty(STATE_SIZE)
    torque = np.empty(3)
    omega = np.empty(4)
    lo, hi = params[P_OMEGA_MIN], params[P_OMEGA_MAX]
    on_ground = state[2] >= 0.0
    sample = 0
    for k in range(attitude_steps):
        add_sensor_noise(state, sensor_noise[k], measured)
        pid_attitude_torque(gains, pid_state, measured[6:10], measured[10:13], qd, feedforward, attitude_dt, torque)
        if not apply_torque:
            torque[:] = 0.0
        if not (
            math.isfinite(thrust_n)
            and math.isfinite(torque[0])
            and math.isfinite(torque[1])
            and math.isfinite(torque[2])
        ):
            return k, on_ground
        saturated[k] = mix(thrust_n, torque[0], torque[1], torque[2], params, omega)
        for i in range(4):
            omega_cmd[i] = min(max(omega[i], lo), hi)
        first = step_index + k * physics_steps
        samples = disturbance_samples_due(first, physics_steps, steps_per_sample)
        on_ground = advance(
            state,
            omega_cmd,
            params,
            wind_params,
            turbulence,
            turbulence_noise[k * physics_steps : (k + 1) * physics_steps],
            disturbance,
            disturbance_samples[sample : sample + samples],
            steps_per_sample,
            first,
            dt,
            physics_steps,
            info,
        )
        sample += samples
    return attitude_steps, on_ground
