"""General 6-6 Gough-Stewart hexapod in the position-based 9-variable model
(Rolland & Chandra 2016, section 2; Chandra & Rolland 2014, Eq. 16).

Solver variables: the base-frame positions of platform joints B1, B2, B3,
``x = (x1, y1, z1, x2, y2, z2, x3, y3, z3)``.  With ``u1 = B1B2/|B1B2|``,
``u2 = B1B3/|B1B3|`` and ``u3 = u1 x u2`` every other joint is
``B_j = B1 + a_j u1 + b_j u2 + c_j u3``; ``(a_j, b_j, c_j)`` solve the same system
written with the platform-frame coordinates CB (once, at configuration time).
Residuals: the six leg errors ``|B_j - A_j| - lg_j`` and the three rigidity
terms ``G_n = d_n^2(configuration) - d_n^2(estimate)`` for the pairs (1,2),
(1,3), (2,3) -- the corrected Eq. 20 of the 2016 paper (six legs, G in
parentheses).

The refinement works in a 6-parameter pose model instead (position p of the
platform origin, rotation R updated multiplicatively by a rotation vector); a
state converts back to the nine variables exactly as ``B_k = p + R CB_k``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .base import Manipulator, Pose

PAIRS = ((0, 1), (0, 2), (1, 2))


@njit(cache=True, error_model="numpy", inline="always")
def residual_kernel(x, data, legs, out):
    base, abc, d0sq = data[0], data[1], data[2]
    e1x = x[3] - x[0]
    e1y = x[4] - x[1]
    e1z = x[5] - x[2]
    e2x = x[6] - x[0]
    e2y = x[7] - x[1]
    e2z = x[8] - x[2]
    n1sq = e1x * e1x + e1y * e1y + e1z * e1z
    n2sq = e2x * e2x + e2y * e2y + e2z * e2z
    n1 = math.sqrt(n1sq)
    n2 = math.sqrt(n2sq)
    u1x, u1y, u1z = e1x / n1, e1y / n1, e1z / n1
    u2x, u2y, u2z = e2x / n2, e2y / n2, e2z / n2
    u3x = u1y * u2z - u1z * u2y
    u3y = u1z * u2x - u1x * u2z
    u3z = u1x * u2y - u1y * u2x
    for j in range(6):
        a, b, c = abc[j, 0], abc[j, 1], abc[j, 2]
        bx = x[0] + a * u1x + b * u2x + c * u3x - base[j, 0]
        by = x[1] + a * u1y + b * u2y + c * u3y - base[j, 1]
        bz = x[2] + a * u1z + b * u2z + c * u3z - base[j, 2]
        out[j] = math.sqrt(bx * bx + by * by + bz * bz) - legs[j]
    e3x = x[6] - x[3]
    e3y = x[7] - x[4]
    e3z = x[8] - x[5]
    out[6] = d0sq[0] - n1sq
    out[7] = d0sq[1] - n2sq
    out[8] = d0sq[2] - (e3x * e3x + e3y * e3y + e3z * e3z)


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of two (n, 3) arrays (``np.cross`` without its
    generic-axis overhead, which dominates at this size)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def frame_coefficients(platform: np.ndarray) -> np.ndarray:
    """(a_j, b_j, c_j) of every platform joint in the frame built on CB1, CB2, CB3."""
    v1 = platform[1] - platform[0]
    v2 = platform[2] - platform[0]
    v1 = v1 / np.linalg.norm(v1)
    v2 = v2 / np.linalg.norm(v2)
    M = np.column_stack((v1, v2, np.cross(v1, v2)))
    return np.linalg.solve(M, (platform - platform[0]).T).T


def rotation_from_vector(w) -> np.ndarray:
    """Rodrigues' formula: rotation matrix of rotation vector ``w``."""
    theta = math.sqrt(float(w @ w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if theta < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + (math.sin(theta) / theta) * K + ((1.0 - math.cos(theta)) / theta ** 2) * K @ K


def quaternion_from_matrix(R) -> np.ndarray:
    """Unit quaternion [qx, qy, qz, qw] of a rotation matrix, qw >= 0."""
    t = np.trace(R)
    if t > 0.0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = np.array([(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s])
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + R[i, i] - R[j, j] - R[k, k], 0.0))
        q = np.empty(4)
        q[i] = 0.25 * s
        q[j] = (R[j, i] + R[i, j]) / s
        q[k] = (R[k, i] + R[i, k]) / s
        q[3] = (R[k, j] - R[j, k]) / s
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def matrix_from_quaternion(q) -> np.ndarray:
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def kabsch(src: np.ndarray, dst: np.ndarray):
    """Rigid transform (R, p) minimising sum |R src_k + p - dst_k|^2."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    H = (src - cs).T @ (dst - cd)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    return R, cd - R @ cs


class Hexapod66(Manipulator):
    kind = "hexapod_66"
    n_legs = 6
    n_vars = 9
    n_res = 9
    n_pose = 6
    variable_names = ("x1", "y1", "z1", "x2", "y2", "z2", "x3", "y3", "z3")
    kind_id = 1  # models.kernels.KIND_HEXAPOD_66

    def __init__(self, base, platform, unit="mm", leg_limits=None):
        super().__init__(base, platform, unit, leg_limits)
        self.abc = np.ascontiguousarray(frame_coefficients(self.platform))
        self.d0sq = np.array([float(np.sum((self.platform[j] - self.platform[i]) ** 2)) for i, j in PAIRS])
        self.data = self._make_data(self.base, self.abc, self.d0sq)
        self.pose_column_scale = np.array([1.0, 1.0, 1.0, 1.0 / self.scale, 1.0 / self.scale, 1.0 / self.scale])

    # -- conversions ----------------------------------------------------------
    def pose_state(self, x):
        """(R, p) of the rigid motion that best maps CB1..CB3 onto B1..B3."""
        B = np.asarray(x, dtype=float).reshape(3, 3)
        return kabsch(self.platform[:3], B)

    def pose_variables(self, state) -> np.ndarray:
        R, p = state
        R = matrix_from_quaternion(quaternion_from_matrix(R))  # exactly orthonormal to round-off
        return (p + self.platform[:3] @ R.T).reshape(-1)

    def joints(self, x) -> np.ndarray:
        """All six platform joints B_j of the rigid pose nearest ``x``, shape (6, 3)."""
        R, p = self.pose_state(x)
        return p + self.platform @ R.T

    def inverse_kinematics(self, x) -> np.ndarray:
        return np.linalg.norm(self.joints(x) - self.base, axis=1)

    def pose(self, x) -> Pose:
        R, p = self.pose_state(x)
        return Pose(np.array(p, dtype=float), quaternion_from_matrix(R))

    def variables_from_pose(self, position, orientation) -> np.ndarray:
        return self.pose_variables((matrix_from_quaternion(orientation), np.asarray(position, dtype=float)))

    # -- refinement in pose space -------------------------------------------
    def pose_residuals_jacobian(self, state, legs):
        R, p = state
        w = self.platform @ R.T                     # R CB_j
        e = p + w - self.base
        n = np.sqrt((e * e).sum(axis=1))
        u = e / n[:, None]
        J = np.hstack((u, cross_rows(w, u)))        # d r_j / d(p, omega)
        return n - legs, J

    def pose_retract(self, state, step):
        R, p = state
        return rotation_from_vector(step[3:]) @ R, p + step[:3]

    def spread_vector(self, length: float) -> np.ndarray:
        """Per-variable spread for a platform displacement of ``length``."""
        return np.full(self.n_vars, float(length))

    def canonical(self, x) -> np.ndarray:
        return np.array(x, dtype=float)

    def distance(self, x1, x2) -> float:
        """Largest distance between the platform joints B1, B2, B3 (the variables)."""
        d = (np.asarray(x1, dtype=float) - np.asarray(x2, dtype=float)).reshape(3, 3)
        return float(np.sqrt((d * d).sum(axis=1).max()))
