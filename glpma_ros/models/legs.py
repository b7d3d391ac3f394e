"""The one leg model: every leg is a rod of known length between a point the actuator moves and a platform joint.

Leg ``i`` closes ``| p + R B_i - P_i(q_i) | = rod_i`` (``p``, ``R``: the platform's pose; ``B_i``: its
platform joint, platform frame), with the *proximal point*

* ``P_i(q) = origin_i + Rot(axis_i, q) crank_i`` for a **revolute** actuator (``q`` in radians; Rodrigues'
  formula ``Rot(a, q) c = c cos q + (a x c) sin q + a (a . c)(1 - cos q)``; planar legs turn about +z),
* ``P_i(q) = origin_i + q axis_i`` for a **prismatic** actuator (a rail; ``q`` in the config unit),
* ``P_i = origin_i`` and ``rod_i = q`` for a **length** actuator (today's RPR / UPS legs: the leg's length is
  the actuator).

This is the distal-rod formulation of Merlet, *Parallel Robots* (2nd ed., 2006, sections 3.1 and 4.2): once
the actuator positions are known, each proximal point is known and the forward kinematics is the same
"distance between a base point and a platform point" problem whatever the actuator.  So the actuator
positions ``q`` are turned *once per input* into the **leg vector** ``w = (rod_1..rod_n, P_1, .., P_n)``
(:func:`leg_vector_into`, compiled), which every compiled solver takes in place of the leg lengths
(:mod:`.residuals`); the inverse kinematics solves each leg for its actuator (:func:`actuator_for_point`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

#: actuator kinds (the YAML's ``actuator`` values, numbered for the compiled code)
LENGTH = 0
REVOLUTE = 1
PRISMATIC = 2
ACTUATOR_KINDS = {"length": LENGTH, "revolute": REVOLUTE, "prismatic": PRISMATIC}
#: a leg's reach equation is solvable while its discriminant is at least this share (relative) below
#: zero: a pose exactly at the boundary of the reach has a zero discriminant up to round-off
REACH_ROUND_OFF = 1e-12


@njit(cache=True, error_model="numpy")
def leg_vector_into(kinds, origin, axis, crank, rod, q, out):
    """The leg vector ``out = (rod_1..rod_n, P_1(q_1), .., P_n(q_n))`` of actuator positions ``q``."""
    n, dim = origin.shape
    for i in range(n):
        at = n + dim * i
        k = kinds[i]
        if k == LENGTH:
            out[i] = q[i]
            for a in range(dim):
                out[at + a] = origin[i, a]
        elif k == PRISMATIC:
            out[i] = rod[i]
            for a in range(dim):
                out[at + a] = origin[i, a] + q[i] * axis[i, a]
        else:
            out[i] = rod[i]
            c = math.cos(q[i])
            s = math.sin(q[i])
            if dim == 2:
                out[at] = origin[i, 0] + c * crank[i, 0] - s * crank[i, 1]
                out[at + 1] = origin[i, 1] + s * crank[i, 0] + c * crank[i, 1]
            else:
                ax, ay, az = axis[i, 0], axis[i, 1], axis[i, 2]
                cx, cy, cz = crank[i, 0], crank[i, 1], crank[i, 2]
                dot = (ax * cx + ay * cy + az * cz) * (1.0 - c)
                out[at] = origin[i, 0] + cx * c + (ay * cz - az * cy) * s + ax * dot
                out[at + 1] = origin[i, 1] + cy * c + (az * cx - ax * cz) * s + ay * dot
                out[at + 2] = origin[i, 2] + cz * c + (ax * cy - ay * cx) * s + az * dot


@njit(cache=True, error_model="numpy")
def readings_into(kinds, origin, axis, crank, rod, lo, hi, offsets, divisor, q, out):
    """The leg vector of actuator readings ``q / divisor`` (``divisor``: per actuator, the reading's unit in the
    model's: 1, or the config unit in metres for a prismatic reading in metres; then ``offsets`` added) into
    ``out`` when every reading is finite and within ``[lo, hi]``: returns -1; else nothing written and returns
    -2 (a reading not finite) or the index of the first reading outside its limits."""
    n = q.shape[0]
    scaled = np.empty(n)
    for i in range(n):
        scaled[i] = q[i] / divisor[i]
        if not math.isfinite(scaled[i]):
            return -2
    for i in range(n):
        if scaled[i] < lo[i] or scaled[i] > hi[i]:
            return i
    for i in range(n):
        scaled[i] += offsets[i]
    leg_vector_into(kinds, origin, axis, crank, rod, scaled, out)
    return -1


def _perpendicular_frame(axis, crank):
    """``(c_perp, a x c)``: the crank's component perpendicular to the axis and its quarter turn (planar: about +z)."""
    if crank.size == 2:
        return crank, np.array([-crank[1], crank[0]])
    c_perp = crank - axis * float(axis @ crank)
    return c_perp, np.cross(axis, crank)


def actuator_from_point(kind, origin, axis, crank, point) -> float:
    """The actuator position that puts the proximal point at ``point`` (the inverse of :func:`leg_vector_into`
    for one leg; a length actuator has no proximal motion: NaN)."""
    d = np.asarray(point, dtype=float) - origin
    if kind == PRISMATIC:
        return float(d @ axis)
    if kind == REVOLUTE:
        c_perp, quarter = _perpendicular_frame(axis, crank)
        return math.atan2(float(d @ quarter), float(d @ c_perp))
    return math.nan


def actuator_roots(kind, origin, axis, crank, rod, distal) -> list:
    """Every actuator position (0, 1 or 2) at which the rod of length ``rod`` reaches the platform joint at
    ``distal`` (base frame): the leg's inverse kinematics.

    Revolute: ``|v - Rot(a, q) c|^2 = rod^2`` with ``v = distal - origin`` is ``A cos q + B sin q = K``,
    ``A = v . c_perp``, ``B = v . (a x c)``, ``K = (|v|^2 + |c|^2 - rod^2) / 2 - (v . a)(a . c)``, so
    ``q = atan2(B, A) +- acos(K / sqrt(A^2 + B^2))``.  Prismatic: ``|v - q a|^2 = rod^2``, a quadratic in
    ``q``.  Length: the distance itself."""
    v = np.asarray(distal, dtype=float) - origin
    if kind == LENGTH:
        return [float(np.linalg.norm(v))]
    if kind == PRISMATIC:
        va = float(v @ axis)
        disc = va * va - float(v @ v) + rod * rod
        if disc < -REACH_ROUND_OFF * rod * rod:
            return []
        root = math.sqrt(max(disc, 0.0))
        return [va - root, va + root]
    c_perp, quarter = _perpendicular_frame(axis, crank)
    A, B = float(v @ c_perp), float(v @ quarter)
    along = 0.0 if v.size == 2 else float(v @ axis) * float(axis @ crank)
    K = 0.5 * (float(v @ v) + float(crank @ crank) - rod * rod) - along
    amplitude = math.hypot(A, B)
    if amplitude == 0.0 or abs(K) > amplitude * (1.0 + REACH_ROUND_OFF):
        return []
    centre, half = math.atan2(B, A), math.acos(max(-1.0, min(1.0, K / amplitude)))
    return [math.remainder(centre - half, 2.0 * math.pi), math.remainder(centre + half, 2.0 * math.pi)]


def choose_root(roots, limits) -> float | None:
    """The inverse kinematics' branch: a root inside the actuator's ``limits`` (``(lo, hi)`` or None), the one
    nearest the middle of the limits (without limits: nearest 0, the configured crank) when two are."""
    middle = 0.0 if limits is None else 0.5 * (limits[0] + limits[1])
    inside = [r for r in roots if limits is None or limits[0] <= r <= limits[1]]
    return min(inside, key=lambda r: abs(r - middle)) if inside else None
