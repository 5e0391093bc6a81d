"""Quaternion products for numba kernels: uavcore.rotation's formulas on tuples of floats.

The attitude laws (the vehicle's PID, ADRC and geometric inner loops) and the sensor noise run inside compiled
loops, where rotation's numpy helpers cannot be called. Same conventions: (w, x, y, z), body FRD -> world NED.
"""

from __future__ import annotations

from uavcore.kernel_cache import cached_kernel

Quat = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]


@cached_kernel
def quat_product(a: Quat, b: Quat) -> Quat:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@cached_kernel
def quat_inverse(q: Quat) -> Quat:
    """The conjugate, which is the inverse of a unit quaternion."""
    return (q[0], -q[1], -q[2], -q[3])


@cached_kernel
def error_quaternion(q: Quat, qd: Quat) -> Quat:
    """q^-1 qd: the rotation from the current body q to the target body qd, in body axes (every attitude law's
    error starts here: the ADRC's tilt-first angles, the geometric law's R^T R_d)."""
    return quat_product(quat_inverse(q), qd)


@cached_kernel
def rotate_vector(q: Quat, v: Vec3) -> Vec3:
    """Rotate the body vector v into the world frame by q."""
    w, x, y, z = q
    vx, vy, vz = v
    # v' = v + 2w (r x v) + 2 r x (r x v), r = (x, y, z)
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    return (
        vx + 2 * (w * cx + y * cz - z * cy),
        vy + 2 * (w * cy + z * cx - x * cz),
        vz + 2 * (w * cz + x * cy - y * cx),
    )
