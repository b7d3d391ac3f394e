"""The Python side of the compiled local solve (:mod:`glpma_ros.solvers.lm`): the ``settings`` vector
of a model (:func:`make_settings`), the result of one solve (:class:`LocalResult`), a per-thread solver
with its own buffers (:class:`LocalSolver`) and the one-call :func:`local_solve`."""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .common import kernel_array
from .lm import (
    I_CONDITIONING,
    I_CONVERGED,
    I_DISTANCE,
    I_FITNESS,
    I_INPUT_OK,
    I_LEG_FITNESS,
    I_MAX_RESIDUAL,
    I_MOVEMENT,
    I_NFEV,
    I_NIT,
    I_PROGRESS,
    I_STATIONARITY,
    LEG_RTOL,
    LSQ_GTOL,
    MAX_ITER,
    N_INFO,
    S_FTOL,
    S_HI,
    S_LO,
    S_MAX_ITER,
    S_RTOL,
    S_STALL,
    lm_kernel,
    multistart_kernel,
    warm_buffer,
    warm_kernel,
    workspace_size,
)


def make_settings(model, *, max_iter=None, rtol=None, ftol=math.inf) -> np.ndarray:
    """The ``settings`` vector of :func:`lm_kernel` for ``model`` (its scale, leg limits and column
    scale; ``rtol`` default ``LEG_RTOL``, ``max_iter`` default ``MAX_ITER``)."""
    limits = model.leg_limits
    lo, hi = (-math.inf, math.inf) if limits is None else (float(limits[0]), float(limits[1]))
    head = [model.scale, lo, hi, LEG_RTOL if rtol is None else rtol, ftol,
            MAX_ITER if max_iter is None else max_iter, 0.0, model.n_res,
            LSQ_GTOL if model.n_legs > model.n_pose else 0.0]
    return np.ascontiguousarray(np.concatenate((head, model.pose_column_scale)), dtype=float)


#: one output vector of :func:`lm_kernel` for a model of n solver variables: the variables x (n), then these
#: slots -- the platform's position (3) and unit quaternion (4) --, then the info (``N_INFO``, the ``I_*``
#: layout); read by name through :class:`LmOutput`
POSE_OUT = 7


class LmInfo(NamedTuple):
    """The ``info`` part of :func:`lm_kernel`'s output, by name (fields in the order of the ``I_*``
    layout, checked below): what the estimator's warm path reads of one compiled call."""

    leg_fitness: float        # sum of squared leg residuals at the returned variables
    max_residual: float       # max |r_i| (config unit)
    fitness: float            # the papers' fitness of the returned variables
    conditioning: float       # reciprocal condition number of the leg Jacobian (0 = singular)
    stationarity: float       # |J^T r| / (|J| |r|)
    distance: float           # platform-joint distance from x_ref
    movement: float           # max |legs - legs_ref|
    nfev: float
    nit: float
    converged: float          # 1.0 when converged
    input_ok: float           # 0.0 when the legs failed the check (nothing solved)
    progress: float           # relative decrease of the leg fitness over the last iterations

    @classmethod
    def of(cls, out, n_vars: int) -> "LmInfo":
        """The info of ``out`` (one output vector of a model with ``n_vars`` solver variables)."""
        return cls._make(out[n_vars + POSE_OUT:].tolist())


assert [LmInfo._fields.index(name) for name in ("leg_fitness", "max_residual", "fitness", "conditioning",
                                                  "stationarity", "distance", "movement", "nfev", "nit",
                                                  "converged", "input_ok", "progress")] == [
    I_LEG_FITNESS, I_MAX_RESIDUAL, I_FITNESS, I_CONDITIONING, I_STATIONARITY, I_DISTANCE, I_MOVEMENT, I_NFEV,
    I_NIT, I_CONVERGED, I_INPUT_OK, I_PROGRESS] and len(LmInfo._fields) == N_INFO, "LmInfo out of step with lm.I_*"


class LmOutput(NamedTuple):
    """One output vector of :func:`lm_kernel`, by name (layout: :data:`POSE_OUT`)."""

    x: np.ndarray             # solver variables
    position: np.ndarray      # platform origin
    orientation: np.ndarray   # unit quaternion [qx, qy, qz, qw]
    info: LmInfo

    @classmethod
    def of(cls, out, n_vars: int) -> "LmOutput":
        """The parts of ``out`` (views, not copies) for a model of ``n_vars`` solver variables."""
        return cls(out[:n_vars], out[n_vars:n_vars + 3], out[n_vars + 3:n_vars + POSE_OUT], LmInfo.of(out, n_vars))


class LocalResult(NamedTuple):
    """Outcome of one local solve (config unit)."""

    x: np.ndarray             # solver variables
    position: np.ndarray      # platform origin
    orientation: np.ndarray   # unit quaternion [qx, qy, qz, qw]
    converged: bool
    max_residual: float       # max |r_i| over the legs
    leg_fitness: float        # sum of squared leg residuals
    fitness: float            # the papers' fitness of x (the model's residual vector)
    conditioning: float       # reciprocal condition number of the leg Jacobian (0 = singular)
    stationarity: float       # |J^T r| / (|J| |r|), small at a stationary point
    progress: float           # relative decrease of the leg fitness over the last 10-20 iterations
    distance: float           # platform-joint distance from x_ref (default: the start)
    movement: float           # max |legs - legs_ref| (0 without legs_ref)
    nfev: int
    nit: int


_NO_LEGS = np.zeros(0)


class LocalSolver:
    """The compiled local solve of one model with its own buffers (one per thread).

    :meth:`run` is the raw call (fills and returns a fresh ``out`` vector, see :func:`lm_kernel`);
    :meth:`solve` wraps it in a :class:`LocalResult`; :meth:`multistart` tries several starts."""

    def __init__(self, model):
        self.model = model
        self.kind = int(model.kind_id)
        self.data = model.data
        self.platform = np.ascontiguousarray(model.platform, dtype=float)
        self.frame = np.ascontiguousarray(model.frame, dtype=float)
        self.n_vars = int(model.n_vars)
        self.n_out = self.n_vars + POSE_OUT + N_INFO
        self.work = np.zeros(workspace_size(model.n_legs, model.n_pose, model.n_res) + self.n_out)
        self.settings = make_settings(model)
        self._limits = model.leg_limits

    def prepare(self):
        """Load (or compile) the kernels for this model's types (the estimator's warm one too), with a call that
        does no iteration."""
        x0 = np.zeros((1, self.n_vars))
        legs = np.ones(self.model.leg_vector_size)
        settings = make_settings(self.model, max_iter=0)
        settings[S_LO], settings[S_HI] = 0.0, math.inf
        out = np.empty(self.n_out)
        lm_kernel(self.kind, self.data, self.platform, self.frame, legs, x0[0], x0[0], _NO_LEGS, settings, out,
                  self.work)
        multistart_kernel(self.kind, self.data, self.platform, self.frame, legs, x0, x0[0], settings, out,
                          self.work)
        warm_kernel(self.warm_buffer(settings), legs, x0[0], _NO_LEGS, out)

    def warm_buffer(self, settings) -> np.ndarray:
        """The buffer of :func:`warm_kernel` for this model with ``settings`` (its own work space)."""
        return warm_buffer(self.kind, self.data, self.platform, self.frame, settings,
                           workspace_size(self.model.n_legs, self.model.n_pose, self.model.n_res))

    def _settings(self, max_iter, rtol, ftol, stall):
        settings = self.settings
        if self.model.leg_limits is not self._limits:          # the model's limits were changed
            self.settings = settings = make_settings(self.model)
            self._limits = self.model.leg_limits
        settings[S_RTOL] = rtol
        settings[S_FTOL] = ftol
        settings[S_MAX_ITER] = max_iter
        settings[S_STALL] = stall
        return settings

    def run(self, x0, legs, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf, x_ref=None, legs_ref=_NO_LEGS,
            stall=0.0):
        """``x0``, ``legs``: contiguous float64 arrays of the model's sizes.  Returns ``out``."""
        settings = self._settings(max_iter, rtol, ftol, stall)
        out = np.empty(self.n_out)
        lm_kernel(self.kind, self.data, self.platform, self.frame, legs, x0, x0 if x_ref is None else x_ref,
                  legs_ref, settings, out, self.work)
        return out

    def solve(self, x0, legs, *, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf, x_ref=None,
              legs_ref=_NO_LEGS, stall=0.0) -> LocalResult | None:
        """:class:`LocalResult`, or None when the legs fail the check (not finite, not positive,
        outside the model's leg limits)."""
        return self.result(self.run(x0, legs, max_iter, rtol, ftol, x_ref, legs_ref, stall))

    def multistart(self, starts, legs, *, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf, x_ref=None,
                   stall=0.0) -> LocalResult | None:
        """The first converged solve from the rows of ``starts`` (contiguous, float64), else the one of
        least leg fitness; ``nfev`` / ``nit`` count every start tried.  ``x_ref`` default: the first
        start."""
        settings = self._settings(max_iter, rtol, ftol, stall)
        out = np.empty(self.n_out)
        multistart_kernel(self.kind, self.data, self.platform, self.frame, legs, starts,
                          starts[0] if x_ref is None else x_ref, settings, out, self.work)
        return self.result(out)

    def result(self, out) -> LocalResult | None:
        o = LmOutput.of(out, self.n_vars)
        i = o.info
        if i.input_ok == 0.0:
            return None
        return LocalResult(o.x, o.position, o.orientation, i.converged == 1.0, i.max_residual, i.leg_fitness,
                           i.fitness, i.conditioning, i.stationarity, i.progress, i.distance, i.movement,
                           int(i.nfev), int(i.nit))


def local_solve(model, x0, legs, *, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf) -> LocalResult:
    """Levenberg-Marquardt from solver variables ``x0`` to the pose for ``legs`` (config unit).

    ``converged``: ``max |r_i| <= rtol * max(scale, max leg)`` (and leg fitness ``< ftol``).  Raises
    ``ValueError`` for legs that are not finite, not positive or outside the model's leg limits.
    Thread-safe (its own buffers); for many calls keep a :class:`LocalSolver` per thread."""
    x0 = kernel_array(x0).reshape(-1)
    legs = kernel_array(legs).reshape(-1)
    if x0.size != model.n_vars or legs.size != model.leg_vector_size:
        raise ValueError(f"expected {model.n_vars} variables and {model.leg_vector_size} legs")
    result = LocalSolver(model).solve(x0, legs, max_iter=max_iter, rtol=rtol, ftol=ftol)
    if result is None:
        raise ValueError("leg lengths must be finite, positive and within the leg limits")
    return result
