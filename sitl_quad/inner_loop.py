"""The vehicle's inner loop compiled as one numba kernel per outer tick: attitude steps and physics.

One outer tick (50 Hz) holds several attitude steps (250 Hz), each: measure the state (sensor noise), the
attitude law, the mixer, clip the rotor commands, then several RK4 physics steps with wind and disturbances.
Stepping that from Python costs ~70 us per attitude step in call overhead; here it is one call per tick.
Every law is the kernel its own module defines (add_sensor_noise, the attitude law, mix, advance): this module
only orders the calls, exactly as FlightLoop.fly() does step by step, so both paths give the same numbers.
`pid_inner_loop` flies the vehicle's PID; an injected attitude loop brings its own loop of the same signature
built on `measure` and `fly_attitude_step` (sitl_quad.attitude_loops for the ADRC: the vehicle imports no
controller package). Simulator.run_attitude_steps prepares the random draws and keeps the books.

An inner loop's signature: (physics, sensor_noise, law, attitude_dt, thrust_n, apply_torque, attitude_steps,
physics_steps, saturated) -> (attitude steps completed, whether the body ends on the ground). physics is the
tuple `Simulator.physics_arguments` gives (advance()'s arguments, turbulence_noise and disturbance_samples
covering all the steps, step_index the first step's number); sensor_noise has one row per attitude step (see
Sensors.noise); law is the attitude law's own arguments (the controller's gains and state, the target);
thrust_n is the collective thrust (N); apply_torque False mixes zero torque (the law still runs, its output
unused); saturated[k] is set to whether the mixer saturated at step k. A step stops the loop, before its rotor
commands and physics, when the mixer's input is not finite.

numba's on-disk cache is invalidated by edits to a kernel's own file only, not to the kernels it calls from
other modules: after changing one of those, delete sitl_quad/__pycache__/*.nbi (tests/test_sitl_fused_loop.py
fails on a stale cache, as the step-by-step path then runs newer code).
"""

from __future__ import annotations

import math

import numpy as np

from sitl_quad.attitude_pid import pid_attitude_torque
from sitl_quad.rigid_body import STATE_SIZE, advance
from sitl_quad.rotors import mix
from sitl_quad.sensors import add_sensor_noise
from uavcore.airframe import P_OMEGA_MAX, P_OMEGA_MIN
from uavcore.kernel_cache import cached_kernel


@cached_kernel
def disturbance_samples_due(first: int, steps: int, steps_per_sample: int) -> int:
    """How many new disturbance samples steps physics steps from step number first take: the multiples of
    steps_per_sample in [first, first + steps)."""
    return (first + steps - 1) // steps_per_sample - (first - 1) // steps_per_sample


@cached_kernel
def measure(physics: tuple, sensor_noise: np.ndarray, k: int, measured: np.ndarray) -> None:
    """Attitude step k's measurement of the body (its row of sensor noise added) into measured."""
    add_sensor_noise(physics[0], sensor_noise[k], measured)


@cached_kernel
def fly_attitude_step(
    physics: tuple,
    k: int,
    physics_steps: int,
    thrust_n: float,
    torque: np.ndarray,
    apply_torque: bool,
    saturated: np.ndarray,
) -> tuple[bool, bool]:
    """The rest of attitude step k once the law gave its torque: mix (zero torque unless apply_torque), clip the
    rotor commands, physics_steps RK4 steps. Returns (whether the mixer's input was finite, whether the body
    is on the ground after the step); with a non-finite input nothing is commanded or stepped (and the second
    value means nothing)."""
    state, omega_cmd, params, wind_params, turbulence, turbulence_noise = physics[:6]
    disturbance, disturbance_samples, steps_per_sample, step_index, dt, info, mixer_params = physics[6:]
    if not apply_torque:
        torque[:] = 0.0
    if not (
        math.isfinite(thrust_n) and math.isfinite(torque[0]) and math.isfinite(torque[1]) and math.isfinite(torque[2])
    ):
        return False, False
    omega = np.empty(4)
    # the autopilot's mixer works with the airframe it was designed for (mixer_params), the body flies the true one
    saturated[k] = mix(thrust_n, torque[0], torque[1], torque[2], mixer_params, omega)
    lo, hi = mixer_params[P_OMEGA_MIN], mixer_params[P_OMEGA_MAX]
    for i in range(4):
        omega_cmd[i] = min(max(omega[i], lo), hi)
    first = step_index + k * physics_steps
    sample = disturbance_samples_due(step_index, k * physics_steps, steps_per_sample)  # drawn by earlier steps
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
    return True, on_ground


@cached_kernel
def pid_inner_loop(
    physics: tuple,
    sensor_noise: np.ndarray,
    law: tuple,
    attitude_dt: float,
    thrust_n: float,
    apply_torque: bool,
    attitude_steps: int,
    physics_steps: int,
    saturated: np.ndarray,
) -> tuple[int, bool]:
    """The inner loop (module docstring) with the PID attitude law; law = (gains, PID state, target quaternion,
    feed-forward body rates)."""
    gains, pid_state, qd, feedforward = law
    measured = np.empty(STATE_SIZE)
    torque = np.empty(3)
    on_ground = physics[0][2] >= 0.0
    for k in range(attitude_steps):
        measure(physics, sensor_noise, k, measured)
        pid_attitude_torque(gains, pid_state, measured[6:10], measured[10:13], qd, feedforward, attitude_dt, torque)
        finite, landed = fly_attitude_step(physics, k, physics_steps, thrust_n, torque, apply_torque, saturated)
        if not finite:
            return k, on_ground
        on_ground = landed
    return attitude_steps, on_ground
