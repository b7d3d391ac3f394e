"""The compiled path tracker of the parameter homotopy (:mod:`.homotopy`).

Every start solution of a family's start system is followed from the start member ``p_0`` to the target ``p_1``
along ``p(t) = (1 - tau) p_0 + tau p_1``, ``tau = t / (t + gamma (1 - t))``, ``t`` from 0 to 1, with a random unit
complex ``gamma`` (the gamma trick; Sommese & Wampler, *The Numerical Solution of Systems of Polynomials Arising in
Engineering and Science*, World Scientific 2005, ch. 2.2 and 7).  The tracker is an adaptive predictor-corrector:
classical Runge-Kutta of order 4 on ``dz/dt = -F_z^{-1} F_t``, Newton corrector, the step halved on a failed
correction; after a success the next step is chosen from the size of the first corrector update (the predictor's
error, of order h^5), aiming at ``STEP_TARGET`` (and not longer than the last one right after a failed correction).
A compiled call (:func:`track_paths`; complex LU with partial pivoting, in place, the corrector's last factors kept
for the next step's first predictor stage) tracks a batch of paths; at ``t = 1`` Newton's method polishes the
endpoint.  The 6-6's paths advance in lockstep (:func:`_track_66_lanes`): ``LANES`` paths at a time, each with its
own point, step and state, their stages and Newton iterations formed together with the paths innermost (real and
imaginary parts in separate arrays), so that the compiler vectorises the evaluator, the LU and the step arithmetic
across them; the steps are those of one path alone.  The paths are independent: :func:`track` splits them over
threads, each running the compiled kernel (which releases the GIL) on a chunk of paths; the endpoints do not depend
on the thread count.  The system along
the path is evaluated by the family's own evaluator from its parameters interpolated at ``tau`` (3-RPR, 6-6:
residual, Jacobian and ``dF/dtau`` written out, the per-leg quantities prepared once per distinct ``tau``, the
6-6's from their coefficients in ``tau`` formed once per path set), or for any family of quadrics from their
coefficients, a quadratic polynomial in ``tau`` (``K``, :meth:`.homotopy_families.Family.coefficient_path`).  Each
path ends with an outcome (:data:`OUTCOMES`): regular, at infinity, a failed step, out of steps, or singular.  No
ROS import.
"""
from __future__ import annotations

import itertools
import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np
from numba import njit

from ..runtime.compat import NUMBA_INLINE

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
#: far from the path (or near another one) and the step is retried at half the size (4 or 5 took 15 % fewer
#: steps but left 34 / 67 of 123 rounds incomplete, Dietmaier's and 40 random 6-6s with 3 gammas each: 3 leaves 2)
CORRECTOR_ITERATIONS = 3
#: the corrector has converged when its update is below this share of 1 + |z| (infinity norm): the endpoint
#: is polished to round-off at t = 1 anyway, so the path need only be followed closely enough to stay in its
#: own basin (a path that jumps meets another's endpoint and the certificate catches it); on Dietmaier's and
#: random 6-6s, 1e-7 and 1e-9 took 20 % more steps and missed as many endpoints, and 1e-9 stalled near
#: ill-conditioned stretches, where round-off times the condition number is larger); stopping instead when the
#: estimated error after the update (the update times its contraction) is below it saved a Newton iteration in
#: four but left 14 of 123 rounds incomplete (Dietmaier's and 40 random 6-6s, 3 gammas each; a retrack round
#: each) where this leaves 2
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
#: ... and at most this many times the last one, at least half of it; right after a rejected step at most the
#: last one (on 20 random 6-6s and Dietmaier's, 3 gammas each: 4 % fewer steps, 28.2 -> 27.0 per path, as many
#: rounds incomplete, 3 of 63; a limit of 2 instead of 4 on top: 27.4)
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

#: the chunks of paths of :func:`track` shrink as the paths are taken ("guided" scheduling): each is this share of
#: the paths left over the threads' count (a 6-6's 40 on two threads: 10, 8, 6, 4, 3, 3, 2, 1, 1, 1, 1).  The threads
#: take the next chunk as they finish one, and paths differ in their steps (a 6-6 path takes 15 to 60): the large
#: first chunks keep the kernel calls few (each costs a few microseconds against about 0.2 ms per 6-6 path), the
#: single paths at the end leave a thread idle for one path at most while the other finishes.  The 6-6's lockstep
#: kernel takes an equal share per thread instead (its lanes stay busy only on many paths)
GUIDED_SHARE = 0.5
#: by default a thread per this many paths at most: a thread hand-over costs tens of microseconds (more on a busy
#: machine), about what a few 3-RPR paths take (50 us each): its 6 paths took 0.29 ms on one thread, 0.37 ms on two
#: (load 3 on 2 cores), so they stay on one; the hexapods' 40 (about 0.25 ms each) are split
MIN_PATHS_PER_THREAD = 8

#: two endpoints closer than this share of 1 + |z| are one (polished regular endpoints are accurate to
#: about round-off / rcond, i.e. 1e-6 at the worst regular conditioning)
SAME_ENDPOINT = 1e-6


# ==========================================================================================================
# the system along the path: dense quadrics (any family) or a family's structured evaluator
# ==========================================================================================================
#: evaluator kinds (track_paths' ``kind``): the dense quadrics of a coefficient path (any family of quadrics,
#: :meth:`.homotopy_families.Family.coefficient_path`), or a family's own evaluator from its parameters
#: interpolated along the path (:meth:`.homotopy_families.Family.parameter_path`): the same polynomials in fewer
#: operations (a 6-6 evaluation with dF/dtau: about 550 complex multiplications instead of about 1,500)
DENSE, PLANAR_3RPR, HEXAPOD_66 = range(3)

#: 3-RPR, the parameters p = (a (3x2), b (3x2), L (3)); per leg at a tau (_prepare_3rpr): a, b, L^2 and their
#: tau-derivatives
RPR_PARAMS = 15
RPR_A, RPR_B, RPR_L2, RPR_DA, RPR_DB, RPR_DL2 = 0, 2, 4, 5, 7, 9
RPR_WIDTH = 10
#: 6-6, the parameters p = (a (6x3), b (6x3), L (6)) and after p_0 and dp the patch: e_0 = c_0 + c . (e_1, e_2, e_3);
#: per leg at a tau (_prepare_66): a, b, b x a, d = b - a, s = b + a, a.b, k = a.a + b.b - L^2 and the
#: tau-derivatives of b x a, d, s, a.b, k, a and b; then the coefficients of the quadratics in tau among them
#: (b x a, a.b and k: a and b are linear in tau), formed with the tau-independent columns once per parameter path
HEX_PARAMS = 42
HEX_A, HEX_B, HEX_BXA, HEX_D, HEX_S, HEX_AB, HEX_K = 0, 3, 6, 9, 12, 15, 16
HEX_DBXA, HEX_DD, HEX_DS, HEX_DAB, HEX_DK, HEX_DA, HEX_DB = 17, 20, 23, 26, 27, 28, 31
HEX_BXA_COEF, HEX_AB_COEF, HEX_K_COEF = 34, 43, 46     # (1, tau, tau^2) coefficients: 3 per quantity
HEX_WIDTH = 49


class ParameterPath(NamedTuple):
    """The system along ``p(tau) = p_0 + tau (p_1 - p_0)`` as :func:`track_paths` reads it: the evaluator
    ``kind``; ``K`` (3, m, n + 1, n + 1) the dense quadrics' coefficients (DENSE; empty otherwise); ``P`` a
    structured kind's ``p_0``, ``p_1 - p_0`` and the family's constants (empty for DENSE)."""

    kind: int
    K: np.ndarray
    P: np.ndarray


def dense_path(K) -> ParameterPath:
    return ParameterPath(DENSE, np.ascontiguousarray(K, dtype=complex), np.zeros(0, complex))


def structured_path(kind, p0, p1, constants=()) -> ParameterPath:
    p0 = np.asarray(p0, complex)
    P = np.concatenate([p0, np.asarray(p1, complex) - p0, np.asarray(constants, complex)])
    return ParameterPath(kind, np.zeros((3, 0, 0, 0), complex), np.ascontiguousarray(P))


# ==========================================================================================================
# compiled tracker
# ==========================================================================================================
@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _evaluate_dense(K, z, tau, dtau, w, H, J, Ht, with_j, with_t):
    """``H = F(z; p(tau))``, when ``with_j`` ``J = F_z`` and when ``with_t`` ``Ht = F_tau dtau/dt``: every equation is
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
            if with_j and j < n:
                J[i, j] = 2.0 * v
        H[i] = h
        Ht[i] = ht * dtau


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _prepare_3rpr(P, tau, S):
    """Per leg of a 3-RPR at ``tau`` (row of ``S``): ``a``, ``b``, ``L^2`` and their tau-derivatives."""
    for i in range(3):
        for k in range(2):
            da = P[RPR_PARAMS + 2 * i + k]
            db = P[RPR_PARAMS + 6 + 2 * i + k]
            S[i, RPR_A + k] = P[2 * i + k] + tau * da
            S[i, RPR_B + k] = P[6 + 2 * i + k] + tau * db
            S[i, RPR_DA + k] = da
            S[i, RPR_DB + k] = db
        dL = P[RPR_PARAMS + 12 + i]
        L = P[12 + i] + tau * dL
        S[i, RPR_L2] = L * L
        S[i, RPR_DL2] = 2.0 * L * dL


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _evaluate_3rpr(S, z, dtau, H, J, Ht, with_h, with_j, with_t):
    """3-RPR, ``z = (x, y, c, s)``: leg ``i`` ``F_i = u.u - L_i^2`` with ``u = (x, y) + R(c, s) b_i - a_i``,
    ``F_z = 2 u^T du/dz``, ``F_tau = 2 u.(R(c, s) b_i' - a_i') - (L_i^2)'``; and ``c^2 + s^2 - 1``."""
    x, y, c, s = z[0], z[1], z[2], z[3]
    for i in range(3):
        ax, ay = S[i, RPR_A], S[i, RPR_A + 1]
        bx, by = S[i, RPR_B], S[i, RPR_B + 1]
        u0 = x + c * bx - s * by - ax
        u1 = y + s * bx + c * by - ay
        if with_h:
            H[i] = u0 * u0 + u1 * u1 - S[i, RPR_L2]
        if with_j:
            J[i, 0] = 2.0 * u0
            J[i, 1] = 2.0 * u1
            J[i, 2] = 2.0 * (u0 * bx + u1 * by)
            J[i, 3] = 2.0 * (u1 * bx - u0 * by)
        if with_t:
            dbx, dby = S[i, RPR_DB], S[i, RPR_DB + 1]
            du0 = c * dbx - s * dby - S[i, RPR_DA]
            du1 = s * dbx + c * dby - S[i, RPR_DA + 1]
            Ht[i] = (2.0 * (u0 * du0 + u1 * du1) - S[i, RPR_DL2]) * dtau
        else:
            Ht[i] = 0j
    if with_h:
        H[3] = c * c + s * s - 1.0
    if with_j:
        J[3, 0] = 0j
        J[3, 1] = 0j
        J[3, 2] = 2.0 * c
        J[3, 3] = 2.0 * s
    Ht[3] = 0j


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _prepare_66_path(P, S):
    """The tau-independent columns of :func:`_prepare_66` per leg of a 6-6: ``a'``, ``b'``, ``d'``, ``s'``
    (``p`` is linear in tau) and the coefficients of ``b x a``, ``a.b`` and ``k`` as quadratics in tau (from
    ``a = a_0 + tau a'``, ``b = b_0 + tau b'``, ``L = L_0 + tau L'``)."""
    for i in range(6):
        for k in range(3):
            da = P[HEX_PARAMS + 3 * i + k]
            db = P[HEX_PARAMS + 18 + 3 * i + k]
            S[i, HEX_DA + k] = da
            S[i, HEX_DB + k] = db
            S[i, HEX_DD + k] = db - da
            S[i, HEX_DS + k] = db + da
        ab0 = ab1 = ab2 = 0j
        aa0 = aa1 = aa2 = 0j                             # a.a + b.b
        for k in range(3):
            a0, da = P[3 * i + k], S[i, HEX_DA + k]
            b0, db = P[18 + 3 * i + k], S[i, HEX_DB + k]
            ab0 += a0 * b0
            ab1 += da * b0 + a0 * db
            ab2 += da * db
            aa0 += a0 * a0 + b0 * b0
            aa1 += 2.0 * (a0 * da + b0 * db)
            aa2 += da * da + db * db
            k1 = (k + 1) % 3
            k2 = (k + 2) % 3
            a0k1, a0k2 = P[3 * i + k1], P[3 * i + k2]
            b0k1, b0k2 = P[18 + 3 * i + k1], P[18 + 3 * i + k2]
            dak1, dak2 = P[HEX_PARAMS + 3 * i + k1], P[HEX_PARAMS + 3 * i + k2]
            dbk1, dbk2 = P[HEX_PARAMS + 18 + 3 * i + k1], P[HEX_PARAMS + 18 + 3 * i + k2]
            S[i, HEX_BXA_COEF + 3 * k] = b0k1 * a0k2 - b0k2 * a0k1
            S[i, HEX_BXA_COEF + 3 * k + 1] = dbk1 * a0k2 - dbk2 * a0k1 + b0k1 * dak2 - b0k2 * dak1
            S[i, HEX_BXA_COEF + 3 * k + 2] = dbk1 * dak2 - dbk2 * dak1
        L0, dL = P[36 + i], P[HEX_PARAMS + 36 + i]
        S[i, HEX_AB_COEF], S[i, HEX_AB_COEF + 1], S[i, HEX_AB_COEF + 2] = ab0, ab1, ab2
        S[i, HEX_K_COEF] = aa0 - L0 * L0
        S[i, HEX_K_COEF + 1] = aa1 - 2.0 * L0 * dL
        S[i, HEX_K_COEF + 2] = aa2 - dL * dL


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _prepare_66(P, tau, S):
    """Per leg of a 6-6 at ``tau`` (row of ``S``, the layout of ``HEX_*``): ``a``, ``b``, ``d``, ``s`` from
    ``p(tau)``, the quadratics ``b x a``, ``a.b``, ``k`` and their derivatives from the coefficients of
    :func:`_prepare_66_path` (already in ``S``)."""
    for i in range(6):
        for k in range(3):
            a = P[3 * i + k] + tau * S[i, HEX_DA + k]
            b = P[18 + 3 * i + k] + tau * S[i, HEX_DB + k]
            S[i, HEX_A + k] = a
            S[i, HEX_B + k] = b
            S[i, HEX_D + k] = b - a
            S[i, HEX_S + k] = b + a
        for k in range(3):
            S[i, HEX_BXA + k], S[i, HEX_DBXA + k] = _quadratic(S, i, HEX_BXA_COEF + 3 * k, tau)
        S[i, HEX_AB], S[i, HEX_DAB] = _quadratic(S, i, HEX_AB_COEF, tau)
        S[i, HEX_K], S[i, HEX_DK] = _quadratic(S, i, HEX_K_COEF, tau)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _quadratic(S, i, at, tau):
    """The value and the derivative at ``tau`` of ``S[i, at] + S[i, at + 1] tau + S[i, at + 2] tau^2``."""
    return _quadratic_at(S[i, at], S[i, at + 1], S[i, at + 2], tau)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _quadratic_at(c0, c1, c2, tau):
    """The value and the derivative at ``tau`` of ``c0 + c1 tau + c2 tau^2``."""
    return c0 + tau * (c1 + tau * c2), c1 + 2.0 * tau * c2


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _evaluate_66(P, S, z, dtau, H, J, Ht, with_h, with_j, with_t):
    """6-6 in Study parameters, ``z = (e_1, e_2, e_3, f)``, ``e_0 = c_0 + c . (e_1, e_2, e_3)`` (the patch).  Leg
    ``i`` (the quadric of :meth:`.homotopy_families.Hexapod66Family.homogeneous_quadrics` written out):
    ``F_i = k e.e - 2 G + 4 C + 4 f.f`` with ``G = (e b).(a e) = (e_0^2 - v.v) a.b + 2 (v.a)(v.b) + 2 e_0 v.(b x a)``
    (``v`` the vector part of ``e``) and ``C = f.(e b - a e) = e_0 w.d - f_0 v.d - (v x w).s`` (``w`` that of ``f``,
    ``d = b - a``, ``s = b + a``); their gradients by hand, through the patch by the chain rule; ``F_tau`` by the
    product rule from the prepared tau-derivatives.  Study's quadric ``e.f``."""
    c = (P[2 * HEX_PARAMS + 1], P[2 * HEX_PARAMS + 2], P[2 * HEX_PARAMS + 3])
    v, f0, w = (z[0], z[1], z[2]), z[3], (z[4], z[5], z[6])
    e0, q, ee, ff, x = _common_66(P[2 * HEX_PARAMS], c, v, f0, w)
    for i in range(6):
        a = (S[i, HEX_A], S[i, HEX_A + 1], S[i, HEX_A + 2])
        b = (S[i, HEX_B], S[i, HEX_B + 1], S[i, HEX_B + 2])
        d = (S[i, HEX_D], S[i, HEX_D + 1], S[i, HEX_D + 2])
        s = (S[i, HEX_S], S[i, HEX_S + 1], S[i, HEX_S + 2])
        n = (S[i, HEX_BXA], S[i, HEX_BXA + 1], S[i, HEX_BXA + 2])
        ab, k = S[i, HEX_AB], S[i, HEX_K]
        va, vb, vn, vd, wd = _dot3(v, a), _dot3(v, b), _dot3(v, n), _dot3(v, d), _dot3(w, d)
        if with_h:
            H[i] = _leg_residual_66(k, ab, e0, q, ee, ff, f0, va, vb, vn, vd, wd, _dot3(x, s))
        if with_j:
            J[i, 0], J[i, 1], J[i, 2], J[i, 3], J[i, 4], J[i, 5], J[i, 6] = _leg_gradient_66(
                k, ab, e0, f0, v, w, c, a, b, d, s, n, va, vb, vn, vd, wd)
        if with_t:
            da = (S[i, HEX_DA], S[i, HEX_DA + 1], S[i, HEX_DA + 2])
            db = (S[i, HEX_DB], S[i, HEX_DB + 1], S[i, HEX_DB + 2])
            dn = (S[i, HEX_DBXA], S[i, HEX_DBXA + 1], S[i, HEX_DBXA + 2])
            dd = (S[i, HEX_DD], S[i, HEX_DD + 1], S[i, HEX_DD + 2])
            ds = (S[i, HEX_DS], S[i, HEX_DS + 1], S[i, HEX_DS + 2])
            Ht[i] = _leg_rate_66(S[i, HEX_DK], S[i, HEX_DAB], e0, q, ee, f0, va, vb, _dot3(v, da), _dot3(v, db),
                                 _dot3(v, dn), _dot3(v, dd), _dot3(w, dd), _dot3(x, ds)) * dtau
        else:
            Ht[i] = 0j
    h, j0, j1, j2, j3, j4, j5, j6 = _study_66(e0, f0, v, w, c)
    if with_h:
        H[6] = h
    if with_j:
        J[6, 0], J[6, 1], J[6, 2], J[6, 3], J[6, 4], J[6, 5], J[6, 6] = j0, j1, j2, j3, j4, j5, j6
    Ht[6] = 0j


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _dot3(x, y):
    """``x . y`` of two 3-vectors (tuples)."""
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _common_66(c0, c, v, f0, w):
    """The leg-independent quantities of :func:`_evaluate_66` at ``z = (v, f_0, w)``: ``e_0 = c_0 + c . v`` (the
    patch), ``e_0^2 - v.v``, ``e_0^2 + v.v``, ``f.f`` and ``v x w``."""
    v1, v2, v3 = v
    w1, w2, w3 = w
    e0 = c0 + c[0] * v1 + c[1] * v2 + c[2] * v3
    vv = _dot3(v, v)
    return (e0, e0 * e0 - vv, e0 * e0 + vv, f0 * f0 + w1 * w1 + w2 * w2 + w3 * w3,
            (v2 * w3 - v3 * w2, v3 * w1 - v1 * w3, v1 * w2 - v2 * w1))


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _leg_residual_66(k, ab, e0, q, ee, ff, f0, va, vb, vn, vd, wd, xs):
    """Leg ``i``'s ``F_i = k e.e - 2 G + 4 C + 4 f.f`` of :func:`_evaluate_66` with ``G = q a.b + 2 ((v.a)(v.b) +
    e_0 v.n)`` (``q = e_0^2 - v.v``, ``n = b x a``) and ``C = e_0 w.d - f_0 v.d - (v x w).s`` (``xs``)."""
    G = q * ab + 2.0 * (va * vb + e0 * vn)
    C = e0 * wd - f0 * vd - xs
    return k * ee - 2.0 * G + 4.0 * C + 4.0 * ff


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _leg_gradient_66(k, ab, e0, f0, v, w, c, a, b, d, s, n, va, vb, vn, vd, wd):
    """Leg ``i``'s row of ``F_z`` (:func:`_evaluate_66`): ``dF/dv`` through the patch ``e_0 = c_0 + c . v``
    (``dF/dv + c dF/de_0``), ``dF/df_0`` and ``dF/dw = 4 (e_0 d - s x v) + 8 w``."""
    v1, v2, v3 = v
    w1, w2, w3 = w
    a1, a2, a3 = a
    b1, b2, b3 = b
    d1, d2, d3 = d
    s1, s2, s3 = s
    n1, n2, n3 = n
    g0 = 2.0 * k * e0 - 4.0 * (e0 * ab + vn) + 4.0 * wd            # dF/de_0
    kv = 2.0 * k + 4.0 * ab
    g1 = kv * v1 - 4.0 * (vb * a1 + va * b1 + e0 * n1 + f0 * d1 + w2 * s3 - w3 * s2)
    g2 = kv * v2 - 4.0 * (vb * a2 + va * b2 + e0 * n2 + f0 * d2 + w3 * s1 - w1 * s3)
    g3 = kv * v3 - 4.0 * (vb * a3 + va * b3 + e0 * n3 + f0 * d3 + w1 * s2 - w2 * s1)
    return (g1 + c[0] * g0, g2 + c[1] * g0, g3 + c[2] * g0, 8.0 * f0 - 4.0 * vd,
            4.0 * (e0 * d1 - s2 * v3 + s3 * v2) + 8.0 * w1,
            4.0 * (e0 * d2 - s3 * v1 + s1 * v3) + 8.0 * w2,
            4.0 * (e0 * d3 - s1 * v2 + s2 * v1) + 8.0 * w3)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _leg_rate_66(dk, dab, e0, q, ee, f0, va, vb, vda, vdb, vdn, vdd, wdd, xds):
    """Leg ``i``'s ``F_tau`` (:func:`_evaluate_66`) by the product rule: ``k' e.e - 2 G' + 4 C'`` with
    ``G' = q (a.b)' + 2 ((v.a')(v.b) + (v.a)(v.b') + e_0 v.n')`` and ``C' = e_0 w.d' - f_0 v.d' - (v x w).s'``
    (the dotted products given: ``vda = v.a'``, ...)."""
    dG = q * dab + 2.0 * (vda * vb + va * vdb + e0 * vdn)
    dC = e0 * wdd - f0 * vdd - xds
    return dk * ee - 2.0 * dG + 4.0 * dC


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _study_66(e0, f0, v, w, c):
    """Study's quadric ``e.f = e_0 f_0 + v.w`` and its row of ``F_z`` through the patch (``w + c f_0``, ``e_0``,
    ``v``)."""
    return (e0 * f0 + v[0] * w[0] + v[1] * w[1] + v[2] * w[2],
            w[0] + c[0] * f0, w[1] + c[1] * f0, w[2] + c[2] * f0, e0, v[0], v[1], v[2])


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _evaluate(kind, K, P, S, prepared, z, tau, dtau, w, H, J, Ht, with_h, with_j, with_t):
    """When ``with_h`` ``H = F(z; p(tau))``, when ``with_j`` ``J = F_z`` and when ``with_t`` ``Ht = F_tau dtau/dt``
    (the dense evaluator forms ``H`` anyway), by the evaluator ``kind``;
    a structured one prepares its per-leg quantities once per distinct ``tau`` (``prepared``: the last one's,
    with a flag: the predictor's middle stages share a tau, its last stage and the corrector another)."""
    if kind == DENSE:
        _evaluate_dense(K, z, tau, dtau, w, H, J, Ht, with_j, with_t)
        return
    if prepared[0] == 0.0 and kind == HEXAPOD_66:
        _prepare_66_path(P, S)
    if prepared[0] == 0.0 or prepared[1] != tau.real or prepared[2] != tau.imag:
        if kind == PLANAR_3RPR:
            _prepare_3rpr(P, tau, S)
        else:
            _prepare_66(P, tau, S)
        prepared[0], prepared[1], prepared[2] = 1.0, tau.real, tau.imag
    if kind == PLANAR_3RPR:
        _evaluate_3rpr(S, z, dtau, H, J, Ht, with_h, with_j, with_t)
    else:
        _evaluate_66(P, S, z, dtau, H, J, Ht, with_h, with_j, with_t)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _lu_factor_solve(A, pivots, x):
    """``x = A^{-1} x`` by Gaussian elimination with partial pivoting, in place: ``A`` is left holding its LU
    factors (the multipliers below the diagonal, ``U`` above it with the reciprocals of the pivots on it, the row
    taken as column ``c``'s pivot in ``pivots[c]``) for :func:`_lu_solve`; False when a pivot is exactly zero.
    The pivot is the largest by ``|Re| + |Im|`` (as LAPACK's complex routines choose it: within a factor sqrt(2)
    of the modulus, and no square root per candidate); its reciprocal is formed once, as ``conj(p) / |p|^2`` (a
    pivot is never near overflow here), for the back substitution too."""
    n = A.shape[0]
    for c in range(n):
        p = c
        best = abs(A[c, c].real) + abs(A[c, c].imag)
        for r in range(c + 1, n):
            a = abs(A[r, c].real) + abs(A[r, c].imag)
            if a > best:
                best, p = a, r
        if best == 0.0:
            return False
        pivots[c] = p
        if p != c:                                       # whole rows: the multipliers follow their row
            for j in range(n):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            x[c], x[p] = x[p], x[c]
        pivot = A[c, c]
        inv = pivot.conjugate() / (pivot.real * pivot.real + pivot.imag * pivot.imag)
        A[c, c] = inv
        xc = x[c]
        for r in range(c + 1, n):
            m = A[r, c] * inv
            A[r, c] = m
            for j in range(c + 1, n):
                A[r, j] -= m * A[c, j]
            x[r] -= m * xc
    _back_substitute(A, x)
    return True


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _back_substitute(LU, x):
    """``x = U^{-1} x``, ``U`` the upper triangle of :func:`_lu_factor_solve`'s factors."""
    n = LU.shape[0]
    for c in range(n - 1, -1, -1):
        s = x[c]
        for j in range(c + 1, n):
            s -= LU[c, j] * x[j]
        x[c] = s * LU[c, c]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _lu_solve(LU, pivots, x):
    """``x = A^{-1} x`` in place from the factors :func:`_lu_factor_solve` left of ``A``: the rows exchanged as
    they were (every exchange first: the factors' rows are in their final order), forward and back
    substitution."""
    n = LU.shape[0]
    for c in range(n):
        p = pivots[c]
        if p != c:
            x[c], x[p] = x[p], x[c]
    for c in range(n):
        xc = x[c]
        for r in range(c + 1, n):
            x[r] -= LU[r, c] * xc
    _back_substitute(LU, x)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _tau(t, gamma):
    """``tau(t) = t / (t + gamma (1 - t))`` and ``dtau/dt = gamma / (t + gamma (1 - t))^2``."""
    d = t + gamma * (1.0 - t)
    inv = d.conjugate() / (d.real * d.real + d.imag * d.imag)      # 1 / d, one real division
    return t * inv, gamma * inv * inv


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _norm(z):
    """``max_k |z_k|`` (one square root, of the largest squared modulus)."""
    m = 0.0
    for k in range(z.shape[0]):
        a = z[k].real * z[k].real + z[k].imag * z[k].imag
        if a > m:
            m = a
    return math.sqrt(m)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _velocity(kind, K, P, S, prepared, z, t, gamma, out, w, H, J, Ht, pivots, factored):
    """``out = dz/dt = -F_z^{-1} F_t`` at ``(z, t)``: ``F_z`` evaluated and factored into ``J`` (``pivots``), or
    when ``factored`` the factors already in ``J`` used (``F_t`` alone evaluated); False when ``F_z`` is
    singular."""
    tau, dtau = _tau(t, gamma)
    _evaluate(kind, K, P, S, prepared, z, tau, dtau, w, H, J, Ht, False, not factored, True)
    for k in range(z.shape[0]):
        out[k] = -Ht[k]
    if factored:
        _lu_solve(J, pivots, out)
        return True
    return _lu_factor_solve(J, pivots, out)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _track_one(kind, K, P, S, prepared, start, gamma, settings, z, J, w, H, Ht, pivots, k1, k2, k3, k4, zt):
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
    k1_current = False                                   # k1 is the velocity at (z, t): kept after a failed step
    # J holds the factors of F_z at the corrector's last iterate, within the corrector's tolerance of (z, t): the
    # next step's first velocity solves with them (an error of that tolerance in k1 is far below the predictor's)
    factors_at_z = False
    while t < 1.0:
        if steps >= max_steps:
            return STEPS_EXHAUSTED, steps, t
        steps += 1
        last = h >= 1.0 - t
        if last:
            h = 1.0 - t
        t1 = 1.0 if last else t + h
        # classical Runge-Kutta predictor
        ok = k1_current or _velocity(kind, K, P, S, prepared, z, t, gamma, k1, w, H, J, Ht, pivots,
                                     factors_at_z)
        k1_current = ok
        if ok:
            for k in range(n):
                zt[k] = z[k] + 0.5 * h * k1[k]
            ok = _velocity(kind, K, P, S, prepared, zt, t + 0.5 * h, gamma, k2, w, H, J, Ht, pivots, False)
        if ok:
            for k in range(n):
                zt[k] = z[k] + 0.5 * h * k2[k]
            ok = _velocity(kind, K, P, S, prepared, zt, t + 0.5 * h, gamma, k3, w, H, J, Ht, pivots, False)
        if ok:
            for k in range(n):
                zt[k] = z[k] + h * k3[k]
            ok = _velocity(kind, K, P, S, prepared, zt, t1, gamma, k4, w, H, J, Ht, pivots, False)
        factors_at_z = False
        if ok:
            for k in range(n):
                zt[k] = z[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k])
            # Newton corrector at t1, F_z evaluated at every iterate (a chord method, F_z kept from the first
            # iteration or from the predictor's last stage, even for the first iteration alone, converged so much
            # more slowly that it took more steps and rejected more of them)
            tau, dtau = _tau(t1, gamma)
            ok = False
            previous = 0.0
            for it in range(iterations):
                _evaluate(kind, K, P, S, prepared, zt, tau, dtau, w, H, J, Ht, True, True, False)
                if not _lu_factor_solve(J, pivots, H):          # H = the Newton update
                    break
                for k in range(n):
                    zt[k] -= H[k]
                step = _norm(H)
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
                    factors_at_z = True
                    break
        if ok:
            for k in range(n):
                z[k] = zt[k]
            t = t1
            k1_current = False
            successes += 1
            if step_target > 0.0:
                h = _next_step(h, first, successes, steps, step_target, h_max)
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
    return _polish(kind, K, P, S, prepared, z, w, H, J, Ht, pivots, final_iterations, final_tol), steps, t


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _next_step(h, first, successes, steps, step_target, h_max):
    """The step after an accepted step ``h`` (``successes`` in a row, ``steps`` taken) whose first corrector update
    was ``first`` (share of 1 + |z|): that update measures the predictor's error, which grows like h^5, so the next
    step aims at ``step_target``, within [1/2, STEP_GROWTH_MAX] times this one and at most this one right after a
    rejected step (the model has just overestimated a step: the usual rule of step control); at most ``h_max``."""
    growth = STEP_GROWTH_MAX if successes > 1 or steps == 1 else 1.0
    if first > 0.0:
        factor = STEP_SAFETY * (step_target / first) ** 0.2
        h = min(max(factor, 0.5), growth) * h
    else:
        h = growth * h
    return min(h, h_max)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _polish(kind, K, P, S, prepared, z, w, H, J, Ht, pivots, final_iterations, final_tol):
    """The final polish of an endpoint ``z`` at t = 1 (tau = 1): Newton's method until its update is below
    ``final_tol`` (share of 1 + |z|) or ``final_iterations``, ``F_z`` there left in ``J``; REGULAR, or SINGULAR
    when ``F_z`` is."""
    for _ in range(final_iterations):
        _evaluate(kind, K, P, S, prepared, z, 1.0 + 0j, 0j, w, H, J, Ht, True, True, False)
        if not _lu_factor_solve(J, pivots, H):
            return SINGULAR
        for k in range(z.shape[0]):
            z[k] -= H[k]
        if _norm(H) <= final_tol * (1.0 + _norm(z)):
            break
    _evaluate(kind, K, P, S, prepared, z, 1.0 + 0j, 0j, w, H, J, Ht, True, True, False)
    return REGULAR


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def track_paths(kind, K, P, starts, gammas, settings, ends, jacobians, outcome, steps, t_end):
    """Tracks every row of ``starts`` (its own ``gammas[p]``) from the start system to the target along the
    parameter path ``(kind, K, P)`` (:class:`ParameterPath`): endpoints in ``ends``, ``F_z`` there in
    ``jacobians``, outcome / steps / t reached per path.  The 6-6's paths advance in lockstep
    (:func:`_track_66_lanes`), every other kind's one after the other (:func:`_track_one`)."""
    if kind == HEXAPOD_66:
        _track_66_lanes(P, starts, gammas, settings, ends, jacobians, outcome, steps, t_end)
    else:
        track_paths_alone(kind, K, P, starts, gammas, settings, ends, jacobians, outcome, steps, t_end)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def track_paths_alone(kind, K, P, starts, gammas, settings, ends, jacobians, outcome, steps, t_end):
    """:func:`track_paths` one path after the other (:func:`_track_one`), for any kind (the 6-6's lockstep kernel
    is checked against it)."""
    n = starts.shape[1]
    m = K.shape[1] if kind == DENSE else n
    z = np.empty(n, np.complex128)
    w = np.empty(n + 1, np.complex128)
    H = np.empty(m, np.complex128)
    Ht = np.empty(m, np.complex128)
    J = np.empty((n, n), np.complex128)
    pivots = np.empty(n, np.int64)
    k1 = np.empty(n, np.complex128)
    k2 = np.empty(n, np.complex128)
    k3 = np.empty(n, np.complex128)
    k4 = np.empty(n, np.complex128)
    zt = np.empty(n, np.complex128)
    if kind == PLANAR_3RPR:
        S = np.empty((3, RPR_WIDTH), np.complex128)
    elif kind == HEXAPOD_66:
        S = np.empty((6, HEX_WIDTH), np.complex128)
    else:
        S = np.empty((0, 0), np.complex128)
    prepared = np.zeros(3)
    for p in range(starts.shape[0]):
        o, s, t = _track_one(kind, K, P, S, prepared, starts[p], gammas[p], settings, z, J, w, H, Ht, pivots, k1,
                             k2, k3, k4, zt)
        _record_path(p, o, s, t, z, J, ends, jacobians, outcome, steps, t_end)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _record_path(p, o, s, t, z, J, ends, jacobians, outcome, steps, t_end):
    """Path ``p``'s results in :func:`track_paths`' arrays: outcome ``o``, ``s`` steps, ``t`` reached, the endpoint
    ``z`` and ``F_z`` there (``J``)."""
    outcome[p] = o
    steps[p] = s
    t_end[p] = t
    for k in range(z.shape[0]):
        ends[p, k] = z[k]
        for j in range(z.shape[0]):
            jacobians[p, k, j] = J[k, j]


# ==========================================================================================================
# the 6-6's paths in lockstep: LANES paths advanced together, the lanes innermost
# ==========================================================================================================
#: paths advanced together by :func:`_track_66_lanes`: every array holds one value per lane in consecutive
#: memory (real and imaginary parts apart), so that the compiler vectorises the loops over the lanes (4 doubles
#: per AVX2 register: two vector passes per loop); 8 lanes keep 7 of 8 busy on average over the 6-6's 40 paths.
#: The offsets use LANES (a constant: the compiler sees that rows do not overlap) but the loops run to the lanes'
#: count taken from an array's length: with a constant count of 8 the compiler unrolls a loop instead and does not
#: vectorise it
LANES = 8
#: the unknowns of the 6-6 in Study parameters (the lanes' row count)
N66 = 7
#: an offset masked with this is known to be non-negative, so the compiler drops Numba's negative-index
#: wraparound (which would keep it from vectorising a loop whose offsets come from arguments)
_OFFSET_MASK = (1 << 40) - 1
# a column of the per-leg table (HEX_*) in the lanes' layout: leg i's column c of lane l at (i HEX_WIDTH + c) LANES + l
_LA, _LB, _LD, _LS, _LN, _LAB, _LK = (c * LANES for c in (HEX_A, HEX_B, HEX_D, HEX_S, HEX_BXA, HEX_AB, HEX_K))
_LDA, _LDB, _LDD, _LDS, _LDN, _LDAB, _LDK = (c * LANES for c in (HEX_DA, HEX_DB, HEX_DD, HEX_DS, HEX_DBXA, HEX_DAB,
                                                                 HEX_DK))
_LEG = HEX_WIDTH * LANES


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _lane(Ar, Ai, u):
    """The complex value at ``u`` of a lanes' array (real parts in ``Ar``, imaginary parts in ``Ai``)."""
    return complex(Ar[u], Ai[u])


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _set_lane(Ar, Ai, u, x):
    """``A[u] = x`` in a lanes' array (real and imaginary parts apart)."""
    Ar[u], Ai[u] = x.real, x.imag


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _vector_lanes(Ar, Ai, u):
    """One lane's 3-vector (a tuple) from a lanes' array: the values at ``u``, ``u + LANES`` and ``u + 2 LANES``
    (a per-leg column of ``HEX_*`` and the next two)."""
    return _lane(Ar, Ai, u), _lane(Ar, Ai, u + LANES), _lane(Ar, Ai, u + 2 * LANES)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _unknowns_lanes(zr, zi, lane):
    """Lane ``lane``'s ``z = (v, f_0, w)`` (the 6-6's unknowns in Study parameters, rows ``LANES`` apart):
    ``v`` and ``w`` as 3-vectors (tuples)."""
    return _vector_lanes(zr, zi, lane), _lane(zr, zi, 3 * LANES + lane), _vector_lanes(zr, zi, 4 * LANES + lane)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _set_row_lanes(Ar, Ai, u, x0, x1, x2, x3, x4, x5, x6):
    """Lane's ``N66`` values ``x0 .. x6`` into a lanes' array at ``u``, ``u + LANES``, ..., ``u + 6 LANES`` (a row
    of ``F_z``, or the rows of :func:`_common_66_lanes`)."""
    _set_lane(Ar, Ai, u, x0)
    _set_lane(Ar, Ai, u + LANES, x1)
    _set_lane(Ar, Ai, u + 2 * LANES, x2)
    _set_lane(Ar, Ai, u + 3 * LANES, x3)
    _set_lane(Ar, Ai, u + 4 * LANES, x4)
    _set_lane(Ar, Ai, u + 5 * LANES, x5)
    _set_lane(Ar, Ai, u + 6 * LANES, x6)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _point_lanes(zr, zi, Cr, Ci, lane):
    """Lane ``lane``'s point and its leg-independent quantities (:func:`_common_66_lanes`): ``v``, ``f_0``, ``w``,
    ``e_0``, ``e_0^2 - v.v``, ``e_0^2 + v.v``, ``f.f`` and ``v x w`` (the 3-vectors as tuples)."""
    v, f0, w = _unknowns_lanes(zr, zi, lane)
    return (v, f0, w, _lane(Cr, Ci, lane), _lane(Cr, Ci, LANES + lane), _lane(Cr, Ci, 2 * LANES + lane),
            _lane(Cr, Ci, 3 * LANES + lane), _vector_lanes(Cr, Ci, 4 * LANES + lane))


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _prepare_66_lanes(P, Tr, Ti, Sr, Si, taur, taui):
    """:func:`_prepare_66` per lane at ``tau[l]``: the tau-dependent columns into ``S``, from ``p(tau)`` and the
    tau-independent columns and coefficients of :func:`_prepare_66_path` in ``T`` (``T`` is read, ``S`` written:
    two arrays, so the compiler need not prove that the columns do not overlap)."""
    lanes = taur.shape[0]  # LANES, as a count known only at run time (see LANES)
    for i in range(6):
        o = i * _LEG
        for k in range(3):
            a0, b0 = P[3 * i + k], P[18 + 3 * i + k]
            ok = o + k * LANES
            for lane in range(lanes):
                tau = complex(taur[lane], taui[lane])
                a = a0 + tau * _lane(Tr, Ti, ok + _LDA + lane)
                b = b0 + tau * _lane(Tr, Ti, ok + _LDB + lane)
                _set_lane(Sr, Si, ok + _LA + lane, a)
                _set_lane(Sr, Si, ok + _LB + lane, b)
                _set_lane(Sr, Si, ok + _LD + lane, b - a)
                _set_lane(Sr, Si, ok + _LS + lane, b + a)
        for k in range(3):
            _quadratic_lanes(Tr, Ti, Sr, Si, taur, taui, i, HEX_BXA_COEF + 3 * k, HEX_BXA + k, HEX_DBXA + k)
        _quadratic_lanes(Tr, Ti, Sr, Si, taur, taui, i, HEX_AB_COEF, HEX_AB, HEX_DAB)
        _quadratic_lanes(Tr, Ti, Sr, Si, taur, taui, i, HEX_K_COEF, HEX_K, HEX_DK)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _quadratic_lanes(Tr, Ti, Sr, Si, taur, taui, i, at, value, derivative):
    """:func:`_quadratic` per lane: leg ``i``'s column ``value`` of ``S`` and its tau-derivative (column
    ``derivative``) at ``tau[l]`` from the coefficients in columns ``at`` to ``at + 2`` of ``T``."""
    lanes = taur.shape[0]  # LANES, as a count known only at run time (see LANES)
    c = ((i * HEX_WIDTH + at) * LANES) & _OFFSET_MASK
    v = ((i * HEX_WIDTH + value) * LANES) & _OFFSET_MASK
    d = ((i * HEX_WIDTH + derivative) * LANES) & _OFFSET_MASK
    for lane in range(lanes):
        c0, c1, c2 = _vector_lanes(Tr, Ti, c + lane)
        q, dq = _quadratic_at(c0, c1, c2, complex(taur[lane], taui[lane]))
        _set_lane(Sr, Si, v + lane, q)
        _set_lane(Sr, Si, d + lane, dq)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _common_66_lanes(P, zr, zi, Cr, Ci):
    """Per lane the leg-independent quantities of :func:`_evaluate_66` at ``z`` (:func:`_common_66`): rows
    ``e_0``, ``e_0^2 - v.v``, ``e_0^2 + v.v``, ``f.f`` and ``v x w`` (3) of ``C``."""
    lanes = zr.shape[0] // N66  # LANES, as a count known only at run time (see LANES)
    c = (P[2 * HEX_PARAMS + 1], P[2 * HEX_PARAMS + 2], P[2 * HEX_PARAMS + 3])
    for lane in range(lanes):
        v, f0, w = _unknowns_lanes(zr, zi, lane)
        e0, q, ee, ff, x = _common_66(P[2 * HEX_PARAMS], c, v, f0, w)
        _set_row_lanes(Cr, Ci, lane, e0, q, ee, ff, x[0], x[1], x[2])


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _jacobian_66_lanes(P, Sr, Si, zr, zi, Cr, Ci, Hr, Hi, Jr, Ji, with_h):
    """:func:`_evaluate_66` per lane, the lanes innermost: ``J = F_z`` and when ``with_h`` ``H = F``, from ``S``
    prepared at the lanes' tau and ``C`` (:func:`_common_66_lanes`) at ``z``."""
    lanes = zr.shape[0] // N66  # LANES, as a count known only at run time (see LANES)
    c = (P[2 * HEX_PARAMS + 1], P[2 * HEX_PARAMS + 2], P[2 * HEX_PARAMS + 3])
    for i in range(6):
        for lane in range(lanes):
            v, f0, w, e0, q, ee, ff, x = _point_lanes(zr, zi, Cr, Ci, lane)
            ol = i * _LEG + lane
            a = _vector_lanes(Sr, Si, ol + _LA)
            b = _vector_lanes(Sr, Si, ol + _LB)
            d = _vector_lanes(Sr, Si, ol + _LD)
            s = _vector_lanes(Sr, Si, ol + _LS)
            n = _vector_lanes(Sr, Si, ol + _LN)
            ab, k = _lane(Sr, Si, ol + _LAB), _lane(Sr, Si, ol + _LK)
            va, vb, vn, vd, wd = _dot3(v, a), _dot3(v, b), _dot3(v, n), _dot3(v, d), _dot3(w, d)
            if with_h:
                _set_lane(Hr, Hi, i * LANES + lane,
                          _leg_residual_66(k, ab, e0, q, ee, ff, f0, va, vb, vn, vd, wd, _dot3(x, s)))
            j0, j1, j2, j3, j4, j5, j6 = _leg_gradient_66(k, ab, e0, f0, v, w, c, a, b, d, s, n, va, vb, vn, vd, wd)
            _set_row_lanes(Jr, Ji, i * N66 * LANES + lane, j0, j1, j2, j3, j4, j5, j6)
    for lane in range(lanes):
        v, f0, w = _unknowns_lanes(zr, zi, lane)
        h, j0, j1, j2, j3, j4, j5, j6 = _study_66(_lane(Cr, Ci, lane), f0, v, w, c)
        if with_h:
            _set_lane(Hr, Hi, 6 * LANES + lane, h)
        _set_row_lanes(Jr, Ji, 6 * N66 * LANES + lane, j0, j1, j2, j3, j4, j5, j6)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _velocity_rhs_66_lanes(P, Tr, Ti, Sr, Si, zr, zi, Cr, Ci, dtr, dti, Xr, Xi):
    """Per lane the right-hand side ``X = -F_tau dtau/dt`` of a velocity (:func:`_evaluate_66`'s ``F_tau``), from
    ``S`` and ``T`` prepared at the lanes' tau and ``C`` at ``z``."""
    lanes = zr.shape[0] // N66  # LANES, as a count known only at run time (see LANES)
    for i in range(6):
        for lane in range(lanes):
            v, f0, w, e0, q, ee, ff, x = _point_lanes(zr, zi, Cr, Ci, lane)
            ol = i * _LEG + lane
            dd = _vector_lanes(Tr, Ti, ol + _LDD)
            rate = _leg_rate_66(_lane(Sr, Si, ol + _LDK), _lane(Sr, Si, ol + _LDAB), e0, q, ee, f0,
                                _dot3(v, _vector_lanes(Sr, Si, ol + _LA)), _dot3(v, _vector_lanes(Sr, Si, ol + _LB)),
                                _dot3(v, _vector_lanes(Tr, Ti, ol + _LDA)), _dot3(v, _vector_lanes(Tr, Ti, ol + _LDB)),
                                _dot3(v, _vector_lanes(Sr, Si, ol + _LDN)), _dot3(v, dd), _dot3(w, dd),
                                _dot3(x, _vector_lanes(Tr, Ti, ol + _LDS)))
            _set_lane(Xr, Xi, i * LANES + lane, -rate * _lane(dtr, dti, lane))
    for lane in range(lanes):
        Xr[6 * LANES + lane], Xi[6 * LANES + lane] = 0.0, 0.0


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _lu_lanes(Ar, Ai, pivots, xr, xi, ok, best, inv_r, inv_i, m_r, m_i):
    """:func:`_lu_factor_solve` per lane: ``x = A^{-1} x`` by Gaussian elimination with partial pivoting (the
    largest ``|Re| + |Im|``), in place; ``A`` left holding the factors (the reciprocals of the pivots on the
    diagonal) and ``pivots`` the rows taken; ``ok[l]`` False when lane ``l``'s pivot is exactly zero.  The row
    exchanges differ between the lanes and are made lane by lane; the elimination runs over the lanes.  Its updates
    ``x -= m u`` (here and in the substitutions) are written out in real and imaginary parts: the same update as an
    inlined helper (storing, or returning the product) took 13 % more CPU per 6-6 path set."""
    n = N66
    lanes = Ar.shape[0] // (N66 * N66)  # LANES, as a count known only at run time (see LANES)
    for lane in range(lanes):
        ok[lane] = True
    for c in range(n):
        for lane in range(lanes):
            best[lane] = abs(Ar[(c * N66 + c) * LANES + lane]) + abs(Ai[(c * N66 + c) * LANES + lane])
            pivots[c * LANES + lane] = c
        for r in range(c + 1, n):
            for lane in range(lanes):
                a = abs(Ar[(r * N66 + c) * LANES + lane]) + abs(Ai[(r * N66 + c) * LANES + lane])
                if a > best[lane]:
                    best[lane] = a
                    pivots[c * LANES + lane] = r
        for lane in range(lanes):
            p = pivots[c * LANES + lane]
            if p != c:
                for j in range(n):                      # whole rows: the multipliers follow their row
                    _swap_lanes(Ar, Ai, (c * N66 + j) * LANES + lane, (p * N66 + j) * LANES + lane)
                _swap_lanes(xr, xi, c * LANES + lane, p * LANES + lane)
            if best[lane] == 0.0:
                ok[lane] = False
        for lane in range(lanes):
            pr, pi = Ar[(c * N66 + c) * LANES + lane], Ai[(c * N66 + c) * LANES + lane]
            d = 1.0 / (pr * pr + pi * pi)
            inv_r[lane] = pr * d
            inv_i[lane] = -pi * d
            Ar[(c * N66 + c) * LANES + lane] = pr * d
            Ai[(c * N66 + c) * LANES + lane] = -pi * d
        for r in range(c + 1, n):
            for lane in range(lanes):
                ar, ai = Ar[(r * N66 + c) * LANES + lane], Ai[(r * N66 + c) * LANES + lane]
                mr = ar * inv_r[lane] - ai * inv_i[lane]
                mi = ar * inv_i[lane] + ai * inv_r[lane]
                Ar[(r * N66 + c) * LANES + lane] = mr
                Ai[(r * N66 + c) * LANES + lane] = mi
                m_r[lane] = mr
                m_i[lane] = mi
                xr[r * LANES + lane] -= mr * xr[c * LANES + lane] - mi * xi[c * LANES + lane]
                xi[r * LANES + lane] -= mr * xi[c * LANES + lane] + mi * xr[c * LANES + lane]
            for j in range(c + 1, n):
                for lane in range(lanes):
                    ur, ui = Ar[(c * N66 + j) * LANES + lane], Ai[(c * N66 + j) * LANES + lane]
                    Ar[(r * N66 + j) * LANES + lane] -= m_r[lane] * ur - m_i[lane] * ui
                    Ai[(r * N66 + j) * LANES + lane] -= m_r[lane] * ui + m_i[lane] * ur
    _back_substitute_lanes(Ar, Ai, xr, xi)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH, inline=NUMBA_INLINE)
def _swap_lanes(Ar, Ai, u, v):
    """Exchanges ``A[u]`` and ``A[v]`` in a lanes' array (a row exchange of the LU, one lane's entry)."""
    Ar[u], Ar[v] = Ar[v], Ar[u]
    Ai[u], Ai[v] = Ai[v], Ai[u]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _back_substitute_lanes(Ar, Ai, xr, xi):
    """:func:`_back_substitute` per lane."""
    lanes = xr.shape[0] // N66  # LANES, as a count known only at run time (see LANES)
    R = N66 * LANES
    for c in range(N66 - 1, -1, -1):
        for j in range(c + 1, N66):
            for lane in range(lanes):
                ur, ui = Ar[c * R + j * LANES + lane], Ai[c * R + j * LANES + lane]
                xjr, xji = xr[j * LANES + lane], xi[j * LANES + lane]
                xr[c * LANES + lane] -= ur * xjr - ui * xji
                xi[c * LANES + lane] -= ur * xji + ui * xjr
        for lane in range(lanes):
            ur, ui = Ar[c * R + c * LANES + lane], Ai[c * R + c * LANES + lane]
            a, b = xr[c * LANES + lane], xi[c * LANES + lane]
            xr[c * LANES + lane], xi[c * LANES + lane] = a * ur - b * ui, a * ui + b * ur


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _lu_solve_lanes(Ar, Ai, pivots, xr, xi):
    """:func:`_lu_solve` per lane, from :func:`_lu_lanes`' factors."""
    lanes = xr.shape[0] // N66  # LANES, as a count known only at run time (see LANES)
    R = N66 * LANES
    for c in range(N66):
        for lane in range(lanes):
            p = pivots[c * LANES + lane]
            if p != c:
                _swap_lanes(xr, xi, c * LANES + lane, p * LANES + lane)
    for c in range(N66):
        for r in range(c + 1, N66):
            for lane in range(lanes):
                lr, li = Ar[r * R + c * LANES + lane], Ai[r * R + c * LANES + lane]
                xcr, xci = xr[c * LANES + lane], xi[c * LANES + lane]
                xr[r * LANES + lane] -= lr * xcr - li * xci
                xi[r * LANES + lane] -= lr * xci + li * xcr
    _back_substitute_lanes(Ar, Ai, xr, xi)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _tau_lanes(t, gr, gi, taur, taui, dtr, dti):
    """:func:`_tau` per lane (``gamma`` of each lane's path)."""
    lanes = t.shape[0]  # LANES, as a count known only at run time (see LANES)
    for lane in range(lanes):
        tau, dtau = _tau(t[lane], complex(gr[lane], gi[lane]))
        _set_lane(taur, taui, lane, tau)
        _set_lane(dtr, dti, lane, dtau)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _shift_lanes(zr, zi, share, h, kr, ki, outr, outi):
    """Per lane ``out = z + share h[l] k`` (a Runge-Kutta stage's point)."""
    lanes = h.shape[0]  # LANES, as a count known only at run time (see LANES)
    for j in range(N66):
        for lane in range(lanes):
            s = share * h[lane]
            outr[j * LANES + lane] = zr[j * LANES + lane] + s * kr[j * LANES + lane]
            outi[j * LANES + lane] = zi[j * LANES + lane] + s * ki[j * LANES + lane]


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _velocity_66_lanes(P, Tr, Ti, Sr, Si, zr, zi, Cr, Ci, dtr, dti, Xr, Xi, Jr, Ji, pivots, ok, work):
    """:func:`_velocity` per lane: ``X = dz/dt = -F_z^{-1} F_t`` at ``z`` (``S`` prepared at the lanes' tau),
    ``F_z`` factored into ``J``; ``ok[l]`` False where it is singular.  ``work``: 5 rows of ``LANES`` scratch."""
    _common_66_lanes(P, zr, zi, Cr, Ci)
    _velocity_rhs_66_lanes(P, Tr, Ti, Sr, Si, zr, zi, Cr, Ci, dtr, dti, Xr, Xi)
    _jacobian_66_lanes(P, Sr, Si, zr, zi, Cr, Ci, Xr, Xi, Jr, Ji, False)
    _lu_lanes(Jr, Ji, pivots, Xr, Xi, ok, work[0], work[1], work[2], work[3], work[4])


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _end_path(P, S, prepared, zs, ws, Hs, Hts, Js, pivots, outcome, final_iterations, final_tol):
    """A path's end at ``zs``: a regular endpoint (``outcome`` REGULAR) polished by Newton's method at t = 1 as in
    :func:`_track_one`, ``F_z`` there in ``Js`` (zero for any other outcome); returns the outcome (SINGULAR when
    ``F_z`` is)."""
    if outcome != REGULAR:
        Js[:, :] = 0.0
        return outcome
    return _polish(HEXAPOD_66, np.zeros((3, 0, 0, 0), np.complex128), P, S, prepared, zs, ws, Hs, Js, Hts, pivots,
                   final_iterations, final_tol)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _track_66_lanes(P, starts, gammas, settings, ends, jacobians, outcome, steps, t_end):
    """:func:`track_paths` for the 6-6 (``HEXAPOD_66``): the method of :func:`_track_one`, step for step, with
    ``LANES`` paths advanced together.  Each lane holds a path's own ``z``, ``t``, step size and state; one round
    forms every lane's Runge-Kutta stages and Newton iterations together (the evaluator, the LU and the stage
    arithmetic run over the lanes, which the compiler vectorises), and each lane then accepts or rejects its step
    by its own rule.  The corrector iterates while any lane's has not finished (a finished lane's results are
    ignored).  A lane whose path ends polishes its endpoint (alone) and takes the next path; the kernel returns
    when every path has ended."""
    n = N66
    count = starts.shape[0]
    h_max, h_min = settings[1], settings[2]
    iterations = int(settings[4])
    tol, contraction, max_first = settings[5], settings[6], settings[7]
    at_infinity, max_steps = settings[8], int(settings[9])
    final_iterations, final_tol, endgame = int(settings[10]), settings[11], settings[12]
    step_target = settings[13]
    # per lane, the lanes innermost (real and imaginary parts apart): z, the stage point zt, k1..k3, a stage's
    # velocity or the Newton update X, F_z (factored) J, the corrector's last factors F kept for the next k1
    zr, zi, ztr, zti = np.zeros(n * LANES), np.zeros(n * LANES), np.zeros(n * LANES), np.zeros(n * LANES)
    k1r, k1i, k2r, k2i = np.zeros(n * LANES), np.zeros(n * LANES), np.zeros(n * LANES), np.zeros(n * LANES)
    k3r, k3i, Xr, Xi = np.zeros(n * LANES), np.zeros(n * LANES), np.zeros(n * LANES), np.zeros(n * LANES)
    Jr, Ji, Fr, Fi = (np.zeros(n * n * LANES), np.zeros(n * n * LANES), np.zeros(n * n * LANES),
                      np.zeros(n * n * LANES))
    pivots, kept_pivots = np.zeros(n * LANES, np.int64), np.zeros(n * LANES, np.int64)
    Cr, Ci = np.zeros(7 * LANES), np.zeros(7 * LANES)
    Sr, Si = np.zeros(6 * _LEG), np.zeros(6 * _LEG)
    Tr, Ti = np.zeros(6 * _LEG), np.zeros(6 * _LEG)
    taur, taui, dtr, dti = np.zeros(LANES), np.zeros(LANES), np.zeros(LANES), np.zeros(LANES)
    gr, gi = np.ones(LANES), np.zeros(LANES)
    work = np.zeros((5, LANES))
    t, t_mid, t1, h = np.zeros(LANES), np.zeros(LANES), np.zeros(LANES), np.zeros(LANES)
    first, previous = np.zeros(LANES), np.zeros(LANES)
    ok, stage_ok, live = np.zeros(LANES, np.bool_), np.zeros(LANES, np.bool_), np.zeros(LANES, np.bool_)
    k1_current, factors_at_z = np.zeros(LANES, np.bool_), np.zeros(LANES, np.bool_)
    path = np.full(LANES, -1, np.int64)
    lane_steps, successes = np.zeros(LANES, np.int64), np.zeros(LANES, np.int64)
    # the per-leg table's tau-independent columns (one path set: the same for every lane); a lane's first
    # velocity and an endpoint's polish use the scalar evaluator on one path
    S = np.zeros((6, HEX_WIDTH), np.complex128)
    _prepare_66_path(P, S)
    for i in range(6):
        for c in range(HEX_WIDTH):
            for lane in range(LANES):
                Tr[i * _LEG + c * LANES + lane], Ti[i * _LEG + c * LANES + lane] = S[i, c].real, S[i, c].imag
    prepared = np.zeros(3)
    K = np.zeros((3, 0, 0, 0), np.complex128)
    zs, ws, Hs, Hts = np.zeros(n, np.complex128), np.zeros(n + 1, np.complex128), np.zeros(n, np.complex128), \
        np.zeros(n, np.complex128)
    Js, pivots_s, ks = np.zeros((n, n), np.complex128), np.zeros(n, np.int64), np.zeros(n, np.complex128)
    following = 0
    running = 0
    for lane in range(LANES):
        if following < count:
            _take_path(lane, following, starts, gammas, settings[0], zr, zi, gr, gi, t, h, lane_steps, successes,
                       k1_current, factors_at_z, path)
            following += 1
            running += 1
    while running > 0:
        need_k1 = False
        for lane in range(LANES):
            ok[lane] = True
            need_k1 = need_k1 or (path[lane] >= 0 and not k1_current[lane])
            if path[lane] >= 0:
                lane_steps[lane] += 1
                if h[lane] >= 1.0 - t[lane]:
                    h[lane] = 1.0 - t[lane]
                    t1[lane] = 1.0
                else:
                    t1[lane] = t[lane] + h[lane]
            t_mid[lane] = t[lane] + 0.5 * h[lane]
        # k1 at (z, t): kept after a rejected step; else with the corrector's last factors (F_t alone evaluated);
        # a path's first one afresh
        if need_k1:
            _tau_lanes(t, gr, gi, taur, taui, dtr, dti)
            _prepare_66_lanes(P, Tr, Ti, Sr, Si, taur, taui)
            _common_66_lanes(P, zr, zi, Cr, Ci)
            _velocity_rhs_66_lanes(P, Tr, Ti, Sr, Si, zr, zi, Cr, Ci, dtr, dti, Xr, Xi)
            _lu_solve_lanes(Fr, Fi, kept_pivots, Xr, Xi)
            for lane in range(LANES):
                if path[lane] < 0 or k1_current[lane]:
                    continue
                if factors_at_z[lane]:
                    for k in range(n):
                        k1r[k * LANES + lane], k1i[k * LANES + lane] = Xr[k * LANES + lane], Xi[k * LANES + lane]
                else:
                    _lane_point(zr, zi, lane, zs)
                    prepared[0] = 0.0
                    ok[lane] = _velocity(HEXAPOD_66, K, P, S, prepared, zs, t[lane], complex(gr[lane], gi[lane]), ks,
                                         ws, Hs, Js, Hts, pivots_s, False)
                    for k in range(n):
                        _set_lane(k1r, k1i, k * LANES + lane, ks[k])
                k1_current[lane] = ok[lane]
        # classical Runge-Kutta predictor: k2, k3 at t + h/2, k4 (into X) at t1
        _tau_lanes(t_mid, gr, gi, taur, taui, dtr, dti)
        _prepare_66_lanes(P, Tr, Ti, Sr, Si, taur, taui)
        _shift_lanes(zr, zi, 0.5, h, k1r, k1i, ztr, zti)
        _velocity_66_lanes(P, Tr, Ti, Sr, Si, ztr, zti, Cr, Ci, dtr, dti, k2r, k2i, Jr, Ji, pivots, stage_ok, work)
        ok &= stage_ok
        _shift_lanes(zr, zi, 0.5, h, k2r, k2i, ztr, zti)
        _velocity_66_lanes(P, Tr, Ti, Sr, Si, ztr, zti, Cr, Ci, dtr, dti, k3r, k3i, Jr, Ji, pivots, stage_ok, work)
        ok &= stage_ok
        _shift_lanes(zr, zi, 1.0, h, k3r, k3i, ztr, zti)
        _tau_lanes(t1, gr, gi, taur, taui, dtr, dti)
        _prepare_66_lanes(P, Tr, Ti, Sr, Si, taur, taui)
        _velocity_66_lanes(P, Tr, Ti, Sr, Si, ztr, zti, Cr, Ci, dtr, dti, Xr, Xi, Jr, Ji, pivots, stage_ok, work)
        ok &= stage_ok
        for k in range(n):
            for lane in range(LANES):
                u = k * LANES + lane
                s = h[lane] / 6.0
                ztr[u] = zr[u] + s * (k1r[u] + 2.0 * k2r[u] + 2.0 * k3r[u] + Xr[u])
                zti[u] = zi[u] + s * (k1i[u] + 2.0 * k2i[u] + 2.0 * k3i[u] + Xi[u])
        # Newton corrector at t1, every lane's iterations together until each has converged or failed
        for lane in range(LANES):
            live[lane] = ok[lane] and path[lane] >= 0
            ok[lane] = False
            factors_at_z[lane] = False
        any_live = np.any(live)
        for it in range(iterations):
            if not any_live:
                break
            _common_66_lanes(P, ztr, zti, Cr, Ci)
            _jacobian_66_lanes(P, Sr, Si, ztr, zti, Cr, Ci, Xr, Xi, Jr, Ji, True)
            _lu_lanes(Jr, Ji, pivots, Xr, Xi, stage_ok, work[0], work[1], work[2], work[3], work[4])
            any_live = False
            for lane in range(LANES):
                if not live[lane]:
                    continue
                live[lane] = False
                if not stage_ok[lane]:
                    continue
                update = 0.0
                size = 0.0
                for k in range(n):
                    u = k * LANES + lane
                    ztr[u] -= Xr[u]
                    zti[u] -= Xi[u]
                    update = max(update, Xr[u] * Xr[u] + Xi[u] * Xi[u])
                    size = max(size, ztr[u] * ztr[u] + zti[u] * zti[u])
                step = math.sqrt(update)
                scale = 1.0 + math.sqrt(size)
                if it == 0:
                    first[lane] = step / scale
                if (it == 0 and step > max_first * scale) or (it > 0 and step > contraction * previous[lane]):
                    continue
                previous[lane] = step
                if step <= tol * scale:
                    ok[lane] = True
                    factors_at_z[lane] = True
                    for k in range(n):
                        kept_pivots[k * LANES + lane] = pivots[k * LANES + lane]
                    for u in range(lane, n * n * LANES, LANES):
                        Fr[u], Fi[u] = Jr[u], Ji[u]
                else:
                    live[lane] = True
                    any_live = True
        # each lane's step control (_track_one's); a lane whose path ended takes the next path
        for lane in range(LANES):
            p = path[lane]
            if p < 0:
                continue
            end = -1
            if ok[lane]:
                size = 0.0
                for k in range(n):
                    u = k * LANES + lane
                    zr[u], zi[u] = ztr[u], zti[u]
                    size = max(size, zr[u] * zr[u] + zi[u] * zi[u])
                t[lane] = t1[lane]
                k1_current[lane] = False
                successes[lane] += 1
                if step_target > 0.0:
                    h[lane] = _next_step(h[lane], first[lane], successes[lane], lane_steps[lane], step_target, h_max)
                if math.sqrt(size) > at_infinity:
                    end = AT_INFINITY_REACHED
                elif t[lane] >= 1.0:
                    end = REGULAR
            else:
                h[lane] *= 0.5
                successes[lane] = 0
                if h[lane] < h_min:
                    end = ENDGAME_SINGULAR if 1.0 - t[lane] < endgame else STEP_FAILED
            if end < 0 and lane_steps[lane] >= max_steps:
                end = STEPS_EXHAUSTED
            if end < 0:
                continue
            _lane_point(zr, zi, lane, zs)
            prepared[0] = 0.0
            o = _end_path(P, S, prepared, zs, ws, Hs, Hts, Js, pivots_s, end, final_iterations, final_tol)
            _record_path(p, o, lane_steps[lane], t[lane], zs, Js, ends, jacobians, outcome, steps, t_end)
            if following < count:
                _take_path(lane, following, starts, gammas, settings[0], zr, zi, gr, gi, t, h, lane_steps,
                           successes, k1_current, factors_at_z, path)
                following += 1
            else:
                path[lane] = -1
                running -= 1


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _lane_point(zr, zi, lane, z):
    """Lane ``lane``'s point of a lanes' array (``N66`` rows) into the complex vector ``z``."""
    for k in range(N66):
        z[k] = complex(zr[k * LANES + lane], zi[k * LANES + lane])


@njit(cache=True, nogil=True, error_model="numpy", fastmath=FAST_MATH)
def _take_path(lane, p, starts, gammas, h0, zr, zi, gr, gi, t, h, lane_steps, successes, k1_current,
               factors_at_z, path):
    """Lane ``lane`` takes path ``p``: its start, its gamma, t = 0 and the first step ``h0``."""
    path[lane] = p
    for k in range(N66):
        zr[k * LANES + lane], zi[k * LANES + lane] = starts[p, k].real, starts[p, k].imag
    gr[lane], gi[lane] = gammas[p].real, gammas[p].imag
    t[lane] = 0.0
    h[lane] = h0
    lane_steps[lane] = 0
    successes[lane] = 0
    k1_current[lane] = False
    factors_at_z[lane] = False


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity; the machine's count where that is unknown)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:              # not Linux
        return os.cpu_count() or 1


def default_threads(paths: int) -> int:
    """:func:`track`'s default thread count: the cores this process may run on, at most one per
    ``MIN_PATHS_PER_THREAD`` paths (at least one)."""
    return max(1, min(available_cores(), int(paths) // MIN_PATHS_PER_THREAD))


class _Pool:
    """One thread pool for every :func:`track` of the process, grown on demand; a forked child (the map's
    worker processes) gets its own, the parent's threads do not exist there."""

    def __init__(self):
        self._lock = threading.Lock()
        self._executor = None
        self._size = 0
        self._pid = 0

    def executor(self, workers: int) -> ThreadPoolExecutor:
        with self._lock:
            if self._executor is None or self._pid != os.getpid() or self._size < workers:
                if self._executor is not None and self._pid == os.getpid():
                    self._executor.shutdown(wait=False)
                self._executor = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="glpma-paths")
                self._size, self._pid = workers, os.getpid()
            return self._executor


_POOL = _Pool()


def track(path: ParameterPath, starts, gammas, settings=SETTINGS, threads=None):
    """Every row of ``starts`` tracked along ``path`` (:func:`track_paths`): (endpoints, ``F_z`` there, outcomes,
    steps, t reached).  ``threads``: how many threads track the paths (default :func:`default_threads`; at most one
    per path); the calling thread is one of them, the others come from a pool shared by every call.  Each path is
    tracked by the same compiled code whichever thread takes it, so the results do not depend on ``threads``."""
    count, n = starts.shape
    threads = default_threads(count) if threads is None else int(threads)
    if threads < 1:
        raise ValueError(f"threads must be at least 1, not {threads}")
    ends = np.empty((count, n), complex)
    jac = np.empty((count, n, n), complex)
    outcome = np.empty(count, np.int64)
    steps = np.empty(count, np.int64)
    t_end = np.empty(count)
    starts = np.ascontiguousarray(starts, dtype=complex)
    gammas = np.ascontiguousarray(gammas, dtype=complex)
    threads = min(threads, max(count, 1))
    if threads == 1:
        track_paths(path.kind, path.K, path.P, starts, gammas, settings, ends, jac, outcome, steps, t_end)
        return ends, jac, outcome, steps, t_end
    bounds, lo = [], 0
    while lo < count:
        if path.kind == HEXAPOD_66:                      # lockstep: an equal share per thread keeps its lanes busy
            size = math.ceil(count / threads)
        else:
            size = max(1, math.ceil(GUIDED_SHARE * (count - lo) / threads))
        bounds.append((lo, min(lo + size, count)))
        lo += size
    taken = itertools.count()                # next(...) is atomic under the GIL: each chunk is taken once

    def worker():
        for k in iter(taken.__next__, None):
            if k >= len(bounds):
                return
            lo, hi = bounds[k]
            track_paths(path.kind, path.K, path.P, starts[lo:hi], gammas[lo:hi], settings, ends[lo:hi],
                        jac[lo:hi], outcome[lo:hi], steps[lo:hi], t_end[lo:hi])

    helpers = [_POOL.executor(threads - 1).submit(worker) for _ in range(threads - 1)]
    worker()
    for f in helpers:
        f.result()
    return ends, jac, outcome, steps, t_end


def evaluate(path: ParameterPath, z, tau, dtau=1.0):
    """``(F, F_z, F_tau dtau)`` at ``z`` and ``p(tau)`` by the evaluator the tracker calls for ``path``."""
    z = np.ascontiguousarray(z, dtype=complex)
    n = z.shape[0]
    m = path.K.shape[1] if path.kind == DENSE else n
    rows, width = {PLANAR_3RPR: (3, RPR_WIDTH), HEXAPOD_66: (6, HEX_WIDTH)}.get(path.kind, (0, 0))
    H, Ht, J = np.empty(m, complex), np.empty(m, complex), np.empty((m, n), complex)
    _evaluate(path.kind, path.K, path.P, np.empty((rows, width), complex), np.zeros(3), z, complex(tau),
              complex(dtau), np.empty(n + 1, complex), H, J, Ht, True, True, True)
    return H, J, Ht


def random_gammas(rng, m):
    return np.exp(2j * math.pi * rng.uniform(size=m))


def distinct(points, tol=SAME_ENDPOINT) -> list:
    """Indices of the first of every group of points within ``tol`` (share of 1 + |z|) of each other."""
    keep = []
    for k, z in enumerate(points):
        if all(np.max(np.abs(z - points[j])) > tol * (1.0 + np.max(np.abs(z))) for j in keep):
            keep.append(k)
    return keep
