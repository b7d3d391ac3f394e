"""The two models in pose space, compiled: what the Levenberg-Marquardt of
:mod:`glpma_ros.solvers.lm` steps in.

The pose state is a float vector of ``STATE_SIZE`` entries: 3-RPR ``(x, y, theta)`` in its first three;
hexapod the platform origin ``p`` (3) and the rotation ``R`` (9, row-major).  Here: the leg residuals
``r_i = |B_i(pose) - A_i| - l_i`` and their analytic Jacobian ``J_i = (u_i, (R CB_i) x u_i)`` (Chandra &
Rolland 2014, Eq. 6-7, for 3-RPR); the retraction of a step (3-RPR: added; hexapod: ``p + dp``,
``exp([w]x) R`` by Rodrigues' formula); rotation matrix <-> unit quaternion; the least-squares rigid fit of
the frame joints CB_F1..CB_F3 (``Manipulator.frame``) onto the hexapod's nine solver variables (Kabsch 1976);
the platform-joint distance of two solver-variable vectors.  Every leg counts (``base.shape[0]`` of them:
redundant legs included).

The actuated kinds (:mod:`.actuated`) are the same pieces with the proximal points and rods of the
per-solve leg vector (:func:`~glpma_ros.models.residuals.split_leg_vector`): planar and spatial full pose
as 3-RPR and the hexapod; a platform that only translates (deltas) has the state ``p`` (R = I kept in
the state) and ``J_i = u_i``."""
from __future__ import annotations

import math

from numba import njit

from .linalg import KABSCH_NEGLIGIBLE, jacobi_svd
from .residuals import (
    KIND_ACTUATED_PLANAR,
    KIND_ACTUATED_SPATIAL,
    KIND_ACTUATED_TRANSLATION,
    KIND_PLANAR_3RPR,
    split_leg_vector,
)

#: rotation angle below which Rodrigues' formula uses its second-order Taylor expansion
SMALL_ANGLE = 1e-8
#: length of a state vector: hexapod p (3) + R (9, row-major); 3-RPR uses its first 3 entries
STATE_SIZE = 12


@njit(cache=True, error_model="numpy")
def _rpr_residuals_jacobian(state, base, platform, legs, r, J):
    c = math.cos(state[2])
    s = math.sin(state[2])
    for i in range(base.shape[0]):
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
    for j in range(base.shape[0]):
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
def _translation_residuals_jacobian(state, base, platform, legs, r, J):
    for j in range(base.shape[0]):
        ex = state[0] + platform[j, 0] - base[j, 0]
        ey = state[1] + platform[j, 1] - base[j, 1]
        ez = state[2] + platform[j, 2] - base[j, 2]
        n = math.sqrt(ex * ex + ey * ey + ez * ez)
        J[j, 0] = ex / n
        J[j, 1] = ey / n
        J[j, 2] = ez / n
        r[j] = n - legs[j]


@njit(cache=True)
def is_planar(kind):
    """The kinds whose pose is ``(x, y, theta)``."""
    return kind == KIND_PLANAR_3RPR or kind == KIND_ACTUATED_PLANAR


@njit(cache=True, error_model="numpy")
def residuals_jacobian(kind, state, base, platform, legs, r, J):
    """Leg residuals and Jacobian at ``state``; returns the sum of squares (inf when not finite).
    ``base``: the fixed proximal points (length-actuated kinds; the actuated kinds read theirs from ``legs``)."""
    n = platform.shape[0]
    if kind == KIND_PLANAR_3RPR:
        _rpr_residuals_jacobian(state, base, platform, legs, r, J)
    elif kind == KIND_ACTUATED_PLANAR:
        rods, points = split_leg_vector(legs, n, 2)
        _rpr_residuals_jacobian(state, points, platform, rods, r, J)
    elif kind == KIND_ACTUATED_SPATIAL:
        rods, points = split_leg_vector(legs, n, 3)
        _hex_residuals_jacobian(state, points, platform, rods, r, J)
    elif kind == KIND_ACTUATED_TRANSLATION:
        rods, points = split_leg_vector(legs, n, 3)
        _translation_residuals_jacobian(state, points, platform, rods, r, J)
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
def retract(kind, state, step, trial, M):
    """``trial`` = the state moved by ``step`` (3-RPR: added; hexapod: p + dp, exp([w]x) R; translation:
    p + dp, R kept)."""
    if is_planar(kind):
        for k in range(3):
            trial[k] = state[k] + step[k]
        return
    if kind == KIND_ACTUATED_TRANSLATION:
        for k in range(STATE_SIZE):
            trial[k] = state[k]
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


# -- rotations: matrix <-> quaternion ----------------------------------------------------------------------------------
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



@njit(cache=True, error_model="numpy")
def kabsch_state(platform, x, state, H, V, s):
    """``state`` = (p, R) of the rigid motion that best maps the frame joints ``platform`` (3 rows:
    the model's ``frame``) onto the solver variables (Kabsch 1976): H = sum (CB_k - cs)(B_k - cd)^T = U S V^T, R = V
    diag(1, 1, d) U^T.
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
    jacobi_svd(H, V, s, KABSCH_NEGLIGIBLE)   # H_in V = U S (H: rank 2, its third column round-off)
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
def joint_distance(kind, platform, x1, x2):
    """Largest distance between corresponding platform joints (3-RPR: the first three rows of
    ``platform``; hexapod: the frame joints, the variables; translation: the platform's displacement), like
    ``Manipulator.distance``."""
    d = 0.0
    if kind == KIND_ACTUATED_TRANSLATION:
        dx = x1[0] - x2[0]
        dy = x1[1] - x2[1]
        dz = x1[2] - x2[2]
        return math.sqrt(dx * dx + dy * dy + dz * dz)
    if is_planar(kind):
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

