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

or, with redundant legs (more than the degrees of freedom; ``S_GTOL`` > 0), at the least-squares pose
(``LSQ_GTOL``: the gradient ``J^T r`` at round-off relative to ``|J| |r|``) -- whether those residuals
are consistent with the leg noise is the estimator's chi-square test (:mod:`glpma_ros.estimation.redundancy`), which
it may hand in as ``ftol``

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

Layout: the pose-space pieces of the two models (residuals and Jacobians, retraction, rotations, Kabsch
fit, joint distance) are in :mod:`glpma_ros.models.pose_kernels`, the small dense linear algebra in
:mod:`glpma_ros.models.linalg`, the Python side (:class:`~glpma_ros.solvers.local.LocalSolver`,
:func:`~glpma_ros.solvers.local.local_solve`) in :mod:`glpma_ros.solvers.local`; this module is the
iteration itself.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..models.kernels import residuals_into
from ..models.linalg import damped_solve, jacobi_svd, normal_equations, orthonormalise_columns
from ..models.pose_kernels import (
    STATE_SIZE,
    is_planar,
    joint_distance,
    kabsch_state,
    quaternion_from_rows,
    residuals_jacobian,
    retract,
    rows_from_quaternion,
)
from ..models.residuals import KIND_ACTUATED_SPATIAL, KIND_ACTUATED_TRANSLATION, KIND_HEXAPOD_66

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
#: redundant legs (more legs than degrees of freedom): measured legs have no exact pose, so a
#: solve has also converged at the least-squares pose, where ``|J^T r| / (|J| max(|r|, LSQ_FLOOR L))``
#: (column-scaled J) is at most ``LSQ_GTOL``.  Then the remaining step is below ``LSQ_GTOL / cond``
#: of the residual: far below the leg noise.  The floor keeps the measure above round-off (about
#: 1e-16 L / |r|) when the residual itself is nearly round-off: at most 1e-7 there
LSQ_GTOL = 1e-6
LSQ_FLOOR = 1e-9

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
S_GTOL = 8            # redundant legs: least-squares stationarity that counts as converged (0: off)
S_COL_SCALE = 9       # then the model's pose_column_scale (n_pose values)


# the memo a work buffer keeps from one solve to the next (after the scratch space; the spatial full-pose kinds
# only, whose state is fitted from their variables and whose Jacobian has 6 columns): the variables a spatial
# solve returned and the pose state they were written from (a solve that starts from exactly those variables,
# the warm path's everyday case, resumes that state instead of fitting it again from the variables: Kabsch), and
# the right singular vectors of the last conditioning (the next one starts from them: on a trajectory the leg
# Jacobian turns little between two inputs, so its columns in that basis are nearly orthogonal and the Jacobi
# SVD needs fewer sweeps).  Either part is a start only: the results are the same to round-off without it.
M_RESUME_X = 0                      # the returned variables (up to STATE_SIZE of them)
M_RESUME_STATE = STATE_SIZE         # the state they were written from
M_RESUME_OK = 2 * STATE_SIZE        # 1.0: the two above are set
M_BASIS_OK = 2 * STATE_SIZE + 1     # 1.0: the basis below is set
M_BASIS = 2 * STATE_SIZE + 2        # the right singular vectors (n_pose x n_pose)


def workspace_size(n_legs: int, n_pose: int, n_res: int) -> int:
    """Length of the float64 work buffer :func:`lm_kernel` needs (one buffer serves one model: it keeps a
    memo of the last solve, see ``M_*``)."""
    return 2 * (n_legs + n_legs * n_pose) + 3 * n_pose * n_pose + 2 * n_pose + 2 * STATE_SIZE \
        + n_legs * n_pose + n_pose + n_res + M_BASIS + n_pose * n_pose


# -- the kernel -------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _reference_length(legs, n_legs, settings):
    """``max(scale, max leg)``, or -1.0 when a leg is not finite, not positive or outside the limits.
    ``legs``' first ``n_legs`` entries are the legs (rods); an actuated kind's proximal points follow,
    which need only be finite."""
    ref = settings[S_SCALE]
    lo, hi = settings[S_LO], settings[S_HI]
    for i in range(n_legs):
        li = legs[i]
        if not (math.isfinite(li) and li > 0.0 and li >= lo and li <= hi):
            return -1.0
        ref = max(ref, li)
    for i in range(n_legs, legs.shape[0]):
        if not math.isfinite(legs[i]):
            return -1.0
    return ref


@njit(cache=True, error_model="numpy")
def _least_squares_reached(A, g, f, col_scale, ref, gtol):
    """The redundant legs' criterion (``LSQ_GTOL``) from the normal equations ``A = J^T J``,
    ``g = J^T r`` and ``f = |r|^2``; False when ``gtol`` is 0 (exactly determined)."""
    if gtol <= 0.0:
        return False
    jn = 0.0
    gn = 0.0
    for k in range(g.shape[0]):
        c2 = col_scale[k] * col_scale[k]
        jn += A[k, k] * c2
        gn += g[k] * g[k] * c2
    den = math.sqrt(jn) * max(math.sqrt(f), LSQ_FLOOR * ref)
    return den > 0.0 and math.sqrt(gn) <= gtol * den


@njit(cache=True, error_model="numpy")
def _is_last_returned(x0, memo):
    """``x0`` is exactly the variables the last spatial solve on this work buffer returned (``memo``)."""
    if memo[M_RESUME_OK] != 1.0:
        return False
    for k in range(x0.shape[0]):
        if x0[k] != memo[M_RESUME_X + k]:
            return False
    return True


@njit(cache=True, error_model="numpy")
def _singular_values(Js, V, sv, memo, basis, row):
    """The singular values ``sv`` of ``Js`` (destroyed) by the Jacobi SVD, started from the memo's basis when
    it holds one (``Js`` multiplied by it first, ``row``: n_pose floats of scratch); the basis is then the
    right singular vectors found, for the next call."""
    n_rows, n = Js.shape
    if memo[M_BASIS_OK] == 1.0:
        for i in range(n_rows):
            for k in range(n):
                acc = 0.0
                for j in range(n):
                    acc += Js[i, j] * basis[j, k]
                row[k] = acc
            for k in range(n):
                Js[i, k] = row[k]
        for i in range(n):
            for k in range(n):
                V[i, k] = basis[i, k]
        jacobi_svd(Js, V, sv, 0.0, True, True)
    else:
        jacobi_svd(Js, V, sv, 0.0, True)
    for i in range(n):
        for k in range(n):
            basis[i, k] = V[i, k]
    memo[M_BASIS_OK] = 1.0 if orthonormalise_columns(basis) else 0.0


@njit(cache=True, error_model="numpy", nogil=True)
def lm_kernel(kind, data, platform, frame, legs, x0, x_ref, legs_ref, settings, out, work):
    """Levenberg-Marquardt from solver variables ``x0`` for leg lengths ``legs``.

    ``kind``/``data``: the model's ``kind_id`` and data tuple (:mod:`glpma_ros.models.kernels`);
    ``platform``: its platform joints (one per leg); ``frame``: its frame joints (``Manipulator.frame``);
    ``settings``: see :func:`make_settings`; ``x_ref``: the variables the distance is measured from;
    ``legs_ref``: the legs the movement is measured from (empty: none).  Fills ``out`` = [solver variables (n_vars),
    position (3), quaternion [qx, qy, qz,
    qw], info (``N_INFO``, layout: the ``I_*`` constants)]; ``work``: :func:`workspace_size` floats.
    Nothing is allocated."""
    ref = _reference_length(legs, platform.shape[0], settings)
    if ref < 0.0:
        out[:] = 0.0                          # I_INPUT_OK = 0: nothing solved
        return
    solve_one(kind, data, platform, frame, legs, ref, x0, x_ref, settings, out, work, True)
    if legs_ref.shape[0] == legs.shape[0]:
        mv = 0.0
        for i in range(legs.shape[0]):
            mv = max(mv, abs(legs[i] - legs_ref[i]))
        out[x0.shape[0] + 7 + I_MOVEMENT] = mv


# -- the warm path's call --------------------------------------------------------------------------
# The warm path's call (:func:`warm_kernel`) takes one buffer (:func:`warm_buffer`) for everything that does not
# change from one input to the next -- the model's kind, its data matrices and vector, platform and frame joints,
# the settings and the work space -- instead of eight arguments: the dispatcher checks the type of every argument
# on every call (of the data tuple the slowest).  Layout: the kind, then (offset, rows, columns) per part in
# WARM_PARTS' order, then the parts' values (row-major), then the work space (its memo is the warm path's own).
WARM_PARTS = 7              # data[0], data[1], data[2], platform, frame, settings, work
WARM_HEADER = 1 + 3 * WARM_PARTS


def warm_buffer(kind, data, platform, frame, settings, work_size) -> np.ndarray:
    """The buffer :func:`warm_kernel` reads from (see ``WARM_PARTS``); ``work_size``: :func:`workspace_size`."""
    parts = [np.ascontiguousarray(a, dtype=float) for a in (data[0], data[1], data[2], platform, frame, settings)]
    parts.append(np.zeros(int(work_size)))
    head = np.zeros(WARM_HEADER)
    head[0] = kind
    offset = WARM_HEADER
    for k, a in enumerate(parts):
        rows, cols = (a.shape[0], a.shape[1]) if a.ndim == 2 else (a.shape[0], 1)
        head[1 + 3 * k:4 + 3 * k] = (offset, rows, cols)
        offset += a.size
    return np.concatenate([head] + [a.ravel() for a in parts])


@njit(cache=True, error_model="numpy")
def _part_matrix(buf, k):
    o, rows, cols = int(buf[1 + 3 * k]), int(buf[2 + 3 * k]), int(buf[3 + 3 * k])
    return buf[o:o + rows * cols].reshape((rows, cols))


@njit(cache=True, error_model="numpy")
def _part_vector(buf, k):
    o, rows = int(buf[1 + 3 * k]), int(buf[2 + 3 * k])
    return buf[o:o + rows]


@njit(cache=True, error_model="numpy", nogil=True)
def warm_kernel(buf, legs, x0, legs_ref, out):
    """:func:`lm_kernel` from ``x0`` (also the reference of the distance) with the rest read from ``buf``
    (:func:`warm_buffer`).  The kernels count no evaluation in the data tuple's counter: a fresh one stands in."""
    data = (_part_matrix(buf, 0), _part_matrix(buf, 1), _part_vector(buf, 2), np.zeros(1, dtype=np.int64))
    lm_kernel(int(buf[0]), data, _part_matrix(buf, 3), _part_matrix(buf, 4), legs, x0, x0, legs_ref,
              _part_vector(buf, 5), out, _part_vector(buf, 6))


@njit(cache=True, error_model="numpy", nogil=True)
def multistart_kernel(kind, data, platform, frame, legs, starts, x_ref, settings, out, work):
    """Levenberg-Marquardt from each row of ``starts`` in turn until one converges.

    Fills ``out`` (as :func:`lm_kernel`) with the first converged solve, or with the one of least leg
    fitness; its ``I_NFEV`` / ``I_NIT`` count every start tried.  ``work``: :func:`workspace_size`
    plus ``len(out)`` floats.  Returns the index of the start reported (-1 when the legs fail the
    check)."""
    ref = _reference_length(legs, platform.shape[0], settings)
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
        solve_one(kind, data, platform, frame, legs, ref, starts[k], x_ref, settings, trial_out, core, True)
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
def solve_one(kind, data, platform, frame, legs, ref, x0, x_ref, settings, out, work, figures):
    """The iteration of :func:`lm_kernel` for legs that passed the check (``ref``: reference length).
    ``figures=False`` leaves out what only a decision on the pose needs -- the papers' fitness,
    stationarity, conditioning and distance (left 0) -- for callers that keep the leg fitness alone
    (solve_all's multistart)."""
    n_legs = platform.shape[0]
    n_vars = x0.shape[0]
    n_pose = settings.shape[0] - S_COL_SCALE
    col_scale = settings[S_COL_SCALE:]
    rtol, ftol, max_iter = settings[S_RTOL], settings[S_FTOL], int(settings[S_MAX_ITER])
    stall = settings[S_STALL]
    gtol = settings[S_GTOL]
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
    o += int(settings[S_N_RES])
    memo = work[o:o + M_BASIS + n_pose * n_pose]
    basis = memo[M_BASIS:].reshape((n_pose, n_pose))
    # the spatial full-pose kinds (fitted by Kabsch, a 6-column Jacobian) keep the memo; the others' state is
    # their variables, and a 3-column SVD costs less than the basis' upkeep
    spatial = kind == KIND_HEXAPOD_66 or kind == KIND_ACTUATED_SPATIAL
    base = data[0]
    M = L[:3, :3]                            # scratch for the rotation of a step (L is free then)

    # start state
    if is_planar(kind):
        for k in range(3):
            state[k] = x0[k]
        ok = True
    elif kind == KIND_ACTUATED_TRANSLATION:
        for k in range(STATE_SIZE):
            state[k] = 0.0
        for k in range(3):
            state[k] = x0[k]
            state[3 + 4 * k] = 1.0           # R = I: the platform only translates
        ok = True
    elif spatial and _is_last_returned(x0, memo):
        for k in range(STATE_SIZE):
            state[k] = memo[M_RESUME_STATE + k]
        ok = True
    else:
        ok = kabsch_state(frame, x0, state, L[:3, :3], V[:3, :3], sv[:3])
    nfev = 0
    nit = 0
    progress = 1.0
    if ok and max_iter > 0:
        f = residuals_jacobian(kind, state, base, platform, legs, r, J)
        nfev += 1
        if f < math.inf:
            normal_equations(J, r, A, g)
            lam = LAMBDA_INIT
            nu = 2.0
            rejections = 0
            rmax = 0.0
            for i in range(n_legs):
                rmax = max(rmax, abs(r[i]))
            done = (rmax <= rtol * ref or _least_squares_reached(A, g, f, col_scale, ref, gtol)) and f < ftol
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
                if damped_solve(A, lam, g, step, L):
                    retract(kind, state, step, trial, M)
                    f2 = residuals_jacobian(kind, trial, base, platform, legs, r2, J2)
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
                    normal_equations(J, r, A, g)
                    if not done:
                        rmax = 0.0
                        for i in range(n_legs):
                            rmax = max(rmax, abs(r[i]))
                        done = (rmax <= rtol * ref or _least_squares_reached(A, g, f, col_scale, ref, gtol)) \
                            and f < ftol
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
        info[I_DISTANCE] = joint_distance(kind, frame, x_out, x_ref)
        return
    if is_planar(kind):
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
    elif kind == KIND_ACTUATED_TRANSLATION:
        for k in range(3):
            x_out[k] = state[k]
            pose_out[k] = state[k]
        for k in range(3):
            pose_out[3 + k] = 0.0
        pose_out[6] = 1.0
    else:
        q = pose_out[3:7]
        quaternion_from_rows(state[3:12], q)
        rows_from_quaternion(q, state[3:12])
        for k in range(3):
            cx, cy, cz = frame[k, 0], frame[k, 1], frame[k, 2]
            for a in range(3):
                x_out[3 * k + a] = state[a] + (state[3 + 3 * a] * cx + state[4 + 3 * a] * cy
                                               + state[5 + 3 * a] * cz)
        for a in range(3):
            pose_out[a] = state[a]
        if spatial:
            finite = True
            for k in range(STATE_SIZE):
                memo[M_RESUME_STATE + k] = state[k]
                finite = finite and math.isfinite(state[k])
            for k in range(n_vars):
                memo[M_RESUME_X + k] = x_out[k]
            memo[M_RESUME_OK] = 1.0 if finite else 0.0

    # the figures at the returned variables
    f = residuals_jacobian(kind, state, base, platform, legs, r, J)
    nfev += 1
    rmax = 0.0
    for i in range(n_legs):
        rmax = max(rmax, abs(r[i]))
    info[I_LEG_FITNESS] = f
    info[I_MAX_RESIDUAL] = rmax if math.isfinite(rmax) else math.inf
    info[I_NFEV] = nfev
    info[I_NIT] = nit
    info[I_PROGRESS] = progress
    lsq = False                       # redundant legs: converged at the least-squares pose (gtol > 0)
    if gtol > 0.0 and f < math.inf:
        normal_equations(J, r, A, g)
        lsq = _least_squares_reached(A, g, f, col_scale, ref, gtol)
    info[I_CONVERGED] = 1.0 if ((rmax <= rtol * ref or lsq) and f < ftol) else 0.0
    if not figures:
        return
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
        if spatial:
            _singular_values(Js, V, sv, memo, basis, step)
        else:
            jacobi_svd(Js, V, sv, 0.0, False)     # the singular values only
        smax = 0.0
        smin = math.inf
        for k in range(n_pose):
            smax = max(smax, sv[k])
            smin = min(smin, sv[k])
        info[I_CONDITIONING] = smin / smax if smax > 0.0 else 0.0
    info[I_DISTANCE] = joint_distance(kind, frame, x_out, x_ref)
