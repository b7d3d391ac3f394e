"""Levenberg-Marquardt in pose space, compiled: the estimator's warm path and every local refinement.

Method.  Marquardt's damped Gauss-Newton step (Marquardt 1963; More 1978) on the leg residuals
``r_i(pose) = |B_i(pose) - A_i| - l_i``::

    (J^T J + lam diag(J^T J)) s = -J^T r

solved by a Cholesky factorisation.  A step is taken when it lowers ``sum r_i^2``; the damping then
shrinks by the gain ratio (actual / predicted decrease ``rho``: ``lam *= max(1/3, 1 - (2 rho - 1)^3)``),
and after a refused step it grows by ``nu``, which doubles on every further refusal (Nielsen 1999;
Madsen, Nielsen & Tingleff 2004, section 3.2).  The damping is scaled by
``diag(J^T J)`` (Marquardt's choice), so ``lam`` is dimensionless and the iterates do not depend on the
unit of length nor on the units of the pose parameters.  The step lives in each model's pose
parameterisation, where the platform is rigid by construction and the Jacobian is analytic:

* 3-RPR: ``(x, y, theta)``, the solver variables themselves; ``J_i = (u_i, (R CB_i) x u_i)`` (planar
  cross product) with the unit leg vector ``u_i`` (Chandra & Rolland 2014, Eq. 6-7);
* hexapod: position ``p`` of the platform origin and rotation ``R``, updated multiplicatively,
  ``R <- exp([w]x) R`` (Rodrigues' formula), ``p <- p + dp``; ``J_i = (u_i, (R CB_i) x u_i)``.  The
  nine solver variables of the papers' model (Rolland & Chandra 2016, section 2) are read in by the
  least-squares rigid fit of CB_1..CB_3 onto them (Kabsch 1976) and written out as ``B_k = p + R CB_k``.

Convergence is judged on the leg residuals, relative to the geometry::

    max_i |r_i| <= rtol * L,    L = max(scale, max_i l_i)

(``scale``: the model's characteristic length; the legs enter ``L`` because a computed leg length is
exact only to a few units in the last place *of the leg*), and optionally ``sum r_i^2 < ftol`` too (the
papers' absolute fitness threshold, for their protocols).  Once converged, ``POLISH_STEPS`` more
Gauss-Newton steps take the residuals to round-off.  Why the legs and a relative threshold: the leg
residuals are what a user checks, they are available in every model (the hexapod's nine-variable fitness
adds rigidity terms ``d^2`` whose round-off, about ``2 d`` times one unit in the last place, is far above
``1e-20 mm^2``, so that absolute threshold was reached only by a random search on the floating-point grid),
and a relative threshold gives the same digits whether the configuration is written in mm, cm or m
(an absolute fitness of ``1e-20`` is round-off in mm but ``1e-10 m`` of leg error in m).  The papers'
fitness of the returned variables is still computed and reported.

Without convergence the iteration stops after ``MAX_REJECTIONS`` consecutive steps that do not lower the
sum of squares (a stationary point, with a residual when the legs have no real assembly there), when
asked to (``S_STALL``) once the sum fell by less than a given fraction over ``PROGRESS_WINDOW``
iterations, or after ``max_iter`` iterations; no clock is read inside, the iteration cap bounds the
call.  :func:`multistart_kernel` runs the same iteration from several starts until one converges.

One call (:func:`lm_kernel`, ``nogil``) also returns the figures the estimator decides with: the
reciprocal condition number of the column-scaled leg Jacobian (one-sided Jacobi SVD, Hestenes 1958),
the stationarity ``|J^T r| / (|J| |r|)``, the distance to a reference pose in platform-joint terms and
how far the legs moved from reference legs.  Evaluation counting: each residual-and-Jacobian
evaluation counts one, including the final one at the returned variables (which also gives the papers'
fitness).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..models.kernels import KIND_PLANAR_3RPR, residuals_into

#: convergence: largest leg residual relative to the reference length L (about 450 units in the last
#: place of L; a converged pose is then polished to round-off by the next step)
LEG_RTOL = 1e-13
#: Gauss-Newton steps taken after convergence (one takes a quadratically converging iterate to round-off)
POLISH_STEPS = 1
#: initial (dimensionless, Marquardt-scaled) damping: the first step is nearly Gauss-Newton
LAMBDA_INIT = 1e-6
#: smallest damping kept (below it the step is Gauss-Newton to round-off anyway)
LAMBDA_MIN = 1e-15
#: consecutive rejected steps after which the iterate is at a stationary point (or at round-off);
#: the damping has then grown by 2^(1 + 2 + ... + 10) ~ 4e16
MAX_REJECTIONS = 10
#: iterations over which the progress figure (``I_PROGRESS``) is measured
PROGRESS_WINDOW = 10
#: default iteration cap of one local solve
MAX_ITER = 100
#: rotation angle below which Rodrigues' formula uses its second-order Taylor expansion
SMALL_ANGLE = 1e-8
#: sweeps of the one-sided Jacobi SVD (it converges quadratically: 6x6 needs 5-7)
JACOBI_SWEEPS = 30
#: two columns count as orthogonal when |a.b| <= JACOBI_TOL |a| |b| (a few units in the last place)
JACOBI_TOL = 4e-16

# layout of the ``info`` vector filled by ``lm_kernel``
I_LEG_FITNESS = 0     # sum of squared leg residuals at the returned variables
I_MAX_RESIDUAL = 1    # max |r_i| at the returned variables (config unit)
I_FITNESS = 2         # the papers' fitness (the model's residual vector) of the returned variables
I_CONDITIONING = 3    # reciprocal condition number of the column-scaled leg Jacobian (0 = singular)
I_STATIONARITY = 4    # |J^T r| / (|J| |r|) with J column-scaled (inf when undefined, e.g. r = 0)
I_DISTANCE = 5        # largest platform-joint distance between the returned variables and x_ref
I_MOVEMENT = 6        # max |legs - legs_ref| (0 when legs_ref is empty)
I_NFEV = 7            # residual-and-Jacobian evaluations
I_NIT = 8             # iterations
I_CONVERGED = 9       # 1.0 when converged (see the module docstring)
I_INPUT_OK = 10       # 0.0 when the legs are not finite, not positive or outside [lo, hi] (nothing solved)
I_PROGRESS = 11       # relative decrease of the leg fitness over the last PROGRESS_WINDOW to 2 PROGRESS_WINDOW
#                       iterations (1.0 when fewer were run; 0.0 when the iteration stopped because no step
#                       lowered it)
N_INFO = 12

# layout of the ``settings`` vector of ``lm_kernel``
S_SCALE = 0           # the model's characteristic length
S_LO = 1              # leg limits (-inf, inf: none)
S_HI = 2
S_RTOL = 3            # relative leg tolerance
S_FTOL = 4            # leg-fitness threshold (inf: none)
S_MAX_ITER = 5        # iteration cap
S_STALL = 6           # stop when the leg fitness fell by less than this fraction over PROGRESS_WINDOW
#                       iterations (0: never)
S_N_RES = 7           # length of the model's residual vector
S_COL_SCALE = 8       # then the model's pose_column_scale (n_pose values)

#: length of a state vector: hexapod p (3) + R (9, row-major); 3-RPR uses its first 3 entries
STATE_SIZE = 12


def workspace_size(n_legs: int, n_pose: int, n_res: int) -> int:
    """Length of the float64 work buffer :func:`lm_kernel` needs."""
    return 2 * (n_legs + n_legs * n_pose) + 3 * n_pose * n_pose + 2 * n_pose + 2 * STATE_SIZE \
        + n_legs * n_pose + n_pose + n_res


# -- the two models' residuals, Jacobians and retractions -------------------------------------------
@njit(cache=True, error_model="numpy")
def _rpr_residuals_jacobian(state, base, platform, legs, r, J):
    c = math.cos(state[2])
    s = math.sin(state[2])
    for i in range(3):
        rx = c * platform[i, 0] - s * platform[i, 1]        # R(theta) CB_i
        ry = s * platform[i, 0] + c * platform[i, 1]
        ex = state[0] + rx - base[i, 0]
        ey = state[1] + ry - base[i, 1]
        n = math.sqrt(ex * ex + ey * ey)
        ux = ex / n
        uy = ey / n
        J[i, 0] = ux
        J[i, 1] = uy
        J[i, 2] = uy * rx - ux * ry                         # d/dtheta of R CB_i is (-ry, rx)
        r[i] = n - legs[i]


@njit(cache=True, error_model="numpy")
def _hex_residuals_jacobian(state, base, platform, legs, r, J):
    for j in range(6):
        cx, cy, cz = platform[j, 0], platform[j, 1], platform[j, 2]
        wx = state[3] * cx + state[4] * cy + state[5] * cz   # w = R CB_j
        wy = state[6] * cx + state[7] * cy + state[8] * cz
        wz = state[9] * cx + state[10] * cy + state[11] * cz
        ex = state[0] + wx - base[j, 0]
        ey = state[1] + wy - base[j, 1]
        ez = state[2] + wz - base[j, 2]
        n = math.sqrt(ex * ex + ey * ey + ez * ez)
        ux = ex / n
        uy = ey / n
        uz = ez / n
        J[j, 0] = ux
        J[j, 1] = uy
        J[j, 2] = uz
        J[j, 3] = wy * uz - wz * uy                          # w x u
        J[j, 4] = wz * ux - wx * uz
        J[j, 5] = wx * uy - wy * ux
        r[j] = n - legs[j]


@njit(cache=True, error_model="numpy")
def _residuals_jacobian(kind, state, base, platform, legs, r, J):
    """Leg residuals and Jacobian at ``state``; returns the sum of squares (inf when not finite)."""
    if kind == KIND_PLANAR_3RPR:
        _rpr_residuals_jacobian(state, base, platform, legs, r, J)
    else:
        _hex_residuals_jacobian(state, base, platform, legs, r, J)
    f = 0.0
    for i in range(r.shape[0]):
        f += r[i] * r[i]
    return f if math.isfinite(f) else math.inf


@njit(cache=True, error_model="numpy")
def rotation_from_vector_into(wx, wy, wz, M):
    """Rodrigues' formula: ``M`` (3x3) = exp([w]x) = I + a K + b K^2, K^2 = w w^T - |w|^2 I."""
    t2 = wx * wx + wy * wy + wz * wz
    theta = math.sqrt(t2)
    if theta < SMALL_ANGLE:
        a = 1.0
        b = 0.5
    else:
        a = math.sin(theta) / theta
        b = (1.0 - math.cos(theta)) / t2
    M[0, 0] = 1.0 + b * (wx * wx - t2)
    M[1, 1] = 1.0 + b * (wy * wy - t2)
    M[2, 2] = 1.0 + b * (wz * wz - t2)
    M[0, 1] = -a * wz + b * wx * wy
    M[1, 0] = a * wz + b * wx * wy
    M[0, 2] = a * wy + b * wx * wz
    M[2, 0] = -a * wy + b * wx * wz
    M[1, 2] = -a * wx + b * wy * wz
    M[2, 1] = a * wx + b * wy * wz


@njit(cache=True, error_model="numpy")
def _retract(kind, state, step, trial, M):
    """``trial`` = the state moved by ``step`` (3-RPR: added; hexapod: p + dp, exp([w]x) R)."""
    if kind == KIND_PLANAR_3RPR:
        for k in range(3):
            trial[k] = state[k] + step[k]
        return
    for k in range(3):
        trial[k] = state[k] + step[k]
    rotation_from_vector_into(step[3], step[4], step[5], M)
    for i in range(3):
        for j in range(3):
            trial[3 + 3 * i + j] = (M[i, 0] * state[3 + j] + M[i, 1] * state[6 + j]
                                    + M[i, 2] * state[9 + j])


# -- rotations ------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def quaternion_from_rows(R, q):
    """Unit quaternion ``q = [qx, qy, qz, qw]`` (qw >= 0) of the row-major rotation ``R`` (9 values);
    the same branches as ``models.hexapod_66.quaternion_from_matrix``."""
    t = R[0] + R[4] + R[8]
    if t > 0.0:
        s = 2.0 * math.sqrt(1.0 + t)
        q[0] = (R[7] - R[5]) / s
        q[1] = (R[2] - R[6]) / s
        q[2] = (R[3] - R[1]) / s
        q[3] = 0.25 * s
    else:
        i = 0
        if R[4] > R[0]:
            i = 1
        if R[8] > R[4 * i]:
            i = 2
        j = (i + 1) % 3
        k = (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + R[4 * i] - R[4 * j] - R[4 * k], 0.0))
        q[i] = 0.25 * s
        q[j] = (R[3 * j + i] + R[3 * i + j]) / s
        q[k] = (R[3 * k + i] + R[3 * i + k]) / s
        q[3] = (R[3 * k + j] - R[3 * j + k]) / s
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    sign = -1.0 if q[3] < 0.0 else 1.0
    for m in range(4):
        q[m] = sign * q[m] / norm


@njit(cache=True, error_model="numpy")
def rows_from_quaternion(q, R):
    """Row-major rotation matrix (9 values) of the unit quaternion ``q = [qx, qy, qz, qw]``."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    R[0] = 1.0 - 2.0 * (y * y + z * z)
    R[1] = 2.0 * (x * y - z * w)
    R[2] = 2.0 * (x * z + y * w)
    R[3] = 2.0 * (x * y + z * w)
    R[4] = 1.0 - 2.0 * (x * x + z * z)
    R[5] = 2.0 * (y * z - x * w)
    R[6] = 2.0 * (x * z - y * w)
    R[7] = 2.0 * (y * z + x * w)
    R[8] = 1.0 - 2.0 * (x * x + y * y)


# -- small dense linear algebra (no LAPACK: numba's would need SciPy) -------------------------------
@njit(cache=True, error_model="numpy")
def _damped_solve(A, lam, g, step, L):
    """Solve ``(A + lam diag(A)) step = -g`` by Cholesky; False when not positive definite."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            if i == j:
                s += lam * max(A[i, i], 1e-300)
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                if not s > 0.0 or not math.isfinite(s):
                    return False
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    for i in range(n):                       # L y = -g
        s = -g[i]
        for k in range(i):
            s -= L[i, k] * step[k]
        step[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):           # L^T step = y
        s = step[i]
        for k in range(i + 1, n):
            s -= L[k, i] * step[k]
        step[i] = s / L[i, i]
    return True


@njit(cache=True, error_model="numpy")
def jacobi_svd(A, V, s):
    """One-sided Jacobi SVD (Hestenes 1958) of ``A`` (m x n, m >= n), in place: on return
    ``A = U diag(s)`` (columns) and ``A_in V = U diag(s)``; singular values unsorted.  The squared
    column norms are carried through each rotation (``alpha - t gamma``, ``beta + t gamma``) and
    recomputed at every sweep, so a pair costs one dot product."""
    m, n = A.shape
    for i in range(n):
        for j in range(n):
            V[i, j] = 1.0 if i == j else 0.0
    for _ in range(JACOBI_SWEEPS):
        for j in range(n):
            acc = 0.0
            for k in range(m):
                acc += A[k, j] * A[k, j]
            s[j] = acc
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                alpha = s[p]
                beta = s[q]
                gamma = 0.0
                for k in range(m):
                    gamma += A[k, p] * A[k, q]
                if not abs(gamma) > JACOBI_TOL * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + math.hypot(1.0, zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                sn = c * t
                for k in range(m):
                    ap = A[k, p]
                    A[k, p] = c * ap - sn * A[k, q]
                    A[k, q] = sn * ap + c * A[k, q]
                for k in range(n):
                    vp = V[k, p]
                    V[k, p] = c * vp - sn * V[k, q]
                    V[k, q] = sn * vp + c * V[k, q]
                s[p] = max(alpha - t * gamma, 0.0)
                s[q] = max(beta + t * gamma, 0.0)
        if not rotated:
            break
    for j in range(n):
        acc = 0.0
        for k in range(m):
            acc += A[k, j] * A[k, j]
        s[j] = math.sqrt(acc)


@njit(cache=True, error_model="numpy")
def _kabsch_state(platform, x, state, H, V, s):
    """``state`` = (p, R) of the rigid motion that best maps CB_1..CB_3 onto the solver variables
    B_1..B_3 (Kabsch 1976): H = sum (CB_k - cs)(B_k - cd)^T = U S V^T, R = V diag(1, 1, d) U^T.
    Three points span a plane, so the third singular pair is replaced by the cross products of the
    first two (which makes det R = +1, Kabsch's d).  False when B_1..B_3 are collinear."""
    cs0 = (platform[0, 0] + platform[1, 0] + platform[2, 0]) / 3.0
    cs1 = (platform[0, 1] + platform[1, 1] + platform[2, 1]) / 3.0
    cs2 = (platform[0, 2] + platform[1, 2] + platform[2, 2]) / 3.0
    cd0 = (x[0] + x[3] + x[6]) / 3.0
    cd1 = (x[1] + x[4] + x[7]) / 3.0
    cd2 = (x[2] + x[5] + x[8]) / 3.0
    for a in range(3):
        for b in range(3):
            H[a, b] = 0.0
    for k in range(3):
        sa = (platform[k, 0] - cs0, platform[k, 1] - cs1, platform[k, 2] - cs2)
        db = (x[3 * k] - cd0, x[3 * k + 1] - cd1, x[3 * k + 2] - cd2)
        for a in range(3):
            for b in range(3):
                H[a, b] += sa[a] * db[b]
    jacobi_svd(H, V, s)                      # H_in V = U S
    i1 = 0
    for j in range(1, 3):
        if s[j] > s[i1]:
            i1 = j
    i2 = -1
    for j in range(3):
        if j != i1 and (i2 < 0 or s[j] > s[i2]):
            i2 = j
    if not s[i2] > 0.0 or not math.isfinite(s[i1]):
        return False
    u1 = (H[0, i1] / s[i1], H[1, i1] / s[i1], H[2, i1] / s[i1])
    u2 = (H[0, i2] / s[i2], H[1, i2] / s[i2], H[2, i2] / s[i2])
    v1 = (V[0, i1], V[1, i1], V[2, i1])
    v2 = (V[0, i2], V[1, i2], V[2, i2])
    u3 = (u1[1] * u2[2] - u1[2] * u2[1], u1[2] * u2[0] - u1[0] * u2[2], u1[0] * u2[1] - u1[1] * u2[0])
    v3 = (v1[1] * v2[2] - v1[2] * v2[1], v1[2] * v2[0] - v1[0] * v2[2], v1[0] * v2[1] - v1[1] * v2[0])
    for a in range(3):
        for b in range(3):
            state[3 + 3 * a + b] = v1[a] * u1[b] + v2[a] * u2[b] + v3[a] * u3[b]
    cs = (cs0, cs1, cs2)
    cd = (cd0, cd1, cd2)
    for a in range(3):
        state[a] = cd[a] - (state[3 + 3 * a] * cs[0] + state[4 + 3 * a] * cs[1] + state[5 + 3 * a] * cs[2])
    return True


@njit(cache=True, error_model="numpy")
def _joint_distance(kind, platform, x1, x2):
    """Largest distance between corresponding platform joints (3-RPR: all three; hexapod: B_1..B_3,
    the variables), like ``Manipulator.distance``."""
    d = 0.0
    if kind == KIND_PLANAR_3RPR:
        c1, s1 = math.cos(x1[2]), math.sin(x1[2])
        c2, s2 = math.cos(x2[2]), math.sin(x2[2])
        for i in range(3):
            px, py = platform[i, 0], platform[i, 1]
            dx = (x1[0] + c1 * px - s1 * py) - (x2[0] + c2 * px - s2 * py)
            dy = (x1[1] + s1 * px + c1 * py) - (x2[1] + s2 * px + c2 * py)
            d = max(d, math.sqrt(dx * dx + dy * dy))
        return d
    for k in range(3):
        dx = x1[3 * k] - x2[3 * k]
        dy = x1[3 * k + 1] - x2[3 * k + 1]
        dz = x1[3 * k + 2] - x2[3 * k + 2]
        d = max(d, math.sqrt(dx * dx + dy * dy + dz * dz))
    return d


@njit(cache=True, error_model="numpy")
def _normal_equations(J, r, A, g):
    n_legs, n = J.shape
    for i in range(n):
        acc = 0.0
        for k in range(n_legs):
            acc += J[k, i] * r[k]
        g[i] = acc
        for j in range(i + 1):
            acc = 0.0
            for k in range(n_legs):
                acc += J[k, i] * J[k, j]
            A[i, j] = acc
            A[j, i] = acc


# -- the kernel -------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _reference_length(legs, settings):
    """``max(scale, max leg)``, or -1.0 when a leg is not finite, not positive or outside the limits."""
    ref = settings[S_SCALE]
    lo, hi = settings[S_LO], settings[S_HI]
    for i in range(legs.shape[0]):
        li = legs[i]
        if not (math.isfinite(li) and li > 0.0 and li >= lo and li <= hi):
            return -1.0
        ref = max(ref, li)
    return ref


@njit(cache=True, error_model="numpy", nogil=True)
def lm_kernel(kind, data, platform, legs, x0, x_ref, legs_ref, settings, out, work):
    """Levenberg-Marquardt from solver variables ``x0`` for leg lengths ``legs``.

    ``kind``/``data``: the model's ``kind_id`` and data tuple (:mod:`glpma_ros.models.kernels`);
    ``platform``: its platform joints; ``settings``: see :func:`make_settings`; ``x_ref``: the
    variables the distance is measured from; ``legs_ref``: the legs the movement is measured from
    (empty: none).  Fills ``out`` = [solver variables (n_vars), position (3), quaternion [qx, qy, qz,
    qw], info (``N_INFO``, layout: the ``I_*`` constants)]; ``work``: :func:`workspace_size` floats.
    Nothing is allocated."""
    ref = _reference_length(legs, settings)
    if ref < 0.0:
        out[:] = 0.0                          # I_INPUT_OK = 0: nothing solved
        return
    _solve_one(kind, data, platform, legs, ref, x0, x_ref, settings, out, work)
    if legs_ref.shape[0] == legs.shape[0]:
        mv = 0.0
        for i in range(legs.shape[0]):
            mv = max(mv, abs(legs[i] - legs_ref[i]))
        out[x0.shape[0] + 7 + I_MOVEMENT] = mv


@njit(cache=True, error_model="numpy", nogil=True)
def multistart_kernel(kind, data, platform, legs, starts, x_ref, settings, out, work):
    """Levenberg-Marquardt from each row of ``starts`` in turn until one converges.

    Fills ``out`` (as :func:`lm_kernel`) with the first converged solve, or with the one of least leg
    fitness; its ``I_NFEV`` / ``I_NIT`` count every start tried.  ``work``: :func:`workspace_size`
    plus ``len(out)`` floats.  Returns the index of the start reported (-1 when the legs fail the
    check)."""
    ref = _reference_length(legs, settings)
    out[:] = 0.0
    if ref < 0.0:
        return -1
    n_out = out.shape[0]
    base_info = n_out - N_INFO
    trial_out = work[work.shape[0] - n_out:]
    core = work[:work.shape[0] - n_out]
    best = -1
    nfev = 0.0
    nit = 0.0
    for k in range(starts.shape[0]):
        _solve_one(kind, data, platform, legs, ref, starts[k], x_ref, settings, trial_out, core)
        nfev += trial_out[base_info + I_NFEV]
        nit += trial_out[base_info + I_NIT]
        converged = trial_out[base_info + I_CONVERGED] == 1.0
        if best < 0 or converged or trial_out[base_info + I_LEG_FITNESS] < out[base_info + I_LEG_FITNESS]:
            out[:] = trial_out
            best = k
        if converged:
            break
    out[base_info + I_NFEV] = nfev
    out[base_info + I_NIT] = nit
    return best


@njit(cache=True, error_model="numpy")
def _solve_one(kind, data, platform, legs, ref, x0, x_ref, settings, out, work):
    """The iteration of :func:`lm_kernel` for legs that passed the check (``ref``: reference length)."""
    n_legs = legs.shape[0]
    n_vars = x0.shape[0]
    n_pose = settings.shape[0] - S_COL_SCALE
    col_scale = settings[S_COL_SCALE:]
    rtol, ftol, max_iter = settings[S_RTOL], settings[S_FTOL], int(settings[S_MAX_ITER])
    stall = settings[S_STALL]
    x_out = out[:n_vars]
    pose_out = out[n_vars:n_vars + 7]
    info = out[n_vars + 7:]
    for k in range(N_INFO):
        info[k] = 0.0
    info[I_INPUT_OK] = 1.0
    # carve the work buffer
    o = 0
    r = work[o:o + n_legs]
    o += n_legs
    J = work[o:o + n_legs * n_pose].reshape((n_legs, n_pose))
    o += n_legs * n_pose
    r2 = work[o:o + n_legs]
    o += n_legs
    J2 = work[o:o + n_legs * n_pose].reshape((n_legs, n_pose))
    o += n_legs * n_pose
    A = work[o:o + n_pose * n_pose].reshape((n_pose, n_pose))
    o += n_pose * n_pose
    L = work[o:o + n_pose * n_pose].reshape((n_pose, n_pose))
    o += n_pose * n_pose
    V = work[o:o + n_pose * n_pose].reshape((n_pose, n_pose))
    o += n_pose * n_pose
    g = work[o:o + n_pose]
    o += n_pose
    step = work[o:o + n_pose]
    o += n_pose
    state = work[o:o + STATE_SIZE]
    o += STATE_SIZE
    trial = work[o:o + STATE_SIZE]
    o += STATE_SIZE
    Js = work[o:o + n_legs * n_pose].reshape((n_legs, n_pose))
    o += n_legs * n_pose
    sv = work[o:o + n_pose]
    o += n_pose
    rm = work[o:o + int(settings[S_N_RES])]  # the model's residual vector
    base = data[0]
    M = L[:3, :3]                            # scratch for the rotation of a step (L is free then)

    # start state
    if kind == KIND_PLANAR_3RPR:
        for k in range(3):
            state[k] = x0[k]
        ok = True
    else:
        ok = _kabsch_state(platform, x0, state, L[:3, :3], V[:3, :3], sv[:3])
    nfev = 0
    nit = 0
    progress = 1.0
    if ok and max_iter > 0:
        f = _residuals_jacobian(kind, state, base, platform, legs, r, J)
        nfev += 1
        if f < math.inf:
            _normal_equations(J, r, A, g)
            lam = LAMBDA_INIT
            nu = 2.0
            rejections = 0
            rmax = 0.0
            for i in range(n_legs):
                rmax = max(rmax, abs(r[i]))
            done = rmax <= rtol * ref and f < ftol
            polish_left = POLISH_STEPS
            f_mark = f                       # the fitness PROGRESS_WINDOW and 2 PROGRESS_WINDOW iterations ago
            f_mark_before = math.inf
            while nit < max_iter:
                if done:
                    if polish_left == 0 or f == 0.0:
                        break
                    polish_left -= 1
                nit += 1
                f2 = math.inf
                if _damped_solve(A, lam, g, step, L):
                    _retract(kind, state, step, trial, M)
                    f2 = _residuals_jacobian(kind, trial, base, platform, legs, r2, J2)
                    nfev += 1
                if f2 < f:
                    # gain ratio against the decrease the linear model predicts (Nielsen 1999)
                    predicted = 0.0
                    for k in range(n_pose):
                        predicted += step[k] * (lam * max(A[k, k], 1e-300) * step[k] - g[k])
                    rho = (f - f2) / predicted if predicted > 0.0 else 1.0
                    lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), LAMBDA_MIN)
                    nu = 2.0
                    rejections = 0
                    for k in range(STATE_SIZE):
                        state[k] = trial[k]
                    for i in range(n_legs):
                        r[i] = r2[i]
                        for k in range(n_pose):
                            J[i, k] = J2[i, k]
                    f = f2
                    _normal_equations(J, r, A, g)
                    if not done:
                        rmax = 0.0
                        for i in range(n_legs):
                            rmax = max(rmax, abs(r[i]))
                        done = rmax <= rtol * ref and f < ftol
                else:
                    lam *= nu
                    nu *= 2.0
                    rejections += 1
                    if rejections > MAX_REJECTIONS or done:
                        break
                if nit % PROGRESS_WINDOW == 0:
                    f_mark_before = f_mark
                    f_mark = f
                    if not done and f_mark_before < math.inf and f_mark_before - f < stall * f_mark_before:
                        break                    # stalled (S_STALL > 0 only)
            if rejections > MAX_REJECTIONS and not done:
                progress = 0.0                   # no step lowers the fitness: a stationary point
            elif f_mark_before < math.inf and f_mark_before > 0.0:
                progress = (f_mark_before - f) / f_mark_before

    # the returned variables: 3-RPR theta wrapped to (-pi, pi]; hexapod R re-orthonormalised
    if not ok:
        for k in range(n_vars):
            x_out[k] = x0[k]
        info[I_LEG_FITNESS] = math.inf
        info[I_MAX_RESIDUAL] = math.inf
        info[I_FITNESS] = math.inf
        info[I_STATIONARITY] = math.inf
        info[I_PROGRESS] = 1.0
        info[I_DISTANCE] = _joint_distance(kind, platform, x_out, x_ref)
        return
    if kind == KIND_PLANAR_3RPR:
        t = np.fmod(state[2], 2.0 * math.pi)     # exact; with one exact correction = math.remainder
        if t > math.pi:
            t -= 2.0 * math.pi
        elif t <= -math.pi:
            t += 2.0 * math.pi
        state[2] = t
        x_out[0] = state[0]
        x_out[1] = state[1]
        x_out[2] = t
        pose_out[0] = state[0]
        pose_out[1] = state[1]
        pose_out[2] = 0.0
        pose_out[3] = 0.0
        pose_out[4] = 0.0
        pose_out[5] = math.sin(0.5 * t)
        pose_out[6] = math.cos(0.5 * t)
    else:
        q = pose_out[3:7]
        quaternion_from_rows(state[3:12], q)
        rows_from_quaternion(q, state[3:12])
        for k in range(3):
            cx, cy, cz = platform[k, 0], platform[k, 1], platform[k, 2]
            for a in range(3):
                x_out[3 * k + a] = state[a] + (state[3 + 3 * a] * cx + state[4 + 3 * a] * cy
                                               + state[5 + 3 * a] * cz)
        for a in range(3):
            pose_out[a] = state[a]

    # the figures at the returned variables
    f = _residuals_jacobian(kind, state, base, platform, legs, r, J)
    nfev += 1
    rmax = 0.0
    for i in range(n_legs):
        rmax = max(rmax, abs(r[i]))
    info[I_LEG_FITNESS] = f
    info[I_MAX_RESIDUAL] = rmax if math.isfinite(rmax) else math.inf
    residuals_into(x_out, kind, data, legs, rm)
    fm = 0.0
    for k in range(rm.shape[0]):
        fm += rm[k] * rm[k]
    info[I_FITNESS] = fm if math.isfinite(fm) else math.inf
    jn = 0.0
    gn = 0.0
    for i in range(n_legs):
        for k in range(n_pose):
            Js[i, k] = J[i, k] * col_scale[k]
            jn += Js[i, k] * Js[i, k]
    for k in range(n_pose):
        acc = 0.0
        for i in range(n_legs):
            acc += Js[i, k] * r[i]
        gn += acc * acc
    den = math.sqrt(jn) * math.sqrt(f)
    info[I_STATIONARITY] = math.sqrt(gn) / den if (den > 0.0 and math.isfinite(den)) else math.inf
    if math.isfinite(jn):
        jacobi_svd(Js, V, sv)
        smax = 0.0
        smin = math.inf
        for k in range(n_pose):
            smax = max(smax, sv[k])
            smin = min(smin, sv[k])
        info[I_CONDITIONING] = smin / smax if smax > 0.0 else 0.0
    info[I_DISTANCE] = _joint_distance(kind, platform, x_out, x_ref)
    info[I_NFEV] = nfev
    info[I_NIT] = nit
    info[I_PROGRESS] = progress
    info[I_CONVERGED] = 1.0 if (rmax <= rtol * ref and f < ftol) else 0.0


# -- Python side ---------------------------------------------------------------------------------------
def make_settings(model, *, max_iter=None, rtol=None, ftol=math.inf) -> np.ndarray:
    """The ``settings`` vector of :func:`lm_kernel` for ``model`` (its scale, leg limits and column
    scale; ``rtol`` default ``LEG_RTOL``, ``max_iter`` default ``MAX_ITER``)."""
    limits = model.leg_limits
    lo, hi = (-math.inf, math.inf) if limits is None else (float(limits[0]), float(limits[1]))
    head = [model.scale, lo, hi, LEG_RTOL if rtol is None else rtol, ftol,
            MAX_ITER if max_iter is None else max_iter, 0.0, model.n_res]
    return np.ascontiguousarray(np.concatenate((head, model.pose_column_scale)), dtype=float)


class LocalResult(NamedTuple):
    """Outcome of one local solve (config unit)."""

    x: np.ndarray             # solver variables
    position: np.ndarray      # platform origin
    orientation: np.ndarray   # unit quaternion [qx, qy, qz, qw]
    converged: bool
    max_residual: float       # max |r_i| over the legs
    leg_fitness: float        # sum of squared leg residuals
    fitness: float            # the papers' fitness of x (the model's residual vector)
    conditioning: float       # reciprocal condition number of the leg Jacobian (0 = singular)
    stationarity: float       # |J^T r| / (|J| |r|), small at a stationary point
    progress: float           # relative decrease of the leg fitness over the last 10-20 iterations
    distance: float           # platform-joint distance from x_ref (default: the start)
    movement: float           # max |legs - legs_ref| (0 without legs_ref)
    nfev: int
    nit: int


_NO_LEGS = np.zeros(0)


class LocalSolver:
    """The compiled local solve of one model with its own buffers (one per thread).

    :meth:`run` is the raw call (fills and returns a fresh ``out`` vector, see :func:`lm_kernel`);
    :meth:`solve` wraps it in a :class:`LocalResult`; :meth:`multistart` tries several starts."""

    def __init__(self, model):
        self.model = model
        self.kind = int(model.kind_id)
        self.data = model.data
        self.platform = np.ascontiguousarray(model.platform, dtype=float)
        self.n_vars = int(model.n_vars)
        self.n_out = self.n_vars + 7 + N_INFO
        self.info_at = self.n_vars + 7
        self.work = np.zeros(workspace_size(model.n_legs, model.n_pose, model.n_res) + self.n_out)
        self.settings = make_settings(model)
        self._limits = model.leg_limits

    def prepare(self):
        """Load (or compile) both kernels for this model's types, with a call that does no iteration."""
        x0 = np.zeros((1, self.n_vars))
        legs = np.ones(self.model.n_legs)
        settings = make_settings(self.model, max_iter=0)
        settings[S_LO], settings[S_HI] = 0.0, math.inf
        out = np.empty(self.n_out)
        lm_kernel(self.kind, self.data, self.platform, legs, x0[0], x0[0], _NO_LEGS, settings, out, self.work)
        multistart_kernel(self.kind, self.data, self.platform, legs, x0, x0[0], settings, out, self.work)

    def _settings(self, max_iter, rtol, ftol, stall):
        settings = self.settings
        if self.model.leg_limits is not self._limits:          # the model's limits were changed
            self.settings = settings = make_settings(self.model)
            self._limits = self.model.leg_limits
        settings[S_RTOL] = rtol
        settings[S_FTOL] = ftol
        settings[S_MAX_ITER] = max_iter
        settings[S_STALL] = stall
        return settings

    def run(self, x0, legs, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf, x_ref=None, legs_ref=_NO_LEGS,
            stall=0.0):
        """``x0``, ``legs``: contiguous float64 arrays of the model's sizes.  Returns ``out``."""
        settings = self._settings(max_iter, rtol, ftol, stall)
        out = np.empty(self.n_out)
        lm_kernel(self.kind, self.data, self.platform, legs, x0, x0 if x_ref is None else x_ref, legs_ref,
                  settings, out, self.work)
        return out

    def solve(self, x0, legs, *, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf, x_ref=None,
              legs_ref=_NO_LEGS, stall=0.0) -> LocalResult | None:
        """:class:`LocalResult`, or None when the legs fail the check (not finite, not positive,
        outside the model's leg limits)."""
        return self.result(self.run(x0, legs, max_iter, rtol, ftol, x_ref, legs_ref, stall))

    def multistart(self, starts, legs, *, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf, x_ref=None,
                   stall=0.0) -> LocalResult | None:
        """The first converged solve from the rows of ``starts`` (contiguous, float64), else the one of
        least leg fitness; ``nfev`` / ``nit`` count every start tried.  ``x_ref`` default: the first
        start."""
        settings = self._settings(max_iter, rtol, ftol, stall)
        out = np.empty(self.n_out)
        multistart_kernel(self.kind, self.data, self.platform, legs, starts,
                          starts[0] if x_ref is None else x_ref, settings, out, self.work)
        return self.result(out)

    def result(self, out) -> LocalResult | None:
        n, info = self.n_vars, out[self.info_at:]
        if info[I_INPUT_OK] == 0.0:
            return None
        return LocalResult(out[:n], out[n:n + 3], out[n + 3:n + 7], info[I_CONVERGED] == 1.0,
                           float(info[I_MAX_RESIDUAL]), float(info[I_LEG_FITNESS]), float(info[I_FITNESS]),
                           float(info[I_CONDITIONING]), float(info[I_STATIONARITY]), float(info[I_PROGRESS]),
                           float(info[I_DISTANCE]),
                           float(info[I_MOVEMENT]), int(info[I_NFEV]), int(info[I_NIT]))


def local_solve(model, x0, legs, *, max_iter=MAX_ITER, rtol=LEG_RTOL, ftol=math.inf) -> LocalResult:
    """Levenberg-Marquardt from solver variables ``x0`` to the pose for ``legs`` (config unit).

    ``converged``: ``max |r_i| <= rtol * max(scale, max leg)`` (and leg fitness ``< ftol``).  Raises
    ``ValueError`` for legs that are not finite, not positive or outside the model's leg limits.
    Thread-safe (its own buffers); for many calls keep a :class:`LocalSolver` per thread."""
    x0 = np.ascontiguousarray(x0, dtype=float).reshape(-1)
    legs = np.ascontiguousarray(legs, dtype=float).reshape(-1)
    if x0.size != model.n_vars or legs.size != model.n_legs:
        raise ValueError(f"expected {model.n_vars} variables and {model.n_legs} legs")
    result = LocalSolver(model).solve(x0, legs, max_iter=max_iter, rtol=rtol, ftol=ftol)
    if result is None:
        raise ValueError("leg lengths must be finite, positive and within the leg limits")
    return result
