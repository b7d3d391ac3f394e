"""The compiled evaluation every solver calls: residuals and fitness of one
individual or of a whole population, for any model.

The model is selected by an integer (``Manipulator.kind_id``) rather than by
passing its residual function: Numba keys an on-disk cache entry of a function
that takes another compiled function as an argument by that function's
per-process identity, so such entries never hit in a new process (each node
start would recompile every solver).  With an integer and a uniform data tuple
``(array2d, array2d, array1d, counter)`` every compiled solver is cached once.

``counter[0]`` counts residual evaluations: an independent check of the
solvers' evaluation bookkeeping (a single increment, negligible cost).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .hexapod_66 import residual_kernel as hexapod_66_residuals
from .planar_3rpr import residual_kernel as planar_3rpr_residuals

KIND_PLANAR_3RPR = 0
KIND_HEXAPOD_66 = 1


@njit(cache=True, error_model="numpy")
def residuals_into(x, kind, data, legs, out):
    """Residual vector of individual ``x`` into ``out``."""
    data[3][0] += 1
    if kind == KIND_PLANAR_3RPR:
        planar_3rpr_residuals(x, data, legs, out)
    else:
        hexapod_66_residuals(x, data, legs, out)


@njit(cache=True, error_model="numpy")
def fitness_one(x, kind, data, legs, r):
    """Sum of squared residuals of ``x`` (``r`` is scratch space); ``+inf`` when
    the residuals are not finite (a degenerate individual)."""
    residuals_into(x, kind, data, legs, r)
    s = 0.0
    for k in range(r.shape[0]):
        s += r[k] * r[k]
    return s if np.isfinite(s) else np.inf


@njit(cache=True, error_model="numpy")
def population_fitness(X, kind, data, legs, n_res):
    """Fitness of every row of ``X`` (one compiled loop)."""
    m = X.shape[0]
    f = np.empty(m)
    r = np.empty(n_res)
    for i in range(m):
        f[i] = fitness_one(X[i], kind, data, legs, r)
    return f


@njit(cache=True, error_model="numpy")
def population_residuals(X, kind, data, legs, n_res):
    """Residual vectors of every row of ``X``."""
    m = X.shape[0]
    out = np.empty((m, n_res))
    for i in range(m):
        residuals_into(X[i], kind, data, legs, out[i])
    return out
