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
    (see :mod:`glpma_ros.modes.exact`), in the affine patch ``l.e = 1`` of a random complex form ``l``: ``e_0``
    is eliminated with it, 7 unknowns and 7 quadrics.  A generic member has 40 solutions.  The patch only
    involves ``e``: the component ``e = 0, f.f = 0`` of solutions at infinity of the homogeneous system
    (every leg quadric vanishes there) is outside it; a complex ``l`` leaves out a real rotation only on a
    curve of SO(3) (``Re l . e = Im l . e = 0``), not on a surface as a real patch would.

* **Start system** (offline, :func:`.monodromy.build_start_system`, shipped as package data under
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
  at ``STEP_TARGET``, not longer than the last one right after a failed correction), compiled
  (:func:`.path_tracker.track_paths`; complex LU with partial pivoting); the paths are independent and split
  over threads (:func:`.path_tracker.track`).  At ``t = 1`` Newton's method polishes the endpoint.  The system
  along the path is evaluated by the family's own evaluator from the
  parameters interpolated at ``tau`` (residual, Jacobian and ``dF/dtau`` written out); a family without one by
  its quadrics, whose coefficients along the path are a quadratic polynomial in ``tau`` (they are of degree two
  in ``p``), interpolated exactly from three evaluations.

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
keeps the real modes that the least-squares polish with every leg leaves consistent.  The parts: the families' systems
(:mod:`.homotopy_families`), the compiled tracker (:mod:`.path_tracker`), the start systems (:mod:`.monodromy`);
this module tracks them to a target and certifies the answer.  No ROS import.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import GlpmaError
from .exact import has_coincident_joints
from .monodromy import family_of, load_start_system
from .path_tracker import (
    AT_INFINITY_REACHED,
    CAREFUL_SETTINGS,
    OUTCOMES,
    REGULAR,
    SAME_ENDPOINT,
    SETTINGS,
    SINGULAR,
    STEP_FAILED,
    STEPS_EXHAUSTED,
    distinct,
    random_gammas,
    track,
)

# -- classification --------------------------------------------------------------------------------------
#: an endpoint whose Jacobian's reciprocal condition number (smallest over largest singular value) is below
#: this is singular: Newton's method then leaves it about sqrt(round-off / rcond) away, too far to count it
REGULAR_RCOND = 1e-10
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
#: ... and a singular endpoint (accurate to about the square root of round-off only) below this share: the
#: singular endpoints of the seed 6-6 (a design with mirror-symmetric joint pairs, 28 finite poses) lie at
#: 1.6e-8 .. 2e-7, a real pose at 1 and a complex one generically at order one
SINGULAR_NULL_ROTATION = 1e-4
#: a path of the seed 6-6 that runs to the exceptional quadric has its step underflow at 1 - t = 1e-4 .. 5e-4
#: (the endpoint is singular and at |z| ~ 1e3), already within 1e-8 of the quadric: such a failure within this
#: share of the end of the path, that close to the quadric, is the path's end, not a lost pose (a regular
#: pose endpoint is approached analytically, at order one from the quadric)
EXCEPTIONAL_ZONE = 1e-2


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


def solve(model, legs, *, seed=0, retrack_rounds=RETRACK_ROUNDS, threads=None) -> HomotopyResult:
    """Every solution of ``model`` at ``legs`` (checked, config unit) by the parameter homotopy (module
    docstring).  Every regular endpoint of every round is a solution of the target, so the distinct ones
    are gathered over the rounds; a retrack round draws a new gamma and (6-6) a new random affine patch
    (a path that crosses the patch's hyperplane at infinity in one patch does not in another).  ``threads``: how many
    threads track a round's paths (:func:`.path_tracker.track`; default the cores this process may run on, one per
    8 paths at most); the answer does not depend on it."""
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
        path = family.parameter_path(start.params, target.params)
        ends, jac, outcome, steps, t_end = track(path, starts[pending], np.full(pending.size, gamma), settings,
                                                threads)
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
            path = family.parameter_path(start.params, target.params)
            starts, gammas = base_family.convert(start.solutions, family), np.full(n_paths, random_gammas(rng, 1)[0])
            ends, jac, outcome, steps, t_end = track(path, starts, gammas, SETTINGS, threads)
            total_steps += int(steps.sum())
            retracked += n_paths
            again = np.flatnonzero((outcome == STEP_FAILED) | (outcome == STEPS_EXHAUSTED))
            if again.size:              # the same paths, tracked carefully (as the second round above)
                ends[again], jac[again], outcome[again], steps, t_end[again] = track(
                    path, starts[again], gammas[again], CAREFUL_SETTINGS, threads)
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
