"""Platform twist from two consecutive poses (finite difference), when leg rates are not measured.

Between poses ``(p0, q0)`` at ``t0`` and ``(p1, q1)`` at ``t1`` the mean velocity of the platform
origin is ``(p1 - p0) / dt`` and the mean angular velocity, about the fixed base axes, is the
rotation vector of ``R1 R0^T`` (quaternion ``q1 q0*``) divided by ``dt``: the backward
difference, exact for a motion at constant twist and first-order accurate otherwise (its error
is at most ``dt / 2`` times the largest acceleration over the interval).  The exact alternative,
from measured leg rates, is :meth:`glpma_ros.estimation.covariance.PoseJacobian.solve`.  Plain Python floats
(a few microseconds per call).  No ROS import.
"""
from __future__ import annotations

import math

#: below this rotation-vector half-angle sine the small-angle form 2 v / w is used (exact to
#: round-off there: atan2(s, w) / s = (1 - s^2 / 3 ...) / w)
SMALL_ANGLE = 1e-8


def rotation_vector_between(q0, q1) -> tuple[float, float, float]:
    """Rotation vector ``w`` (radians, base frame) with ``R(q1) = exp([w]x) R(q0)``; unit
    quaternions [x, y, z, w]; the shorter of the two rotations."""
    x0, y0, z0, w0 = q0
    x1, y1, z1, w1 = q1
    # q1 * conj(q0) (Hamilton product, [x, y, z, w])
    x = -w1 * x0 + x1 * w0 - y1 * z0 + z1 * y0
    y = -w1 * y0 + y1 * w0 - z1 * x0 + x1 * z0
    z = -w1 * z0 + z1 * w0 - x1 * y0 + y1 * x0
    w = w1 * w0 + x1 * x0 + y1 * y0 + z1 * z0
    if w < 0.0:                                   # q and -q are the same rotation
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    factor = 2.0 / w if s < SMALL_ANGLE else 2.0 * math.atan2(s, w) / s
    return x * factor, y * factor, z * factor


def finite_difference_twist(p0, q0, p1, q1, dt: float):
    """``(linear, angular)`` mean twist between two poses (position, unit quaternion) ``dt > 0``
    seconds apart, base frame.  (Take ``dt`` from integer nanosecond stamps: a difference of two
    epoch times in float seconds keeps only about 0.2 us.)"""
    linear = tuple((b - a) / dt for a, b in zip(p0, p1))
    angular = tuple(v / dt for v in rotation_vector_between(q0, q1))
    return linear, angular
