"""The compiled evaluation every solver calls: residuals and fitness of one
individual or of a whole population, for any model.

The model is selected by an integer (``Manipulator.kind_id``) rather than by
passing its residual function: Numba keys an on-disk cache entry of a function
that takes another compiled function as an argument by that function's
per-process identity, so such entries never hit in a new process (each node
start would recompile every solver).  With an integer and a uniform data tuple
``(array2d, array2d, array1d, counter)`` every compiled solver is cached once.

``counter[0]`` counts residual evaluations: an independent check of the
solvers' evaluation bookkeeping (incremented once per call, outside the loops:
an increment inside them stops LLVM from keeping the geometry in registers
and slows the compiled loops down).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..runtime.compat import NUMBA_INLINE
from .residuals import (
    KIND_HEXAPOD_66,
    KIND_PLANAR_3RPR,
    actuated_residuals,
    hexapod_66_residuals,
    planar_3rpr_residuals,
)


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def residuals_into(x, kind, data, legs, out):
    """Residual vector of individual ``x`` into ``out`` (not counted: callers count)."""
    if kind == KIND_PLANAR_3RPR:
        planar_3rpr_residuals(x, data, legs, out)
    elif kind == KIND_HEXAPOD_66:
        hexapod_66_residuals(x, data, legs, out)
    else:
        actuated_residuals(x, kind, data, legs, out)


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def _sum_of_squares(x, kind, data, legs, r):
    residuals_into(x, kind, data, legs, r)
    s = 0.0
    for k in range(r.shape[0]):
        s += r[k] * r[k]
    return s if np.isfinite(s) else np.inf


@njit(cache=True, error_model="numpy")
def fitness_one(x, kind, data, legs, r):
    """Sum of squared residuals of ``x`` (``r`` is scratch space); ``+inf`` when
    the residuals are not finite (a degenerate individual).  Counts one."""
    data[3][0] += 1
    return _sum_of_squares(x, kind, data, legs, r)


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def population_fitness(X, kind, data, legs, n_res):
    """Fitness of every row of ``X`` (one compiled loop).  Counts one per row."""
    m = X.shape[0]
    data[3][0] += m
    f = np.empty(m)
    r = np.empty(n_res)
    for i in range(m):
        f[i] = _sum_of_squares(X[i], kind, data, legs, r)
    return f


@njit(cache=True, error_model="numpy")
def population_residuals(X, kind, data, legs, n_res):
    """Residual vectors of every row of ``X``.  Counts one per row."""
    m = X.shape[0]
    data[3][0] += m
    out = np.empty((m, n_res))
    for i in range(m):
        residuals_into(X[i], kind, data, legs, out[i])
    return out
