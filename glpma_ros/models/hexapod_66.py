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


import numpy as np

from .base import Manipulator, Pose
from .residuals import KIND_HEXAPOD_66
from .rotations import cross_rows, kabsch, matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector

PAIRS = ((0, 1), (0, 2), (1, 2))


def frame_coefficients(platform: np.ndarray) -> np.ndarray:
    """(a_j, b_j, c_j) of every platform joint in the frame built on CB1, CB2, CB3."""
    v1 = platform[1] - platform[0]
    v2 = platform[2] - platform[0]
    v1 = v1 / np.linalg.norm(v1)
    v2 = v2 / np.linalg.norm(v2)
    M = np.column_stack((v1, v2, np.cross(v1, v2)))
    return np.linalg.solve(M, (platform - platform[0]).T).T


class Hexapod66(Manipulator):
    kind = "hexapod_66"
    n_legs = 6
    n_vars = 9
    n_res = 9
    n_pose = 6
    variable_names = ("x1", "y1", "z1", "x2", "y2", "z2", "x3", "y3", "z3")
    kind_id = KIND_HEXAPOD_66

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
