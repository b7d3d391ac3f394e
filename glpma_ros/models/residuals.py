"""Residual vectors of one individual for every manipulator kind, compiled.

Each function fills ``out`` with the residuals of solver variables ``x`` for leg
lengths ``legs``; ``data`` is the model's uniform tuple (see
:meth:`~glpma_ros.models.base.Manipulator._make_data`).  The kinds are numbered
here, once; a model class names its number as ``kind_id``.
The formulas are documented with the models (:mod:`.planar_3rpr`, :mod:`.hexapod_66`, :mod:`.actuated`).

Every kind is the one leg model of :mod:`.legs`: leg ``i`` is a rod of length ``rod_i`` between a proximal
point ``P_i`` and the platform joint ``p + R B_i``.  The length-actuated kinds (3-RPR, hexapod) have fixed
proximal points (the model's ``base``, ``data[0]``) and the rods are the measured legs; the actuated kinds
(``KIND_ACTUATED_*``) read both from the per-solve *leg vector* ``legs = (rod_1..rod_n, P_1, .., P_n)``
(:func:`split_leg_vector`), computed from the actuator positions once per input by :mod:`.legs`.
"""
from __future__ import annotations

import math

from numba import njit

from ..runtime.compat import NUMBA_INLINE

KIND_PLANAR_3RPR = 0
KIND_HEXAPOD_66 = 1
#: the actuated families: planar full pose (3-RRR, 3-PRR), spatial full pose (6-RUS, 6-PUS), translation (deltas)
KIND_ACTUATED_PLANAR = 2
KIND_ACTUATED_SPATIAL = 3
KIND_ACTUATED_TRANSLATION = 4


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def split_leg_vector(legs, n, dim):
    """The rods (``n``) and the proximal points (``n x dim``) of an actuated kind's leg vector."""
    return legs[:n], legs[n:n + n * dim].reshape((n, dim))


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def planar_rods_residuals(x, base, platform, legs, out):
    """``|C + R(theta) CB_i - A_i| - l_i`` for the planar pose ``x = (x, y, theta)``."""
    c = math.cos(x[2])
    s = math.sin(x[2])
    for i in range(base.shape[0]):
        bx = x[0] + c * platform[i, 0] - s * platform[i, 1] - base[i, 0]
        by = x[1] + s * platform[i, 0] + c * platform[i, 1] - base[i, 1]
        out[i] = math.sqrt(bx * bx + by * by) - legs[i]


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def planar_3rpr_residuals(x, data, legs, out):
    planar_rods_residuals(x, data[0], data[1], legs, out)


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def spatial_rods_residuals(x, base, abc, d0sq, legs, out):
    """The nine-variable residuals (leg errors, then the three rigidity terms) of :mod:`.hexapod_66`."""
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
    n = base.shape[0]
    for j in range(n):
        a, b, c = abc[j, 0], abc[j, 1], abc[j, 2]
        bx = x[0] + a * u1x + b * u2x + c * u3x - base[j, 0]
        by = x[1] + a * u1y + b * u2y + c * u3y - base[j, 1]
        bz = x[2] + a * u1z + b * u2z + c * u3z - base[j, 2]
        out[j] = math.sqrt(bx * bx + by * by + bz * bz) - legs[j]
    e3x = x[6] - x[3]
    e3y = x[7] - x[4]
    e3z = x[8] - x[5]
    out[n] = d0sq[0] - n1sq
    out[n + 1] = d0sq[1] - n2sq
    out[n + 2] = d0sq[2] - (e3x * e3x + e3y * e3y + e3z * e3z)


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def hexapod_66_residuals(x, data, legs, out):
    spatial_rods_residuals(x, data[0], data[1], data[2], legs, out)


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def translation_rods_residuals(x, base, platform, legs, out):
    """``|p + B_i - P_i| - rod_i`` for a platform that only translates, ``x = p``."""
    for i in range(base.shape[0]):
        bx = x[0] + platform[i, 0] - base[i, 0]
        by = x[1] + platform[i, 1] - base[i, 1]
        bz = x[2] + platform[i, 2] - base[i, 2]
        out[i] = math.sqrt(bx * bx + by * by + bz * bz) - legs[i]


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def actuated_residuals(x, kind, data, legs, out):
    """The actuated kinds: the same distance residuals with the proximal points of the leg vector.
    ``data`` = (platform joints or frame coefficients, platform joints, rigidity d0^2, counter)."""
    platform = data[1]
    n = platform.shape[0]
    if kind == KIND_ACTUATED_PLANAR:
        rods, base = split_leg_vector(legs, n, 2)
        planar_rods_residuals(x, base, platform, rods, out)
    elif kind == KIND_ACTUATED_SPATIAL:
        rods, base = split_leg_vector(legs, n, 3)
        spatial_rods_residuals(x, base, data[0], data[2], rods, out)
    else:
        rods, base = split_leg_vector(legs, n, 3)
        translation_rods_residuals(x, base, platform, rods, out)
