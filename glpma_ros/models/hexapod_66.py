"""Gough-Stewart hexapod in the position-based 9-variable model (Rolland & Chandra 2016,
section 2; Chandra & Rolland 2014, Eq. 16): the general 6-6, the designs whose joints coincide
in pairs (6-3, 3-6, 3-3: two legs share a joint) and redundant ones (7 to 12 legs).

Solver variables: the base-frame positions of three platform joints, the *frame joints*
``F1, F2, F3``: joints 1, 2, 3 when they form a triangle (every general 6-6, and the papers'
``x = (x1, y1, z1, x2, y2, z2, x3, y3, z3)``), otherwise the first three distinct, non-collinear
platform joints in leg order (a 6-3 whose joints 1 and 2 coincide: joints 1, 3 and 5; the
variables are then named ``x1 y1 z1 x3 y3 z3 x5 y5 z5``).  Coincident joints would make the
papers' frame ``u1 = B1B2/|B1B2|`` undefined, so the frame is built on the frame joints: with
``u1 = F1F2/|F1F2|``, ``u2 = F1F3/|F1F3|`` and ``u3 = u1 x u2`` every platform joint is
``B_j = F1 + a_j u1 + b_j u2 + c_j u3``; ``(a_j, b_j, c_j)`` solve the same system
written with the platform-frame coordinates CB (once, at configuration time).
Residuals: the leg errors ``|B_j - A_j| - lg_j`` (one per leg) and the three rigidity
terms ``G_n = d_n^2(configuration) - d_n^2(estimate)`` for the frame-joint pairs (1,2),
(1,3), (2,3) -- the corrected Eq. 20 of the 2016 paper (six legs, G in
parentheses); with more than six legs the sum of squares is the least-squares fitness.

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
#: two joints closer than this share of the joints' spread are one joint; three whose triangle has
#: an area below this share of the spread squared are on one line (the config's validation uses it too)
COINCIDENT_RELATIVE = 1e-9


def frame_joints(platform: np.ndarray) -> tuple | None:
    """Indices of the frame joints: the first three distinct, non-collinear platform joints in
    leg order (``(0, 1, 2)`` for a general 6-6), or None when there are no such three (fewer than
    three distinct joints, or all on one line: the pose is then not determined)."""
    pts = np.asarray(platform, dtype=float)
    size = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    if size <= 0.0:
        return None
    first = 0
    second = next((j for j in range(1, len(pts)) if np.linalg.norm(pts[j] - pts[first]) > COINCIDENT_RELATIVE * size),
                  None)
    if second is None:
        return None
    e1 = pts[second] - pts[first]
    for k in range(second + 1, len(pts)):
        if np.linalg.norm(np.cross(e1, pts[k] - pts[first])) > COINCIDENT_RELATIVE * size * size:
            return (first, second, k)
    return None


def frame_coefficients(platform: np.ndarray, joints=(0, 1, 2)) -> np.ndarray:
    """(a_j, b_j, c_j) of every platform joint in the frame built on the frame joints
    CB_F1, CB_F2, CB_F3."""
    o, p, q = (platform[k] for k in joints)
    v1 = (p - o) / np.linalg.norm(p - o)
    v2 = (q - o) / np.linalg.norm(q - o)
    M = np.column_stack((v1, v2, np.cross(v1, v2)))
    return np.linalg.solve(M, (platform - o).T).T


class Hexapod66(Manipulator):
    kind = "hexapod_66"
    min_legs = 6
    n_vars = 9
    n_pose = 6
    kind_id = KIND_HEXAPOD_66

    def __init__(self, base, platform, unit="mm", leg_limits=None):
        joints = frame_joints(platform)
        if joints is None:
            raise ValueError("the platform joints leave the pose undetermined (fewer than three distinct "
                             "joints, or all on one line)")
        self.frame_joints = joints
        super().__init__(base, platform, unit, leg_limits)
        self.n_res = self.n_legs + len(PAIRS)
        self.variable_names = tuple(f"{c}{k + 1}" for k in joints for c in "xyz")
        self.abc = np.ascontiguousarray(frame_coefficients(self.platform, joints))
        self.d0sq = np.array([float(np.sum((self.frame[j] - self.frame[i]) ** 2)) for i, j in PAIRS])
        self.data = self._make_data(self.base, self.abc, self.d0sq)
        self.pose_column_scale = np.array([1.0, 1.0, 1.0, 1.0 / self.scale, 1.0 / self.scale, 1.0 / self.scale])

    # -- conversions ----------------------------------------------------------
    def pose_state(self, x):
        """(R, p) of the rigid motion that best maps the frame joints CB_F onto the variables B_F."""
        B = np.asarray(x, dtype=float).reshape(3, 3)
        return kabsch(self.frame, B)

    def pose_variables(self, state) -> np.ndarray:
        R, p = state
        R = matrix_from_quaternion(quaternion_from_matrix(R))  # exactly orthonormal to round-off
        return (p + self.frame @ R.T).reshape(-1)

    def joints(self, x) -> np.ndarray:
        """Every platform joint B_j (one per leg) of the rigid pose nearest ``x``, shape (n, 3)."""
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
        """Largest distance between the frame joints (the variables)."""
        d = (np.asarray(x1, dtype=float) - np.asarray(x2, dtype=float)).reshape(3, 3)
        return float(np.sqrt((d * d).sum(axis=1).max()))
