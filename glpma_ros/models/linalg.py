"""Small dense linear algebra, compiled with Numba (no LAPACK: Numba's would need SciPy), for the
few-by-few systems of the pose-space Levenberg-Marquardt (:mod:`glpma_ros.solvers.lm`) and the Kabsch fit
(:mod:`glpma_ros.models.pose_kernels`): the normal equations ``J^T J``, ``J^T r``; the damped solve
``(A + lam diag(A)) s = -g`` by Cholesky; the one-sided Jacobi SVD (Hestenes 1958).

A leaf module (of the package it imports only numba_cache), so that models and solvers can both use it."""
from __future__ import annotations

import math

from numba import njit

from ..runtime import numba_cache

numba_cache.install()      # before the first compiled function (see numba_cache): this module may be imported first

#: sweeps of the one-sided Jacobi SVD (it converges quadratically: 6x6 needs 5-7)
JACOBI_SWEEPS = 30
#: two columns count as orthogonal when |a.b| <= JACOBI_TOL |a| |b| (a few units in the last place); tested
#: squared, (a.b)^2 <= JACOBI_TOL^2 |a|^2 |b|^2, without a square root per pair
JACOBI_TOL = 4e-16
JACOBI_TOL_SQUARED = JACOBI_TOL * JACOBI_TOL
#: the rotation's tangent t = sign(zeta) / (|zeta| + sqrt(1 + zeta^2)) takes its limit 1 / (2 |zeta|) above this |zeta|,
#: where zeta^2 would overflow (and the two agree to round-off long before)
JACOBI_ZETA_HUGE = 1e150
#: the Kabsch fit's matrix (three points: rank 2 at most) has a column that the sweeps drive to round-off; its
#: direction is noise, so the test above never passes for it and the sweeps would run to JACOBI_SWEEPS.  A column
#: shorter than this share of the matrix's Frobenius norm is left alone (rotating it would change no
#: singular value by more than that share: a few units in the last place)
KABSCH_NEGLIGIBLE = 1e-15
#: a column of a nearly orthogonal basis, less its projections on the columns before it, keeps a norm of about 1;
#: below this share the basis was not nearly orthogonal (or not finite) and is given up
ORTHONORMAL_MIN_NORM = 0.5


@njit(cache=True, error_model="numpy")
def normal_equations(J, r, A, g):
    """``A = J^T J`` and ``g = J^T r`` (the Gauss-Newton normal equations)."""
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



@njit(cache=True, error_model="numpy")
def damped_solve(A, lam, g, step, L):
    """Solve ``(A + lam diag(A)) step = -g`` by Cholesky; False when not positive definite.  ``L`` receives the
    factor with the reciprocals of its diagonal on the diagonal (one division per row; the rest multiplies)."""
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
                L[i, i] = 1.0 / math.sqrt(s)
            else:
                L[i, j] = s * L[j, j]
    for i in range(n):                       # L y = -g
        s = -g[i]
        for k in range(i):
            s -= L[i, k] * step[k]
        step[i] = s * L[i, i]
    for i in range(n - 1, -1, -1):           # L^T step = y
        s = step[i]
        for k in range(i + 1, n):
            s -= L[k, i] * step[k]
        step[i] = s * L[i, i]
    return True


@njit(cache=True, error_model="numpy")
def jacobi_svd(A, V, s, negligible=0.0, vectors=True, from_V=False):
    """One-sided Jacobi SVD (Hestenes 1958) of ``A`` (m x n, m >= n), in place: on return
    ``A = U diag(s)`` (columns) and ``A_in V = U diag(s)``; singular values unsorted.  The squared
    column norms are carried through each rotation (``alpha - t gamma``, ``beta + t gamma``) and
    recomputed at every sweep, so a pair costs one dot product.  ``negligible`` (a share of the Frobenius
    norm, e.g. :data:`KABSCH_NEGLIGIBLE`; 0: none): a column shorter than that is not rotated, for a matrix
    known to be rank deficient (the default keeps the method's high relative accuracy for every column).
    ``vectors=False``: only the singular values are wanted (``V`` is left as it was; the rotations of ``A``, and
    so ``s``, are the same).  ``from_V=True`` (with ``vectors``): the rotations are accumulated onto ``V`` as given
    instead of the identity -- for ``A`` that is a matrix already multiplied by an orthogonal ``V0`` (``V`` = ``V0``
    on entry), so that on return ``A_in V0^T V = U diag(s)``: a warm start, when the columns of ``A_in`` are nearly
    orthogonal already (:func:`orthonormalise_columns` keeps a reused basis orthogonal)."""
    m, n = A.shape
    if vectors and not from_V:
        for i in range(n):
            for j in range(n):
                V[i, j] = 1.0 if i == j else 0.0
    floor = 0.0                              # squared: compared with squared column norms
    if negligible > 0.0:
        for i in range(n):
            for k in range(m):
                floor += A[k, i] * A[k, i]
        floor *= negligible * negligible
    for _ in range(JACOBI_SWEEPS):
        for j in range(n):
            acc = 0.0
            for k in range(m):
                acc += A[k, j] * A[k, j]
            s[j] = acc
        rotated = False
        # the pairs in round-robin order: each round's pairs are disjoint, so that a rotation need not wait for the
        # one before it (the circle method: index 0 stays, the others turn by one place per round; an odd n gets a
        # bye, the pairs with the extra index are skipped)
        players = n + (n % 2)
        turn = players - 1
        for rnd in range(turn):
            for slot in range(players // 2):
                p = 0
                if slot > 0:
                    p = rnd + slot - 1
                    p = 1 + (p - turn if p >= turn else p)
                q = rnd + turn - 1 - slot
                q = 1 + (q - turn if q >= turn else q)
                if p > q:
                    p, q = q, p
                if q >= n:
                    continue
                alpha = s[p]
                beta = s[q]
                gamma = 0.0
                for k in range(m):
                    gamma += A[k, p] * A[k, q]
                if not gamma * gamma > JACOBI_TOL_SQUARED * alpha * beta or min(alpha, beta) < floor:
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                az = abs(zeta)
                t = 1.0 / (az + math.sqrt(1.0 + az * az)) if az < JACOBI_ZETA_HUGE else 0.5 / az
                if zeta < 0.0:
                    t = -t
                c = 1.0 / math.sqrt(1.0 + t * t)
                sn = c * t
                for k in range(m):
                    ap = A[k, p]
                    A[k, p] = c * ap - sn * A[k, q]
                    A[k, q] = sn * ap + c * A[k, q]
                if vectors:
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
def orthonormalise_columns(V):
    """The columns of the square ``V`` made orthonormal in place (modified Gram-Schmidt): a basis updated by
    many rotations, each orthogonal to round-off, stays orthogonal to round-off.  False (``V`` then unusable)
    when a column is not finite or depends on the ones before it."""
    n = V.shape[1]
    for j in range(n):
        for i in range(j):
            d = 0.0
            for k in range(V.shape[0]):
                d += V[k, i] * V[k, j]
            for k in range(V.shape[0]):
                V[k, j] -= d * V[k, i]
        norm = 0.0
        for k in range(V.shape[0]):
            norm += V[k, j] * V[k, j]
        norm = math.sqrt(norm)
        if not (norm > ORTHONORMAL_MIN_NORM and math.isfinite(norm)):
            return False
        for k in range(V.shape[0]):
            V[k, j] /= norm
    return True
