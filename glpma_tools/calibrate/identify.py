"""Kinematic calibration of a parallel manipulator from externally measured poses: the geometry
(base joints A_i, platform joints B_i, leg-sensor offsets o_i) by nonlinear least squares on the
inverse-kinematic leg residuals, with standard errors and an identifiability analysis.

**Model** (Zhuang, Yan & Masory 1998, "inverse kinematic residuals"; Wampler, Hollerbach & Arai 1995).
Measurement ``j`` is the n sensor readings ``l_ij`` and the platform pose ``(p_j, R_j)`` measured in the
base frame by an external instrument (laser tracker, motion capture).  Leg ``i`` of a rigid geometry
satisfies ``|p_j + R_j B_i - A_i| = l_ij + o_i``, so its residual is

    r_ij(A_i, B_i, o_i) = |p_j + R_j B_i - A_i| - (l_ij + o_i),

with the analytic Jacobian ``dr/dA_i = -u_ij``, ``dr/dB_i = R_j^T u_ij``, ``dr/do_i = -1`` where
``u_ij`` is the unit vector of the leg.  All parameters are lengths in the config's unit, so the
Jacobian's columns are commensurate as they stand.  Leg i's parameters appear in leg i's residuals
only: the Jacobian is block-diagonal, one (m x k) block per leg (k = 2d + 1 parameters in d
dimensions), and with the poses taken as given the problem separates into n independent small
problems, solved here all at once (NumPy, vectorised over legs and measurements) by Gauss-Newton with
step halving (Bjorck 1996, section 9.2), each step the pseudo-inverse solution from the
eigen-decomposition of the leg's k x k normal matrix.  The base frame is the one the
instrument measures in and the platform frame the one its pose refers to, so there is no gauge
freedom by construction: every parameter is identifiable from poses that move and rotate enough.

**Statistics** (Seber & Wild 1989, "Nonlinear Regression", section 2.1).  The estimator is ordinary
least squares with the measured poses taken as exact.  The pose errors are not ignored: a pose error
(dp, dw) moves residual r_ij by ``u_ij . dp + ((R_j B_i) x u_ij) . dw``, a zero-mean term of nearly
constant variance per leg that adds to the sensor noise; the noise variance of each leg is therefore
estimated from the leg's own residuals, ``s_i^2 = RSS_i / (m - k)``, and the covariance of its
parameters is ``s_i^2 (J_i^T J_i)^-1``: the standard errors include the pose noise.  Not modelled: the
correlation between legs through the shared pose error (it couples the legs' estimates, not the
standard error of each parameter) and the errors-in-variables bias, of order sigma_pose^2 / leg
length (1e-7 mm for 0.01 mm on a 1 m hexapod), far below the standard errors.

**Identifiability** (Hollerbach & Wampler 1996).  The SVD of each leg's block, ``J_i = U S V^T`` (S
and V from the eigen-decomposition of ``J_i^T J_i``), gives the directions in parameter space (columns of V) and how
well the data see them: the standard error along direction v_k is ``s_i / sigma_k``.  A direction is
*unidentifiable* when sigma_k is at round-off relative to the largest singular value, or when its
standard error exceeds :data:`UNIDENTIFIABLE_SE_SHARE` of the geometry's size -- the data then cannot
determine it to the order of the errors a calibration corrects; it is *weak* above
:data:`WEAK_SE_SHARE`.  Such a direction is named in words from its largest components (e.g. the
offset of a leg and the coordinate of its base joint along the leg move together when the leg never
changes direction), with the kind of pose that would separate them.  The condition number of the
identification is that of the whole (block-diagonal) Jacobian, ``max sigma / min sigma`` over all legs.

References: H. Zhuang, J. Yan, O. Masory, *Calibration of Stewart platforms and other parallel
manipulators by minimizing inverse kinematic residuals*, J. Robotic Systems 15(7), 1998; C. W. Wampler,
J. M. Hollerbach, T. Arai, *An implicit loop method for kinematic calibration and its application to
closed-chain mechanisms*, IEEE Trans. Robotics and Automation 11(5), 1995; J. M. Hollerbach,
C. W. Wampler, *The calibration index and taxonomy for robot kinematic calibration methods*, IJRR 15(6),
1996; G. A. F. Seber, C. J. Wild, *Nonlinear Regression*, Wiley 1989; A. Bjorck, *Numerical Methods for
Least Squares Problems*, SIAM 1996.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: parameter groups of a leg, in the order of the Jacobian's columns
GROUPS = ("base", "platform", "offsets")
AXES = ("x", "y", "z")
#: Gauss-Newton stops when no parameter moves by more than this share of the geometry's scale
#: (1e-12: a few hundred times double round-off on the joints' coordinates)
STEP_RTOL = 1e-12
#: ... or when every leg's step is below this share of its standard errors: |J_i d|^2 <= share^2 s_i^2
#: (a step the data cannot tell from zero; the round-off of the sums of squares hides such steps, so
#: on noisy data this is the criterion that ends the iteration)
STEP_SE_SHARE = 1e-6
#: unit round-off of a double
EPS = float(np.finfo(float).eps)
#: units in the last place a leg residual may be off by (the norm of a sum of three products, less
#: a length: a few roundings, each half an ulp of the leg's length; 8 bounds them with room)
ROUNDOFF_ULPS = 8.0
#: Gauss-Newton iterations at most (from millimetre errors on a metre-sized geometry it converges in
#: 3-5: the residuals are nearly linear in the parameters)
MAX_ITERATIONS = 50
#: a step that raises a leg's sum of squares is halved at most this many times (2^-30 of a step is
#: below the round-off of the parameters: no descent is left)
MAX_HALVINGS = 30
#: singular values below this share of the largest (over all legs) are round-off: the direction is
#: not seen by the data at all.  They come from the eigenvalues of J^T J, which are exact to ~1e-16 of
#: the largest, so singular values are resolved down to ~1e-8 of the largest; 1e-7 is above that floor
RANK_RTOL = 1e-7
#: a direction whose standard error exceeds this share of the geometry's scale is unidentifiable:
#: 0.1 %, about the size of the joint and offset errors a calibration corrects (a millimetre on a
#: metre-sized hexapod), so the data say nothing useful about it
UNIDENTIFIABLE_SE_SHARE = 1e-3
#: a direction whose standard error exceeds this share of the scale is reported as weakly identified
WEAK_SE_SHARE = 1e-4
#: components of a direction (a unit vector) at least this large in magnitude are named in its
#: description (1/sqrt(k) of a k-parameter direction spread evenly is 0.38 for k = 7)
NAMED_COMPONENT = 0.3


@dataclass
class Geometry:
    """Base joints A (n, d), platform joints B (n, d) and sensor offsets (n,), config unit."""

    base: np.ndarray
    platform: np.ndarray
    offsets: np.ndarray

    @property
    def n_legs(self) -> int:
        return self.base.shape[0]

    @property
    def dim(self) -> int:
        return self.base.shape[1]

    def copy(self) -> "Geometry":
        return Geometry(self.base.copy(), self.platform.copy(), self.offsets.copy())


@dataclass
class Measurements:
    """``legs`` (m, n): the sensors' readings; ``position`` (m, d) and ``rotation`` (m, d, d): the
    measured platform poses in the base frame (platform -> base); config unit."""

    legs: np.ndarray
    position: np.ndarray
    rotation: np.ndarray

    def __len__(self) -> int:
        return self.legs.shape[0]

    def subset(self, index) -> "Measurements":
        return Measurements(self.legs[index], self.position[index], self.rotation[index])


@dataclass
class Parameter:
    leg: int                  # 1-based
    group: str                # base | platform | offsets
    axis: str                 # x | y | z, "" for an offset
    nominal: float
    value: float
    se: float

    @property
    def name(self) -> str:
        return f"leg {self.leg} offset" if self.group == "offsets" else f"leg {self.leg} {self.group} {self.axis}"


@dataclass
class Direction:
    """A direction of parameter space the data see badly: its leg, unit vector over the leg's
    identified parameters (names -> component), standard error along it and a description."""

    leg: int
    components: dict
    singular_value: float
    se: float
    text: str


@dataclass
class Identification:
    geometry: Geometry                   # identified (the groups not identified as given)
    parameters: list                     # Parameter, leg by leg, in GROUPS order
    residual_std: np.ndarray             # s_i per leg (config unit)
    condition_number: float
    unidentifiable: list = field(default_factory=list)   # Direction
    weak: list = field(default_factory=list)             # Direction
    iterations: int = 0
    converged: bool = False


def leg_residuals(geometry: Geometry, meas: Measurements) -> np.ndarray:
    """r_ij = |p_j + R_j B_i - A_i| - (l_ij + o_i), shape (m, n)."""
    e = _leg_vectors(geometry, meas)
    return np.sqrt((e * e).sum(axis=1)) - (meas.legs + geometry.offsets)


def _leg_vectors(geometry: Geometry, meas: Measurements) -> np.ndarray:
    """e_ij = p_j + R_j B_i - A_i, laid out (m, d, n)."""
    return meas.position[:, :, None] + meas.rotation @ geometry.platform.T - geometry.base.T


def parameter_labels(dim: int, groups) -> list:
    """(group, axis) of a leg's identified parameters, the Jacobian's column order."""
    out = []
    for g in GROUPS:
        if g in groups:
            out += [(g, "")] if g == "offsets" else [(g, AXES[a]) for a in range(dim)]
    return out


def _residuals_jacobian(geometry: Geometry, meas: Measurements, groups):
    """Residuals (n, m) and the per-leg Jacobian blocks (n, m, k) of the identified groups."""
    e = _leg_vectors(geometry, meas)
    dist = np.sqrt((e * e).sum(axis=1))                                 # (m, n)
    u = e / dist[:, None, :]
    r = (dist - (meas.legs + geometry.offsets)).T
    blocks = []
    if "base" in groups:
        blocks.append(-u)                                               # dr/dA_i = -u_ij
    if "platform" in groups:
        blocks.append(meas.rotation.transpose(0, 2, 1) @ u)             # dr/dB_i = R_j^T u_ij
    if "offsets" in groups:
        blocks.append(-np.ones((u.shape[0], 1, u.shape[2])))            # dr/do_i = -1
    return r, np.ascontiguousarray(np.concatenate(blocks, axis=1).transpose(2, 0, 1))


def _vector(geometry: Geometry, groups) -> np.ndarray:
    """The identified parameters, (n, k)."""
    parts = [getattr(geometry, g) for g in GROUPS if g in groups]
    return np.concatenate([p if p.ndim == 2 else p[:, None] for p in parts], axis=1)


def _with_vector(geometry: Geometry, theta: np.ndarray, groups) -> Geometry:
    g = geometry.copy()
    d, col = g.dim, 0
    if "base" in groups:
        g.base = theta[:, col:col + d].copy()
        col += d
    if "platform" in groups:
        g.platform = theta[:, col:col + d].copy()
        col += d
    if "offsets" in groups:
        g.offsets = theta[:, col].copy()
    return g


def _spectrum(J: np.ndarray):
    """Singular values (n, k), ascending, and right singular vectors (n, k, k; columns) of each leg's
    block, from the eigen-decomposition of the small normal matrix J_i^T J_i (k x k): the blocks
    are tall (m >> k), and forming J^T J costs one pass over them."""
    lam, V = np.linalg.eigh(J.transpose(0, 2, 1) @ J)
    return np.sqrt(np.maximum(lam, 0.0)), V


def _seen(s: np.ndarray) -> np.ndarray:
    """The singular values the data see: above round-off relative to the largest of all legs."""
    return s > RANK_RTOL * float(s.max())


def _step(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Gauss-Newton step of every leg, ``-J^+ r`` = ``-V S^-2 V^T J^T r`` over the directions the data
    see (the others are left alone), (n, k)."""
    s, V = _spectrum(J)
    inv2 = np.where(_seen(s), 1.0 / np.where(_seen(s), s, 1.0) ** 2, 0.0)
    g = np.einsum("nmk,nm->nk", J, r)                                   # J^T r
    return -np.einsum("nkj,nj->nk", V, inv2 * np.einsum("nkj,nk->nj", V, g))


def _cost_roundoff(r: np.ndarray, meas: Measurements, scale: float) -> np.ndarray:
    """How much each leg's sum of squares may rise by round-off alone, (n,): a residual is the
    difference of two lengths of the order of the leg (|e_ij| and l_ij + o_i), exact to
    ``d_ij = ROUNDOFF_ULPS eps (l_ij + scale)``, so its square moves by up to ``2 |r_ij| d_ij + d_ij^2``
    (far above the sum's own rounding when the residuals are small beside the legs)."""
    d = ROUNDOFF_ULPS * EPS * (meas.legs.T + scale)
    return np.einsum("nm,nm->n", 2.0 * np.abs(r) + d, d)


def identify(nominal: Geometry, meas: Measurements, groups=GROUPS, scale: float | None = None) -> Identification:
    """Least-squares geometry from ``meas``, starting from ``nominal``; only ``groups`` (a subset of
    :data:`GROUPS`) are estimated, the others stay as in ``nominal``.  ``scale``: the geometry's size
    (config unit) for the thresholds (default: the largest extent of the base joints)."""
    groups = tuple(g for g in GROUPS if g in groups)
    if not groups:
        raise ValueError("nothing to identify")
    scale = float(scale if scale is not None else np.ptp(nominal.base, axis=0).max())
    geometry = nominal.copy()
    theta = _vector(geometry, groups)
    r, J = _residuals_jacobian(geometry, meas, groups)
    cost = np.einsum("nm,nm->n", r, r)
    converged, iterations = False, 0
    for iterations in range(1, MAX_ITERATIONS + 1):
        step = _step(J, r)
        predicted = np.einsum("nmk,nk->nm", J, step)        # J d: the step's change of the residuals
        in_se = np.einsum("nm,nm->n", predicted, predicted) * max(len(meas) - J.shape[2], 1)
        if float(np.abs(step).max()) <= STEP_RTOL * scale or np.all(in_se <= STEP_SE_SHARE ** 2 * cost):
            converged = True
            break
        trial_theta = theta + step
        allowed = cost + _cost_roundoff(r, meas, scale)
        for _ in range(MAX_HALVINGS):
            r_trial = leg_residuals(_with_vector(geometry, trial_theta, groups), meas).T
            worse = ~(np.einsum("nm,nm->n", r_trial, r_trial) <= allowed)
            if not worse.any():
                break
            step[worse] *= 0.5               # only the legs whose sum of squares rose
            trial_theta[worse] = theta[worse] + step[worse]
        else:
            break                            # no descent left along the Gauss-Newton direction
        theta = trial_theta
        geometry = _with_vector(geometry, theta, groups)
        r, J = _residuals_jacobian(geometry, meas, groups)
        cost = np.einsum("nm,nm->n", r, r)
    return _statistics(nominal, geometry, r, J, groups, scale, iterations, converged)


def _statistics(nominal, geometry, r, J, groups, scale, iterations, converged) -> Identification:
    n, m, k = J.shape
    s, V = _spectrum(J)
    dof = m - k
    resid_std = np.sqrt(np.einsum("nm,nm->n", r, r) / dof) if dof > 0 else np.full(n, math.nan)
    s_max = float(s.max())
    seen = _seen(s)
    inv2 = np.where(seen, 1.0 / np.where(seen, s, 1.0) ** 2, math.inf)
    # the diagonal of the covariance s_i^2 V diag(1/sigma^2) V^T (inf along a direction not seen)
    with np.errstate(invalid="ignore"):
        var = resid_std[:, None] ** 2 * np.einsum("njk,nk->nj", V ** 2, inv2)
    se = np.sqrt(np.where(np.isnan(var), math.inf, var))
    labels = parameter_labels(geometry.dim, groups)
    theta0, theta = _vector(nominal, groups), _vector(geometry, groups)
    params = [Parameter(i + 1, g, a, float(theta0[i, c]), float(theta[i, c]), float(se[i, c]))
              for i in range(n) for c, (g, a) in enumerate(labels)]
    s_min = float(s.min())
    cond = s_max / s_min if s_min > 0 else math.inf
    unident, weak = [], []
    for i in range(n):
        for c in range(k):
            sigma = float(s[i, c])
            dir_se = resid_std[i] / sigma if seen[i, c] else math.inf
            if not seen[i, c] or dir_se > UNIDENTIFIABLE_SE_SHARE * scale:
                unident.append(_direction(i, V[i, :, c], labels, sigma, dir_se, geometry.dim))
            elif dir_se > WEAK_SE_SHARE * scale:
                weak.append(_direction(i, V[i, :, c], labels, sigma, dir_se, geometry.dim))
    return Identification(geometry, params, resid_std, cond, unident, weak, iterations, converged)


def _direction(i, v, labels, sigma, se, dim) -> Direction:
    """Name direction ``v`` (unit vector over leg i's parameters ``labels``) in words."""
    v = v if v[int(np.argmax(np.abs(v)))] > 0 else -v
    comps = {("offset" if g == "offsets" else f"{g} {a}"): float(x) for (g, a), x in zip(labels, v)}
    big = [(g, a, x) for (g, a), x in zip(labels, v) if abs(x) >= NAMED_COMPONENT]
    leg = i + 1
    words = []
    for g, a, x in big:
        words.append(f"the offset of leg {leg}" if g == "offsets" else f"the {a} of its {g} joint")
    if words and words[0].startswith("the ") and "offset" not in words[0]:
        words[0] = words[0].replace("its", f"leg {leg}'s", 1)
    involved = {g for g, _, _ in big}
    if len(words) == 1:
        what = f"{words[0]} is not seen"
    else:
        what = ", ".join(words[:-1]) + f" and {words[-1]} move together"
    if {"base", "platform"} <= involved and "offsets" not in involved:
        advice = "add poses that rotate the platform"
    elif "offsets" in involved:
        advice = ("add poses that tilt the platform and move it sideways (leg "
                  f"{leg} must change direction)" if dim == 3 else
                  f"add poses that move and rotate the platform so that leg {leg} changes direction")
    else:
        advice = "add poses spread wider over the workspace"
    return Direction(leg, comps, sigma, se, f"{what}: {advice}")
