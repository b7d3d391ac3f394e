"""Common interface of the manipulator models.

A model turns the forward-kinematics problem into minimisation (Chandra & Rolland
2014, "GLPMA", section 4; Rolland & Chandra 2016, section 2): *solver variables*
``x`` (the papers' search space) map to a residual vector whose squared sum is
the fitness.  Each model provides

* a residual function in :mod:`.residuals` -- a Numba-compiled function that fills
  ``out`` with the residuals of one individual, dispatched by ``kind_id`` in
  :mod:`.kernels`; the solvers call it inside their compiled loops so a whole
  population is evaluated without Python overhead;
* a *pose parameterisation* used by the Levenberg-Marquardt refinement and by
  warm starts: ``pose_state(x)``, ``pose_residuals_jacobian(state, legs)``,
  ``pose_retract(state, step)`` and ``pose_variables(state)``;
* inverse kinematics and the conversion of variables to a position and a unit
  quaternion (x, y, z, w).

No ROS import here: this is the core.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import InputError
from .kernels import population_fitness, population_residuals


def number_vector(values, what: str, copy: bool = False) -> np.ndarray:
    """``values`` (the ``what`` a caller hands a model, e.g. "leg lengths") as a flat float array -- a copy of
    its own with ``copy`` -- or :class:`InputError` naming them: the first check of every such vector."""
    try:
        return (np.array if copy else np.asarray)(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what} are not numbers: {exc}") from None


@njit(cache=True, error_model="numpy", nogil=True)
def lengths_from_readings(readings, divisor, lo, hi, offsets, out) -> bool:
    """The usual measured input in one compiled pass: each reading divided by ``divisor`` (a topic's metres ->
    the config's unit) must lie in ``[lo, hi]`` (the plausible band: finite, no unit mistake possible), then
    ``out = readings / divisor + offsets`` (:meth:`Manipulator.legs_from_sensors`).  False, ``out`` partly
    written, when a reading is outside the band or not a number (NaN): the caller's checks then name it."""
    for i in range(readings.shape[0]):
        x = readings[i] / divisor
        if not (lo <= x <= hi):
            return False
        out[i] = x + offsets[i]
    return True


@dataclass(frozen=True)
class Pose:
    """Platform pose: position of the platform frame origin (config unit) and a
    unit quaternion ``[qx, qy, qz, qw]`` rotating platform to base frame."""

    position: np.ndarray
    orientation: np.ndarray

    def as_dict(self) -> dict:
        return {"position": [float(v) for v in self.position],
                "orientation": [float(v) for v in self.orientation]}


class Manipulator:
    """Base class; concrete models set the attributes below in ``__init__``."""

    kind: str = ""
    unit: str = "mm"
    #: the legs the pose needs (the degrees of freedom); a model may have more (redundant legs)
    min_legs: int = 0
    n_legs: int = 0
    n_vars: int = 0
    n_res: int = 0
    variable_names: tuple = ()
    # dimension of the pose-space step used by the refinement
    n_pose: int = 0
    base: np.ndarray
    platform: np.ndarray
    leg_limits: tuple | None = None
    #: zero offsets of the leg sensors (config unit, one per leg; None = none): the model's leg length
    #: |B_i - A_i| is the sensor's reading plus its offset (``leg_offsets`` in the YAML, identified by
    #: ``glpma-fk calibrate``)
    leg_offsets: np.ndarray | None = None
    scale: float = 1.0  # characteristic length of the geometry (config unit)
    pose_column_scale: np.ndarray  # makes the pose Jacobian's columns commensurate
    data: tuple = ()
    #: the platform joints (indices) whose base-frame positions the solver variables and the
    #: platform-joint distance are about; ``frame`` = their platform-frame coordinates
    frame_joints: tuple = (0, 1, 2)

    def __init__(self, base, platform, unit="mm", leg_limits=None):
        self.base = np.ascontiguousarray(base, dtype=float)
        self.platform = np.ascontiguousarray(platform, dtype=float)
        if self.base.shape != self.platform.shape or self.base.shape[0] < self.min_legs:
            raise ValueError(f"{self.kind} needs as many base as platform joints, at least {self.min_legs}")
        self.n_legs = int(self.base.shape[0])
        self.frame = np.ascontiguousarray(self.platform[list(self.frame_joints)])
        self.unit = unit
        self.leg_limits = leg_limits
        self.scale = float(max(np.ptp(self.base, axis=0).max(), np.ptp(self.platform, axis=0).max()))

    @property
    def redundancy(self) -> int:
        """Legs beyond the degrees of freedom (0: exactly determined)."""
        return self.n_legs - self.n_pose

    # -- evaluation --------------------------------------------------------
    kind_id: int = -1   # selects the compiled residual kernel (models.kernels)

    def _make_data(self, first, second, third=None) -> tuple:
        """The uniform data tuple of the compiled kernels: two matrices, a vector
        and the residual-evaluation counter."""
        third = np.zeros(0) if third is None else third
        self.evaluation_counter = np.zeros(1, dtype=np.int64)
        return (np.ascontiguousarray(first, dtype=float), np.ascontiguousarray(second, dtype=float),
                np.ascontiguousarray(third, dtype=float), self.evaluation_counter)

    def residuals(self, X, legs) -> np.ndarray:
        X2 = np.ascontiguousarray(np.atleast_2d(np.asarray(X, dtype=float)))
        return population_residuals(X2, self.kind_id, self.data, np.asarray(legs, dtype=float), self.n_res)

    def fitness(self, X, legs) -> np.ndarray:
        X2 = np.ascontiguousarray(np.atleast_2d(np.asarray(X, dtype=float)))
        return population_fitness(X2, self.kind_id, self.data, np.asarray(legs, dtype=float), self.n_res)

    # -- the leg model (:mod:`.legs`): fixed proximal points, the legs are the rods -------------
    @property
    def leg_vector_size(self) -> int:
        """Length of the vector the solvers take for one input (here the leg lengths; an actuated
        family's leg vector also carries its proximal points, :mod:`.actuated`)."""
        return self.n_legs

    def proximal_points(self, legs) -> np.ndarray:
        """The points the legs start from for input ``legs``: the base joints, fixed here."""
        return self.base

    def rods_of(self, legs) -> np.ndarray:
        """The rod lengths of input ``legs``: the leg lengths themselves here."""
        return np.asarray(legs, dtype=float)

    # -- measured legs ---------------------------------------------------
    def legs_from_sensors(self, measured) -> np.ndarray:
        """The leg lengths the kinematics needs, |B_i - A_i|, from the sensors' readings (config unit):
        ``measured + leg_offsets``.  Every measured input goes through here once, where it enters the
        core (the node's :class:`~glpma_ros.node.service.FkService`, the command line); a reading of the
        wrong size or type is returned as it is, for :meth:`check_legs` to name the problem."""
        if self.leg_offsets is None:
            return measured
        try:
            arr = np.asarray(measured, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            return measured
        return arr + self.leg_offsets if arr.size == self.n_legs else measured

    def sensors_from_legs(self, legs) -> np.ndarray:
        """What the leg sensors read for leg lengths |B_i - A_i| ``legs`` (config unit): ``legs -
        leg_offsets``; the inverse of :meth:`legs_from_sensors`, for simulated controllers."""
        arr = np.asarray(legs, dtype=float)
        return arr if self.leg_offsets is None else arr - self.leg_offsets

    # -- validation --------------------------------------------------------
    def check_legs(self, legs) -> np.ndarray:
        """Validated leg lengths as a float array, or :class:`InputError`."""
        arr = number_vector(legs, "leg lengths")
        if arr.size != self.n_legs:
            raise InputError(f"expected {self.n_legs} leg lengths for {self.kind}, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise InputError("leg lengths must be finite (got NaN or inf)")
        if np.any(arr <= 0.0):
            raise InputError("leg lengths must be positive")
        if self.leg_limits is not None:
            lo, hi = self.leg_limits
            if np.any(arr < lo) or np.any(arr > hi):
                raise InputError(
                    f"leg lengths outside the configured limits [{lo:g}, {hi:g}] {self.unit}")
        return arr

    def check_variables(self, x) -> np.ndarray:
        arr = number_vector(x, "solver variables")
        if arr.size != self.n_vars:
            raise InputError(
                f"expected {self.n_vars} solver variables ({' '.join(self.variable_names)}), got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise InputError("solver variables must be finite")
        return arr

    # -- kinematics (subclasses) ----------------------------------------------
    def inverse_kinematics(self, x) -> np.ndarray:
        """Leg lengths (config unit) of the pose given by solver variables ``x``."""
        raise NotImplementedError

    def pose(self, x) -> Pose:
        raise NotImplementedError

    def variables_from_pose(self, position, orientation) -> np.ndarray:
        raise NotImplementedError

    def pose_state(self, x):
        raise NotImplementedError

    def pose_residuals_jacobian(self, state, legs):
        raise NotImplementedError

    def pose_retract(self, state, step):
        raise NotImplementedError

    def pose_variables(self, state) -> np.ndarray:
        raise NotImplementedError

    def distance(self, x1, x2) -> float:
        """Distance between two solutions in config units (platform joints)."""
        raise NotImplementedError

    def conditioning(self, x, legs) -> float:
        """Reciprocal condition number of the leg Jacobian at ``x`` (0 = singular)."""
        _, J = self.pose_residuals_jacobian(self.pose_state(x), legs)
        # rotation columns are per radian: scale them to per unit of length
        s = np.linalg.svd(J * self.pose_column_scale, compute_uv=False)
        return float(s[-1] / s[0]) if s[0] > 0 else 0.0
