"""The model families of the parameter homotopy (:mod:`.homotopy`): each a square system of complex quadrics.

Every equation is ``w^T Q_i(p) w = 0`` with ``w = (z, 1)`` and ``Q_i`` symmetric, its entries polynomials of
degree at most two in the parameters ``p`` (geometry and legs), so that the coefficients along a parameter path
are exactly quadratic (:meth:`Family.coefficient_path`).

- *Planar 3-RPR* (:class:`Planar3RPRFamily`): ``z = (x, y, c, s)``, the platform origin and the cosine and sine
  of its angle; three leg circles ``|(x, y) + R(c, s) b_i - a_i|^2 = L_i^2`` and ``c^2 + s^2 = 1``.  A generic
  member has 6 solutions (Gosselin, Sefrioui & Richard 1992, Mech. Mach. Theory 27(2)).
- *General 6-6 hexapod* (:class:`Hexapod66Family`): Study's kinematic mapping (Husty 1996, Mech. Mach. Theory
  31(4); Wampler 1996, Mech. Mach. Theory 31(3)): the rotation quaternion ``e`` and the dual part ``f``, Study's
  quadric ``e.f = 0`` and one quadric per leg (see :mod:`glpma_ros.modes.exact`), in the affine patch
  ``l.e = 1`` of a random complex form ``l``: 7 unknowns, 7 quadrics, 40 solutions for a generic member.

A family also maps a real target (a model and its legs) to normalised parameters (:class:`Target`) and an
endpoint back to the model's solver variables.  No ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..models.hexapod_66 import matrix_from_quaternion
from .path_tracker import HEXAPOD_66, PLANAR_3RPR, ParameterPath, dense_path, structured_path
from .polynomials import qmul

#: an endpoint is real when its imaginary part is below this share of its size (a real solution of the
#: real target, polished in complex arithmetic, keeps an imaginary part of round-off; a complex pair closer
#: to the real space than this is within about its square of a singularity, where the rounding of the
#: input already decides)
REAL_TOLERANCE = 1e-8
#: a 6-6 endpoint with |e.e| below this share of |e|^2 is not a pose (Study's exceptional quadric)
NULL_ROTATION = 1e-8


def _quaternion_left(p):
    """``L(p)``, 4x4 (rows of a stack): ``p q = L(p) q`` (scalar first); ``p`` of shape (..., 4)."""
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    return np.stack([np.stack([p0, -p1, -p2, -p3], -1), np.stack([p1, p0, -p3, p2], -1),
                     np.stack([p2, p3, p0, -p1], -1), np.stack([p3, -p2, p1, p0], -1)], -2)


def _quaternion_right(p):
    """``R(p)``: ``q p = R(p) q``."""
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    return np.stack([np.stack([p0, -p1, -p2, -p3], -1), np.stack([p1, p0, p3, -p2], -1),
                     np.stack([p2, -p3, p0, p1], -1), np.stack([p3, p2, -p1, p0], -1)], -2)


def _pure(v):
    """Pure quaternions (0, v) of the rows ``v`` (..., 3)."""
    return np.concatenate([np.zeros(v.shape[:-1] + (1,), v.dtype), v], -1)


def _bdot(u, v):
    """Bilinear (not Hermitian) dot product over the last axis."""
    return np.sum(u * v, axis=-1)


@dataclass
class Target:
    """A real target in the family's normalised coordinates: parameters and the map back."""

    params: np.ndarray
    base_centre: np.ndarray
    platform_centre: np.ndarray
    scale: float


class Family:
    """A model family: its unknowns, its quadrics ``Q_i(p)`` and the conversions (subclasses)."""

    name = ""
    root_count = 0
    n_unknowns = 0
    dof = 0

    def quadrics(self, p) -> np.ndarray:
        raise NotImplementedError

    def coefficient_path(self, p0, p1) -> np.ndarray:
        """``K`` (3, m, n + 1, n + 1) with ``Q(p0 + tau (p1 - p0)) = K_0 + tau K_1 + tau^2 K_2`` exactly (the
        quadrics are of degree two in ``p``: three evaluations determine the quadratic)."""
        q0, qh, q1 = self.quadrics(p0), self.quadrics(0.5 * (p0 + p1)), self.quadrics(p1)
        return np.ascontiguousarray(np.stack([q0, 4.0 * qh - 3.0 * q0 - q1, 2.0 * q0 + 2.0 * q1 - 4.0 * qh]))

    def parameter_path(self, p0, p1) -> ParameterPath:
        """The system along ``p0 -> p1`` for the compiled tracker: the dense quadrics (a family without an
        evaluator of its own)."""
        return dense_path(self.coefficient_path(p0, p1))

    def target(self, model, legs) -> Target:
        """The target's parameters: the first ``dof`` legs, frames moved to their joints' centroids, lengths
        divided by the scale (every coordinate of order one)."""
        k = self.dof_legs
        base = np.asarray(model.base, float)[:k]
        platform = np.asarray(model.platform, float)[:k]
        ca, cb, s = base.mean(axis=0), platform.mean(axis=0), float(model.scale)
        p = np.concatenate([((base - ca) / s).ravel(), ((platform - cb) / s).ravel(),
                            np.asarray(legs, float)[:k] / s]).astype(complex)
        return Target(p, ca, cb, s)


class Planar3RPRFamily(Family):
    """3-RPR: ``z = (x, y, c, s)``; parameters ``a`` (3x2), ``b`` (3x2), ``L`` (3)."""

    name = "planar_3rpr"
    root_count = 6
    n_unknowns = 4
    dof_legs = 3

    def another_patch(self, rng) -> "Planar3RPRFamily":
        return self                                       # affine unknowns: no patch

    def convert(self, z, other) -> np.ndarray:
        return np.ascontiguousarray(z)

    def split(self, p):
        return p[0:6].reshape(3, 2), p[6:12].reshape(3, 2), p[12:15]

    def parameter_path(self, p0, p1) -> ParameterPath:
        """The 3-RPR's own evaluator (:func:`.path_tracker._evaluate_3rpr`) on the interpolated parameters."""
        return structured_path(PLANAR_3RPR, p0, p1)

    def quadrics(self, p) -> np.ndarray:
        a, b, L = self.split(np.asarray(p, complex))
        Q = np.zeros((4, 5, 5), complex)
        # leg i: u = (x, y) + R(c, s) b - a = P w with w = (x, y, c, s, 1)
        P = np.zeros((3, 2, 5), complex)
        P[:, 0, 0] = P[:, 1, 1] = 1.0
        P[:, 0, 2], P[:, 0, 3], P[:, 0, 4] = b[:, 0], -b[:, 1], -a[:, 0]
        P[:, 1, 2], P[:, 1, 3], P[:, 1, 4] = b[:, 1], b[:, 0], -a[:, 1]
        Q[:3] = np.einsum("ikm,ikn->imn", P, P)
        Q[:3, 4, 4] -= L * L
        Q[3, 2, 2] = Q[3, 3, 3] = 1.0
        Q[3, 4, 4] = -1.0
        return Q

    def random_instance(self, rng):
        """Random complex geometry and a random complex point ``z``; legs that make ``z`` a solution."""
        a = _crandn(rng, (3, 2))
        b = _crandn(rng, (3, 2))
        c = _crandn(rng, ())
        z = np.array([_crandn(rng, ()), _crandn(rng, ()), c, np.sqrt(1.0 - c * c)])
        p = np.concatenate([a.ravel(), b.ravel(), np.zeros(3, complex)])
        w = np.append(z, 1.0)
        L2 = np.einsum("m,imn,n->i", w, self.quadrics(p)[:3], w)
        p[12:15] = np.sqrt(L2)
        return p, z

    def random_params(self, rng):
        return _crandn(rng, 15)

    def to_pose(self, model, target: Target, z, tolerance=REAL_TOLERANCE):
        """Solver variables ``(x, y, theta)`` of a real endpoint (imaginary part within ``tolerance`` of its
        size), or None when it is not real."""
        if np.max(np.abs(z.imag)) > tolerance * (1.0 + np.max(np.abs(z))):
            return None
        x, y, c, s = z.real
        theta = math.atan2(s, c)
        R = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
        origin = target.scale * np.array([x, y]) + target.base_centre - R @ target.platform_centre
        return np.array([origin[0], origin[1], theta])

    def is_pose(self, z, tol=None) -> bool:
        return True


class Hexapod66Family(Family):
    """General 6-6 in Study parameters on the patch ``l.e = 1``: ``z = (e1, e2, e3, f0, f1, f2, f3)``;
    parameters ``a`` (6x3), ``b`` (6x3), ``L`` (6)."""

    name = "hexapod_66"
    root_count = 40
    n_unknowns = 7
    dof_legs = 6

    def __init__(self, patch):
        self.patch = np.asarray(patch, complex)            # l: the affine patch l.e = 1
        # (e, f) = T (z, 1): e0 = (1 - l1 e1 - l2 e2 - l3 e3) / l0
        T = np.zeros((8, 8), complex)
        T[0, 0:3] = -self.patch[1:4] / self.patch[0]
        T[0, 7] = 1.0 / self.patch[0]
        T[1, 0] = T[2, 1] = T[3, 2] = 1.0
        T[4, 3] = T[5, 4] = T[6, 5] = T[7, 6] = 1.0
        self.T = T

    def another_patch(self, rng) -> "Hexapod66Family":
        return Hexapod66Family(_crandn(rng, 4))

    def convert(self, z, other: "Hexapod66Family") -> np.ndarray:
        """Unknowns ``z`` (rows) of this patch in the patch of ``other`` (the same projective points)."""
        ef = self.full(z)
        ef = ef / (ef[..., :4] @ other.patch)[..., None]
        return np.ascontiguousarray(ef[..., [1, 2, 3, 4, 5, 6, 7]])

    def split(self, p):
        return p[0:18].reshape(6, 3), p[18:36].reshape(6, 3), p[36:42]

    def parameter_path(self, p0, p1) -> ParameterPath:
        """The 6-6's own evaluator (:func:`.path_tracker._evaluate_66`) on the interpolated parameters; the
        patch as ``e_0 = c_0 + c . (e_1, e_2, e_3)``: the first row of ``T``."""
        return structured_path(HEXAPOD_66, p0, p1, [self.T[0, 7], self.T[0, 0], self.T[0, 1], self.T[0, 2]])

    def homogeneous_quadrics(self, p) -> np.ndarray:
        """The seven quadrics in ``(e, f)`` (8x8 each): six legs and Study's quadric."""
        a, b, L = self.split(np.asarray(p, complex))
        La = _quaternion_left(_pure(a))
        Rb = _quaternion_right(_pure(b))
        k = _bdot(a, a) + _bdot(b, b) - L * L
        Q = np.zeros((7, 8, 8), complex)
        RtL = np.einsum("ikj,ikl->ijl", Rb, La)                 # R(b)^T L(a)
        Q[:6, :4, :4] = k[:, None, None] * np.eye(4) - (RtL + np.transpose(RtL, (0, 2, 1)))
        fe = 2.0 * (Rb - La)                                  # f^T (4 R(b) - 4 L(a)) e, symmetrised
        Q[:6, 4:, :4] = fe
        Q[:6, :4, 4:] = np.transpose(fe, (0, 2, 1))
        Q[:6, 4:, 4:] = 4.0 * np.eye(4)
        Q[6, :4, 4:] = Q[6, 4:, :4] = 0.5 * np.eye(4)        # Study's quadric e.f = 0
        return Q

    def quadrics(self, p) -> np.ndarray:
        return np.einsum("ji,mjk,kl->mil", self.T, self.homogeneous_quadrics(p), self.T)

    def full(self, z):
        """``(e, f)`` of reduced unknowns ``z`` (rows)."""
        z = np.asarray(z, complex)
        return np.einsum("ij,...j->...i", self.T, np.concatenate([z, np.ones(z.shape[:-1] + (1,))], -1))

    def random_instance(self, rng):
        a = _crandn(rng, (6, 3))
        b = _crandn(rng, (6, 3))
        z = _crandn(rng, 7)
        ef = self.full(z)
        e, f = ef[:4], ef[4:]
        f = f - _bdot(e, f) / _bdot(e, e) * e                 # onto Study's quadric
        z[3:] = f
        ef = self.full(z)
        p = np.concatenate([a.ravel(), b.ravel(), np.zeros(6, complex)])
        Q = self.homogeneous_quadrics(p)
        value = np.einsum("m,imn,n->i", ef, Q[:6], ef)        # with L = 0
        p[36:42] = np.sqrt(value / _bdot(ef[:4], ef[:4]))
        return p, z

    def random_params(self, rng):
        return _crandn(rng, 42)

    def is_pose(self, z, tol=NULL_ROTATION) -> bool:
        """Off Study's exceptional quadric: ``|e.e| > tol |e|^2``."""
        e = self.full(z)[:4]
        return abs(_bdot(e, e)) > tol * float(np.sum(np.abs(e) ** 2))

    def to_pose(self, model, target: Target, z, tolerance=REAL_TOLERANCE):
        """Solver variables of a real endpoint (real up to a complex factor, within ``tolerance``), or None."""
        ef = self.full(z)
        lam = np.sqrt(_bdot(ef, ef))                          # ef = lam * (real vector) when real
        if abs(lam) == 0.0:
            return None
        v = ef / lam
        if np.max(np.abs(v.imag)) > tolerance * np.max(np.abs(v)):
            return None
        e, f = v.real[:4], v.real[4:]
        D = float(e @ e)
        if not D > NULL_ROTATION * float(v.real @ v.real):
            return None
        t = np.array(qmul(tuple(2.0 * f), (e[0], -e[1], -e[2], -e[3]))[1:]) / D      # 2 f e~ / D
        q = np.array([e[1], e[2], e[3], e[0]]) / math.sqrt(D)
        R = matrix_from_quaternion(q)
        position = target.base_centre + target.scale * t - R @ target.platform_centre
        return model.variables_from_pose(position, q)


def _crandn(rng, shape):
    """Complex standard normal numbers (real and imaginary parts N(0, 1/2))."""
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / math.sqrt(2.0)
