"""Quaternion and Euler helpers, and the thrust-vector -> attitude map shared by every position loop.

Quaternions are (w, x, y, z), body FRD -> world NED. Euler angles are ZYX: yaw psi about down, pitch theta,
roll phi. Scalar maths on floats: these run in 250 Hz and 50 Hz loops where numpy's per-call cost dominates.

Heading and yaw: the heading of an attitude is the direction of its body x axis projected on the horizontal
plane (`heading`), which is also the ZYX Euler yaw. A yaw setpoint means that heading (as in PX4), so
`acceleration_to_attitude` builds targets whose heading is exactly the commanded yaw at any tilt, and a yaw
error is heading minus yaw setpoint.
"""

from __future__ import annotations

import math

import numpy as np

from uavcore.state import AttitudeTarget


def quat_from_euler(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )


def euler_from_quat(q) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in radians; pitch clamped at +-90 deg where the ZYX form is singular."""
    w, x, y, z = (float(c) for c in q)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def heading(q) -> float:
    """Direction of the body x axis projected on the horizontal plane, radians from north toward east: atan2 of
    the east and north components of R(q) e_x. Identical to the ZYX Euler yaw (the first column of
    Rz(psi) Ry(theta) Rx(phi) is (cos psi cos theta, sin psi cos theta, -sin theta)); undefined when the body x
    axis points straight up or down."""
    w, x, y, z = (float(c) for c in q)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def quat_multiply(a, b) -> np.ndarray:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def quat_conjugate(q) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def matrix_from_quat(q) -> np.ndarray:
    """The 3x3 matrix taking body vectors to the world frame (as `rotate` does), of q normalised: for rotating
    many vectors at once (a camera's pixel rays)."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def rotate(q, v) -> np.ndarray:
    """Rotate the body vector v into the world frame by q."""
    w, x, y, z = q
    vx, vy, vz = v
    # v' = v + 2w (r x v) + 2 r x (r x v), r = (x, y, z)
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    return np.array(
        [
            vx + 2 * (w * cx + y * cz - z * cy),
            vy + 2 * (w * cy + z * cx - x * cz),
            vz + 2 * (w * cz + x * cy - y * cx),
        ]
    )


def wrap_pi(angle: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def acceleration_to_attitude(
    acceleration_ned,
    yaw: float,
    mass: float,
    g: float,
    max_thrust_n: float,
    max_tilt_rad: float = math.radians(35.0),
    yaw_rate: float = 0.0,
) -> AttitudeTarget:
    """Desired world acceleration + yaw -> attitude quaternion and normalised thrust (PX4's thrust vector), with the
    yaw rate as body-rate feed-forward.

    The rotors can only push along body -z, so the wanted specific force f = a - g (NED, g = +z) fixes the
    body z axis; yaw fixes the rest as PX4's ControlMath::bodyzToAttitude does: the body x axis is taken
    perpendicular to y_c = (-sin yaw, cos yaw, 0), i.e. in the vertical plane of the commanded heading, so the
    target's heading (`heading`) is the commanded yaw at any tilt. (Taking the body y axis perpendicular to
    x_c = (cos yaw, sin yaw, 0) instead biases the heading by up to 9 deg at a 35 deg tilt off the heading's
    plane.) The tilt is limited to max_tilt_rad keeping the vertical component, because altitude matters more
    than horizontal speed near the water. body_rates = R^T e_z yaw_rate (world down axis in the target's body
    axes): PX4's yaw-rate feed-forward, AttitudeControl::update's q^-1 dcm_z * yawspeed, with the target for q.
    """
    ax, ay, az = (float(c) for c in acceleration_ned)
    fx, fy, fz = ax, ay, az - g  # specific force wanted, NED (fz < 0 when pushing up)
    fz = min(fz, -0.1 * g)  # never ask to push down: rotors cannot
    horizontal = math.hypot(fx, fy)
    max_horizontal = -fz * math.tan(max_tilt_rad)
    if horizontal > max_horizontal:
        scale = max_horizontal / horizontal
        fx, fy = fx * scale, fy * scale
    norm = math.sqrt(fx * fx + fy * fy + fz * fz)
    # body z axis (down) points against the specific force
    zbx, zby, zbz = -fx / norm, -fy / norm, -fz / norm
    # body x axis: xb = y_c x zb with y_c = (-sin yaw, cos yaw, 0); never parallel, as zbz > 0 (tilt < 90 deg)
    ycx, ycy = -math.sin(yaw), math.cos(yaw)
    xbx, xby, xbz = ycy * zbz, -ycx * zbz, ycx * zby - ycy * zbx
    xn = math.sqrt(xbx * xbx + xby * xby + xbz * xbz)
    xbx, xby, xbz = xbx / xn, xby / xn, xbz / xn
    # yb = zb x xb completes the right-handed frame
    ybx, yby, ybz = zby * xbz - zbz * xby, zbz * xbx - zbx * xbz, zbx * xby - zby * xbx
    quaternion = _quat_from_matrix(xbx, ybx, zbx, xby, yby, zby, xbz, ybz, zbz)
    thrust = min(1.0, max(0.0, mass * norm / max_thrust_n))
    # R^T e_z is the third row of R = (xbz, ybz, zbz): the world down axis in the target's body axes
    body_rates = np.array([xbz, ybz, zbz]) * float(yaw_rate)
    return AttitudeTarget(quaternion=quaternion, thrust=thrust, body_rates=body_rates)


def quat_from_matrix(matrix) -> np.ndarray:
    """3x3 rotation matrix (columns = body axes in the world) -> unit quaternion (w >= 0)."""
    m = np.asarray(matrix, dtype=float)
    return _quat_from_matrix(*(float(v) for v in m.reshape(9)))


def _quat_from_matrix(
    m00: float, m01: float, m02: float, m10: float, m11: float, m12: float, m20: float, m21: float, m22: float
) -> np.ndarray:
    """Rotation matrix (columns = body axes in world) -> unit quaternion, Shepperd's method."""
    trace = m00 + m11 + m22
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    quaternion = np.array(q)
    if quaternion[0] < 0:
        quaternion = -quaternion
    return quaternion / np.linalg.norm(quaternion)
