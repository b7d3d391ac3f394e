"""Local refinement: Levenberg-Marquardt on the leg-residual vector in pose space.

The papers stop at fitness 1e-20 and ask for a refinement to follow the
evolutionary search (Rolland & Chandra 2016, conclusion; Chandra & Rolland 2014,
section 3 admits any local search in GLPMA).  The refinement is the compiled
Levenberg-Marquardt of :mod:`.lm` (Marquardt 1963; More 1978) on the model's pose
parameterisation, where the rigidity of the platform holds by construction and
the Jacobian is analytic; for models whose solver variables are redundant (the
hexapod's nine) a search on the floating-point grid may follow, so that the
papers' absolute fitness threshold is met (:func:`round_off_search`).

Each residual-and-Jacobian evaluation counts as one function evaluation.
"""
from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np

from .common import kernel_array
from .local import LocalSolver


def levenberg_marquardt(model, x0, legs, *, tolerance=1e-20, max_iter=50, deadline=None):
    """Refine solver variables ``x0`` (one compiled call, :func:`.lm.lm_kernel`).

    Returns ``(x, leg_fitness, nfev, iterations)``: ``leg_fitness`` is the sum of
    squared leg residuals of the returned pose.  Iterates until the leg residuals
    are within :data:`.lm.LEG_RTOL` of the geometry's scale and their sum of
    squares is below ``tolerance``, then takes one more Gauss-Newton step (to
    round-off); or until steps stop reducing the sum, or ``max_iter``.  The
    call is bounded by ``max_iter`` (microseconds per iteration), so the
    ``deadline`` (a ``time.perf_counter`` value) is checked before it only: past
    it, ``x0`` is evaluated but not moved.
    """
    if deadline is not None and time.perf_counter() >= deadline:
        max_iter = 0
    x0 = kernel_array(x0).reshape(-1)
    legs = kernel_array(legs).reshape(-1)
    solver = LocalSolver(model)
    r = solver.solve(x0, legs, max_iter=max_iter, ftol=tolerance)
    if r is None or not math.isfinite(r.leg_fitness):
        return x0.copy(), math.inf, 1 if r is None else r.nfev, 0
    return r.x.copy(), r.leg_fitness, r.nfev, r.nit


#: candidates per round and rounds of the floating-point-grid search
GRID_CANDIDATES = 64
GRID_ROUNDS = 8
#: perturbations of up to this many units in the last place per variable
GRID_ULPS = 3
#: the longest round of the grid search measured so far, per model kind (the thread's CPU time, s): a round is
#: NumPy and Python around one compiled evaluation of the candidates, several times the evaluation's own time,
#: so a round starts only when this much still fits before the deadline, and the driver leaves this much free
#: for the first (:func:`round_s`)
_ROUND_S: dict = {}
#: ... forgetting this share of itself per shorter round: a round slowed once (an interrupt on its core) does
#: not hold the search back for long, while the rounds' usual time stays reserved
ROUND_DECAY = 0.01


def round_s(model) -> float:
    """The expected time (s) of one round of :func:`round_off_search` on ``model`` (0: none measured yet)."""
    return _ROUND_S.get(model.kind, 0.0)


def round_off_search(model, x, legs, f, rng, *, target, deadline=None):
    """Greedy search on the floating-point grid around a refined ``x``.

    In the hexapod's 9-variable model the rigidity terms ``G_n`` change by about
    ``2 d_n`` times one unit in the last place of a coordinate (~1e-10 mm^2), so
    the float vector nearest the exact solution can have a fitness of 1e-19.
    Random perturbations of a few ulps, evaluated as one population, find a
    representable neighbour whose fitness is at round-off (< ``target``).  Under a ``deadline`` (a
    ``time.perf_counter`` value) a round starts only when its expected time (:func:`round_s`) still fits.
    Returns ``(x, f, nfev)``.
    """
    nfev = 0
    expected = round_s(model)
    for _ in range(GRID_ROUNDS):
        if f < target or (deadline is not None and time.perf_counter() + expected >= deadline):
            break
        c0 = time.thread_time()
        steps = rng.integers(-GRID_ULPS, GRID_ULPS + 1, size=(GRID_CANDIDATES, x.size))
        X = x + steps * np.spacing(x)
        F = model.fitness(X, legs)
        nfev += GRID_CANDIDATES
        i = int(np.argmin(F))
        if F[i] < f:
            x, f = X[i], float(F[i])
        expected = max(time.thread_time() - c0, (1.0 - ROUND_DECAY) * expected)
    _ROUND_S[model.kind] = expected
    return x, f, nfev


class Polished(NamedTuple):
    """Outcome of :func:`polish`: solver variables, the solver model's fitness, evaluations, and
    whether the Levenberg-Marquardt converged (redundant legs: at the least-squares pose)."""

    x: np.ndarray
    fitness: float
    nfev: int
    converged: bool


def polish(model, x0, legs, rng, *, tolerance=1e-20, max_iter=50, deadline=None) -> Polished:
    """Levenberg-Marquardt in pose space (:mod:`.lm`; its last evaluation gives the
    fitness of the solver's model), then, for models whose solver variables are
    redundant like the hexapod's nine, the round-off search.  Past ``deadline`` (a
    ``time.perf_counter`` value) nothing is computed: ``x0`` comes back with an infinite fitness."""
    x0 = kernel_array(x0).reshape(-1)
    if deadline is not None and time.perf_counter() >= deadline:
        return Polished(x0.copy(), math.inf, 0, False)      # no work after the deadline: not even evaluated
    legs = kernel_array(legs).reshape(-1)
    # redundant legs: measured legs leave a residual, the least-squares pose is the goal
    r = LocalSolver(model).solve(x0, legs, max_iter=max_iter, ftol=tolerance if model.redundancy == 0 else math.inf)
    if r is None:                       # legs outside the model's limits: evaluated, not refined
        return Polished(x0.copy(), float(model.fitness(x0, legs)[0]), 1, False)
    x, f, nfev = r.x.copy(), r.fitness, r.nfev
    if model.n_vars > model.n_pose and f >= tolerance * 0.1 and f < tolerance * 1e4:
        x, f, n = round_off_search(model, x, legs, f, rng, target=0.1 * tolerance, deadline=deadline)
        nfev += n
    return Polished(x, f, nfev, r.converged)
