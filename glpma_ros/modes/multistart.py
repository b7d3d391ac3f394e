"""Every distinct real assembly mode of a manipulator for given leg lengths.

Four methods (``solve_all(model, legs, method=...)``):

``"homotopy"`` (default where the model's family has a start system: the 3-RPR and every hexapod with six
  legs, coincident joints included) -- the compiled parameter homotopy of :mod:`glpma_ros.modes.homotopy`:
  one path per complex solution of a generic member, tracked to the given legs.  ``complete`` is a
  certificate, not a probability: the distinct regular endpoints are as many as the family's (or the
  design's) root count, so every real mode is among them.  Its real endpoints are polished by the model's
  refinement and de-duplicated as below.  When the count falls short (paths failed twice, a double root at
  a singularity) the answer says so (``complete`` false, ``paths_failed``) and, when msolve is installed and
  the legs are not redundant, the exact method's modes replace it (``fallback``: ``"exact"``).  With
  redundant legs the homotopy solves the first ``n_pose`` legs and the least-squares polish with every leg
  keeps the consistent modes.

``"multistart"`` -- many cheap local solves from starts spread over the pose space.
  Each start is a pose drawn at random (seeded ``numpy.random.Generator``): an orientation
  uniform on SO(3) (a normalised 4-D Gaussian, i.e. a uniform unit quaternion; 3-RPR: an
  angle uniform on (-pi, pi]) and a platform centre uniform in the region the legs can reach,
  the intersection of the balls around the base joints ``A_i`` of radius
  ``L_i + |b_i - c|`` (``c`` the centroid of the platform joints ``b_i``; any assembly has its
  centre there, so an empty intersection proves there is none).  From each start one
  Levenberg-Marquardt solve in pose space (the compiled iteration of
  :mod:`glpma_ros.solvers.lm`) with an iteration cap ``LOCAL_MAX_ITER``: a start that has not
  converged by then is dropped.  A converged pose
  farther than ``DEDUP_RELATIVE`` of the scale from every mode found so far is a new mode.

  Stopping rule: after ``n`` starts of which the last new mode was found at start ``n_new``,
  stop once ``n - n_new >= max(STALL_MIN, STALL_FACTOR * n_new)`` -- the search has gone on at
  least ``STALL_FACTOR`` times as long as it took to find everything seen, and at least
  ``STALL_MIN`` starts, without finding anything new -- or at ``max_starts`` starts, or when
  ``budget_s`` runs out (checked between batches of ``BATCH`` starts).  The solves, the
  de-duplication and the stopping rule run compiled (:func:`_multistart_batch`), one call per
  batch; the starts are drawn in NumPy per batch.  Reported with the result:

  * ``miss_probability``: the Good-Turing estimate of the probability that one more start
    would find a mode not yet seen, ``n1 / n`` with ``n1`` the number of modes found by
    exactly one start (Good 1953, "The population frequencies of species and the estimation
    of population parameters", Biometrika 40);
  * ``unseen_share_bound``: a 95 % upper confidence bound on the total share of the starts
    that lead to modes not seen, from the final run of ``k`` starts that found nothing new:
    ``1 - 0.05 ** (1 / k)`` (about ``3 / k``, the "rule of three").

  Both are statements about the basins of this start distribution, not a proof: a mode whose
  basin is tiny can be missed.  On Dietmaier's 6-6 with 40 real modes (1998) the search stops with 36 to
  38 of them while the Good-Turing estimate reads 0 to 0.001: the missed modes' basins hold less than one
  start in a thousand, so no start-count statistic sees them.  So ``miss_probability`` is not reported
  (None): the Good-Turing figure is kept as ``good_turing`` under its own meaning, the chance that the
  next start finds a new mode.  Use ``"homotopy"`` or ``"exact"`` for a certificate.

  Partner search: real modes are born and die in pairs, at a fold of the forward kinematics
  where the leg Jacobian ``J`` turns singular (the real roots of a polynomial system with real
  coefficients meet and leave the real space as a complex-conjugate pair; e.g. Merlet,
  *Parallel Robots*, 2nd ed., 2006, section 4.5).  Near a fold the two modes of the pair lie on
  either side of the midpoint along the nearly-null direction of ``J`` (its right singular
  vector of the smallest singular value), and the one nearer the fold often has a basin too
  small for the random starts (the stopping rule then ends with one mode of the pair missing).  So,
  once the random starts stop, every mode whose reciprocal condition number is below
  ``PARTNER_CONDITIONING`` gets one local solve from each of ``PARTNER_STEPS`` (shares of the scale)
  both ways along that direction; a new mode found so gets its own partner search.  These starts are
  counted in ``partner_starts``, apart from the random ``starts`` that the estimates above are about.

  Parity rule: the forward kinematics is a polynomial system with real coefficients (3-RPR: a
  sextic, Gosselin, Sefrioui & Richard 1992; 6-6: 40 complex solutions, Husty 1996; 16 for the
  coincident-joint designs), whose non-real solutions come in conjugate pairs: with an even number
  of complex solutions the real ones are even in number, counted with multiplicity.  A mode is
  double when its conditioning, polished to round-off, is below ``DOUBLE_CONDITIONING``: two modes
  met at a singularity, found as one (a grid point exactly on a singularity curve has one, and
  whether the rounded legs give two real modes or a complex pair there is decided by round-off).
  Counting each double mode twice, an odd count therefore means a mode missed.  So when the search
  stalls with an odd count so counted, it goes on drawing random starts, without the stopping rule,
  until the count is even or ``PARITY_EXTENSION`` times the starts used so far (a design whose
  count is odd by nature, e.g. one with solutions at infinity, costs that much more and keeps its
  count).  Not
  with redundant legs (least-squares poses).  ``conditioning`` reports each mode's reciprocal
  condition number (of the polished mode for the candidates below ``DOUBLE_CANDIDATE``),
  ``double_modes`` how many are double.

``"g3pcx"`` -- the papers' method: ``runs`` independent polished G3-PCX searches from the wide
  initial range ``U[-2R, 2R]^n`` (Rolland & Chandra 2016, section 5.5.2 collect the 16 hexapod
  solutions with 100 runs from U[-2000, 2000]^9), de-duplicated the same way.

``"closed_form"`` -- a model's closed-form forward kinematics (the three-leg Delta's sphere intersection,
  :meth:`~glpma_ros.models.actuated.DeltaTranslation.closed_form`: two mirror modes), each polished; the
  default for such a model.

``"exact"`` -- the certified count (:mod:`glpma_ros.modes.exact`, msolve's real root isolation of
  the rational polynomial system; the optional ``exact`` extra): every real solution,
  polished, and the number of complex solutions.

Every mode returned is polished to round-off by the model's refinement
(:func:`glpma_ros.solvers.refine.polish`), unless the multistart is asked not to (``polish=False``:
the modes as found, for counting them, e.g. ``glpma-fk map``).  With redundant legs (more than the
degrees of freedom) a mode is a least-squares pose whose leg residuals pass the estimator's
consistency test (:func:`consistent_fitness`: chi-square against the leg noise ``leg_noise_std``, by
default the node's default); the exact
method refuses them.  Plain Python + NumPy: no ROS import.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from .. import solvers
from ..errors import GlpmaError
from ..estimation.redundancy import chi2_limit, leg_noise
from ..models.pose_kernels import joint_distance
from ..solvers import refine
from ..solvers.common import CONVERGED, SolveResult
from ..solvers.lm import I_LEG_FITNESS, I_NFEV, solve_one
from ..solvers.local import LocalSolver, make_settings

METHODS = ("homotopy", "multistart", "g3pcx", "exact", "closed_form")

#: two polished solutions closer than this share of the scale are the same mode
DEDUP_RELATIVE = 1e-4
#: half-width of the G3-PCX initial range in units of the geometry's size (longest leg or joint spread)
RANGE_FACTOR = 2.0
#: default number of G3-PCX runs (the papers' 100, doubled: one run misses a mode now and then)
G3PCX_RUNS = 200

#: multistart: Levenberg-Marquardt iterations allowed per start; converging starts need a
#: handful (quadratic convergence once near a mode), so a start still far off by then is dropped
LOCAL_MAX_ITER = 30
#: multistart: a local solve has converged when its leg residuals' root sum of squares is below
#: this share of the scale (the final polish takes every mode to round-off afterwards)
LOCAL_RESIDUAL_RELATIVE = 1e-9
#: multistart stopping rule: stop after max(STALL_MIN, STALL_FACTOR * n_new) consecutive
#: starts without a new mode, n_new = the start that found the last new one
STALL_MIN = 150
STALL_FACTOR = 2.0
#: multistart: starts drawn per batch (one compiled call solves them until the stopping rule ends the
#: search; the rule is checked per start, the budget per batch).  Large enough that the usual search
#: (a few modes, stalled after about STALL_MIN starts) takes one batch: the Python around a batch costs
#: as much as tens of local solves, and drawing a start that is never solved costs next to nothing
BATCH = 256
#: multistart: default cap on the number of starts
MAX_STARTS = 20_000
#: confidence of ``unseen_share_bound``
UNSEEN_CONFIDENCE = 0.95
#: rejection sampling of the reachable region: candidate rounds before falling back to its bounding box
REJECTION_ROUNDS = 20
#: rejection sampling: candidates drawn per round = still needed / acceptance so far x this margin (one
#: round usually suffices), at least MIN_CANDIDATES, the acceptance taken as at least MIN_ACCEPTANCE (a
#: region that small of its box costs more rounds, not more memory)
CANDIDATE_MARGIN = 1.25
MIN_CANDIDATES = 16
MIN_ACCEPTANCE = 1.0 / 64

#: partner search (module docstring): a mode whose leg Jacobian has a reciprocal condition number below
#: this is near a fold and its partner is sought.  The partners the random starts missed on the seed 6-6's
#: default map slice had a found twin of conditioning 1.3e-4 .. 1.05e-2; on every 7th point of that map
#: 0.02 and this gave the same counts, this with a fifth of the partner starts (an odd count left is the
#: parity rule's)
PARTNER_CONDITIONING = 0.003
#: partner search: the steps from the mode along the Jacobian's nearly-null direction, in shares of the
#: scale, each both ways.  A local solve started beyond the midpoint of the pair goes to the partner; the
#: missed partners lay 0.013 .. 0.53 of the scale away (pairs nearer than 0.06 were found from 0.09 on)
PARTNER_STEPS = (0.0625, 0.125, 0.25, 0.5)
#: a mode whose leg Jacobian's reciprocal condition number, once the mode is polished to round-off, is
#: below this is double: two real modes met at a singularity (a double root), counted once.  Polished,
#: a double root is left about sqrt(machine epsilon) of the scale from the exact one (the residual grows
#: with the square of the distance), where the conditioning is of that order: 1.5e-8 .. 1.6e-7 on the
#: seed 3-RPR's singular lines.  2**-20 = 64 sqrt(epsilon) leaves a margin both ways (the closest pair of
#: distinct modes on the seed 6-6 map slice has conditioning 7.5e-6)
DOUBLE_CONDITIONING = 2.0 ** -20
#: a mode found with a conditioning below this may be double and is polished to decide: a local solve
#: stops at a residual of LOCAL_RESIDUAL_RELATIVE of the scale, which leaves it up to sqrt(that) of the
#: scale from a double root, where the conditioning is of that order (up to 2.9e-5 seen on the seed 3-RPR
#: map, whose distinct modes start at 1.1e-4); twice that bound
DOUBLE_CANDIDATE = 2.0 * math.sqrt(LOCAL_RESIDUAL_RELATIVE)

#: parity rule (module docstring): an odd count (a double mode counted twice) goes on with random starts (no
#: stopping rule) until the count is even or this many times the starts used so far.  The modes the
#: stopping rule missed on the seed 6-6's default map slice drew 1.1 % .. 4.7 % of the starts, so three
#: times the usual ~200 starts more miss one with a chance below 0.989 ** 600 = 0.13 %
PARITY_EXTENSION = 4

#: multistart stop reasons
STALLED = "stalled"
MAX_STARTS_REACHED = "max_starts"
BUDGET_EXHAUSTED = "budget_exhausted"
UNREACHABLE = "unreachable"


@dataclass
class AllSolutions:
    solutions: list       # SolveResult per distinct mode, sorted by variables
    runs: int             # G3-PCX runs / multistart starts used / 0 (exact)
    elapsed_s: float
    evaluations: int      # residual(-and-Jacobian) evaluations, counted as in solvers.common
    method: str = "g3pcx"
    starts: int = 0                      # multistart: starts used (= runs)
    miss_probability: float | None = None  # not estimable by the multistart (module docstring): None
    good_turing: float | None = None     # multistart: Good-Turing chance that the next start finds a new mode
    unseen_share_bound: float | None = None  # multistart: 95 % bound on the share of starts leading to unseen modes
    complex_solutions: int | None = None  # exact: complex solutions (with multiplicity)
    stop_reason: str = ""                # multistart: stalled | max_starts | budget_exhausted | unreachable
    stall: int = 0                       # multistart: consecutive starts at the end that found nothing new
    hits: tuple = ()                     # multistart: starts that converged to each mode (order of solutions)
    partner_starts: int = 0              # multistart: local solves of the partner search (module docstring)
    parity_starts: int = 0               # multistart: random starts added by the parity rule (among ``starts``)
    conditioning: tuple = ()             # multistart, homotopy: each mode's conditioning (order of solutions)
    complete: bool | None = None         # homotopy / exact: every real mode certainly found
    paths: int = 0                       # homotopy: paths tracked (the family's generic root count)
    paths_failed: tuple = ()             # homotopy, incomplete: the paths without a solution of their own
    fallback: str = ""                   # homotopy, incomplete: "exact" when msolve's modes replaced its own
    retracked: int = 0                   # homotopy: path trackings repeated (another gamma / more care)
    steps: int = 0                       # homotopy: predictor-corrector steps over every path

    @property
    def real_solutions(self) -> int:
        """Distinct real assembly modes (the solutions' count)."""
        return len(self.solutions)

    @property
    def double_modes(self) -> int:
        """Multistart, homotopy: the modes that are double at the solver's tolerance (``DOUBLE_CONDITIONING``)."""
        return sum(c < DOUBLE_CONDITIONING for c in self.conditioning)


def consistent_fitness(model, leg_noise_std=None) -> float:
    """Redundant legs: the largest sum of squared leg residuals (config unit squared) of a mode, the
    estimator's consistency limit for the leg noise ``leg_noise_std`` (config unit; default the
    node's default, :func:`~glpma_ros.estimation.redundancy.leg_noise`); 0 without redundant legs."""
    if not model.redundancy:
        return 0.0
    return chi2_limit(model.redundancy) * leg_noise(model, leg_noise_std) ** 2


def _leg_fitness(model, x, legs) -> float:
    return float(np.sum((model.inverse_kinematics(x) - legs) ** 2))


def wide_range(model, legs) -> tuple[float, float]:
    half = RANGE_FACTOR * max(model.scale, float(np.max(model.rods_of(legs))))
    return -half, half


def solve_all(model, legs, *, method=None, runs=None, seed=0, solver="g3pcx", max_evals=None,
              max_starts=None, budget_s=None, polish=True, leg_noise_std=None) -> AllSolutions:
    """Every distinct real assembly mode of ``model`` at ``legs`` (config unit) by ``method``
    (module docstring; default ``"homotopy"`` where the model's family has a start system, else
    ``"multistart"``; ``"g3pcx"`` when ``runs`` is given, as before the multistart existed, and the
    multistart when one of its limits or ``polish=False`` is).  ``runs``: G3-PCX runs (default ``G3PCX_RUNS``);
    ``solver``, ``max_evals``: of those runs; ``max_starts`` (default ``MAX_STARTS``) and
    ``budget_s`` (seconds, default none): limits of the multistart, ``polish=False``: its modes as
    found (counting only); ``seed``: the random stream; ``leg_noise_std`` (config unit, default the
    node's default): redundant legs, the noise of the consistency test of a mode."""
    legs = model.check_legs(legs)
    if leg_noise_std is not None:
        leg_noise(model, leg_noise_std)         # checked up front, for every model
    if method is None:
        if runs is not None:
            method = "g3pcx"
        elif max_starts is not None or budget_s is not None or not polish:
            method = "multistart"
        else:
            method = default_method(model)
    if runs is not None and method != "g3pcx":
        raise GlpmaError(f"runs counts G3-PCX searches (method g3pcx); {method} does not take it")
    if (max_starts is not None or budget_s is not None or not polish) and method != "multistart":
        raise GlpmaError(f"max_starts, budget_s and polish=False are the multistart's; {method} does not take them")
    if method == "multistart":
        return multistart(model, legs, seed=seed, max_starts=MAX_STARTS if max_starts is None else max_starts,
                          budget_s=budget_s, polish=polish, leg_noise_std=leg_noise_std)
    if method == "g3pcx":
        return g3pcx_runs(model, legs, runs=G3PCX_RUNS if runs is None else runs, seed=seed, solver=solver,
                          max_evals=max_evals, leg_noise_std=leg_noise_std)
    if method == "exact":
        return exact_modes(model, legs, seed=seed)
    if method == "closed_form":
        return closed_form_modes(model, legs, seed=seed)
    if method == "homotopy":
        return homotopy_modes(model, legs, seed=seed, leg_noise_std=leg_noise_std)
    raise GlpmaError(f"unknown solve_all method {method!r}; choose one of {', '.join(METHODS)}")


def default_method(model) -> str:
    """``"closed_form"`` where the model has one (the Delta), ``"homotopy"`` where the model's family has a
    start system, else ``"multistart"``."""
    from . import homotopy
    if has_closed_form(model):
        return "closed_form"
    return "homotopy" if homotopy.has_start_system(model) else "multistart"


def _order(model, found: list) -> list:
    """Indices of ``found`` (SolveResults, their ``x`` made canonical here) sorted by variables."""
    for s in found:
        s.x = model.canonical(s.x)
    return sorted(range(len(found)), key=lambda k: tuple(np.round(found[k].x, 6)))


def _sorted(model, found: list) -> list:
    return [found[k] for k in _order(model, found)]


# -- the papers' method ---------------------------------------------------------------------------
def g3pcx_runs(model, legs, *, runs, seed=0, solver="g3pcx", max_evals=None, leg_noise_std=None) -> AllSolutions:
    t0 = time.perf_counter()
    limit = consistent_fitness(model, leg_noise_std)
    rng = np.random.default_rng(seed)
    found = []
    evaluations = 0
    for _ in range(runs):
        r = solvers.solve(solver, model, legs, rng=rng, init_range=wide_range(model, legs), polish=True,
                          max_evals=max_evals)
        evaluations += r.nfev
        if not r.success or (model.redundancy and _leg_fitness(model, r.x, legs) > limit):
            continue
        if all(model.distance(r.x, s.x) > DEDUP_RELATIVE * model.scale for s in found):
            found.append(r)
    return AllSolutions(_sorted(model, found), runs, time.perf_counter() - t0, evaluations, method="g3pcx")


# -- multistart -------------------------------------------------------------------------------------
#: codes of :func:`_multistart_batch`'s outcome (``counters[C_STOP]``)
GOING, STALL_RULE, FULL = 0, 1, 2
#: layout of the multistart's integer ``counters``
C_MODES, C_STARTS, C_LAST_NEW, C_NFEV, C_STOP = range(5)
#: modes the arrays hold at first (a 6-6 has at most 40 complex solutions; grown when a
#: near-singular input yields more distinct converged poses)
MODES_CAPACITY = 40


@njit(cache=True, error_model="numpy", nogil=True)
def _multistart_batch(kind, data, platform, frame, legs, ref, starts, settings, tolerance, dedup, modes, hits,
                      counters, out, work, stall_rule=True):
    """The multistart's inner loop over one batch of ``starts``, compiled: from each start one
    Levenberg-Marquardt solve (:func:`~glpma_ros.solvers.lm.lm_kernel`'s iteration, the caps in
    ``settings``); a solve whose leg fitness is below ``tolerance`` is a mode, the same as the
    nearest one found so far when their platform joints are within ``dedup``
    (``Manipulator.distance``), else a new one appended to ``modes``; then the stopping rule of the
    module docstring, checked after every start (unless ``stall_rule`` is false: the partner
    search's starts).  ``counters`` (``C_*``) carry the state from batch to batch.  Returns the number of starts used;
    ``counters[C_STOP]`` says why it returned
    (``GOING``: the batch is used up; ``STALL_RULE``; ``FULL``: ``modes`` has no room left)."""
    n_vars = modes.shape[1]
    info = n_vars + 7
    counters[C_STOP] = GOING
    for k in range(starts.shape[0]):
        if counters[C_MODES] == modes.shape[0]:
            counters[C_STOP] = FULL
            return k
        solve_one(kind, data, platform, frame, legs, ref, starts[k], starts[k], settings, out, work, False)
        counters[C_STARTS] += 1
        counters[C_NFEV] += int(out[info + I_NFEV])
        if out[info + I_LEG_FITNESS] < tolerance:
            x = out[:n_vars]
            nearest, d_nearest = -1, math.inf
            for j in range(counters[C_MODES]):
                d = joint_distance(kind, frame, x, modes[j])
                if d < d_nearest:
                    nearest, d_nearest = j, d
            if nearest >= 0 and d_nearest <= dedup:
                hits[nearest] += 1
            else:
                m = counters[C_MODES]
                modes[m, :] = x
                hits[m] = 1
                counters[C_MODES] = m + 1
                counters[C_LAST_NEW] = counters[C_STARTS]
        stall = counters[C_STARTS] - counters[C_LAST_NEW]
        if stall_rule and stall >= max(STALL_MIN, STALL_FACTOR * counters[C_LAST_NEW]):
            counters[C_STOP] = STALL_RULE
            return k + 1
    return starts.shape[0]


@njit(cache=True, error_model="numpy")
def _in_every_ball(P, centres, radii):
    """Which rows of ``P`` lie in every ball (``centres[i]``, ``radii[i]``), compiled: the rejection
    test of the start sampler, run on every candidate."""
    inside = np.ones(P.shape[0], np.bool_)
    for k in range(P.shape[0]):
        for i in range(centres.shape[0]):
            d2 = 0.0
            for a in range(P.shape[1]):
                d2 += (P[k, a] - centres[i, a]) ** 2
            if d2 > radii[i] * radii[i]:
                inside[k] = False
                break
    return inside


class StartSampler:
    """Random starting poses (solver variables) over the region the legs can reach
    (module docstring).  ``empty``: the bounding box of that region is empty, which proves that
    no assembly exists."""

    def __init__(self, model, legs):
        self.model = model
        self.planar = model.platform.shape[1] == 2
        self.centroid = model.platform.mean(axis=0)
        radius = model.rods_of(legs) + np.linalg.norm(model.platform - self.centroid, axis=1)
        # the legs' proximal points: the base joints, or an actuated family's for these actuator positions
        centres = np.ascontiguousarray(model.proximal_points(legs), dtype=float)
        self.translation = model.n_pose == 3 and not self.planar     # deltas: the platform only translates
        self.centres, self.radii = centres, radius
        self.low = np.max(centres - radius[:, None], axis=0)
        self.high = np.min(centres + radius[:, None], axis=0)
        self.empty = bool(np.any(self.low > self.high))
        self.tried = self.accepted = 0
        self.acceptance = 1.0                # share of the box's candidates inside, as seen so far

    def _inside(self, P) -> np.ndarray:
        return _in_every_ball(P, self.centres, self.radii)

    def centres_in_reach(self, rng, m) -> np.ndarray:
        """``m`` platform centres uniform in the intersection of the balls: rejection from its
        bounding box, each round drawing as many candidates as the acceptance seen so far says are
        needed (times ``CANDIDATE_MARGIN``), so that one round usually suffices; after
        ``REJECTION_ROUNDS`` rounds the rest are taken from the box."""
        dim = self.low.size
        parts, have = [], 0
        for _ in range(REJECTION_ROUNDS):
            need = m - have
            n = max(MIN_CANDIDATES, math.ceil(need * CANDIDATE_MARGIN / max(self.acceptance, MIN_ACCEPTANCE)))
            P = rng.uniform(self.low, self.high, size=(n, dim))
            inside = P[self._inside(P)]
            self.tried += n
            self.accepted += len(inside)
            self.acceptance = self.accepted / self.tried
            parts.append(inside[:need])
            have += len(parts[-1])
            if have >= m:
                return np.concatenate(parts)
        parts.append(rng.uniform(self.low, self.high, size=(m - have, dim)))
        return np.concatenate(parts)

    def draw(self, rng, m) -> np.ndarray:
        """``m`` starts (rows of solver variables): centres in reach, orientations uniform (the
        random numbers from ``rng``, the arithmetic compiled)."""
        P = self.centres_in_reach(rng, m)
        if self.planar:
            return _planar_starts(P, rng.uniform(-math.pi, math.pi, size=m), self.centroid)
        if self.translation:
            return np.ascontiguousarray(P - self.centroid)
        return _spatial_starts(P, rng.standard_normal((m, 4)), self.model.frame - self.centroid)


@njit(cache=True, error_model="numpy")
def _planar_starts(P, theta, centroid):
    """3-RPR starts ``(x, y, theta)``: the platform's origin placed so that its joints' centroid,
    rotated by ``theta``, is at ``P``."""
    out = np.empty((P.shape[0], 3))
    cx, cy = centroid[0], centroid[1]
    for k in range(P.shape[0]):
        c, s = math.cos(theta[k]), math.sin(theta[k])
        out[k, 0] = P[k, 0] - (c * cx - s * cy)
        out[k, 1] = P[k, 1] - (s * cx + c * cy)
        out[k, 2] = theta[k]
    return out


@njit(cache=True, error_model="numpy")
def _spatial_starts(P, q, arms):
    """Hexapod starts ``(B1, B2, B3)``: ``B_k = P + R (b_k - c)`` with ``R`` the rotation of the
    normalised 4-D Gaussian ``q`` (a uniform unit quaternion ``x, y, z, w``) and ``arms`` the
    rows ``b_k - c``."""
    out = np.empty((P.shape[0], 3 * arms.shape[0]))
    R = np.empty((3, 3))
    for k in range(P.shape[0]):
        n = math.sqrt(q[k, 0] ** 2 + q[k, 1] ** 2 + q[k, 2] ** 2 + q[k, 3] ** 2)
        x, y, z, w = q[k, 0] / n, q[k, 1] / n, q[k, 2] / n, q[k, 3] / n
        R[0, 0], R[0, 1], R[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
        R[1, 0], R[1, 1], R[1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
        R[2, 0], R[2, 1], R[2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
        for j in range(arms.shape[0]):
            for a in range(3):
                out[k, 3 * j + a] = P[k, a] + R[a, 0] * arms[j, 0] + R[a, 1] * arms[j, 1] + R[a, 2] * arms[j, 2]
    return out


class _Search:
    """The multistart's state (``leg_noise_std``: redundant legs, as :func:`consistent_fitness`): the modes found
    (grown when full), the hits of the random starts, the
    conditioning of the modes seen by the partner search, and the compiled kernel's arguments; :meth:`run`
    solves a batch of starts with :func:`_multistart_batch`."""

    def __init__(self, model, legs, seed=0, leg_noise_std=None):
        self.model = model
        self.rng = np.random.default_rng(seed)      # of the polish that decides a double mode
        self.local = LocalSolver(model)
        self.settings = make_settings(model, max_iter=LOCAL_MAX_ITER)
        self.legs = np.ascontiguousarray(legs, dtype=float)
        self.ref = max(model.scale, float(np.max(model.rods_of(legs))))
        # redundant legs: a consistent least-squares pose has a residual (the leg noise's limit)
        self.tolerance = max((LOCAL_RESIDUAL_RELATIVE * model.scale) ** 2, consistent_fitness(model, leg_noise_std))
        self.dedup = DEDUP_RELATIVE * model.scale
        self.modes = np.empty((MODES_CAPACITY, model.n_vars))
        self.hits = np.zeros(MODES_CAPACITY, np.int64)
        self.counters = np.zeros(5, np.int64)
        self.out = np.empty(self.local.n_out)
        self.polish_evaluations = 0
        self.conditioning = []          # per mode (in the order found), once its partner search ran; of the
        #                                 polished mode when it was below DOUBLE_CANDIDATE

    @property
    def n_modes(self) -> int:
        return int(self.counters[C_MODES])

    def run(self, starts, counters=None, random=True, stall_rule=True) -> None:
        """Local solves from ``starts`` into the modes, growing the arrays when they are full.  ``random``:
        random starts (their hits counted; ``stall_rule``: the stopping rule on); else the partner search's
        (``counters`` its own, the hits not kept, no stopping rule)."""
        counters = self.counters if counters is None else counters
        starts = np.ascontiguousarray(starts)
        while True:
            hits = self.hits if random else np.zeros_like(self.hits)
            used = _multistart_batch(self.local.kind, self.local.data, self.local.platform, self.local.frame,
                                     self.legs, self.ref, starts, self.settings, self.tolerance, self.dedup,
                                     self.modes, hits, counters, self.out, self.local.work, random and stall_rule)
            if counters[C_STOP] != FULL:
                return
            self.modes = np.vstack((self.modes, np.empty_like(self.modes)))
            self.hits = np.concatenate((self.hits, np.zeros_like(self.hits)))
            starts = starts[used:]

    def partner_starts(self, x) -> tuple[float, np.ndarray]:
        """The conditioning of the mode ``x`` (reciprocal condition number of its leg Jacobian, as
        ``Manipulator.conditioning``) and the starts (rows of solver variables) for its partner (module
        docstring): none when ``x`` is well conditioned."""
        model = self.model
        state = model.pose_state(x)
        _, J = model.pose_residuals_jacobian(state, self.legs)
        _, sv, vt = np.linalg.svd(J * model.pose_column_scale)
        conditioning = float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0
        if conditioning < DOUBLE_CANDIDATE:     # double or not: decided on the mode polished to round-off
            xp, _, nfev, _ = refine.polish(model, x, self.legs, self.rng)
            self.polish_evaluations += nfev
            conditioning = model.conditioning(xp, self.legs)
        if not conditioning < PARTNER_CONDITIONING:
            return conditioning, np.empty((0, model.n_vars))
        direction = vt[-1] * model.pose_column_scale        # a step of unit length (rotations per scale)
        return conditioning, np.array([model.pose_variables(model.pose_retract(state, sign * step * model.scale *
                                                                                 direction))
                                       for step in PARTNER_STEPS for sign in (1.0, -1.0)])

    def partner_search(self) -> int:
        """The partner search of every mode not yet searched from, and of the modes it finds; returns its
        starts."""
        counters = self.counters.copy()       # the random starts' counts stay theirs
        counters[C_STARTS] = counters[C_LAST_NEW] = 0
        used = 0
        while len(self.conditioning) < int(counters[C_MODES]):
            batch = []
            for k in range(len(self.conditioning), int(counters[C_MODES])):
                conditioning, starts = self.partner_starts(self.modes[k].copy())
                self.conditioning.append(conditioning)
                batch.append(starts)
            starts = np.concatenate(batch)
            if len(starts):
                self.run(starts, counters=counters, random=False)
                used += len(starts)
        self.counters[C_MODES] = counters[C_MODES]
        self.counters[C_NFEV] = counters[C_NFEV]
        return used

    def odd_and_unexplained(self) -> bool:
        """An odd number of modes counted with multiplicity, a double mode twice (module docstring, parity
        rule); never with redundant legs (least-squares poses: no polynomial system)."""
        doubles = sum(c < DOUBLE_CONDITIONING for c in self.conditioning)
        return not self.model.redundancy and (self.n_modes + doubles) % 2 == 1


def multistart(model, legs, *, seed=0, max_starts=MAX_STARTS, budget_s=None, polish=True,
               leg_noise_std=None) -> AllSolutions:
    """The multistart of the module docstring (``legs`` already checked), with its partner search and
    parity rule.  ``polish=False`` returns each mode as its first local solve left it (leg residuals below
    ``LOCAL_RESIDUAL_RELATIVE`` of the scale) instead of polished to round-off: what counting the modes
    needs."""
    if max_starts < 1:
        raise GlpmaError("max_starts must be at least 1")
    if budget_s is not None and not budget_s > 0:
        raise GlpmaError("budget_s must be positive")
    t0 = time.perf_counter()
    deadline = None if budget_s is None else t0 + budget_s
    rng = np.random.default_rng(seed)
    sampler = StartSampler(model, legs)
    search = _Search(model, legs, seed, leg_noise_std)
    counters = search.counters
    reason = UNREACHABLE if sampler.empty else ""
    while not reason:
        search.run(sampler.draw(rng, min(BATCH, max_starts - int(counters[C_STARTS]))))
        if counters[C_STOP] == STALL_RULE:
            reason = STALLED
        elif counters[C_STARTS] >= max_starts:
            reason = MAX_STARTS_REACHED
        elif deadline is not None and time.perf_counter() >= deadline:
            reason = BUDGET_EXHAUSTED
    partner_starts = 0 if reason == UNREACHABLE else search.partner_search()
    parity_starts = 0
    if reason == STALLED:
        limit = min(max_starts, PARITY_EXTENSION * int(counters[C_STARTS]))
        while (search.odd_and_unexplained() and counters[C_STARTS] < limit
               and (deadline is None or time.perf_counter() < deadline)):
            before = int(counters[C_STARTS])
            search.run(sampler.draw(rng, min(BATCH, limit - before)), stall_rule=False)
            parity_starts += int(counters[C_STARTS]) - before
            partner_starts += search.partner_search()
    n_modes, starts_used = search.n_modes, int(counters[C_STARTS])
    evaluations = int(counters[C_NFEV]) + search.polish_evaluations
    polish_rng = np.random.default_rng(seed) if polish else None
    found = []
    for x in search.modes[:n_modes]:
        t1 = time.perf_counter()
        if polish:
            xp, fp, nfev, _ = refine.polish(model, x, search.legs, polish_rng)
        else:
            xp, fp, nfev = x.copy(), float(model.fitness(x, search.legs)[0]), 1
        evaluations += nfev
        found.append(SolveResult(xp, fp, nfev, 0, time.perf_counter() - t1, CONVERGED, "multistart",
                                 polished=polish))
    order = _order(model, found)
    stall = starts_used - int(counters[C_LAST_NEW])
    hits = search.hits[:n_modes]
    singletons = int(np.sum(hits == 1))
    conditioning = search.conditioning if len(search.conditioning) == n_modes else [math.nan] * n_modes
    return AllSolutions([found[k] for k in order], starts_used, time.perf_counter() - t0, evaluations,
                        method="multistart", starts=starts_used,
                        good_turing=singletons / starts_used if starts_used else None,
                        unseen_share_bound=1.0 - (1.0 - UNSEEN_CONFIDENCE) ** (1.0 / stall) if stall else 1.0,
                        stop_reason=reason, stall=stall, hits=tuple(int(hits[k]) for k in order),
                        partner_starts=partner_starts, parity_starts=parity_starts,
                        conditioning=tuple(conditioning[k] for k in order))


# -- certified ----------------------------------------------------------------------------------
def exact_modes(model, legs, *, seed=0) -> AllSolutions:
    """Every real mode certified by msolve (:mod:`glpma_ros.modes.exact`), each polished."""
    from . import exact
    t0 = time.perf_counter()
    sol = exact.solve_exact(model, legs)
    rng = np.random.default_rng(seed)
    found, evaluations = [], 0
    for x in sol.variables:
        t1 = time.perf_counter()
        xp, fp, nfev, _ = refine.polish(model, x, legs, rng)
        evaluations += nfev
        if model.distance(xp, x) > exact.POLISH_SHIFT_RELATIVE * model.scale:
            raise GlpmaError(f"polishing a certified solution moved it by {model.distance(xp, x):.3g} "
                             f"{model.unit} (near-singular legs?)")
        found.append(SolveResult(xp, fp, nfev, 0, time.perf_counter() - t1, CONVERGED, "exact", polished=True))
    return AllSolutions(_sorted(model, found), 0, time.perf_counter() - t0, evaluations, method="exact",
                        complex_solutions=sol.complex_solutions, complete=True)


# -- closed form ----------------------------------------------------------------------------------
def has_closed_form(model) -> bool:
    """The model's forward kinematics has a closed form (:meth:`DeltaTranslation.closed_form
    <glpma_ros.models.actuated.DeltaTranslation.closed_form>`: a Delta with three legs)."""
    return getattr(model, "closed_form", None) is not None and model.n_legs == model.n_pose


def closed_form_modes(model, legs, *, seed=0) -> AllSolutions:
    """Every real mode of the model's closed form, each polished to round-off."""
    if not has_closed_form(model):
        raise GlpmaError(f"{model.kind} has no closed-form forward kinematics; use multistart or exact")
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    found, evaluations = [], 0
    for x in model.closed_form(legs):
        t1 = time.perf_counter()
        xp, fp, nfev, _ = refine.polish(model, x, legs, rng)
        evaluations += nfev
        found.append(SolveResult(xp, fp, nfev, 0, time.perf_counter() - t1, CONVERGED, "closed_form", polished=True))
    return AllSolutions(_sorted(model, found), 0, time.perf_counter() - t0, evaluations, method="closed_form")


# -- homotopy -------------------------------------------------------------------------------------
def homotopy_modes(model, legs, *, seed=0, leg_noise_std=None, fallback=True) -> AllSolutions:
    """Every real mode by the parameter homotopy (:mod:`glpma_ros.modes.homotopy`), each polished with every
    leg; redundant legs: those the polish leaves consistent (:func:`consistent_fitness`).  Incomplete: the real
    double roots the paths met as well (polished; ``conditioning`` says they are double) and, with ``fallback``
    and msolve installed (not with redundant legs), msolve's modes instead, ``fallback = "exact"``."""
    from . import homotopy
    t0 = time.perf_counter()
    res = homotopy.solve(model, legs, seed=seed)
    rng = np.random.default_rng(seed)
    limit = max((LOCAL_RESIDUAL_RELATIVE * model.scale) ** 2, consistent_fitness(model, leg_noise_std))
    found, evaluations = [], 0
    for x in list(res.real) + list(res.singular):
        t1 = time.perf_counter()
        xp, fp, nfev, _ = refine.polish(model, x, legs, rng)
        evaluations += nfev
        if _leg_fitness(model, xp, legs) > limit:
            continue                     # redundant legs: inconsistent with the others
        if all(model.distance(xp, s.x) > DEDUP_RELATIVE * model.scale for s in found):
            found.append(SolveResult(xp, fp, nfev, 0, time.perf_counter() - t1, CONVERGED, "homotopy",
                                     polished=True))
    used = ""
    complex_solutions, complete = res.complex_solutions, res.complete
    if fallback and not res.complete and not model.redundancy:
        try:
            certified = exact_modes(model, legs, seed=seed)
        except GlpmaError:              # not installed, a degenerate system or a polish off its box: as it is
            certified = None
        if certified is not None:
            found, used = certified.solutions, "exact"
            complex_solutions, complete = certified.complex_solutions, True
            evaluations += certified.evaluations
    found = _sorted(model, found)
    return AllSolutions(found, 0, time.perf_counter() - t0, evaluations, method="homotopy",
                        complex_solutions=complex_solutions, complete=complete, paths=res.paths,
                        paths_failed=tuple(res.paths_failed), fallback=used, retracked=res.retracked,
                        steps=res.steps, conditioning=tuple(float(model.conditioning(s.x, legs)) for s in found))
