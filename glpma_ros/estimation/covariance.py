"""Uncertainty and velocity of the platform pose from the leg Jacobian at the solution.

A parallel manipulator's leg lengths are a function of its pose, ``l = f(p, R)``.  For a
small motion of the platform -- a displacement ``dp`` of its origin and a small rotation
``dw`` about the **fixed** base axes, ``R <- exp([dw]x) R`` -- each leg changes by

    dl_i = u_i . dp + ((R CB_i) x u_i) . dw,        u_i = (B_i - A_i) / |B_i - A_i|,

i.e. ``dl = J [dp; dw]`` with the rows of ``J`` = ``[u_i, (R CB_i) x u_i]``: the same Jacobian as
:meth:`Hexapod66.pose_residuals_jacobian <glpma_ros.models.hexapod_66.Hexapod66.pose_residuals_jacobian>`
(whose rotation parameter is exactly that left-applied rotation vector); for the planar 3-RPR
it is the same formula in the plane, columns ``(x, y, rotation about z)`` = the columns of
:meth:`Planar3RPR.pose_residuals_jacobian <glpma_ros.models.planar_3rpr.Planar3RPR.pose_residuals_jacobian>`.
The tests check :func:`leg_jacobian` against both models' Jacobians.  It is compiled here
because the node evaluates it for every input, where NumPy's overhead costs more than the
arithmetic.

* **Covariance** (first-order propagation; e.g. Hartley & Zisserman, *Multiple View
  Geometry*, 2nd ed., section 5.2.3): with independent leg-length errors of standard
  deviation ``sigma``, the least-squares pose has ``Sigma = sigma^2 (J^T J)^-1`` -- a 6x6
  matrix in the order of ``geometry_msgs/PoseWithCovariance`` (x, y, z, rotation about the
  fixed x, y, z axes; metres, radians).  For the planar 3-RPR, z and the rotations about x and y
  are not measured at all: they get :data:`UNOBSERVED_VARIANCE`, as ``robot_localization``
  expects of an unmeasured axis.
* **Singularities**: ``Sigma`` is formed from the singular value decomposition of ``J`` with
  the rotation columns scaled by the platform size (so that all columns are lengths).  Near a
  singularity the smallest singular value goes to zero and the covariance grows as its
  inverse square; no direction gets more than :data:`VARIANCE_CAP`, so that the matrix stays
  finite (and symmetric positive semi-definite) even at a singularity, where ``capped`` is
  reported.
* **Velocity** (forward velocity kinematics): leg rates ``dl/dt = J t`` for the platform twist
  ``t = (v, w)`` -- ``v`` the velocity of the platform origin, ``w`` the angular velocity, both
  in the base frame.  ``t`` is the least-squares solution by the same decomposition (exact
  when ``J`` is square and regular; the 3-RPR gives ``(vx, vy, wz)``).

* **Actuated legs** (the one leg model of :mod:`glpma_ros.models.legs`: a rod of fixed length from a
  proximal point ``P_i(q_i)`` the actuator moves to the platform joint): the leg's closure
  ``|p + R CB_i - P_i(q_i)| = rod_i`` differentiated gives ``J_i [dp; dw] = g_i dq_i`` with ``J_i`` the row
  above (``P_i`` as its base joint) and the actuator's gain ``g_i = u_i . dP_i/dq_i``: ``u_i . (a_i x (P_i -
  origin_i))`` for a revolute actuator of axis ``a_i``, ``u_i . a_i`` for a prismatic rail, and 1 for a leg
  whose length is the actuator (today's legs: ``dq_i = dl_i``).  So the actuated Jacobian ``dq/d(p, w)`` has
  the rows ``J_i / g_i``, and the covariance and twist above follow with it and each actuator's own noise:
  rows and rates divided by ``sigma_i`` (radians for a revolute actuator, metres otherwise), ``Sigma =
  (J_w^T J_w)^-1`` -- the same ``sigma^2 (J^T J)^-1`` when every ``sigma_i`` is one ``sigma``.  A platform
  that only translates (the Delta) measures x, y, z; its orientation is fixed by the mechanism: the
  rotation block of its covariance is zero and its twist has no angular part.

Everything here is in metres and radians: the model's geometry is converted once.
No ROS import.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..models.legs import LENGTH, PRISMATIC, REVOLUTE
from ..models.linalg import jacobi_svd
from ..models.residuals import KIND_ACTUATED_TRANSLATION

#: variance (m^2, rad^2) of a pose component the manipulator does not measure (the planar
#: 3-RPR's z, roll and pitch): robot_localization's convention for "not measured"
UNOBSERVED_VARIANCE = 1e6
#: largest variance of any direction of the scaled pose (m^2; a rotation counted as the arc
#: it sweeps at the platform's size): at a singularity the first-order covariance is infinite
VARIANCE_CAP = 1e6
#: the columns (x, y, z, rotation about x, y, z) the spatial models measure, and the planar ones
SPATIAL_COLUMNS = np.arange(6)
PLANAR_COLUMNS = np.array([0, 1, 5])
#: the columns a translating platform (the Delta) measures; its rotations are fixed by the mechanism
TRANSLATION_COLUMNS = np.arange(3)
#: variance (rad^2) of a rotation the mechanism fixes (a translating platform's): known exactly
FIXED_VARIANCE = 0.0
#: an actuator gain (m per unit of actuator motion) smaller than this share of its lever (the crank's
#: radius; a rail: 1) is raised to it: the rod at right angles to the proximal point's motion, where the
#: first-order pose does not move with the actuator (the division stays finite; that row's noise vanishes)
GAIN_FLOOR = 1e-12
#: first rotation column
ROTATION = 3


@njit(cache=True, nogil=True, error_model="numpy")
def leg_jacobian(base, platform, position, quaternion, J):
    """Fill ``J`` (n, 6) with ``d l_i / d(p, w)`` at the pose (``position``, unit ``quaternion``
    [x, y, z, w] rotating platform to base); ``base``, ``platform``: the joints A_i (base frame)
    and CB_i (platform frame), (n, 3), same length unit as ``position``."""
    qx, qy, qz, qw = quaternion[0], quaternion[1], quaternion[2], quaternion[3]
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
    r00 = 1.0 - 2.0 * (qy * qy + qz * qz)
    r01 = 2.0 * (qx * qy - qz * qw)
    r02 = 2.0 * (qx * qz + qy * qw)
    r10 = 2.0 * (qx * qy + qz * qw)
    r11 = 1.0 - 2.0 * (qx * qx + qz * qz)
    r12 = 2.0 * (qy * qz - qx * qw)
    r20 = 2.0 * (qx * qz - qy * qw)
    r21 = 2.0 * (qy * qz + qx * qw)
    r22 = 1.0 - 2.0 * (qx * qx + qy * qy)
    for i in range(base.shape[0]):
        cx, cy, cz = platform[i, 0], platform[i, 1], platform[i, 2]
        wx = r00 * cx + r01 * cy + r02 * cz           # R CB_i
        wy = r10 * cx + r11 * cy + r12 * cz
        wz = r20 * cx + r21 * cy + r22 * cz
        ex = position[0] + wx - base[i, 0]            # B_i - A_i
        ey = position[1] + wy - base[i, 1]
        ez = position[2] + wz - base[i, 2]
        n = math.sqrt(ex * ex + ey * ey + ez * ez)
        ux, uy, uz = ex / n, ey / n, ez / n
        J[i, 0], J[i, 1], J[i, 2] = ux, uy, uz
        J[i, 3] = wy * uz - wz * uy                   # (R CB_i) x u_i
        J[i, 4] = wz * ux - wx * uz
        J[i, 5] = wx * uy - wy * ux


@njit(cache=True, nogil=True, error_model="numpy")
def covariance_and_twist(J, columns, length, sigma, cap, unobserved, rates, work, V, cov, twist):
    """Sigma (6x6, into ``cov``) and, when ``rates`` has one entry per leg, the least-squares
    twist (into ``twist``) from the measured ``columns`` of ``J``; ``work`` (n, k) and ``V``
    (k, k) are scratch.  Returns True when a singular value was raised to the cap."""
    n, k = work.shape
    for c in range(k):
        inv = 1.0 / length if columns[c] >= ROTATION else 1.0
        for i in range(n):
            work[i, c] = J[i, columns[c]] * inv
    s = np.empty(k)
    jacobi_svd(work, V, s)                        # work = U diag(s) (high relative accuracy)
    floor = sigma / math.sqrt(cap)
    capped = False
    for c in range(k):
        if not s[c] > floor:                      # also catches NaN
            s[c] = floor
            capped = True
    cov[:, :] = 0.0
    for c in range(6):
        cov[c, c] = unobserved
    for a in range(k):
        sa = length if columns[a] >= ROTATION else 1.0
        for b in range(a, k):
            sb = length if columns[b] >= ROTATION else 1.0
            acc = 0.0
            for m in range(k):
                acc += V[a, m] * V[b, m] / (s[m] * s[m])
            value = sigma * sigma * acc / (sa * sb)
            cov[columns[a], columns[b]] = value
            cov[columns[b], columns[a]] = value
    twist[:] = 0.0
    if rates.size == n:
        for a in range(k):
            sa = length if columns[a] >= ROTATION else 1.0
            acc = 0.0
            for m in range(k):
                proj = 0.0                        # (U^T rates)_m = (work^T rates)_m / s_m
                for i in range(n):
                    proj += work[i, m] * rates[i]
                acc += V[a, m] * proj / (s[m] * s[m])
            twist[columns[a]] = acc / sa
    return capped


@njit(cache=True, nogil=True, error_model="numpy")
def actuator_jacobian(kinds, origin, axis, proximal, platform, position, quaternion, J):
    """Fill ``J`` (n, 6) with ``d q_i / d(p, w)``, the actuated Jacobian (module docstring): :func:`leg_jacobian`
    with the proximal points ``proximal`` (n, 3) as base joints, each row divided by its actuator's gain;
    ``kinds`` (n,) of :mod:`glpma_ros.models.legs`, ``origin``, ``axis`` (n, 3) the actuated joints (a
    length leg's are unused)."""
    leg_jacobian(proximal, platform, position, quaternion, J)
    for i in range(kinds.shape[0]):
        k = kinds[i]
        if k == LENGTH:
            continue                                  # the length is the actuator: gain 1
        ax, ay, az = axis[i, 0], axis[i, 1], axis[i, 2]
        if k == PRISMATIC:
            tx, ty, tz, lever = ax, ay, az, 1.0
        else:                                         # REVOLUTE: the crank tip turns about the axis
            rx, ry, rz = proximal[i, 0] - origin[i, 0], proximal[i, 1] - origin[i, 1], proximal[i, 2] - origin[i, 2]
            tx, ty, tz = ay * rz - az * ry, az * rx - ax * rz, ax * ry - ay * rx
            lever = math.sqrt(tx * tx + ty * ty + tz * tz)
        gain = J[i, 0] * tx + J[i, 1] * ty + J[i, 2] * tz
        floor = GAIN_FLOOR * lever
        if abs(gain) < floor:
            gain = floor if gain >= 0.0 else -floor
        for c in range(6):
            J[i, c] /= gain


@njit(cache=True, nogil=True, error_model="numpy")
def pose_covariance_twist(kinds, origin, axis, proximal, platform, position, scale, quaternion, columns, length,
                          noise, cap, unobserved, rates, J, weighted, weighted_rates, work, V, cov, twist):
    """:func:`actuator_jacobian` at (``position * scale``, ``quaternion``) into ``J``, its rows (and the
    ``rates``, when one per leg) divided by each actuator's ``noise`` into ``weighted`` (and
    ``weighted_rates``), then :func:`covariance_and_twist` of unit noise: one compiled call per input."""
    p = np.empty(3)
    for c in range(3):
        p[c] = position[c] * scale if c < position.size else 0.0
    actuator_jacobian(kinds, origin, axis, proximal, platform, p, quaternion, J)
    n = J.shape[0]
    for i in range(n):
        for c in range(6):
            weighted[i, c] = J[i, c] / noise[i]
    given = rates
    if rates.size == n:
        for i in range(n):
            weighted_rates[i] = rates[i] / noise[i]
        given = weighted_rates
    return covariance_and_twist(weighted, columns, length, 1.0, cap, unobserved, given, work, V, cov, twist)


class PoseJacobian:
    """The actuated Jacobian ``dq/d(p, w)`` of one manipulator at a pose, in metres (the leg Jacobian for
    legs whose length is the actuator), with the covariance and the twist it gives.  Buffers are
    preallocated: one call per input, no allocation besides the decomposition's."""

    def __init__(self, model):
        mpu = float(model.metres_per_unit)
        self.planar = model.base.shape[1] == 2
        pad = (lambda a: np.hstack((a, np.zeros((a.shape[0], 1))))) if self.planar else (lambda a: a)
        n = model.n_legs
        self.actuated = bool(getattr(model, "actuated", False))
        if self.actuated:
            self.kinds = np.ascontiguousarray(model.actuators, dtype=np.int64)
            self.origin = np.ascontiguousarray(pad(model.origin) * mpu)
            # a planar crank turns about +z; a planar rail runs in the plane
            axis = np.where((self.kinds == REVOLUTE)[:, None], [0.0, 0.0, 1.0], pad(model.axis)) \
                if self.planar else model.axis
            self.axis = np.ascontiguousarray(axis, dtype=float)
            self.proximal = np.zeros((n, 3))          # set from each input's leg vector
        else:
            self.kinds = np.full(n, LENGTH, dtype=np.int64)
            self.origin = self.axis = np.zeros((n, 3))
            self.proximal = np.ascontiguousarray(pad(model.base) * mpu)
        self._model = model
        self._mpu = mpu
        self.platform = np.ascontiguousarray(pad(model.platform) * mpu)
        translation = getattr(model, "kind_id", None) == KIND_ACTUATED_TRANSLATION
        self.columns = TRANSLATION_COLUMNS if translation else (PLANAR_COLUMNS if self.planar else SPATIAL_COLUMNS)
        #: variance of the pose components not measured: fixed rotations (a translating platform) are exact
        self.unobserved = FIXED_VARIANCE if translation else UNOBSERVED_VARIANCE
        #: platform size (m) that turns rotations into lengths for the decomposition
        self.length = float(model.scale) * mpu
        self.J = np.zeros((n, 6))
        self.covariance = np.zeros((6, 6))
        self.twist = np.zeros(6)
        self.noise = np.zeros(n)
        self._revolute = self.kinds == REVOLUTE
        self._weighted = np.zeros((n, 6))
        self._weighted_rates = np.zeros(n)
        self._work = np.zeros((n, self.columns.size))
        self._V = np.zeros((self.columns.size, self.columns.size))
        self._no_rates = np.zeros(0)

    @property
    def base(self) -> np.ndarray:
        """The legs' base joints (m, (n, 3)): the proximal points of the last input for an actuated family."""
        return self.proximal

    def set_legs(self, legs) -> None:
        """An actuated family: the proximal points ``P_i`` of the leg vector ``legs`` (config unit), the base
        joints of the next :meth:`at` / :meth:`solve` (nothing to do for length legs)."""
        if self.actuated:
            points = self._model.proximal_points(legs) * self._mpu
            self.proximal[:, :points.shape[1]] = points

    def at(self, position_m, quaternion, legs=None) -> np.ndarray:
        """The Jacobian (n, 6) at a pose (metres, unit quaternion [x, y, z, w]; an actuated family: and its
        leg vector ``legs``, config unit): ``dq/d(p, w)`` (q in radians for revolute actuators, metres
        otherwise); the planar model's columns 2-4 (z, rotations about x and y) are zero."""
        if legs is not None:
            self.set_legs(legs)
        actuator_jacobian(self.kinds, self.origin, self.axis, self.proximal, self.platform,
                          np.asarray(position_m, dtype=float), np.asarray(quaternion, dtype=float), self.J)
        return self.J

    def solve(self, position, quaternion, sigma_m: float, leg_rates_m=None, unit: float = 1.0, legs=None,
              sigma_rad: float | None = None) -> bool:
        """Fill :attr:`J` at the pose (``position * unit`` metres, unit quaternion [x, y, z, w];
        float arrays; an actuated family: its leg vector ``legs``, config unit), :attr:`covariance` (6x6,
        ROS order, m^2 / rad^2) for the noise of each length measurement (legs, prismatic actuators)
        ``sigma_m`` (metres) and of each revolute actuator ``sigma_rad`` (radians) and, given
        ``leg_rates_m`` (the actuators' rates, leg order, a float array: m/s, rad/s for revolute ones),
        :attr:`twist` (vx, vy, vz, wx, wy, wz; m/s, rad/s, base frame).  Returns True when the covariance
        was capped (the pose is at a singularity, to within the noise)."""
        if legs is not None:
            self.set_legs(legs)
        self.noise[:] = sigma_m
        if sigma_rad is not None:
            self.noise[self._revolute] = sigma_rad
        rates = self._no_rates if leg_rates_m is None else leg_rates_m
        return pose_covariance_twist(self.kinds, self.origin, self.axis, self.proximal, self.platform, position,
                                     unit, quaternion, self.columns, self.length, self.noise, VARIANCE_CAP,
                                     self.unobserved, rates, self.J, self._weighted, self._weighted_rates,
                                     self._work, self._V, self.covariance, self.twist)


def warm_up() -> None:
    """Compile (or load) the kernels before the first input."""
    from types import SimpleNamespace
    angles = np.linspace(0.0, 2.0 * np.pi, 7)[:-1]
    ring = np.column_stack((np.cos(angles), np.sin(angles), np.zeros(6)))
    for base in (ring[::2, :2], ring):
        model = SimpleNamespace(base=base, platform=0.5 * base, metres_per_unit=1.0, scale=1.0,
                                n_legs=base.shape[0])
        jac = PoseJacobian(model)
        for rates in (None, np.zeros(base.shape[0])):
            jac.solve(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0, 1.0]), 1e-5, rates)
        jac.at(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
