"""The 6-DOF rigid body (paper eq. 1-3) as numba kernels on one flat float64 state array.

State layout (17 floats): position NED [0:3] m, velocity NED [3:6] m/s, attitude quaternion w,x,y,z body
FRD -> world NED [6:10], body rates p,q,r [10:13] rad/s, rotor speeds [13:17] rad/s.

Dynamics, in NED (the paper's eq. 2 is written z up; here gravity is +g on z):
    m dv/dt = R(q) (F_thrust + F_drag) + m g e_z + m D_xyz
        F_thrust = [0, 0, -U1], U1 = kl sum(Omega_i^2)                           eq. (2), (3)
        F_drag   = -(c_lin + c_quad |v_b|) v_b per body axis, v_b = R^T (v - wind)
    I dw/dt = tau - w x (I w) + I D_angular                                       eq. (1)
        i.e. dp/dt = q r (Iy - Iz)/Ix + L U2/Ix + D_phi, and likewise for q and r: eq. (1)'s gyroscopic
        coupling terms, written with body rates instead of Euler-angle rates (exact for any attitude).
    dq/dt = q (x) [0, w] / 2   (quaternion: no gimbal lock; Euler angles are only reported)
    dOmega/dt = (clip(Omega_cmd) - Omega) / tau_motor
Integration: classic RK4 with rotor commands, wind and disturbances held over the step; the quaternion is
renormalised after each step.

Ground: z >= 0 is ground. After a step that ends at or below it the body is put on the ground: z = 0,
velocity and body rates zero, roll and pitch levelled, yaw kept. The vehicle thus rests while thrust is
below its weight and lifts off as soon as a step ends above the ground. The D terms do not act on a body
that starts a step on the ground (the ground holds it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from sitl_quad.rotors import rotor_wrench
from sitl_quad.wind import mean_and_gust, wind_velocity
from uavcore.airframe import (
    P_DRAG_LIN_XY,
    P_DRAG_LIN_Z,
    P_DRAG_QUAD_XY,
    P_DRAG_QUAD_Z,
    P_G,
    P_IXX,
    P_IYY,
    P_IZZ,
    P_MASS,
    P_MOTOR_TAU,
    P_OMEGA_MAX,
    P_OMEGA_MIN,
    Airframe,
)
from uavcore.kernel_cache import cached_kernel

STATE_SIZE = 17
P_ROTOR_HEALTH = len(Airframe.field_names())  # physics_params(): the four rotors' health after the airframe
POS, VEL, QUAT, RATES, ROTORS = slice(0, 3), slice(3, 6), slice(6, 10), slice(10, 13), slice(13, 17)
# last-step disturbance report written by advance(): wind NED [0:3], D_xyz [3:6], D_angular [6:9], external
# acceleration NED [9:12] (drag + D_xyz), and at the step's end the body's angular acceleration split in two:
# external [12:15] (eq. 1's gyroscopic coupling + D_angular, rad/s^2 about the body axes) and the rotors' [15:18]
# (the torque the spinning rotors deliver / inertia): the attitude loop's true disturbance is their sum minus
# what its model says the command does (see bench/control/flight.py's FlightRecorder)
INFO_SIZE = 18


@cached_kernel
def body_to_world(q: np.ndarray, vx: float, vy: float, vz: float) -> tuple[float, float, float]:
    w, x, y, z = q[0], q[1], q[2], q[3]
    return (
        (1 - 2 * (y * y + z * z)) * vx + 2 * (x * y - w * z) * vy + 2 * (x * z + w * y) * vz,
        2 * (x * y + w * z) * vx + (1 - 2 * (x * x + z * z)) * vy + 2 * (y * z - w * x) * vz,
        2 * (x * z - w * y) * vx + 2 * (y * z + w * x) * vy + (1 - 2 * (x * x + y * y)) * vz,
    )


@cached_kernel
def world_to_body(q: np.ndarray, vx: float, vy: float, vz: float) -> tuple[float, float, float]:
    w, x, y, z = q[0], q[1], q[2], q[3]
    return (
        (1 - 2 * (y * y + z * z)) * vx + 2 * (x * y + w * z) * vy + 2 * (x * z - w * y) * vz,
        2 * (x * y - w * z) * vx + (1 - 2 * (x * x + z * z)) * vy + 2 * (y * z + w * x) * vz,
        2 * (x * z + w * y) * vx + 2 * (y * z - w * x) * vy + (1 - 2 * (x * x + y * y)) * vz,
    )


@cached_kernel
def drag_acceleration(state: np.ndarray, params: np.ndarray, wind: np.ndarray) -> tuple[float, float, float]:
    """World-frame acceleration (m/s^2) of the aerodynamic drag on the air-relative velocity."""
    q = state[6:10]
    bx, by, bz = world_to_body(q, state[3] - wind[0], state[4] - wind[1], state[5] - wind[2])
    c_xy, k_xy = params[P_DRAG_LIN_XY], params[P_DRAG_QUAD_XY]
    c_z, k_z = params[P_DRAG_LIN_Z], params[P_DRAG_QUAD_Z]
    fx = -(c_xy + k_xy * abs(bx)) * bx
    fy = -(c_xy + k_xy * abs(by)) * by
    fz = -(c_z + k_z * abs(bz)) * bz
    ax, ay, az = body_to_world(q, fx, fy, fz)
    m = params[P_MASS]
    return ax / m, ay / m, az / m


@cached_kernel
def derivative(
    state: np.ndarray,
    omega_cmd: np.ndarray,
    params: np.ndarray,
    wind: np.ndarray,
    d_accel: np.ndarray,
    d_angular: np.ndarray,
) -> np.ndarray:
    """d(state)/dt, eq. (1)-(3) plus drag and motor lag (see the module docstring)."""
    out = np.empty(17)
    q = state[6:10]
    p, qr, r = state[10], state[11], state[12]
    thrust, tau_x, tau_y, tau_z = rotor_wrench(state[13:17], params)
    m = params[P_MASS]
    tx, ty, tz = body_to_world(q, 0.0, 0.0, -thrust / m)
    dx, dy, dz = drag_acceleration(state, params, wind)
    out[0], out[1], out[2] = state[3], state[4], state[5]
    out[3] = tx + dx + d_accel[0]
    out[4] = ty + dy + d_accel[1]
    out[5] = tz + dz + params[P_G] + d_accel[2]
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[6] = 0.5 * (-x * p - y * qr - z * r)
    out[7] = 0.5 * (w * p + y * r - z * qr)
    out[8] = 0.5 * (w * qr - x * r + z * p)
    out[9] = 0.5 * (w * r + x * qr - y * p)
    ixx, iyy, izz = params[P_IXX], params[P_IYY], params[P_IZZ]
    out[10] = qr * r * (iyy - izz) / ixx + tau_x / ixx + d_angular[0]  # eq. (1), roll
    out[11] = r * p * (izz - ixx) / iyy + tau_y / iyy + d_angular[1]  # eq. (1), pitch
    out[12] = p * qr * (ixx - iyy) / izz + tau_z / izz + d_angular[2]  # eq. (1), yaw
    lo, hi, tau_m = params[P_OMEGA_MIN], params[P_OMEGA_MAX], params[P_MOTOR_TAU]
    health = params.shape[0] >= P_ROTOR_HEALTH + 4  # physics_params() appended the ESCs' health
    for i in range(4):
        command = min(max(omega_cmd[i], lo), hi)
        if health and params[P_ROTOR_HEALTH + i] == 0.0:
            command = 0.0  # a blocked ESC (injected motor failure): the rotor spins down and stays stopped
        out[13 + i] = (command - state[13 + i]) / tau_m
    return out


def physics_params(airframe: Airframe, rotor_health: Sequence[float] = (1.0, 1.0, 1.0, 1.0)) -> np.ndarray:
    """The kernels' parameter array: the airframe's fields (Airframe.as_array()) then, per rotor, 1.0 while its ESC
    drives it and 0.0 once it is blocked (sitl_quad.failure_injection). An airframe-only array flies all four."""
    return np.concatenate([airframe.as_array(), np.asarray(rotor_health, dtype=np.float64)])


@cached_kernel
def rk4_step(
    state: np.ndarray,
    omega_cmd: np.ndarray,
    params: np.ndarray,
    wind: np.ndarray,
    d_accel: np.ndarray,
    d_angular: np.ndarray,
    dt: float,
) -> None:
    """One classic Runge-Kutta 4 step in place, then renormalise the quaternion."""
    k1 = derivative(state, omega_cmd, params, wind, d_accel, d_angular)
    k2 = derivative(state + 0.5 * dt * k1, omega_cmd, params, wind, d_accel, d_angular)
    k3 = derivative(state + 0.5 * dt * k2, omega_cmd, params, wind, d_accel, d_angular)
    k4 = derivative(state + dt * k3, omega_cmd, params, wind, d_accel, d_angular)
    for i in range(17):
        state[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    norm = math.sqrt(state[6] ** 2 + state[7] ** 2 + state[8] ** 2 + state[9] ** 2)
    for i in range(6, 10):
        state[i] /= norm


@cached_kernel
def ground_contact(state: np.ndarray) -> bool:
    """Put the body on the ground if it ended at or below z = 0; True when it is on the ground."""
    if state[2] < 0.0:
        return False
    w, x, y, z = state[6], state[7], state[8], state[9]
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    state[2] = 0.0
    for i in range(3, 6):
        state[i] = 0.0
    for i in range(10, 13):
        state[i] = 0.0
    state[6], state[7], state[8], state[9] = math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)
    return True


@cached_kernel
def advance(
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
    steps: int,
    info: np.ndarray,
) -> bool:
    """Run `steps` RK4 steps from step number step_index; returns whether the body ends on the ground.

    Per step: a new disturbance sample is taken from disturbance_samples whenever the step number is a
    multiple of steps_per_sample (zero-order hold) and acts unless the body starts the step on the ground
    (the paper's D terms are in-flight disturbances; lift-off is thrust against weight); the wind (mean +
    gust + turbulence advanced by one step) is evaluated at the step's start with the airspeed relative to
    the mean wind and gust.
    """
    wind = np.zeros(3)
    steady = np.zeros(3)
    applied = np.zeros(6)  # the D terms that act: none while the ground holds the body
    on_ground = state[2] >= 0.0
    next_sample = 0
    for k in range(steps):
        number = step_index + k
        if number % steps_per_sample == 0:
            disturbance[:] = disturbance_samples[next_sample]
            next_sample += 1
        t = number * dt
        mean_and_gust(wind_params, t, steady)
        airspeed = math.sqrt((state[3] - steady[0]) ** 2 + (state[4] - steady[1]) ** 2 + state[5] ** 2)
        wind_velocity(wind_params, turbulence, turbulence_noise[k], t, dt, -state[2], airspeed, wind)
        for i in range(6):
            applied[i] = 0.0 if on_ground else disturbance[i]
        rk4_step(state, omega_cmd, params, wind, applied[0:3], applied[3:6], dt)
        on_ground = ground_contact(state)
    dx, dy, dz = drag_acceleration(state, params, wind)
    info[0:3] = wind
    info[3:9] = applied
    info[9] = dx + applied[0]
    info[10] = dy + applied[1]
    info[11] = dz + applied[2]
    _, tau_x, tau_y, tau_z = rotor_wrench(state[13:17], params)
    p, qr, r = state[10], state[11], state[12]
    ixx, iyy, izz = params[P_IXX], params[P_IYY], params[P_IZZ]
    info[12] = qr * r * (iyy - izz) / ixx + applied[3]
    info[13] = r * p * (izz - ixx) / iyy + applied[4]
    info[14] = p * qr * (ixx - iyy) / izz + applied[5]
    info[15] = tau_x / ixx
    info[16] = tau_y / iyy
    info[17] = tau_z / izz
    return on_ground
