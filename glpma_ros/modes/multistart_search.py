"""The multistart search for every real assembly mode (``solve_all(method="multistart")``,
:mod:`glpma_ros.modes.multistart`): many cheap local solves from starts spread over the pose space.

Each start is a pose drawn at random (seeded ``numpy.random.Generator``): an orientation
uniform on SO(3) (a normalised 4-D Gaussian, i.e. a uniform unit quaternion; 3-RPR: an
angle uniform on (-pi, pi]) and a platform centre uniform in the region the legs can reach
(:mod:`glpma_ros.modes.starts`; an empty region proves there is no assembly).  From each start one
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
basin is tiny can be missed while no start-count statistic sees it (on Dietmaier's 6-6 with 40 real
modes: BENCHMARKS.md, "Design measurements").  So ``miss_probability`` is not reported (None): the
Good-Turing figure is kept as ``good_turing`` under its own meaning, the chance that the next start
finds a new mode.  Use ``"homotopy"`` or ``"exact"`` for a certificate.

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

Plain Python + NumPy/Numba: no ROS import.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from ..errors import GlpmaError
from ..models.pose_kernels import joint_distance
from ..solvers import refine
from ..solvers.common import CONVERGED, SolveResult
from ..solvers.lm import I_LEG_FITNESS, I_NFEV, solve_one
from ..solvers.local import POSE_OUT, LocalSolver, make_settings
from .solutions import (
    DEDUP_RELATIVE,
    DOUBLE_CONDITIONING,
    LOCAL_RESIDUAL_RELATIVE,
    AllSolutions,
    consistent_fitness,
    order,
)
from .starts import StartSampler

#: Levenberg-Marquardt iterations allowed per start; converging starts need a handful (quadratic
#: convergence once near a mode), so a start still far off by then is dropped
LOCAL_MAX_ITER = 30
#: stopping rule: stop after max(STALL_MIN, STALL_FACTOR * n_new) consecutive starts without a new mode,
#: n_new = the start that found the last new one
STALL_MIN = 150
STALL_FACTOR = 2.0
#: starts drawn per batch (one compiled call solves them until the stopping rule ends the search; the rule
#: is checked per start, the budget per batch).  Large enough that the usual search (a few modes, stalled
#: after about STALL_MIN starts) takes one batch: the Python around a batch costs as much as tens of local
#: solves, and drawing a start that is never solved costs next to nothing
BATCH = 256
#: default cap on the number of starts
MAX_STARTS = 20_000
#: confidence of ``unseen_share_bound``
UNSEEN_CONFIDENCE = 0.95

#: partner search (module docstring): a mode whose leg Jacobian has a reciprocal condition number below
#: this is near a fold and its partner is sought: above the conditioning of the twins of the partners the
#: random starts miss, and as good as a larger threshold with fewer partner starts (BENCHMARKS.md, "Design
#: measurements"; an odd count left is the parity rule's)
PARTNER_CONDITIONING = 0.003
#: partner search: the steps from the mode along the Jacobian's nearly-null direction, in shares of the
#: scale, each both ways.  A local solve started beyond the midpoint of the pair goes to the partner; the
#: steps double from the smallest pair distance missed to beyond the largest (BENCHMARKS.md)
PARTNER_STEPS = (0.0625, 0.125, 0.25, 0.5)
#: a mode found with a conditioning below this may be double and is polished to decide: a local solve
#: stops at a residual of LOCAL_RESIDUAL_RELATIVE of the scale, which leaves it up to sqrt(that) of the
#: scale from a double root, where the conditioning is of that order; twice that bound
DOUBLE_CANDIDATE = 2.0 * math.sqrt(LOCAL_RESIDUAL_RELATIVE)

#: parity rule (module docstring): an odd count (a double mode counted twice) goes on with random starts (no
#: stopping rule) until the count is even or this many times the starts used so far: three times the usual
#: starts more find a mode the stopping rule missed but for a small chance (its basin and the chance:
#: BENCHMARKS.md, "Design measurements")
PARITY_EXTENSION = 4

#: multistart stop reasons
STALLED = "stalled"
MAX_STARTS_REACHED = "max_starts"
BUDGET_EXHAUSTED = "budget_exhausted"
UNREACHABLE = "unreachable"


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
    info = n_vars + POSE_OUT
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
    ranked = order(model, found)
    stall = starts_used - int(counters[C_LAST_NEW])
    hits = search.hits[:n_modes]
    singletons = int(np.sum(hits == 1))
    conditioning = search.conditioning if len(search.conditioning) == n_modes else [math.nan] * n_modes
    return AllSolutions([found[k] for k in ranked], starts_used, time.perf_counter() - t0, evaluations,
                        method="multistart", starts=starts_used,
                        good_turing=singletons / starts_used if starts_used else None,
                        unseen_share_bound=1.0 - (1.0 - UNSEEN_CONFIDENCE) ** (1.0 / stall) if stall else 1.0,
                        stop_reason=reason, stall=stall, hits=tuple(int(hits[k]) for k in ranked),
                        partner_starts=partner_starts, parity_starts=parity_starts,
                        conditioning=tuple(conditioning[k] for k in ranked))
