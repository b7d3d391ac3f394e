"""Planar 3-RPR parallel manipulator (Chandra & Rolland 2014, section 4.1, Eq. 6-7), and the
planar manipulator with redundant legs (4 or more RPR legs on the same platform).

Solver variables ``x = (x, y, theta)``: position of the platform frame origin C
in the base frame and the platform angle (rad).  Leg ``i`` joins base joint
``A_i`` to platform joint ``B_i = C + R(theta) CB_i``; its residual is
``|B_i - A_i| - lg_i`` and the fitness is the sum of the squares (three; with more
legs, the least-squares fitness).
The variables are already a minimal pose, so the refinement works on them
directly.
"""
from __future__ import annotations

import math

import numpy as np

from .base import Manipulator, Pose
from .residuals import KIND_PLANAR_3RPR


class Planar3RPR(Manipulator):
    kind = "planar_3rpr"
    min_legs = 3
    n_vars = 3
    n_pose = 3
    variable_names = ("x", "y", "theta")
    kind_id = KIND_PLANAR_3RPR

    def __init__(self, base, platform, unit="mm", leg_limits=None):
        super().__init__(base, platform, unit, leg_limits)
        self.n_res = self.n_legs
        self.data = self._make_data(self.base, self.platform)
        self.pose_column_scale = np.array([1.0, 1.0, 1.0 / self.scale])

    def joints(self, x) -> np.ndarray:
        """Platform joints B_i in the base frame, shape (n, 2)."""
        x = np.asarray(x, dtype=float)
        c, s = math.cos(x[2]), math.sin(x[2])
        R = np.array([[c, -s], [s, c]])
        return x[:2] + self.platform @ R.T

    def inverse_kinematics(self, x) -> np.ndarray:
        return np.linalg.norm(self.joints(x) - self.base, axis=1)

    def pose(self, x) -> Pose:
        half = 0.5 * float(x[2])
        return Pose(np.array([x[0], x[1], 0.0]), np.array([0.0, 0.0, math.sin(half), math.cos(half)]))

    def variables_from_pose(self, position, orientation) -> np.ndarray:
        qx, qy, qz, qw = (float(v) for v in orientation)
        return np.array([float(position[0]), float(position[1]), 2.0 * math.atan2(qz, qw)])

    # pose parameterisation for the refinement: the variables themselves
    def pose_state(self, x):
        return np.array(x, dtype=float)

    def pose_residuals_jacobian(self, state, legs):
        c, s = math.cos(state[2]), math.sin(state[2])
        rot = self.platform @ np.array([[c, s], [-s, c]])          # R(theta) CB_i, rows
        e = state[:2] + rot - self.base
        n = np.sqrt((e * e).sum(axis=1))
        J = np.empty((self.n_legs, 3))
        J[:, :2] = e / n[:, None]                                  # unit leg vectors u_i
        # d/dtheta of R CB_i is (-(R CB_i)_y, (R CB_i)_x)
        J[:, 2] = J[:, 1] * rot[:, 0] - J[:, 0] * rot[:, 1]
        return n - legs, J

    def pose_retract(self, state, step):
        return state + step

    def pose_variables(self, state) -> np.ndarray:
        return np.asarray(state, dtype=float)

    def spread_vector(self, length: float) -> np.ndarray:
        """Per-variable spread for a platform displacement of ``length``."""
        return np.array([length, length, length / self.scale])

    def canonical(self, x) -> np.ndarray:
        """Variables with theta wrapped to (-pi, pi]."""
        y = np.array(x, dtype=float)
        y[2] = math.remainder(y[2], 2.0 * math.pi)
        return y

    def distance(self, x1, x2) -> float:
        return float(np.max(np.linalg.norm(self.joints(x1)[:3] - self.joints(x2)[:3], axis=1)))
