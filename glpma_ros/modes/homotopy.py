"""Every assembly mode by a parameter homotopy, with a root-count certificate.

Method (Sommese & Wampler, *The Numerical Solution of Systems of Polynomials Arising in Engineering
and Science*, World Scientific 2005, ch. 7 "parameter homotopies" and ch. 2.2 "the gamma trick";
Morgan & Sommese 1989, "Coefficient-parameter polynomial continuation", Appl. Math. Comput. 29):

* **Family.**  The forward kinematics of a model family is a square polynomial system ``F(z; p)`` in a few
  complex unknowns ``z`` whose coefficients depend on the geometry and the legs ``p``.  Every equation is a
  quadric, written as ``w^T Q_i(p) w = 0`` with ``w = (z, 1)`` and ``Q_i`` symmetric, and the entries of
  ``Q_i`` are polynomials of degree at most two in ``p``.

  - *Planar 3-RPR*: ``z = (x, y, c, s)``, the platform origin and the cosine and sine of its angle; three
    leg circles ``|(x, y) + R(c, s) b_i - a_i|^2 = L_i^2`` and ``c^2 + s^2 = 1``.  A generic member has 6
    solutions (Gosselin, Sefrioui & Richard 1992, Mech. Mach. Theory 27(2)).
  - *General 6-6 hexapod*: Study's kinematic mapping (Husty 1996, Mech. Mach. Theory 31(4); Wampler 1996,
    "Forward displacement analysis of general six-in-parallel SPS (Stewart) platform manipulators using
    soma coordinates", Mech. Mach. Theory 31(3)): the rotation quaternion ``e`` and the dual part ``f``,
    Study's quadric ``e.f = 0`` and one quadric per leg,
    ``(|a|^2 + |b|^2 - L^2) e.e + 4 f.f + 4 (e b).f - 2 a.(e b e~) - 4 a.(f e~) = 0``
    (see :mod:`glpma_ros.exact`), in the affine patch ``l.e = 1`` of a random complex form ``l``: ``e_0``
    is eliminated with it, 7 unknowns and 7 quadrics.  A generic member has 40 solutions.  The patch only
    involves ``e``: the component ``e = 0, f.f = 0`` of solutions at infinity of the homogeneous system
    (every leg quadric vanishes there) is outside it; a complex ``l`` leaves out a real rotation only on a
    curve of SO(3) (``Re l . e = Im l . e = 0``), not on a surface as a real patch would.

* **Start system** (offline, :func:`build_start_system`, shipped as package data under
  ``start_systems/``): a generic *complex* member ``p_0`` (random complex geometry; legs chosen so that a
  random complex point is a solution) and all its solutions, found by monodromy loops (Duff, Hill, Jensen,
  Lee, Leykin & Sommars 2019, "Solving polynomial systems via homotopy continuation and monodromy", IMA J.
  Numer. Anal. 39(3)): the known solutions are tracked around a triangle ``p_0 -> p_1 -> p_2 -> p_0`` of
  random complex members, the new endpoints are added, until the count has not grown for
  ``MONODROMY_STABLE_LOOPS`` loops and equals the family's generic root count (checked by msolve on a
  random real member, when installed).

* **Per query**: every start solution is tracked from ``p_0`` to the real target ``p_1`` along
  ``p(t) = (1 - tau) p_0 + tau p_1``, ``tau = t / (t + gamma (1 - t))``, ``t`` from 0 to 1, with a random
  unit complex ``gamma`` (the gamma trick: with probability one no path meets a singular point for ``t <
  1``).  The tracker is an adaptive predictor-corrector (classical Runge-Kutta of order 4 on
  ``dz/dt = -F_z^{-1} F_t``, Newton corrector, the step halved on a failed correction; after a success the
  next step is chosen from the size of the first corrector update, the predictor's error, of order h^5, aiming
  at ``STEP_TARGET``), every path in one compiled call (:func:`track_paths`; complex LU with
  partial pivoting).  At ``t = 1`` Newton's method polishes the endpoint.  The coefficients along the path
  are a quadratic polynomial in ``tau`` (they are of degree two in ``p``), interpolated exactly from three
  evaluations.

* **Certificate.**  The endpoints are classified: *regular* (finite, Newton converged, reciprocal
  condition number of ``F_z`` above ``REGULAR_RCOND``), *singular* (the tracker reached ``t = 1`` but ``F_z``
  is singular there, or the step underflowed in the endgame zone ``t > 1 - ENDGAME_ZONE``), *at infinity*
  (the solution grew beyond ``AT_INFINITY``) or *failed*.  Two regular endpoints closer than
  ``SAME_ENDPOINT`` are one (a path jumped).  The paths that failed and every path of a shared endpoint are
  tracked again with another gamma, up to ``RETRACK_ROUNDS`` times.  When the distinct regular endpoints are
  as many as the family's generic root count, they are every solution of the target (by the parameter
  homotopy theorem, Sommese & Wampler 2005, Theorem 7.1.6: the endpoints include every isolated
  solution; all are distinct and nonsingular, and there are at most that many): ``complete``.  Otherwise
  the answer is ``complete = False`` and names the paths.  A design whose count is lower than the family's
  (hexapods with coincident joints: the 6-3, 3-6 and 3-3 have 16, Faugere & Lazard 1995) is certified by
  its own count ``design_root_count``; the other paths end on the component ``e.e = 0`` of non-poses or at
  infinity.  Other special designs (the seed 6-6, mirror-symmetric joint pairs: 28 finite poses) are certified
  when every path is accounted for (:func:`_accounted`: a regular pose endpoint of its own, at infinity, or on
  the exceptional quadric ``e.e = 0``) and an independent homotopy (another gamma and patch) accounts for every
  path and ends at the same poses.  A real double root that paths meet (a target on a singularity) leaves the
  answer incomplete; it is returned apart (``singular``) for the caller to polish and mark as double.

* **Real modes** are the regular endpoints that are real up to ``REAL_TOLERANCE`` (the 6-6's are real up
  to a complex factor, removed first), converted to the model's solver variables; the caller polishes
  them with the model's Levenberg-Marquardt refinement.

Redundant legs (more legs than degrees of freedom): the homotopy solves the first ``n_pose`` legs; the caller
keeps the real modes that the least-squares polish with every leg leaves consistent.  No ROS import.
"""
from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
from numba import njit

from ..errors import GlpmaError
from ..models.hexapod_66 import matrix_from_quaternion
from .exact import has_coincident_joints
from .polynomials import qmul

START_SYSTEMS = Path(__file__).with_name("start_systems")
#: the compiled tracker may reassociate and contract (fused multiply-add) its sums and use reciprocals: it follows
#: a path to a loose tolerance and polishes the endpoint, so the last bits do not matter; not the flags that
#: assume no NaN or infinity (a path may run off to infinity, and is classified by its norm)
FAST_MATH = {"reassoc", "contract", "arcp", "nsz"}

# -- tracker settings (indices into the settings array of track_paths) ---------------------------------------
#: first step in t (a path's t runs over [0, 1]; the start is a regular solution, so a few predictor steps
#: reach the usual step size quickly)
STEP_INITIAL = 0.05
#: largest step in t: the predictor's error grows with the fifth power of the step and the coefficients'
#: curvature in t is of order one, so steps above a fifth of the path save little and risk a path jump
STEP_MAX = 0.2
#: a path whose step falls below this share of t has failed (its Jacobian turned singular)
STEP_MIN = 1e-13
#: with STEP_TARGET 0: double the step after this many successful steps in a row (Bertini's default heuristics)
STEP_EXPAND_AFTER = 3
#: Newton iterations of the corrector after each predictor step: a predicted point needing more is too
#: far from the path (or near another one) and the step is retried at half the size
CORRECTOR_ITERATIONS = 3
#: the corrector has converged when its update is below this share of 1 + |z| (infinity norm): the endpoint
#: is polished to round-off at t = 1 anyway, so the path need only be followed closely enough to stay in its
#: own basin (a path that jumps meets another's endpoint and the certificate catches it); on Dietmaier's and
#: random 6-6s, 1e-7 and 1e-9 took 20 % more steps and missed as many endpoints, and 1e-9 stalled near
#: ill-conditioned stretches, where round-off times the condition number is larger)
CORRECTOR_TOLERANCE = 1e-5
#: a corrector update that does not shrink at least by this factor from one iteration to the next fails:
#: Newton's method converges quadratically near a regular path, so a slower one is off the path
CORRECTOR_CONTRACTION = 0.5
#: the first corrector update may be at most this share of 1 + |z|: a larger one has left the path's
#: neighbourhood (the guard against path jumping)
CORRECTOR_MAX_FIRST = 0.2
#: |z| (infinity norm) beyond which a path is at infinity: the normalised geometry puts every real mode
#: and the start solutions within a few units
AT_INFINITY = 1e8
#: step cap per path: a regular path needs tens of steps; one that needs this many is spiralling
MAX_STEPS = 4000
#: Newton iterations of the final polish at t = 1 at most (it stops once converged): next to a fold two roots
#: are close and Newton's method only halves the error per iteration until it is within their distance, so
#: from the corrector's tolerance (1e-5) it takes up to about 40 iterations to reach round-off
FINAL_ITERATIONS = 48
#: the final polish stops when its update is below this share of 1 + |z| (a few units of round-off)
FINAL_TOLERANCE = 1e-14
#: a path whose step underflows at t > 1 - ENDGAME_ZONE ends on a singular endpoint (two solutions merging
#: at t = 1 approach each other like sqrt(1 - t): the step needed shrinks with 1 - t)
ENDGAME_ZONE = 1e-4
#: step-size control: after a successful step the next one aims at a first corrector update of this share of
#: 1 + |z| (the predictor's error, of order h^5 for the Runge-Kutta predictor); 0 = the doubling rule alone.
#: On random and Dietmaier's 6-6s, 1e-2 took 12 % fewer steps than the doubling rule and completed every case in
#: one round (1e-4: 40 % more steps); an update above CORRECTOR_MAX_FIRST fails the step anyway
STEP_TARGET = 1e-2
#: the next step is this share of the step the error model predicts (the usual safety factor of step control)
STEP_SAFETY = 0.8
#: ... and at most this many times the last one, at least half of it
STEP_GROWTH_MAX = 4.0
SETTINGS = np.array([STEP_INITIAL, STEP_MAX, STEP_MIN, STEP_EXPAND_AFTER, CORRECTOR_ITERATIONS,
                     CORRECTOR_TOLERANCE, CORRECTOR_CONTRACTION, CORRECTOR_MAX_FIRST, AT_INFINITY, MAX_STEPS,
                     FINAL_ITERATIONS, FINAL_TOLERANCE, ENDGAME_ZONE, STEP_TARGET])

#: the careful retrack of the paths that failed or met another's endpoint: a quarter of the largest step,
#: of the first corrector update and of its target, four times the steps
CAREFUL = 4.0
CAREFUL_SETTINGS = SETTINGS.copy()
CAREFUL_SETTINGS[[1, 7, 13]] /= CAREFUL
CAREFUL_SETTINGS[9] *= CAREFUL

#: path outcomes (track_paths' status)
REGULAR, AT_INFINITY_REACHED, STEP_FAILED, STEPS_EXHAUSTED, ENDGAME_SINGULAR, SINGULAR = range(6)
OUTCOMES = ("regular", "at_infinity", "step_failed", "max_steps", "singular", "singular")

# -- classification --------------------------------------------------------------------------------------
#: an endpoint whose Jacobian's reciprocal condition number (smallest over largest singular value) is below
#: this is singular: Newton's method then leaves it about sqrt(round-off / rcond) away, too far to count it
REGULAR_RCOND = 1e-10
#: two endpoints closer than this share of 1 + |z| are one (polished regular endpoints are accurate to
#: about round-off / rcond, i.e. 1e-6 at the worst regular conditioning)
SAME_ENDPOINT = 1e-6
#: an endpoint is real when its imaginary part is below this share of its size (a real solution of the
#: real target, polished in complex arithmetic, keeps an imaginary part of round-off; a complex pair closer
#: to the real space than this is within about its square of a singularity, where the rounding of the
#: input already decides)
REAL_TOLERANCE = 1e-8
#: singular endpoints (a double root: its paths end within about sqrt(round-off / curvature) of it, and Newton's
#: method converges only linearly there) within this share of 1 + |z| of each other are one root, and such a root
#: is real when its imaginary part is within this share of its size; the model's polish then decides whether a
#: real pose is there (a complex pair this close to the real space is within round-off of a singularity)
SINGULAR_SAME = 1e-5
SINGULAR_REAL_TOLERANCE = 1e-5
#: rounds of tracking again when the count is short: first the paths that failed or met another's endpoint,
#: carefully (``CAREFUL_SETTINGS``); then every path with a new gamma and patch
RETRACK_ROUNDS = 4
#: independent homotopies at most that confirm the poses of a design with fewer than the family's root count
#: (every path accounted for, the same poses): a disagreement adds the poses found and tries once more
CONFIRM_ROUNDS = 3
#: the design's own root count (hexapods whose joints coincide in pairs: 6-3, 3-6, 3-3; Faugere & Lazard
#: 1995, "Combinatorial classes of parallel manipulators", Mech. Mach. Theory 30(6); msolve agrees)
COINCIDENT_ROOT_COUNT = 16
#: a 6-6 endpoint with |e.e| below this share of |e|^2 is not a pose (Study's exceptional quadric)
NULL_ROTATION = 1e-8
#: ... and a singular endpoint (accurate to about the square root of round-off only) below this share: the
#: singular endpoints of the seed 6-6 (a design with mirror-symmetric joint pairs, 28 finite poses) lie at
#: 1.6e-8 .. 2e-7, a real pose at 1 and a complex one generically at order one
SINGULAR_NULL_ROTATION = 1e-4
#: a path of the seed 6-6 that runs to the exceptional quadric has its step underflow at 1 - t = 1e-4 .. 5e-4
#: (the endpoint is singular and at |z| ~ 1e3), already within 1e-8 of the quadric: such a failure within this
#: share of the end of the path, that close to the quadric, is the path's end, not a lost pose (a regular
#: pose endpoint is approached analytically, at order one from the quadric)
EXCEPTIONAL_ZONE = 1e-2

# -- monodromy ---------------------------------------------------------------------------------------------
#: the count must not have grown for this many loops before the start system is accepted
MONODROMY_STABLE_LOOPS = 20
#: loops at most
MONODROMY_MAX_LOOPS = 400


# ==========================================================================================================
# compiled tracker
# ==========================================================================================================
@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _evaluate(K, z, tau, dtau, w, H, J, Ht, with_t):
    """``H = F(z; p(tau))``, ``J = F_z`` and, when ``with_t``, ``Ht = F_tau dtau/dt``: every equation is
    ``w^T Q_i w`` with ``w = (z, 1)`` and ``Q_i = K_0 + tau K_1 + tau^2 K_2`` (symmetric), so with
    ``P_l = K_l w``: ``Q_i w = P_0 + tau P_1 + tau^2 P_2``, ``F_z = 2 (Q_i w)[:n]`` and
    ``F_tau = w^T (P_1 + 2 tau P_2)``."""
    n = z.shape[0]
    n1 = n + 1
    for k in range(n):
        w[k] = z[k]
    w[n] = 1.0
    tau2 = tau * tau
    two_tau = 2.0 * tau
    for i in range(K.shape[1]):
        h = 0j
        ht = 0j
        for j in range(n1):
            p0 = 0j
            p1 = 0j
            p2 = 0j
            for k in range(n1):
                wk = w[k]
                p0 += K[0, i, j, k] * wk
                p1 += K[1, i, j, k] * wk
                p2 += K[2, i, j, k] * wk
            v = p0 + tau * p1 + tau2 * p2
            h += w[j] * v
            if with_t:
                ht += w[j] * (p1 + two_tau * p2)
            if j < n:
                J[i, j] = 2.0 * v
        H[i] = h
        Ht[i] = ht * dtau


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _lu_solve(A, b, x, LU):
    """``x = A^{-1} b`` by Gaussian elimination with partial pivoting (``LU`` a work copy); False when a
    pivot is exactly zero."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            LU[i, j] = A[i, j]
        x[i] = b[i]
    for c in range(n):
        p = c
        best = abs(LU[c, c])
        for r in range(c + 1, n):
            a = abs(LU[r, c])
            if a > best:
                best, p = a, r
        if best == 0.0:
            return False
        if p != c:
            for j in range(n):
                LU[c, j], LU[p, j] = LU[p, j], LU[c, j]
            x[c], x[p] = x[p], x[c]
        inv = 1.0 / LU[c, c]
        for r in range(c + 1, n):
            m = LU[r, c] * inv
            if m != 0:
                for j in range(c + 1, n):
                    LU[r, j] -= m * LU[c, j]
                x[r] -= m * x[c]
    for c in range(n - 1, -1, -1):
        s = x[c]
        for j in range(c + 1, n):
            s -= LU[c, j] * x[j]
        x[c] = s / LU[c, c]
    return True


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _tau(t, gamma):
    """``tau(t) = t / (t + gamma (1 - t))`` and ``dtau/dt = gamma / (t + gamma (1 - t))^2``."""
    d = t + gamma * (1.0 - t)
    return t / d, gamma / (d * d)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _norm(z):
    m = 0.0
    for k in range(z.shape[0]):
        a = abs(z[k])
        if a > m:
            m = a
    return m


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _velocity(K, z, t, gamma, out, w, H, J, Ht, LU, rhs):
    """``out = dz/dt = -F_z^{-1} F_t`` at ``(z, t)``; False when ``F_z`` is singular."""
    tau, dtau = _tau(t, gamma)
    _evaluate(K, z, tau, dtau, w, H, J, Ht, True)
    for k in range(z.shape[0]):
        rhs[k] = -Ht[k]
    return _lu_solve(J, rhs, out, LU)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _track_one(K, start, gamma, settings, z, J, w, H, Ht, LU, rhs, dz, k1, k2, k3, k4, zt):
    """Tracks one path from ``start`` at t = 0; leaves the endpoint in ``z`` and ``F_z`` there in ``J``;
    returns (outcome, steps, t reached)."""
    n = start.shape[0]
    h = settings[0]
    h_max, h_min = settings[1], settings[2]
    expand_after = int(settings[3])
    iterations = int(settings[4])
    tol, contraction, max_first = settings[5], settings[6], settings[7]
    at_infinity, max_steps = settings[8], int(settings[9])
    final_iterations, final_tol, endgame = int(settings[10]), settings[11], settings[12]
    step_target = settings[13]
    first = 0.0
    for k in range(n):
        z[k] = start[k]
    t = 0.0
    steps = 0
    successes = 0
    while t < 1.0:
        if steps >= max_steps:
            return STEPS_EXHAUSTED, steps, t
        steps += 1
        last = h >= 1.0 - t
        if last:
            h = 1.0 - t
        t1 = 1.0 if last else t + h
        # classical Runge-Kutta predictor
        ok = _velocity(K, z, t, gamma, k1, w, H, J, Ht, LU, rhs)
        if ok:
            for k in range(n):
                zt[k] = z[k] + 0.5 * h * k1[k]
            ok = _velocity(K, zt, t + 0.5 * h, gamma, k2, w, H, J, Ht, LU, rhs)
        if ok:
            for k in range(n):
                zt[k] = z[k] + 0.5 * h * k2[k]
            ok = _velocity(K, zt, t + 0.5 * h, gamma, k3, w, H, J, Ht, LU, rhs)
        if ok:
            for k in range(n):
                zt[k] = z[k] + h * k3[k]
            ok = _velocity(K, zt, t1, gamma, k4, w, H, J, Ht, LU, rhs)
        if ok:
            for k in range(n):
                zt[k] = z[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k])
            # Newton corrector at t1
            tau, dtau = _tau(t1, gamma)
            ok = False
            previous = 0.0
            for it in range(iterations):
                _evaluate(K, zt, tau, dtau, w, H, J, Ht, False)
                if not _lu_solve(J, H, dz, LU):
                    break
                for k in range(n):
                    zt[k] -= dz[k]
                step = _norm(dz)
                scale = 1.0 + _norm(zt)
                if it == 0:
                    first = step / scale
                if it == 0 and step > max_first * scale:
                    break
                if it > 0 and step > contraction * previous:
                    break
                previous = step
                if step <= tol * scale:
                    ok = True
                    break
        if ok:
            for k in range(n):
                z[k] = zt[k]
            t = t1
            successes += 1
            if step_target > 0.0:
                # the predictor's error, measured by the first corrector update, grows like h^5: the next step
                # aims at step_target, within [1/2, STEP_GROWTH_MAX] times this one
                if first > 0.0:
                    factor = STEP_SAFETY * (step_target / first) ** 0.2
                    h = min(max(factor, 0.5), STEP_GROWTH_MAX) * h
                else:
                    h = STEP_GROWTH_MAX * h
                h = min(h, h_max)
            elif successes >= expand_after:
                h = min(2.0 * h, h_max)
                successes = 0
            if _norm(z) > at_infinity:
                return AT_INFINITY_REACHED, steps, t
        else:
            h *= 0.5
            successes = 0
            if h < h_min:
                if 1.0 - t < endgame:
                    return ENDGAME_SINGULAR, steps, t
                return STEP_FAILED, steps, t
    # final polish at t = 1 (tau = 1)
    for _ in range(final_iterations):
        _evaluate(K, z, 1.0 + 0j, 0j, w, H, J, Ht, False)
        if not _lu_solve(J, H, dz, LU):
            return SINGULAR, steps, t
        for k in range(n):
            z[k] -= dz[k]
        if _norm(dz) <= final_tol * (1.0 + _norm(z)):
            break
    _evaluate(K, z, 1.0 + 0j, 0j, w, H, J, Ht, False)
    return REGULAR, steps, t


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def track_paths(K, starts, gammas, settings, ends, jacobians, outcome, steps, t_end):
    """Tracks every row of ``starts`` (its own ``gammas[p]``) from the start system to the target of the
    coefficient path ``K`` (shape ``(3, m, n + 1, n + 1)``: ``Q_i(tau) = K_0 + tau K_1 + tau^2 K_2``):
    endpoints in ``ends``, ``F_z`` there in ``jacobians``, outcome / steps / t reached per path."""
    n = starts.shape[1]
    z = np.empty(n, np.complex128)
    w = np.empty(n + 1, np.complex128)
    H = np.empty(K.shape[1], np.complex128)
    Ht = np.empty(K.shape[1], np.complex128)
    J = np.empty((n, n), np.complex128)
    LU = np.empty((n, n), np.complex128)
    rhs = np.empty(n, np.complex128)
    dz = np.empty(n, np.complex128)
    k1 = np.empty(n, np.complex128)
    k2 = np.empty(n, np.complex128)
    k3 = np.empty(n, np.complex128)
    k4 = np.empty(n, np.complex128)
    zt = np.empty(n, np.complex128)
    for p in range(starts.shape[0]):
        o, s, t = _track_one(K, starts[p], gammas[p], settings, z, J, w, H, Ht, LU, rhs, dz, k1, k2, k3, k4, zt)
        outcome[p] = o
        steps[p] = s
        t_end[p] = t
        for k in range(n):
            ends[p, k] = z[k]
            for j in range(n):
                jacobians[p, k, j] = J[k, j]


# ==========================================================================================================
# families
# ==========================================================================================================
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


# ==========================================================================================================
# start systems
# ==========================================================================================================
@dataclass
class StartSystem:
    family: Family
    params: np.ndarray         # the generic complex member p_0
    solutions: np.ndarray      # all its solutions (root_count, n_unknowns)
    loops: int                 # monodromy loops that found them


def family_of(model) -> str | None:
    """The homotopy family of ``model``, or None: 3-RPR, hexapod (every 6-6, the coincident-joint designs
    included, which are members of the 6-6 family)."""
    return model.kind if model.kind in ("planar_3rpr", "hexapod_66") else None


def has_start_system(model) -> bool:
    """The model's family has a shipped start system."""
    name = family_of(model)
    return name is not None and (START_SYSTEMS / f"{name}.npz").exists()


@lru_cache(maxsize=None)
def load_start_system(name: str) -> StartSystem:
    path = START_SYSTEMS / f"{name}.npz"
    if not path.exists():
        raise GlpmaError(f"no homotopy start system for {name} ({path} missing; build it with "
                         "python -m glpma_ros.modes.homotopy --build-start-systems)")
    data = np.load(path)
    family = Hexapod66Family(data["patch"]) if name == "hexapod_66" else Planar3RPRFamily()
    if int(data["root_count"]) != family.root_count:
        raise GlpmaError(f"{path}: root count {int(data['root_count'])}, expected {family.root_count}")
    return StartSystem(family, data["params"], np.ascontiguousarray(data["solutions"]), int(data["loops"]))


def track(K, starts, gammas, settings=SETTINGS):
    P, n = starts.shape
    ends = np.empty((P, n), complex)
    jac = np.empty((P, n, n), complex)
    outcome = np.empty(P, np.int64)
    steps = np.empty(P, np.int64)
    t_end = np.empty(P)
    track_paths(K, np.ascontiguousarray(starts), np.ascontiguousarray(gammas, dtype=complex), settings, ends,
                jac, outcome, steps, t_end)
    return ends, jac, outcome, steps, t_end


def random_gammas(rng, m):
    return np.exp(2j * math.pi * rng.uniform(size=m))


def distinct(points, tol=SAME_ENDPOINT) -> list:
    """Indices of the first of every group of points within ``tol`` (share of 1 + |z|) of each other."""
    keep = []
    for k, z in enumerate(points):
        if all(np.max(np.abs(z - points[j])) > tol * (1.0 + np.max(np.abs(z))) for j in keep):
            keep.append(k)
    return keep


def build_start_system(family: Family, seed: int, *, verbose=False) -> StartSystem:
    """Every solution of a random complex member by monodromy loops (module docstring)."""
    rng = np.random.default_rng(seed)
    p0, z0 = family.random_instance(rng)
    sols = z0[None, :].astype(complex)
    stable = loops = 0
    while loops < MONODROMY_MAX_LOOPS and not (stable >= MONODROMY_STABLE_LOOPS and len(sols) == family.root_count):
        loops += 1
        p1, p2 = family.random_params(rng), family.random_params(rng)
        current = sols
        ok = np.ones(len(current), bool)
        for pa, pb in ((p0, p1), (p1, p2), (p2, p0)):
            K = family.coefficient_path(pa, pb)
            ends, jac, outcome, _, _ = track(K, current, random_gammas(rng, 1).repeat(len(current)))
            ok &= outcome == REGULAR
            current = ends
        found = current[ok]
        before = len(sols)
        allpts = np.concatenate([sols, found])
        sols = allpts[distinct(allpts)]
        stable = stable + 1 if len(sols) == before else 0
        if verbose:
            print(f"{family.name}: loop {loops}, {len(sols)} solutions")
    if len(sols) != family.root_count:
        raise GlpmaError(f"monodromy found {len(sols)} solutions of {family.name}, expected {family.root_count}")
    # residual check at p0
    Q = family.quadrics(p0)
    w = np.concatenate([sols, np.ones((len(sols), 1))], 1)
    residual = np.abs(np.einsum("pm,imn,pn->pi", w, Q, w)).max()
    if residual > 1e-9:
        raise GlpmaError(f"start solutions of {family.name} have residual {residual:.3g}")
    return StartSystem(family, p0, sols, loops)


# ==========================================================================================================
# per query
# ==========================================================================================================
@dataclass
class HomotopyResult:
    """What the homotopy found for one target."""

    complete: bool                 # every solution found (distinct regular endpoints = the root count)
    paths: int                     # paths tracked (the family's generic root count)
    paths_failed: list             # indices of the paths without a regular endpoint of their own
    complex_solutions: int         # distinct finite endpoints that are poses (regular; incomplete: and real double)
    real: list                     # solver variables of the real ones (not yet polished)
    root_count: int                # the count that certifies
    singular: list = field(default_factory=list)  # incomplete: solver variables of real singular endpoints
    outcomes: dict = field(default_factory=dict)   # outcome name -> number of paths (last round)
    retracked: int = 0             # path trackings repeated with another gamma
    steps: int = 0                 # predictor-corrector steps, every path and round
    elapsed_s: float = 0.0


def root_count(model) -> int:
    """The count that certifies ``model``'s answer: the family's, or the design's (coincident joints)."""
    if model.kind == "hexapod_66" and has_coincident_joints(_first_legs_model(model)):
        return COINCIDENT_ROOT_COUNT if _three_and_three(model) else 0
    return load_start_system(model.kind).family.root_count


def _first_legs_model(model):
    k = 6 if model.kind == "hexapod_66" else 3

    class _View:
        base = np.asarray(model.base)[:k]
        platform = np.asarray(model.platform)[:k]
    return _View


def _three_and_three(model) -> bool:
    """6-3, 3-6 or 3-3: each side's joints either all distinct or coinciding in three pairs."""
    v = _first_legs_model(model)
    sizes = [len({tuple(np.round(p, 12)) for p in pts.tolist()}) for pts in (v.base, v.platform)]
    return all(s in (3, 6) for s in sizes) and sizes != [6, 6]


def solve(model, legs, *, seed=0, retrack_rounds=RETRACK_ROUNDS) -> HomotopyResult:
    """Every solution of ``model`` at ``legs`` (checked, config unit) by the parameter homotopy (module
    docstring).  Every regular endpoint of every round is a solution of the target, so the distinct ones
    are gathered over the rounds; a retrack round draws a new gamma and (6-6) a new random affine patch
    (a path that crosses the patch's hyperplane at infinity in one patch does not in another)."""
    t0 = time.perf_counter()
    name = family_of(model)
    if name is None:
        raise GlpmaError(f"no homotopy for manipulator {model.kind!r}")
    start = load_start_system(name)
    base_family = start.family
    target = base_family.target(model, legs)
    rng = np.random.default_rng(seed)
    n_paths = len(start.solutions)
    certify = root_count(model)
    found = np.empty((0, base_family.n_unknowns), complex)     # distinct regular pose endpoints (base patch)
    singular = np.empty((0, base_family.n_unknowns), complex)  # singular or shared endpoints (base patch)
    pending = np.arange(n_paths)
    outcome_of = np.full(n_paths, STEP_FAILED, np.int64)
    total_steps = retracked = 0
    family, starts, gamma, settings = base_family, start.solutions, random_gammas(rng, 1)[0], SETTINGS
    for round_ in range(retrack_rounds + 1):
        if round_ == 1:
            # the same homotopy (same gamma and patch: each path keeps its endpoint), tracked more carefully
            settings = CAREFUL_SETTINGS
        elif round_ > 1:
            # another gamma and patch: another pairing of start solutions and endpoints, so every path again
            family = base_family.another_patch(rng)
            starts = base_family.convert(start.solutions, family)
            gamma = random_gammas(rng, 1)[0]
            pending = np.arange(n_paths)
        retracked += pending.size if round_ else 0
        K = family.coefficient_path(start.params, target.params)
        ends, jac, outcome, steps, t_end = track(K, starts[pending], np.full(pending.size, gamma), settings)
        total_steps += int(steps.sum())
        good = _regular(jac, outcome)
        outcome_of[pending] = outcome
        ends = family.convert(ends, base_family)
        unexplained = [int(pending[k]) for k in _unexplained(ends, good, outcome)]
        shared = [k for k in range(len(pending)) if outcome[k] == SINGULAR or (good[k] and pending[k] in unexplained)]
        singular = np.vstack([singular, ends[shared]])
        for k in np.flatnonzero(good):
            if not base_family.is_pose(ends[k]):
                continue
            if _new(ends[k], found):
                found = np.vstack([found, ends[k]])
            elif round_ == 1:               # retracked on the same homotopy, it met a solution found before
                unexplained.append(int(pending[k]))
        full_round = pending.size == n_paths
        if len(found) >= certify > 0 or not unexplained:
            break
        pending = np.array(sorted(set(unexplained)), np.int64)
    complete = certify > 0 and len(found) == certify
    if not complete and certify > 0 and full_round and _accounted(base_family, ends, good, outcome, t_end):
        # fewer poses than the root count (a special design), every path accounted for: confirmed by an independent
        # homotopy (another gamma and patch) that accounts for every path and ends at the same poses; the poses it
        # finds that the last did not (a path of the last that jumped) are added and another one confirms
        for _ in range(CONFIRM_ROUNDS):
            family = base_family.another_patch(rng)
            K = family.coefficient_path(start.params, target.params)
            starts, gammas = base_family.convert(start.solutions, family), np.full(n_paths, random_gammas(rng, 1)[0])
            ends, jac, outcome, steps, t_end = track(K, starts, gammas, SETTINGS)
            total_steps += int(steps.sum())
            retracked += n_paths
            again = np.flatnonzero((outcome == STEP_FAILED) | (outcome == STEPS_EXHAUSTED))
            if again.size:              # the same paths, tracked carefully (as the second round above)
                ends[again], jac[again], outcome[again], steps, t_end[again] = track(
                    K, starts[again], gammas[again], CAREFUL_SETTINGS)
                total_steps += int(steps.sum())
                retracked += again.size
            good = _regular(jac, outcome)
            ends = family.convert(ends, base_family)
            poses = [z for k, z in enumerate(ends) if good[k] and base_family.is_pose(z)]
            new = [z for z in poses if _new(z, found)]
            if _accounted(base_family, ends, good, outcome, t_end) and len(poses) == len(found) and not new:
                complete = True
                break
            for z in new:
                found = np.vstack([found, z])
    real, double = [], []
    if not complete:                # a double root: endpoints shared by paths or singular, real up to its accuracy
        for k in distinct(singular, SINGULAR_SAME):
            if base_family.is_pose(singular[k], SINGULAR_NULL_ROTATION):
                x = base_family.to_pose(model, target, singular[k], SINGULAR_REAL_TOLERANCE)
                if x is not None:
                    double.append(x)
                    found = found[[not _near(z, singular[k], SINGULAR_SAME) for z in found]]
    for z in found:
        x = base_family.to_pose(model, target, z)
        if x is not None:
            real.append(x)
    counts = {}
    for o in outcome_of:
        counts[OUTCOMES[o]] = counts.get(OUTCOMES[o], 0) + 1
    failed = [] if complete else sorted(int(k) for k in pending)
    return HomotopyResult(complete, n_paths, failed, len(found) + len(double), real, certify, double, counts,
                          retracked, total_steps, time.perf_counter() - t0)


def _accounted(family, ends, good, outcome, t_end) -> bool:
    """Every path of a round ended where it may: at a regular endpoint of its own (no two shared), at infinity, or
    at a singular endpoint that is not a pose (on Study's exceptional quadric, to a singular endpoint's accuracy;
    a path whose step underflowed within ``EXCEPTIONAL_ZONE`` of t = 1 already that close to the quadric counts as
    ending there).  Then every isolated pose solution of the target is a regular endpoint (Sommese & Wampler
    2005, Theorem 7.1.6: each is the endpoint of as many paths as its multiplicity)."""
    if outcome.size and np.any(outcome == STEPS_EXHAUSTED):
        return False
    failed = outcome == STEP_FAILED
    if np.any(failed & (1.0 - t_end > EXCEPTIONAL_ZONE)):
        return False
    good_only = np.where(failed, AT_INFINITY_REACHED, outcome)       # no retrack asked for the failed ones here
    if _unexplained(ends, good, good_only):
        return False
    return not any(outcome[k] != AT_INFINITY_REACHED and family.is_pose(ends[k], SINGULAR_NULL_ROTATION)
                   for k in np.flatnonzero(~good))


def _near(z, w, tol) -> bool:
    return bool(np.max(np.abs(z - w)) <= tol * (1.0 + np.max(np.abs(w))))


def _new(z, found) -> bool:
    """``z`` is farther than ``SAME_ENDPOINT`` from every row of ``found``."""
    if not len(found):
        return True
    return bool(np.min(np.max(np.abs(found - z), axis=1)) > SAME_ENDPOINT * (1.0 + np.max(np.abs(z))))


def _regular(jac, outcome) -> np.ndarray:
    """Regular endpoints: tracked to t = 1, polished, and well conditioned."""
    good = outcome == REGULAR
    if good.any():
        sv = np.linalg.svd(jac[good], compute_uv=False)
        rcond = sv[:, -1] / np.maximum(sv[:, 0], np.finfo(float).tiny)
        idx = np.flatnonzero(good)
        good[idx[rcond < REGULAR_RCOND]] = False
        outcome[idx[rcond < REGULAR_RCOND]] = SINGULAR
    return good


def _unexplained(ends, good, outcome) -> list:
    """Paths (indices into ``ends``) to track again: failed ones (not those at infinity or singular: such
    endpoints may be the target's own) and every path of a regular endpoint shared with another path."""
    bad = set(np.flatnonzero((outcome == STEP_FAILED) | (outcome == STEPS_EXHAUSTED)).tolist())
    idx = np.flatnonzero(good)
    if idx.size > 1:
        Z = ends[idx]
        size = 1.0 + np.max(np.abs(Z), axis=1)
        close = np.max(np.abs(Z[:, None, :] - Z[None, :, :]), axis=2) <= SAME_ENDPOINT * size[:, None]
        np.fill_diagonal(close, False)
        bad.update(idx[np.any(close, axis=1)].tolist())
    return sorted(bad)


# ==========================================================================================================
# offline build
# ==========================================================================================================
#: seeds of the shipped start systems (any seed gives a generic member with probability one)
BUILD_SEEDS = {"planar_3rpr": 3401, "hexapod_66": 3466}


def build_all(out_dir=START_SYSTEMS, verbose=True) -> None:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, seed in BUILD_SEEDS.items():
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        if name == "hexapod_66":
            family = Hexapod66Family(_crandn(rng, 4))
        else:
            family = Planar3RPRFamily()
        start = build_start_system(family, seed + 1, verbose=verbose)
        extra = {"patch": family.patch} if name == "hexapod_66" else {}
        np.savez(out_dir / f"{name}.npz", params=start.params, solutions=start.solutions,
                 root_count=np.int64(family.root_count), loops=np.int64(start.loops), seed=np.int64(seed), **extra)
        if verbose:
            print(f"{name}: {len(start.solutions)} solutions after {start.loops} loops "
                  f"({time.perf_counter() - t0:.1f} s)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glpma_ros.modes.homotopy",
                                 description="build the start systems of the parameter homotopy (offline, once)")
    ap.add_argument("--build-start-systems", action="store_true", required=True)
    ap.add_argument("--out", default=str(START_SYSTEMS))
    args = ap.parse_args(argv)
    build_all(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
