"""The compiled path tracker of the parameter homotopy (:mod:`.homotopy`).

Every start solution of a family's start system is followed from the start member ``p_0`` to the target
``p_1`` along ``p(t) = (1 - tau) p_0 + tau p_1``, ``tau = t / (t + gamma (1 - t))``, ``t`` from 0 to 1, with a
random unit complex ``gamma`` (the gamma trick; Sommese & Wampler, *The Numerical Solution of Systems of
Polynomials Arising in Engineering and Science*, World Scientific 2005, ch. 2.2 and 7).  The tracker is an
adaptive predictor-corrector: classical Runge-Kutta of order 4 on ``dz/dt = -F_z^{-1} F_t``, Newton corrector,
the step halved on a failed correction; after a success the next step is chosen from the size of the first
corrector update (the predictor's error, of order h^5), aiming at ``STEP_TARGET``.  Every path is tracked in
one compiled call (:func:`track_paths`; complex LU with partial pivoting); at ``t = 1`` Newton's method
polishes the endpoint.  The system's coefficients along the path are a quadratic polynomial in ``tau``
(``K``, :meth:`.homotopy_families.Family.coefficient_path`).  Each path ends with an outcome
(:data:`OUTCOMES`): regular, at infinity, a failed step, out of steps, or singular.  No ROS import.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

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

#: two endpoints closer than this share of 1 + |z| are one (polished regular endpoints are accurate to
#: about round-off / rcond, i.e. 1e-6 at the worst regular conditioning)
SAME_ENDPOINT = 1e-6


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
