"""Residual vectors of one individual for every manipulator kind, compiled.

Each function fills ``out`` with the residuals of solver variables ``x`` for leg
lengths ``legs``; ``data`` is the model's uniform tuple (see
:meth:`~glpma_ros.models.base.Manipulator._make_data`).  The kinds are numbered
here, once; a model class names its number as ``kind_id``.
The formulas are documented with the models (:mod:`.planar_3rpr`, :mod:`.hexapod_66`).
"""
from __future__ import annotations

import math

from numba import njit

KIND_PLANAR_3RPR = 0
KIND_HEXAPOD_66 = 1


@njit(cache=True, error_model="numpy", inline="always")
def planar_3rpr_residuals(x, data, legs, out):
    base, platform = data[0], data[1]
    c = math.cos(x[2])
    s = math.sin(x[2])
    for i in range(base.shape[0]):
        bx = x[0] + c * platform[i, 0] - s * platform[i, 1] - base[i, 0]
        by = x[1] + s * platform[i, 0] + c * platform[i, 1] - base[i, 1]
        out[i] = math.sqrt(bx * bx + by * by) - legs[i]


@njit(cache=True, error_model="numpy", inline="always")
def hexapod_66_residuals(x, data, legs, out):
    base, abc, d0sq = data[0], data[1], data[2]
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
