"""Local refinement: Levenberg-Marquardt on the leg-residual vector in pose space.

The papers stop at fitness 1e-20 and ask for a refinement to follow the
evolutionary search (Rolland & Chandra 2016, conclusion; Chandra & Rolland 2014,
section 3 admits any local search in GLPMA).  We use Marquardt's damped
Gauss-Newton step ``(J^T J + lam diag(J^T J)) s = -J^T r`` (Marquardt 1963;
More 1978) on the model's pose parameterisation, where the rigidity of the
platform holds by construction and the Jacobian is analytic.

Each residual-and-Jacobian evaluation counts as one function evaluation.
"""
from __future__ import annotations

import time

import numpy as np

#: initial damping relative to the largest diagonal entry of J^T J
LAMBDA_INIT = 1e-6
#: damping update on a rejected / accepted step (Nielsen-style factors)
LAMBDA_UP = 10.0
LAMBDA_DOWN = 0.1
#: consecutive rejected steps after which the iterate is at round-off
MAX_REJECTIONS = 6


def levenberg_marquardt(model, x0, legs, *, tolerance=1e-20, max_iter=50, deadline=None):
    """Refine solver variables ``x0``.

    Returns ``(x, leg_fitness, nfev, iterations)``: ``leg_fitness`` is the sum of
    squared leg residuals of the returned pose.  Iterates until the fitness is
    below ``tolerance`` and one more Gauss-Newton step has brought it to
    round-off, until steps stop reducing it, ``max_iter`` or ``deadline``
    (a ``time.perf_counter`` value) passes.
    """
    state = model.pose_state(x0)
    r, J = model.pose_residuals_jacobian(state, legs)
    nfev = 1
    with np.errstate(over="ignore", invalid="ignore"):   # huge legs: an infinite fitness, reported as such
        f = float(r @ r)
    if not np.isfinite(f):
        return np.asarray(x0, dtype=float), np.inf, nfev, 0
    A = J.T @ J
    n = A.shape[0]
    lam = LAMBDA_INIT * float(A.diagonal().max())
    rejections = 0
    below_tol_steps = 0
    it = 0
    for it in range(1, max_iter + 1):
        if deadline is not None and time.perf_counter() >= deadline:
            break
        g = J.T @ r
        damped = A.copy()
        damped.flat[::n + 1] += lam * np.maximum(A.diagonal(), 1e-300)   # Marquardt's scaling
        try:
            step = np.linalg.solve(damped, -g)
        except np.linalg.LinAlgError:
            lam *= LAMBDA_UP
            rejections += 1
            if rejections > MAX_REJECTIONS:
                break
            continue
        trial = model.pose_retract(state, step)
        r2, J2 = model.pose_residuals_jacobian(trial, legs)
        nfev += 1
        f2 = float(r2 @ r2)
        if np.isfinite(f2) and f2 < f:
            state, r, J, f = trial, r2, J2, f2
            A = J.T @ J
            lam *= LAMBDA_DOWN
            rejections = 0
            if f < tolerance:
                below_tol_steps += 1
                if below_tol_steps >= 2 or f == 0.0:
                    break
        else:
            lam *= LAMBDA_UP
            rejections += 1
            if rejections > MAX_REJECTIONS or (f < tolerance and rejections > 1):
                break
    return model.pose_variables(state), f, nfev, it


#: candidates per round and rounds of the floating-point-grid search
GRID_CANDIDATES = 64
GRID_ROUNDS = 8
#: perturbations of up to this many units in the last place per variable
GRID_ULPS = 3


def round_off_search(model, x, legs, f, rng, *, target, deadline=None):
    """Greedy search on the floating-point grid around a refined ``x``.

    In the hexapod's 9-variable model the rigidity terms ``G_n`` change by about
    ``2 d_n`` times one unit in the last place of a coordinate (~1e-10 mm^2), so
    the float vector nearest the exact solution can have a fitness of 1e-19.
    Random perturbations of a few ulps, evaluated as one population, find a
    representable neighbour whose fitness is at round-off (< ``target``).
    Returns ``(x, f, nfev)``.
    """
    nfev = 0
    for _ in range(GRID_ROUNDS):
        if f < target or (deadline is not None and time.perf_counter() >= deadline):
            break
        steps = rng.integers(-GRID_ULPS, GRID_ULPS + 1, size=(GRID_CANDIDATES, x.size))
        X = x + steps * np.spacing(x)
        F = model.fitness(X, legs)
        nfev += GRID_CANDIDATES
        i = int(np.argmin(F))
        if F[i] < f:
            x, f = X[i], float(F[i])
    return x, f, nfev


def polish(model, x0, legs, rng, *, tolerance=1e-20, max_iter=50, deadline=None):
    """Levenberg-Marquardt in pose space, then (for models whose solver
    variables are redundant, like the hexapod's nine) the round-off search.
    Returns ``(x, fitness, nfev)`` with the fitness of the solver's model."""
    x, _, nfev, _ = levenberg_marquardt(model, x0, legs, tolerance=tolerance, max_iter=max_iter,
                                        deadline=deadline)
    f = float(model.fitness(x, legs)[0])
    nfev += 1
    if model.n_vars > model.n_pose and f >= tolerance * 0.1 and f < tolerance * 1e4:
        x, f, n = round_off_search(model, x, legs, f, rng, target=0.1 * tolerance, deadline=deadline)
        nfev += n
    return x, f, nfev
