"""Kinematic calibration of a parallel manipulator from externally measured poses: the geometry
(base joints A_i, platform joints B_i, leg-sensor offsets o_i; for an actuated family the legs'
origins, cranks or rail directions, rods, platform joints and actuator offsets) by nonlinear least
squares on the inverse-kinematic leg residuals, with standard errors and an identifiability analysis.

**Model** (Zhuang, Yan & Masory 1998, "inverse kinematic residuals"; Wampler, Hollerbach & Arai 1995).
Measurement ``j`` is the n sensor readings ``q_ij`` and the platform pose ``(p_j, R_j)`` measured in the
base frame by an external instrument (laser tracker, motion capture).  Every leg is the one leg model of
:mod:`glpma_ros.models.legs`, a rod between the point ``P_i`` its actuator moves and its platform joint
``B_i``, so a rigid geometry's leg residual is

    r_ij = |p_j + R_j B_i - P_i(q_ij + o_i)| - rod_i,

``P_i = A_i`` and ``rod_i = q_ij + o_i`` for a length leg (3-RPR, Gough-Stewart: ``|p_j + R_j B_i - A_i| -
(l_ij + o_i)``), ``P_i = origin_i + Rot(axis_i, q + o_i) crank_i`` for a revolute actuator,
``origin_i + (q + o_i) axis_i`` for a prismatic one (:func:`residuals_jacobian`).  The analytic
Jacobian, with ``u_ij`` the unit vector of the leg: ``dr/dA_i = dr/dorigin_i = -u_ij``, ``dr/dB_i = R_j^T
u_ij``, ``dr/drod_i = -1``, ``dr/dcrank_i = -Rot^T u_ij``, ``dr/daxis_i = -(q + o)(I - a a^T) u_ij`` (a unit
vector), ``dr/do_i = -1`` (length) or ``-u_ij . dP_i/dq``.  Its columns are made commensurate by weights
(:func:`parameter_weights`): every parameter is a length in the config's unit but a revolute offset
(radians: times the crank's radius, the arc its tip moves) and a rail direction (times the carriage's RMS
travel), so singular values, standard errors along directions and the thresholds below are in lengths;
parameters and their standard errors are reported in their own units.  Leg i's parameters appear in leg
i's residuals only: the Jacobian is block-diagonal, one (m x k) block per leg (k = 2d + 1 parameters in d
dimensions for a length leg, 3d + 2 for an actuated one), and with the poses taken as given the problem
separates into n independent small problems, solved here all at once (NumPy, vectorised over legs and
measurements) by Gauss-Newton with step halving (Bjorck 1996, section 9.2), each step the
pseudo-inverse solution from the eigen-decomposition of the leg's k x k normal matrix.  The base frame is
the one the instrument measures in and the platform frame the one its pose refers to, so a length leg
has no gauge freedom: every parameter is identifiable from poses that move and rotate enough.

**Gauges** of the leg model (:func:`gauge_vectors`): an actuated leg has directions of parameter space
that change no residual at any pose -- a crank turned about its axis against its offset, origin and
crank moved oppositely along the axis (in space), a rail's origin moved along the rail against its offset,
and for a platform that only translates (Delta: ``R_j = I``) the origin and the platform joint moved
together (only ``B_i - origin_i`` is seen).  No data separate them: they are taken out of each leg's
block (the normal matrix restricted to their orthogonal complement), left at nominal like the
rank-deficient directions below, and reported apart, in words (not warnings: ``--strict`` does not
refuse them); a parameter's share in them counts in its share left at nominal.

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
and V from the eigen-decomposition of ``J_i^T J_i``), gives the directions in parameter space (columns
of V) and how well the data see them: the standard error along direction v_k is ``s_i / sigma_k``.
A direction is

- *rank-deficient* when sigma_k is at round-off relative to the largest singular value (a parameter
  with no effect, poses that never turn the platform): the data do not see it at all;
- *unidentifiable from these data* when its standard error exceeds :data:`UNIDENTIFIABLE_SE_SHARE` of
  the geometry's size, the size of the joint and offset errors a calibration corrects;
- *weak* when its standard error exceeds :data:`WEAK_SE_SHARE` of the size (estimated, reported).

Each is named in words from its largest components (e.g. the offset of a leg and the coordinate of its
base joint along the leg move together when the leg never changes direction), with the kind of pose
that would separate them.

**What is estimated: the truncated SVD** (Hansen 1998, the truncated SVD of a rank-deficient
least-squares problem; in kinematic calibration Hollerbach & Wampler 1996 identify through the SVD
of the identification Jacobian and remove the parameter combinations it shows unidentifiable).
Rank-deficient and unidentifiable directions are not estimated: every Gauss-Newton step is the
minimum-norm least-squares step over the other directions, ``d = -sum_{k kept} v_k v_k^T J^T r /
sigma_k^2``, so the identification moves only along directions the data determine and leaves the
geometry at nominal along the rest.  The threshold is the bias-variance balance of a truncated
estimate: a direction estimated from the data carries its standard error ``se_k``, one left at nominal
carries the geometry's error along it, ``|v_k . (theta_true - theta_nominal)|``, of the order of the
errors calibrated; estimating is the better choice when ``se_k`` is below that size,
:data:`UNIDENTIFIABLE_SE_SHARE` of the scale (a millimetre on a metre-sized hexapod).  A direction
left at nominal costs little inside the range the data cover, by construction: the leg residual it
leaves is sigma_k times the error along it, which is what makes it unidentifiable.  The noise ``s_i``
behind ``se_k`` is that of the current residuals (the nominal geometry's in the first step, so more
directions are left out of the first step than of the last), and a direction once estimated stays
estimated: every direction reported as left at nominal was left out of every step.  The parameters'
standard errors are those of their estimated part (the covariance over the kept directions); each
parameter's share in the directions left at nominal, ``sum_{k left} v_kj^2`` (0: fully identified,
1: fully at nominal), says how much of it is nominal.  Not modelled: the geometry's error along the
directions left at nominal also reaches the estimated ones through the residuals' curvature (of order
error^2 / leg length), a bias that matters on a small manipulator (the errors over their standard
errors in simulated campaigns: BENCHMARKS.md, "Design measurements").

**Observability** of the campaign (the indices compared by Sun & Hollerbach 2008): the singular
values of the whole (block-diagonal) identification Jacobian per pose, ``sigma_k / sqrt(m)`` -- the
leg residual RMS a unit move along direction k causes over the m measurements, dimensionless because
every parameter is a length (the columns are commensurate and need no further scaling) and
independent of how many poses were taken.  Reported: O1 = ``(prod sigma_k)^(1/L) / sqrt(m)`` over the
L parameters (Borm & Menq 1991; near 0 when a direction is rank-deficient), O3 = ``min sigma_k /
sqrt(m)`` (the minimum singular value, Nahvi, Hollerbach & Hayward 1994: the worst direction, whose
standard error is the noise over ``sqrt(m)`` O3), and the condition number ``max sigma / min sigma``
(Driels & Pathre 1990; O2).

References: H. Zhuang, J. Yan, O. Masory, *Calibration of Stewart platforms and other parallel
manipulators by minimizing inverse kinematic residuals*, J. Robotic Systems 15(7), 1998; C. W. Wampler,
J. M. Hollerbach, T. Arai, *An implicit loop method for kinematic calibration and its application to
closed-chain mechanisms*, IEEE Trans. Robotics and Automation 11(5), 1995; J. M. Hollerbach, C. W.
Wampler, *The calibration index and taxonomy for robot kinematic calibration methods*, IJRR 15(6), 1996;
G. A. F. Seber, C. J. Wild, *Nonlinear Regression*, Wiley 1989; A. Bjorck, *Numerical Methods for Least
Squares Problems*, SIAM 1996; P. C. Hansen, *Rank-Deficient and Discrete Ill-Posed Problems*, SIAM 1998;
J.-H. Borm, C.-H. Menq, *Determination of optimal measurement configurations for robot calibration based
on observability measure*, IJRR 10(1), 1991; A. Nahvi, J. M. Hollerbach, V. Hayward, *Calibration of a
parallel robot using multiple kinematic closed loops*, ICRA 1994; M. R. Driels, U. S. Pathre,
*Significance of observation strategy on the design of robot calibration experiments*, J. Robotic
Systems 7(2), 1990; Y. Sun, J. M. Hollerbach, *Observability index selection for robot calibration*,
ICRA 2008.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..models.legs import LENGTH, PRISMATIC, REVOLUTE
from .parameters import (
    Geometry,
    Identification,
    Measurements,
    Observability,
    Parameter,
    describe_direction,
    gauge_direction,
    kind_groups,
)

#: parameter groups of every leg kind, in the order of the Jacobian's columns (a leg of a kind has
#: :func:`~.parameters.kind_groups` of them: base platform offsets for length legs; origin, crank or
#: axis, rod, platform, offsets for actuated ones)
GROUPS = ("base", "origin", "crank", "axis", "rod", "platform", "offsets")
#: the Geometry field each group is
FIELD = {"base": "base", "origin": "base", "crank": "crank", "axis": "axis", "rod": "rods", "platform": "platform",
         "offsets": "offsets"}
#: groups of one parameter per leg (the others: one per coordinate)
SCALAR_GROUPS = ("rod", "offsets")
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
#: a direction whose standard error exceeds this share of the geometry's scale is unidentifiable from
#: the data and left at nominal (truncated SVD): 0.1 %, about the size of the joint and offset errors a
#: calibration corrects (a millimetre on a metre-sized hexapod), the error along the direction that
#: leaving it at nominal keeps: estimating it would add more error than it removes
UNIDENTIFIABLE_SE_SHARE = 1e-3
#: a direction whose standard error exceeds this share of the scale is reported as weakly identified
WEAK_SE_SHARE = 1e-4
#: joints closer than this share of the scale in the nominal geometry are one physical joint that
#: their legs share (6-3, 3-6, 3-3 designs), identified once (the config's own coincidence rule)
COINCIDENT_RTOL = 1e-9

#: gauge vectors shorter than this share of the longest are linearly dependent on the others (their
#: singular values are exact to round-off: 1e-9 is far above it and far below any real direction's)
GAUGE_RTOL = 1e-9


def _perp(v: np.ndarray) -> np.ndarray:
    """A planar vector (axis 1 of length 2) turned a quarter turn about +z."""
    return np.stack((-v[:, 1], v[:, 0]), axis=1)


def _proximal(geometry: Geometry, meas: Measurements):
    """The leg model at every measurement: proximal points P (m, d, n), their derivative dP/dq (m, d, n;
    None for length legs), the rods' lengths (m, n) or (1, n) and the actuator positions q = reading +
    offset (m, n)."""
    q = meas.legs + geometry.offsets
    m, d = q.shape[0], geometry.dim
    origin = geometry.base.T[None]
    if geometry.kind == LENGTH:
        return np.broadcast_to(origin, (m, d, geometry.n_legs)), None, q, q
    rods = geometry.rods[None]
    if geometry.kind == PRISMATIC:
        a = geometry.axis.T[None]
        return origin + q[:, None, :] * a, np.broadcast_to(a, (m, d, geometry.n_legs)), rods, q
    c = geometry.crank.T[None]
    cos, sin = np.cos(q)[:, None, :], np.sin(q)[:, None, :]
    if d == 2:                                                  # planar: about +z
        turned = c * cos + _perp(c) * sin
        return origin + turned, _perp(turned), rods, q
    a = geometry.axis.T[None]                                   # Rodrigues' formula
    turned = c * cos + np.cross(a, c, axis=1) * sin + a * (a * c).sum(axis=1, keepdims=True) * (1.0 - cos)
    return origin + turned, np.cross(a, turned, axis=1), rods, q


def leg_residuals(geometry: Geometry, meas: Measurements) -> np.ndarray:
    """r_ij = |p_j + R_j B_i - P_i(q_ij + o_i)| - rod_i, shape (m, n) (length legs: P_i = A_i and
    rod_i = q_ij + o_i, i.e. ``|p_j + R_j B_i - A_i| - (l_ij + o_i)``)."""
    P, _, rods, _ = _proximal(geometry, meas)
    e = _leg_vectors(geometry, meas, P)
    return np.sqrt((e * e).sum(axis=1)) - rods


def _leg_vectors(geometry: Geometry, meas: Measurements, P: np.ndarray) -> np.ndarray:
    """e_ij = p_j + R_j B_i - P_ij, laid out (m, d, n)."""
    return meas.position[:, :, None] + meas.rotation @ geometry.platform.T - P


def _width(group: str, dim: int) -> int:
    return 1 if group in SCALAR_GROUPS else dim


def parameter_labels(dim: int, groups) -> list:
    """(group, axis) of a leg's identified parameters, the Jacobian's column order."""
    out = []
    for g in GROUPS:
        if g in groups:
            out += [(g, "")] if g in SCALAR_GROUPS else [(g, AXES[a]) for a in range(dim)]
    return out


def quantity(geometry: Geometry, group: str) -> str:
    """What a parameter of ``group`` measures: "angle" (radians), "direction" (a unit vector's component)
    or "length" (config unit)."""
    if group == "offsets" and geometry.kind == REVOLUTE:
        return "angle"
    return "direction" if group == "axis" else "length"


@dataclass
class Layout:
    """The distinct parameters: a joint that several legs share (6-3, 3-6, 3-3 designs: joints that
    coincide in the nominal geometry) is one physical joint, identified once.  ``labels``: (legs,
    group, axis) of each distinct parameter; ``index`` (n, k): leg i's local parameter c is distinct
    parameter ``index[i, c]``; ``component`` (p,): the group of legs tied by shared joints that each
    distinct parameter belongs to (legs that share nothing are their own component: the problem
    separates by component)."""

    labels: list
    index: np.ndarray
    component: np.ndarray

    @property
    def size(self) -> int:
        return len(self.labels)


def _joint_ids(points: np.ndarray, scale: float) -> np.ndarray:
    """For each joint, the first joint it coincides with (itself when none)."""
    ids = np.arange(len(points))
    for i in range(len(points)):
        for j in range(i):
            if ids[j] == j and np.linalg.norm(points[i] - points[j]) <= COINCIDENT_RTOL * scale:
                ids[i] = j
                break
    return ids


def layout(nominal: Geometry, groups, scale: float) -> Layout:
    n, d = nominal.base.shape
    labels, columns = [], []
    for g in GROUPS:
        if g not in groups:
            continue
        joint = g in ("base", "origin", "platform")             # a point that legs may share
        ids = _joint_ids(getattr(nominal, FIELD[g]), scale) if joint else np.arange(n)
        axes = ("",) if g in SCALAR_GROUPS else AXES[:d]
        cols = np.empty((n, len(axes)), dtype=int)
        for j in dict.fromkeys(ids.tolist()):                  # in the order of first appearance
            legs = tuple(int(i) + 1 for i in np.flatnonzero(ids == j))
            for a, axis in enumerate(axes):
                cols[ids == j, a] = len(labels)
                labels.append((legs, g, axis))
        columns.append(cols)
    parent = list(range(n))                                     # union-find of legs sharing a joint

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i
    for legs, _, _ in labels:
        for leg in legs[1:]:
            parent[root(leg - 1)] = root(legs[0] - 1)
    component = np.array([root(legs[0] - 1) for legs, _, _ in labels])
    return Layout(labels, np.concatenate(columns, axis=1), component)


def residuals_jacobian(geometry: Geometry, meas: Measurements, groups, weights: np.ndarray):
    """Residuals (n, m) and the per-leg Jacobian blocks (n, m, k) of the identified groups, each column
    divided by its weight (n, k): the derivative by the parameter in length units (:func:`parameter_weights`).

    With ``u_ij`` the unit vector of e_ij = p_j + R_j B_i - P_ij: dr/dA_i = dr/dorigin_i = -u_ij,
    dr/dB_i = R_j^T u_ij, dr/drod_i = -1; dr/dcrank_i = -Rot(axis_i, q_ij)^T u_ij; dr/daxis_i =
    -q_ij (I - a_i a_i^T) u_ij (a unit vector: its length is no parameter); dr/do_i = -1 for a length leg,
    -u_ij . dP_i/dq otherwise (revolute: dP/dq = axis x Rot crank; prismatic: the axis)."""
    P, dP, rods, q = _proximal(geometry, meas)
    e = _leg_vectors(geometry, meas, P)
    dist = np.sqrt((e * e).sum(axis=1))                                 # (m, n)
    u = e / dist[:, None, :]
    r = (dist - rods).T
    minus_one = -np.ones((u.shape[0], 1, u.shape[2]))
    blocks = []
    for g in GROUPS:
        if g not in groups:
            continue
        if g in ("base", "origin"):
            blocks.append(-u)
        elif g == "crank":
            cos, sin = np.cos(q)[:, None, :], np.sin(q)[:, None, :]
            if geometry.dim == 2:
                blocks.append(-(u * cos - _perp(u) * sin))              # Rot(-q) u
            else:
                a = geometry.axis.T[None]
                blocks.append(-(u * cos - np.cross(a, u, axis=1) * sin
                                + a * (a * u).sum(axis=1, keepdims=True) * (1.0 - cos)))
        elif g == "axis":
            a = geometry.axis.T[None]
            blocks.append(-q[:, None, :] * (u - a * (a * u).sum(axis=1, keepdims=True)))
        elif g == "rod":
            blocks.append(minus_one)
        elif g == "platform":
            blocks.append(meas.rotation.transpose(0, 2, 1) @ u)
        elif dP is None:                                                # a length leg's offset
            blocks.append(minus_one)
        else:
            blocks.append(-(u * dP).sum(axis=1, keepdims=True))
    J = np.concatenate(blocks, axis=1).transpose(2, 0, 1) / weights[:, None, :]
    return r, np.ascontiguousarray(J)


def parameter_weights(nominal: Geometry, meas: Measurements, groups) -> np.ndarray:
    """Each leg's parameter weights (n, k): the length a unit of the parameter moves the leg's proximal
    point by, so that every weighted parameter is a length in the config unit and the Jacobian's columns
    are commensurate (lengths: 1; a revolute offset: the crank's radius |crank_perp|, the arc its tip
    moves per radian; a rail's direction: the RMS of the carriage's position q + o over the measurements,
    how far a change of the direction moves the carriage)."""
    n, d = nominal.base.shape
    cols = []
    for g in GROUPS:
        if g not in groups:
            continue
        w = np.ones((n, _width(g, d)))
        if g == "offsets" and nominal.kind == REVOLUTE:
            c = nominal.crank
            along = 0.0 if d == 2 else (c * nominal.axis).sum(axis=1, keepdims=True) * nominal.axis
            w[:, 0] = np.linalg.norm(c - along, axis=1)
        elif g == "axis":
            w *= np.sqrt(np.mean((meas.legs + nominal.offsets) ** 2, axis=0))[:, None]
        cols.append(w)
    return np.concatenate(cols, axis=1)


def gauge_vectors(geometry: Geometry, groups) -> list:
    """Per leg, the gauge directions of the leg model among the identified ``groups``: changes of the
    leg's parameters (natural units, the Jacobian's column order) that change no residual at any pose,
    as (name, axis word, vector); the name is a key of :data:`~.parameters.GAUGE_TEXT`, or "unit_axis" (a
    rail direction's length, no parameter).

    * a revolute leg: its crank turned about the axis against its offset (``dcrank = axis x crank``,
      ``do = -1``); in space, origin and crank moved oppositely along the axis;
    * a prismatic leg: its origin moved along the rail against its offset (``dorigin = axis``,
      ``do = -1``); the rail direction's length (``daxis = axis``);
    * a platform that only translates: the origin (or base joint) and the platform joint moved together."""
    labels = parameter_labels(geometry.dim, groups)
    col = {lab: c for c, lab in enumerate(labels)}
    d, has = geometry.dim, set(groups)
    proximal = "origin" if geometry.actuated else "base"
    out = []

    def vector(parts):
        v = np.zeros(len(labels))
        for key, value in parts.items():
            v[col[key]] = value
        return v
    for i in range(geometry.n_legs):
        found = []

        def add(name, axis, parts, found=found):
            found.append((name, axis, vector(parts)))
        if geometry.translation and {proximal, "platform"} <= has:
            for a in AXES[:d]:
                add("translation", a, {(proximal, a): 1.0, ("platform", a): 1.0})
        if geometry.kind == REVOLUTE:
            c = geometry.crank[i]
            if {"crank", "offsets"} <= has:
                turn = np.array([-c[1], c[0]]) if d == 2 else np.cross(geometry.axis[i], c)
                add("crank_turn", "", {**{("crank", a): t for a, t in zip(AXES, turn)}, ("offsets", ""): -1.0})
            if d == 3 and {"origin", "crank"} <= has:
                a_i = geometry.axis[i]
                add("crank_along_axis", "", {**{("origin", a): t for a, t in zip(AXES, a_i)},
                                             **{("crank", a): -t for a, t in zip(AXES, a_i)}})
        if geometry.kind == PRISMATIC:
            a_i = geometry.axis[i]
            if {"origin", "offsets"} <= has:
                add("rail_origin", "", {**{("origin", a): t for a, t in zip(AXES, a_i)}, ("offsets", ""): -1.0})
            if "axis" in has:
                add("unit_axis", "", {("axis", a): t for a, t in zip(AXES, a_i)})
        out.append(found)
    return out


def _gauge_basis(geometry: Geometry, groups, lay: Layout, weights: np.ndarray) -> tuple:
    """The gauge directions in the weighted distinct parameters: (their unit vectors as columns (p, g), the
    (leg, name, axis, unit vector) of each).  A gauge that moves a joint several legs share is none (the
    other legs see it) and is dropped."""
    p = lay.size
    shared = np.array([len(legs) > 1 for legs, _, _ in lay.labels])
    vectors, named = [], []
    for i, found in enumerate(gauge_vectors(geometry, groups)):
        for name, axis, v in found:
            full = np.zeros(p)
            full[lay.index[i]] = v * weights[i]
            if np.any(shared[full != 0.0]):
                continue
            full /= np.linalg.norm(full)
            vectors.append(full)
            named.append((i + 1, name, axis, full))
    return (np.array(vectors).T if vectors else np.zeros((p, 0))), named


def parameter_vector(geometry: Geometry, groups) -> np.ndarray:
    """Each leg's identified parameters, (n, k)."""
    parts = [getattr(geometry, FIELD[g]) for g in GROUPS if g in groups]
    return np.concatenate([p if p.ndim == 2 else p[:, None] for p in parts], axis=1)


def with_parameters(geometry: Geometry, theta: np.ndarray, groups) -> Geometry:
    """``geometry`` with the identified parameters ``theta`` (n, k); a rail direction normalised."""
    g = geometry.copy()
    d, col = g.dim, 0
    for group in GROUPS:
        if group not in groups:
            continue
        w = _width(group, d)
        value = theta[:, col:col + w].copy()
        if group == "axis":
            value /= np.linalg.norm(value, axis=1, keepdims=True)
        setattr(g, FIELD[group], value[:, 0] if group in SCALAR_GROUPS else value)
        col += w
    return g


def _assemble(blocks: np.ndarray, index: np.ndarray, p: int) -> np.ndarray:
    """``sum_i P_i^T blocks_i P_i`` of per-leg matrices (n, k, k) -> (p, p), or vectors (n, k) -> (p,),
    where ``P_i`` places leg i's local parameters at ``index[i]``."""
    if blocks.ndim == 3:
        out = np.zeros(p * p)
        np.add.at(out, (index[:, :, None] * p + index[:, None, :]).ravel(), blocks.ravel())
        return out.reshape(p, p)
    out = np.zeros(p)
    np.add.at(out, index.ravel(), blocks.ravel())
    return out


def _spectra(N: np.ndarray, lay: Layout, gauge: np.ndarray) -> list:
    """(parameters, singular values ascending, right singular vectors as columns, gauge basis) of each
    component's block of J, over the complement of the gauge directions (``gauge``: unit columns, the
    model's own null space, left at nominal and reported apart): from the eigen-decomposition of the
    normal matrix restricted to that complement (small: k parameters per leg), so that a direction never
    mixes legs that share nothing."""
    out = []
    for c in dict.fromkeys(lay.component.tolist()):
        sub = np.flatnonzero(lay.component == c)
        vectors = gauge[sub][:, np.any(gauge[sub] != 0.0, axis=0)]
        Nc = N[np.ix_(sub, sub)]
        G = vectors
        if vectors.shape[1]:
            U, sv, _ = np.linalg.svd(vectors, full_matrices=True)
            rank = int(np.sum(sv > GAUGE_RTOL * sv[0]))
            G, Q = U[:, :rank], U[:, rank:]              # the gauges' span (orthonormal) and its complement
            lam, W = np.linalg.eigh(Q.T @ Nc @ Q)
            V = Q @ W
        else:
            lam, V = np.linalg.eigh(Nc)
        out.append((sub, np.sqrt(np.maximum(lam, 0.0)), V, G))
    return out


def _kept(spectra: list, M: np.ndarray, s_max: float, se_limit: float, cap=None) -> list:
    """Per component: (standard error of each direction, which directions are estimated).  A direction
    is left at nominal when its singular value is at round-off (``RANK_RTOL s_max``; its standard
    error is then inf) or its standard error ``sqrt(v^T M v) / sigma^2`` exceeds ``se_limit``; at most
    ``cap[c]`` directions of component c are left (the largest standard errors first), never fewer than
    those at round-off."""
    out = []
    for c, (sub, s, V, _) in enumerate(spectra):
        seen = s > RANK_RTOL * s_max
        se = np.full(len(s), math.inf)
        Vs = V[:, seen]
        se[seen] = np.sqrt(np.maximum(np.einsum("ik,ij,jk->k", Vs, M[np.ix_(sub, sub)], Vs), 0.0)) / s[seen] ** 2
        left = int(np.sum(se > se_limit))
        if cap is not None:
            left = min(left, cap[c])
        left = max(left, int(np.sum(~seen)))
        kept = np.ones(len(s), dtype=bool)
        kept[np.argsort(-se, kind="stable")[:left]] = False
        out.append((se, kept))
    return out


def _pinv(spectra: list, p: int, kept: list) -> np.ndarray:
    """N^+ over the kept directions: ``sum_k v_k v_k^T / sigma_k^2`` (the truncated SVD's)."""
    out = np.zeros((p, p))
    for (sub, s, V, _), (_, keep) in zip(spectra, kept):
        out[np.ix_(sub, sub)] = (V[:, keep] / s[keep] ** 2) @ V[:, keep].T
    return out


def _cost_roundoff(r: np.ndarray, meas: Measurements, geometry: Geometry, scale: float) -> np.ndarray:
    """How much each leg's sum of squares may rise by round-off alone, (n,): a residual is the
    difference of two lengths of the order of the leg (|e_ij| and the rod, l_ij + o_i for a length leg),
    exact to ``d_ij = ROUNDOFF_ULPS eps (rod_ij + scale)``, so its square moves by up to
    ``2 |r_ij| d_ij + d_ij^2`` (far above the sum's own rounding when the residuals are small beside the legs)."""
    rods = meas.legs.T if geometry.kind == LENGTH else geometry.rods[:, None]
    d = ROUNDOFF_ULPS * EPS * (np.abs(rods) + scale)
    return np.einsum("nm,nm->n", 2.0 * np.abs(r) + d, d)


def _normal(J: np.ndarray, r: np.ndarray, lay: Layout):
    """Each leg's J_i^T J_i (n, k, k), the normal matrix J^T J (p, p) and the gradient J^T r (p,) of the
    distinct parameters."""
    JtJ = J.transpose(0, 2, 1) @ J
    return (JtJ, _assemble(JtJ, lay.index, lay.size),
            _assemble(np.einsum("nmk,nm->nk", J, r), lay.index, lay.size))


def _leg_dof(m: int, k: int, lay: Layout, gauge: np.ndarray) -> np.ndarray:
    """Each leg's residual degrees of freedom: measurements less the parameters the data can see (its
    k parameters less its gauge directions)."""
    g = np.array([np.linalg.matrix_rank(gauge[lay.index[i]]) if gauge.shape[1] else 0
                  for i in range(lay.index.shape[0])])
    return m - (k - g)


def identify(nominal: Geometry, meas: Measurements, groups=None, scale: float | None = None) -> Identification:
    """Least-squares geometry from ``meas``, starting from ``nominal``; only ``groups`` (a subset of
    :data:`GROUPS`; default: every group of the legs' kind) are estimated, the others stay as in
    ``nominal``; joints that coincide in ``nominal`` stay one joint; directions the data do not identify
    and the leg model's gauge directions stay at nominal (truncated SVD, see the module's docstring).
    ``scale``: the geometry's size (config unit) for the thresholds (default: the largest extent of the
    base joints)."""
    own = kind_groups(nominal.kind)
    groups = tuple(g for g in own if groups is None or g in groups)
    if not groups:
        raise ValueError("nothing to identify")
    scale = float(scale if scale is not None else np.ptp(nominal.base, axis=0).max())
    se_limit = UNIDENTIFIABLE_SE_SHARE * scale
    lay = layout(nominal, groups, scale)
    weights = parameter_weights(nominal, meas, groups)
    w = np.empty(lay.size)
    w[lay.index] = weights
    theta = np.empty(lay.size)
    theta[lay.index] = parameter_vector(nominal, groups)
    geometry = with_parameters(nominal, theta[lay.index], groups)
    leg_component = lay.component[lay.index[:, 0]]
    components = np.unique(lay.component)
    k = lay.index.shape[1]
    r, J = residuals_jacobian(geometry, meas, groups, weights)
    gauge, _ = _gauge_basis(geometry, groups, lay, weights)
    cost = np.einsum("nm,nm->n", r, r)
    dof = np.maximum(_leg_dof(len(meas), k, lay, gauge), 1)
    converged, iterations, left = False, 0, None
    for iterations in range(1, MAX_ITERATIONS + 1):  # noqa: B007 - the count is reported after the loop
        JtJ, N, G = _normal(J, r, lay)
        spectra = _spectra(N, lay, gauge)
        M = _assemble((cost / dof)[:, None, None] * JtJ, lay.index, lay.size)     # the current noise s_i^2
        kept = _kept(spectra, M, max(float(s.max()) for _, s, _, _ in spectra), se_limit, left)
        now = [int(np.sum(~keep)) for _, keep in kept]
        step = -_pinv(spectra, lay.size, kept) @ G          # Gauss-Newton, truncated: -(J^T J)_k^+ J^T r
        predicted = np.einsum("nmk,nk->nm", J, step[lay.index])     # J d: the step's change of the residuals
        in_se = np.einsum("nm,nm->n", predicted, predicted) * dof
        small = float(np.abs(step).max()) <= STEP_RTOL * scale or np.all(in_se <= STEP_SE_SHARE ** 2 * cost)
        if small and now == left:                           # and the same directions left at nominal
            converged = True
            break
        left = now
        allowed = cost + _cost_roundoff(r, meas, geometry, scale)
        allowed_c = np.array([allowed[leg_component == c].sum() for c in components])
        trial = theta + step / w                            # the step in the parameters' own units
        for _ in range(MAX_HALVINGS):
            r_trial = leg_residuals(with_parameters(geometry, trial[lay.index], groups), meas).T
            cost_leg = np.einsum("nm,nm->n", r_trial, r_trial)
            worse = components[~(np.array([cost_leg[leg_component == c].sum() for c in components]) <= allowed_c)]
            if not worse.size:
                break
            halve = np.isin(lay.component, worse)            # only where a component's sum of squares rose
            step[halve] *= 0.5
            trial[halve] = theta[halve] + step[halve] / w[halve]
        else:
            break                            # no descent left along the Gauss-Newton direction
        geometry = with_parameters(geometry, trial[lay.index], groups)
        theta[lay.index] = parameter_vector(geometry, groups)        # a rail direction back to unit length
        r, J = residuals_jacobian(geometry, meas, groups, weights)
        gauge, _ = _gauge_basis(geometry, groups, lay, weights)
        cost = np.einsum("nm,nm->n", r, r)
    return _statistics(nominal, geometry, theta, lay, r, J, groups, scale, iterations, converged, left, weights)


def _statistics(nominal, geometry, theta, lay, r, J, groups, scale, iterations, converged, left,
                weights) -> Identification:
    """Standard errors (sandwich ``N_k^+ M N_k^+`` over the kept directions, with ``M = sum_i s_i^2
    J_i^T J_i``: each leg with its own noise; for legs that share nothing and nothing left at nominal
    this is ``s_i^2 (J_i^T J_i)^-1``), the identifiability of every direction, the gauge directions, the
    observability.  Standard errors and parameters in their own units (a weighted one divided by its
    weight); directions in the weighted parameters (lengths)."""
    n, m, k = J.shape
    gauge, named_gauges = _gauge_basis(geometry, groups, lay, weights)
    dof = _leg_dof(m, k, lay, gauge)
    resid_std = np.where(dof > 0, np.sqrt(np.einsum("nm,nm->n", r, r) / np.maximum(dof, 1)), math.nan)
    JtJ, N, _ = _normal(J, r, lay)
    M = _assemble(resid_std[:, None, None] ** 2 * JtJ, lay.index, lay.size)
    spectra = _spectra(N, lay, gauge)
    s_all = np.sort(np.concatenate([s for _, s, _, _ in spectra]))
    s_max = float(s_all[-1])
    se_limit = UNIDENTIFIABLE_SE_SHARE * scale
    kept = _kept(spectra, M, s_max, se_limit, left)
    Np = _pinv(spectra, lay.size, kept)
    w = np.empty(lay.size)
    w[lay.index] = weights
    se = np.sqrt(np.maximum(np.diag(Np @ M @ Np), 0.0)) / w
    fixed_share = np.zeros(lay.size)
    for (sub, _, V, G), (_, keep) in zip(spectra, kept):
        fixed_share[sub] = np.sum(V[:, ~keep] ** 2, axis=1) + np.sum(G ** 2, axis=1)
    theta0 = np.empty(lay.size)
    theta0[lay.index] = parameter_vector(nominal, groups)
    params = [Parameter(legs, g, a, float(theta0[j]), float(theta[j]), float(se[j]), float(fixed_share[j]),
                        quantity(geometry, g))
              for j, (legs, g, a) in enumerate(lay.labels)]
    s_min = float(s_all[0])
    cond = s_max / s_min if s_min > 0 else math.inf
    per_pose = s_all / math.sqrt(m)
    o1 = float(np.exp(np.mean(np.log(per_pose)))) if per_pose[0] > 0 else 0.0
    unident, weak = [], []
    for (sub, s, V, _), (dir_se, keep) in zip(spectra, kept):
        for c in range(len(s)):
            if not keep[c] or dir_se[c] > WEAK_SE_SHARE * scale:
                d = describe_direction(V[:, c], [lay.labels[j] for j in sub], float(s[c]) / math.sqrt(m),
                                       float(dir_se[c]), geometry.dim, rank_deficient=not s[c] > RANK_RTOL * s_max)
                (weak if keep[c] else unident).append(d)
    gauges = []
    for leg, name, axis, v in named_gauges:
        if name == "unit_axis":                 # a unit vector's length: no parameter, nothing to report
            continue
        components = {Parameter(lay.labels[j][0], lay.labels[j][1], lay.labels[j][2], 0.0, 0.0, 0.0).name:
                      float(v[j]) for j in np.flatnonzero(v)}
        gauges.append(gauge_direction(name, leg, axis, components))
    result = Identification(geometry, params, resid_std, cond, unident, weak, iterations, converged,
                            Observability(per_pose, o1, float(per_pose[0]), cond), se_limit)
    result.gauges = gauges
    return result
