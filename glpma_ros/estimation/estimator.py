"""The per-message logic of the node: warm start, escalation, branch choice, status.

Rolland & Chandra (2016, section 5.5) show that an initial population drawn near
one solution isolates that solution; Funes Lora et al. (2018) inject the
previous pose into the population and keep the configuration nearest the
previous one.  For every new set of leg lengths the estimator

1. **warm** (with the refinement on, the node's everyday case): one compiled
   Levenberg-Marquardt call from the previous estimate
   (:mod:`glpma_ros.solvers.lm`); accepted when it converges to a solution near
   the previous one;
2. otherwise, legs that no pose can reach by the loop bounds of a pair of legs
   (:mod:`glpma_ros.models.reach`, told from the legs alone) are ``no_solution`` at once;
3. otherwise the population stages: **warm** (the solver's population around the
   previous estimate, with a spread equal to how far the legs moved; without the
   refinement this is the first stage), **widened** (the same with a spread
   ``WIDEN_FACTOR`` times larger), **cold** (the papers' wide initial range);

and, among the converged candidates, keeps the one nearest the previous pose,
so that it does not jump assembly mode on a continuous trajectory.

**The deadline is hard.**  No work starts after ``time_budget_s``: the population stages share the
budget less a *reserve* for the deciding work below (``STAGE_SHARE``), and every compiled call of the
deciding work starts only when its expected duration (the longest seen so far of that kind) still ends
before the deadline.  When the deciding work does not fit, the answer is ``budget_exhausted`` at the
deadline.  The reserve is :data:`DECISION_MARGIN` times the longest deciding work seen so far (the
thread's CPU time of its calls, measured once when the estimator is built, then on every input), at
least :data:`DECISION_MIN_SHARE` and at most :data:`DECISION_MAX_SHARE` of the budget.  The smallest
budget at which the deciding work fits is therefore ``decision_reserve_s / DECISION_MAX_SHARE``
(:attr:`Estimator.smallest_deciding_budget_s`).

**Convergence** (with the refinement) is judged on the leg residuals of the
pose, relative to the geometry: ``max |r_i| <= leg_rtol * max(scale, max leg)``
(``leg_rtol`` default :data:`~glpma_ros.solvers.lm.LEG_RTOL`, near round-off),
so the same digits are reached whether the configuration is in mm, cm or m, and
the hexapod needs no search on the floating-point grid to meet an absolute
threshold.  ``tolerance`` (default 1e-20, the papers' threshold, in config
unit squared) stays the fitness at which the evolutionary search stops and
hands over to the refinement; the papers' fitness of the estimate is still
reported (``Estimate.fitness``).  Without the refinement (``polish=False``, the
papers' setting) convergence is the papers' ``fitness < tolerance``.

**Statuses come from work done, not from the clock.**  Every point a search
ends on is polished by the compiled Levenberg-Marquardt (its iteration cap bounds it):
a polish that meets the leg criterion is ``converged`` however little of the search
fitted in the budget.  When none does, a *probe* runs: the same Levenberg-Marquardt from
``PROBE_STARTS`` fixed starts in the papers' initial range (a fixed seed, so the
same work on every machine), stopping at the first that converges (reported as
a ``cold`` start).  If the whole probe fails, the best polished point decides (:func:`classify`):
``near_singular`` (leg Jacobian nearly singular, small residual), ``no_solution`` (a residual that
the polish cannot lower: a stationary point of the fitness, or a polish that stalled; no real
assembly there); only when neither holds, or when the probe could not run to its end before the
deadline, is the status ``budget_exhausted`` (the time ran out) or ``max_evals`` (the evaluation
caps did).  Above the smallest budget at which the deciding work fits (README, "Deadlines"), the
same legs get the same status on an idle or a busy machine.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from .. import solvers
from ..errors import InputError
from ..models.base import Pose, lengths_from_readings
from ..models.reach import PairBounds
from ..runtime.collector import HOLD
from ..solvers import lm, local
from ..solvers.driver import POLISH_MAX_ITER
from ..units import UNIT_TO_METRES
from . import redundancy

#: spread of the widened stage relative to the warm one
WIDEN_FACTOR = 10.0
#: share of the remaining search time each population stage may use (warm, widened, cold)
STAGE_SHARE = (0.4, 0.5, 1.0)
#: a converged solution farther than this many leg displacements from the previous
#: pose (in platform-joint distance) triggers the search for a nearer branch
CONTINUITY_FACTOR = 20.0
#: smallest warm-start spread, relative to the geometry's scale
MIN_SPREAD = 1e-6
#: largest warm-start spread, relative to the scale (beyond it the cold stage's range is the better start)
MAX_SPREAD = 10.0
#: iteration cap of the warm stage's Levenberg-Marquardt (as the driver's refinement)
WARM_MAX_ITER = POLISH_MAX_ITER
#: iteration cap of the polish that settles a search's end point (one compiled call: microseconds)
SETTLE_MAX_ITER = lm.MAX_ITER
#: an unconverged fitness whose RMS leg residual exceeds this share of the scale
#: means the legs have no real assembly (rather than too little time)
NO_SOLUTION_RMS = 1e-6
#: |J^T r| / (|J| |r|) below which the best point is a stationary point of the fitness
STATIONARY = 1e-2
#: a polish that lowered the fitness by less than this fraction over its last 10-20 iterations has
#: stalled: Levenberg-Marquardt approaching a real assembly lowers it by more than 75 % per iteration
#: even at a double root, while one creeping toward a singular least-squares point (where unreachable
#: legs usually end) crawls
STALLED = 0.1
#: reciprocal condition number of the leg Jacobian below which a pose is near a
#: singularity (assembly modes meet; the seed examples are at 0.02-0.13)
NEAR_SINGULAR = 1e-3
#: an unconverged best point near a singularity counts as "near singular" rather
#: than "no solution" while its RMS residual is below this share of the scale
NEAR_SINGULAR_RMS = 1e-2
#: starts of the probe that decides a failed search: Levenberg-Marquardt from fixed starts drawn in the
#: papers' initial range (on the seed examples one start in five or more converges on any feasible legs)
PROBE_STARTS = 32
#: starts per compiled call of the probe: the deadline is looked at between two calls, so one call
#: must be short (a few starts, tens of microseconds) and the calls few (each costs a Python call)
PROBE_CHUNK = 4
#: seed of the probe's starts (fixed: the probe is the same work on every machine)
PROBE_SEED = 0
#: the reserve for the deciding work is this many times the longest deciding work seen (its duration
#: varies with the legs and with the machine's load: twice covers both on the machines measured)
DECISION_MARGIN = 2.0
#: ... and at most this share of the budget: the search keeps the rest (when the deciding work needs
#: more, it is cut at the deadline: budget_exhausted)
DECISION_MAX_SHARE = 0.8
#: ... and at least this share: with a budget far above the deciding work's own time, a busy machine that
#: preempts the solving thread for milliseconds still leaves the deciding work the time it needs (the
#: search has the other half; where the search converges the reserve is not waited for)
DECISION_MIN_SHARE = 0.5
#: an expected duration (longest seen) forgets this share of itself per input that measures less, so
#: that a one-off delay (a preemption) does not hold the reserve high for good
EXPECTED_DECAY = 0.01
#: the unit of the papers' initial ranges (``solvers.PAPER_SETTINGS``; their manipulators are in mm)
PAPER_UNIT = "mm"
#: solver variables that are angles (radians: the same in every unit of length)
ANGLE_VARIABLES = frozenset({"theta"})

STATUS_CONVERGED = "converged"
STATUS_NO_SOLUTION = "no_solution"
STATUS_BUDGET = "budget_exhausted"
STATUS_NEAR_SINGULAR = "near_singular"
STATUS_MAX_EVALS = "max_evals"
#: redundant legs that no pose explains within the leg noise (:mod:`glpma_ros.estimation.redundancy`)
STATUS_INCONSISTENT = redundancy.STATUS_INCONSISTENT


@dataclass
class Estimate:
    status: str
    start: str                 # warm | widened | cold
    x: np.ndarray | None       # solver variables (config unit)
    pose: Pose | None
    fitness: float             # the papers' fitness of x (config unit squared)
    evaluations: int
    elapsed_s: float
    conditioning: float        # reciprocal condition number of the leg Jacobian, 0 = singular
    solver: str
    message: str = ""
    max_residual: float = math.nan   # max |IK(x) - legs| over the legs (config unit)
    # redundant legs (glpma_ros.estimation.redundancy), set after construction; legs are numbered from 0 here.  Class
    # attributes, not fields: the everyday estimate (exactly determined legs) does not pay for them
    consistency = math.nan           # chi-square statistic sum r_i^2 / sigma^2 at the least-squares pose
    consistency_limit = math.nan     # its limit (inconsistent above)
    suspect_leg = None               # inconsistent_legs: the leg most likely at fault
    excluded_leg = None              # the leg left out of the pose (the pose is then from the others)

    @property
    def converged(self) -> bool:
        return self.status == STATUS_CONVERGED

    @property
    def publishable(self) -> bool:
        """A pose to publish: converged, or inconsistent legs with the faulty one left out."""
        return self.pose is not None and (self.converged or self.excluded_leg is not None)

    @property
    def near_singular(self) -> bool:
        return self.conditioning < NEAR_SINGULAR


def cold_range(model):
    """The papers' initial range for ``model`` as per-variable ``(low, high)`` in its config unit:
    the same physical range whatever the unit (lengths converted from :data:`PAPER_UNIT`, angles
    kept).  An actuated family has its own, in its config unit: the box its legs can reach
    (``initial_range``, :mod:`glpma_ros.models.actuated`)."""
    own = getattr(model, "initial_range", None)
    if own is not None:
        return np.array(own[0], dtype=float), np.array(own[1], dtype=float)
    low, high = solvers.PAPER_SETTINGS[model.kind]["init_range"]
    factor = UNIT_TO_METRES[PAPER_UNIT] / UNIT_TO_METRES.get(model.unit, UNIT_TO_METRES[PAPER_UNIT])
    f = np.array([1.0 if name in ANGLE_VARIABLES else factor for name in model.variable_names])
    return low * f, high * f


def classify(best, model, *, probe_complete: bool, probe_converged: bool, out_of_time: bool) -> tuple[str, str]:
    """``(status, why)`` of an estimate no candidate converged for, from the work done: ``best`` (a
    :class:`~glpma_ros.solvers.local.LocalResult`) the polished point of least leg fitness;
    ``probe_complete`` the probe ran to its end (every start, or up to one that converged), and
    ``probe_converged`` one did; ``out_of_time`` a search was stopped by its deadline.  A pure function of
    its arguments: a probe cut by the deadline leaves the question open (``budget_exhausted``)."""
    rms = math.sqrt(best.leg_fitness / model.n_legs)
    cond = best.conditioning
    if not probe_complete:
        return STATUS_BUDGET, (f"not converged within the budget (the deciding work did not fit; RMS residual "
                               f"{rms:.3g} {model.unit})")
    if cond < NEAR_SINGULAR and rms < NEAR_SINGULAR_RMS * model.scale:
        return STATUS_NEAR_SINGULAR, (f"near a singularity: not converged (conditioning {cond:.2g}, "
                                      f"RMS residual {rms:.3g} {model.unit})")
    if rms > NO_SOLUTION_RMS * model.scale and not probe_converged and \
            (best.stationarity <= STATIONARY or best.progress < STALLED):
        return STATUS_NO_SOLUTION, f"no real assembly found (RMS residual {rms:.3g} {model.unit})"
    if out_of_time:
        return STATUS_BUDGET, f"not converged within the budget (RMS residual {rms:.3g} {model.unit})"
    return STATUS_MAX_EVALS, f"not converged within the evaluation cap (RMS residual {rms:.3g} {model.unit})"


class _Expected:
    """The expected duration (s) of one kind of compiled call: the longest seen, forgetting
    :data:`EXPECTED_DECAY` of itself per shorter one.  Durations are the thread's CPU time
    (``time.thread_time``): the work itself, not the time other processes took the core meanwhile
    (a preemption would otherwise hold the expectation high, and cut the next deciding work short)."""

    __slots__ = ("s",)

    def __init__(self, s: float = 0.0):
        self.s = s

    def note(self, seconds: float) -> None:
        self.s = max(seconds, (1.0 - EXPECTED_DECAY) * self.s)


@njit(cache=True, error_model="numpy", nogil=True)
def warm_readings_kernel(readings, divisor, lo, hi, offsets, buf, x0, legs_ref, legs, out) -> bool:
    """:func:`~glpma_ros.models.base.lengths_from_readings` (sensor readings -> ``legs``, each reading inside
    ``[lo, hi]``) and the warm stage (:func:`~glpma_ros.solvers.lm.warm_kernel` from ``x0``) in one compiled
    call: the node's everyday input without a Python step between the two.  False (nothing solved) when a
    reading is outside the band."""
    if not lengths_from_readings(readings, divisor, lo, hi, offsets, legs):
        return False
    lm.warm_kernel(buf, legs, x0, legs_ref, out)
    return True


@njit(cache=True, error_model="numpy", nogil=True)
def warm_accepted(out, n_vars, near_floor) -> bool:
    """Whether the warm stage's output ``out`` (:func:`~glpma_ros.solvers.lm.warm_kernel`, ``n_vars`` solver
    variables) is the estimate: the legs were accepted, it converged, and its platform joints moved at most
    :data:`CONTINUITY_FACTOR` times the legs' largest change (at least ``near_floor``) from the last pose's;
    otherwise the search looks for the branch nearest the last pose."""
    info = n_vars + local.POSE_OUT
    return out[info + lm.I_INPUT_OK] != 0.0 and out[info + lm.I_CONVERGED] == 1.0 and \
        out[info + lm.I_DISTANCE] <= max(CONTINUITY_FACTOR * out[info + lm.I_MOVEMENT], near_floor)


class Estimator:
    """Keeps the last solution and solves each new set of leg lengths from it.

    ``tolerance``: fitness (config unit squared) at which the evolutionary search stops (the papers'
    1e-20 by default) and, with ``polish=False``, the convergence criterion; ``leg_rtol``: with the
    refinement, a pose has converged when its largest leg residual is at most ``leg_rtol`` times
    ``max(scale, max leg)`` (see the module docstring); ``init_range``: ``(low, high)`` of the cold
    stage's uniform initial population for every variable (config unit, radians), the papers'
    protocol; default the papers' per-manipulator range (:func:`cold_range`).

    Redundant legs (more than the degrees of freedom): the pose is the least-squares one, converged
    when its residuals pass the chi-square test against ``leg_noise_std`` (config unit; default
    :data:`~glpma_ros.estimation.redundancy.DEFAULT_LEG_NOISE_M` in the config's unit); otherwise the status is
    ``inconsistent_legs`` with the leg most likely at fault, and, when ``exclude_faulty_leg`` and the other
    legs determine the pose consistently, the pose without it (the policy:
    :class:`~glpma_ros.estimation.redundancy.RedundantLegs`)."""

    def __init__(self, model, solver="glpma", time_budget_s=0.002, tolerance=solvers.common.DEFAULT_TOLERANCE,
                 seed=0, polish=True, initial_pose=None, population=None, local_population=None,
                 ls_interval=None, ls_intensity=None, max_evals=None, leg_rtol=lm.LEG_RTOL, init_range=None,
                 leg_noise_std=None, exclude_faulty_leg=True):
        self.model = model
        self.time_budget_s = float(time_budget_s)
        self.tolerance = float(tolerance)
        self.leg_rtol = float(leg_rtol)
        self.polish = bool(polish)
        self.max_evals = max_evals
        self.rng = np.random.default_rng(seed)
        self._lm = local.LocalSolver(model)
        self._n = model.n_vars
        self._info_at = model.n_vars + local.POSE_OUT       # where the kernel's info slots start in its output
        self._warm_buffer = None            # the warm stage's kernel buffer (lm.warm_buffer), built on first use
        self._near_floor = MIN_SPREAD * model.scale
        self._cold_range = cold_range(model) if init_range is None else \
            tuple(np.full(model.n_vars, float(v)) for v in init_range)
        self._probe_starts = np.ascontiguousarray(
            np.random.default_rng(PROBE_SEED).uniform(*self._cold_range, size=(PROBE_STARTS, model.n_vars)))
        self.redundant = redundancy.RedundantLegs(model, leg_noise_std, exclude_faulty_leg, self._probe_starts)
        self.leg_noise_std = self.redundant.leg_noise_std
        self._redundant = self.redundant.active     # read on every input: a plain attribute
        self._warm_message = f"warm start, {'least-squares pose' if self._redundant else 'leg residuals at round-off'}"
        # the loop bounds tell unreachable legs only where every leg is needed (redundant legs with a
        # faulty one are the redundancy policy's to judge)
        self._bounds = None if model.redundancy else PairBounds(model)
        self._lm.prepare()        # compiled code loaded now, not on the first input that needs it
        self.set_solver(solver, population=population, local_population=local_population,
                        ls_interval=ls_interval, ls_intensity=ls_intensity)
        self._settle_s, self._chunk_s = _Expected(), _Expected()
        self.calibrate()
        self.reset(initial_pose)

    # -- state ------------------------------------------------------------------
    def set_solver(self, name, **params):
        if name not in solvers.SOLVERS:
            raise InputError(f"unknown solver {name!r}; choose one of {', '.join(solvers.SOLVERS)}")
        self.solver = name
        # options of another solver (GLPMA's local search for G3-PCX, say) do not apply to this one
        self.params = {k: v for k, v in params.items() if v is not None and k in solvers.OPTIONS[name]}

    def reset(self, initial_pose=None):
        """Forget the warm-start state; ``initial_pose`` (solver variables) selects
        the assembly mode to start from."""
        self.redundant.reset()
        if initial_pose is None or len(initial_pose) == 0:
            self.last_x = self.last_legs = None
        else:
            self.last_x = np.array(self.model.check_variables(initial_pose), dtype=float)
            self.last_legs = np.ascontiguousarray(self.model.inverse_kinematics(self.last_x), dtype=float)

    @property
    def has_warm_state(self) -> bool:
        return self.last_x is not None

    @property
    def warm_output_size(self) -> int:
        """The size of the warm stage's output (:func:`~glpma_ros.solvers.lm.warm_kernel`'s ``out``)."""
        return self._lm.n_out

    @property
    def warm_x(self):
        """The solver variables the next input starts from (None: a cold start)."""
        return self.last_x

    @property
    def decision_reserve_s(self) -> float:
        """The time (s) the deciding work is expected to take, with its margin: the settle of a
        search's end point and the whole probe; with redundant legs also the isolation of a faulty leg."""
        return DECISION_MARGIN * (self._settle_s.s + self._chunk_s.s * math.ceil(PROBE_STARTS / PROBE_CHUNK)
                                  + self.redundant.isolation_s)

    @property
    def smallest_deciding_budget_s(self) -> float:
        """The smallest budget (s) whose reserve holds the deciding work with its margin: above it, the
        same legs get the same status whatever fitted of the search (on a machine no busier than the
        margin covers)."""
        return self.decision_reserve_s / DECISION_MAX_SHARE

    def calibrate(self) -> None:
        """A first measure of the deciding work's calls, before any input: a settle and the whole probe
        on the legs of the cold range's centre, with a fitness threshold no start meets (so that every
        start runs to its stationary point or stall, as on legs with no assembly).  Run twice, the first
        time to load the code and the caches; the inputs then keep the measures up to date.  Called again,
        it adds a new measure (the machine's load changed, say)."""
        model = self.model
        reference = getattr(model, "reference_legs", None)
        if reference is not None:       # an actuated family: its actuators at mid-range
            legs = reference()
        else:
            legs = model.inverse_kinematics(0.5 * (self._cold_range[0] + self._cold_range[1]))
            legs = np.where(legs > 0.0, legs, model.scale)          # any legs the kernel accepts will do
            if model.leg_limits is not None:
                legs = np.clip(legs, *model.leg_limits)
        legs = np.ascontiguousarray(legs, dtype=float)
        for _ in range(2):
            t0 = time.thread_time()
            self._lm.solve(self._probe_starts[0], legs, max_iter=SETTLE_MAX_ITER, rtol=self.leg_rtol, stall=STALLED,
                           ftol=-1.0)
            t1 = time.thread_time()
            self._lm.multistart(self._probe_starts[:PROBE_CHUNK], legs, max_iter=SETTLE_MAX_ITER, rtol=self.leg_rtol,
                                stall=STALLED, ftol=-1.0)
            t2 = time.thread_time()
        self._settle_s.note(t1 - t0)
        self._chunk_s.note(t2 - t1)
        if self.redundant.active:
            self.redundant.isolator.calibrate(legs, self._probe_starts[0])

    # -- solving ------------------------------------------------------------------
    def estimate(self, legs) -> Estimate:
        """Solve one set of leg lengths (config unit); raises :class:`InputError`.  Python's garbage
        collector is held off until the estimate returns (:data:`~glpma_ros.runtime.collector.HOLD`):
        its pauses, between two clock checks, are not bounded by the deadline."""
        t0 = time.perf_counter()
        HOLD.acquire()
        try:
            return self._estimate(legs, t0)
        finally:
            HOLD.release()

    def _estimate(self, legs, t0: float) -> Estimate:
        model = self.model
        if self._redundant:
            self.redundant.note_input()
        if self.last_x is None or not self.polish:
            return self._search(np.array(model.check_legs(legs), dtype=float), t0, None)
        try:
            arr = np.array(legs, dtype=float)           # a copy: kept as the next warm start's legs
        except (TypeError, ValueError, OverflowError):
            model.check_legs(legs)                      # raises with the reason
            raise
        if arr.shape != self.last_legs.shape:
            arr = np.array(model.check_legs(arr), dtype=float)
        if self.time_budget_s <= 0.0:                   # no time for any work: straight to what the legs tell
            return self._search(np.array(model.check_legs(arr), dtype=float), t0, None)
        # the warm stage: one compiled call (checks the legs, solves, measures)
        out = np.empty(self._lm.n_out)
        lm.warm_kernel(self._warm_kernel_buffer(), arr, self.last_x, self.last_legs, out)
        return self._after_warm(arr, out, t0)

    def estimate_readings(self, readings, divisor: float, lo: float, hi: float, offsets):
        """The everyday input in one compiled call (:func:`warm_readings_kernel`): sensor ``readings`` (one per
        leg, a message's floats) divided by ``divisor``, each inside ``[lo, hi]`` (the plausible band, config
        unit), plus ``offsets`` (:meth:`~glpma_ros.models.base.Manipulator.legs_from_sensors`), and the warm
        stage of :meth:`estimate` on them.  ``(legs, estimate)``, the same estimate :meth:`estimate` gives
        for those legs; None when this way does not apply (no warm start yet, the refinement off, no
        budget, not one reading per leg, a reading outside the band or not a number): then nothing was
        done, and the caller converts and checks the readings the long way and calls :meth:`estimate`."""
        legs_ref = self.last_legs
        if not self._warm_in_one_call or len(readings) != legs_ref.shape[0]:
            return None
        t0 = time.perf_counter()
        HOLD.acquire()
        try:
            try:
                values = np.array(readings, dtype=float)
            except (TypeError, ValueError):
                return None
            legs, out = np.empty(legs_ref.shape[0]), np.empty(self._lm.n_out)
            if not warm_readings_kernel(values, divisor, lo, hi, offsets, self._warm_kernel_buffer(),
                                        self.last_x, legs_ref, legs, out):
                return None
            if self._redundant:
                self.redundant.note_input()
            return legs, self._after_warm(legs, out, t0)
        finally:
            HOLD.release()

    def _warm_kernel_buffer(self) -> np.ndarray:
        buf = self._warm_buffer
        if buf is None or self._warm_key != (self.model.leg_limits, self.leg_rtol):
            buf = self._warm_buffer = self._lm.warm_buffer(
                local.make_settings(self.model, max_iter=WARM_MAX_ITER, rtol=self.leg_rtol))
            self._warm_key = (self.model.leg_limits, self.leg_rtol)
        return buf

    def warm_lane(self):
        """``(buf, x0, legs_ref, near_floor)`` for a compiled caller that runs the warm stage and its decision
        itself (:func:`warm_readings_kernel`, :func:`warm_accepted`: the node's message lane,
        :mod:`glpma_ros.node.pose_lane`) when the everyday one-call way applies -- a warm start, the
        refinement on, a budget, no redundant legs (whose consistency test is Python) -- else None.  After an
        accepted warm stage the caller calls :meth:`advance` (before the next input) and, when it needs the
        estimate, :meth:`warm_estimate`; after a declined one, :meth:`finish_warm`."""
        if not self._warm_in_one_call or self._redundant:
            return None
        return self._warm_kernel_buffer(), self.last_x, self.last_legs, self._near_floor

    @property
    def _warm_in_one_call(self) -> bool:
        """Whether the next input's warm stage can run as one compiled call with its conversion: a warm start,
        the refinement on, a budget for any work (:meth:`estimate_readings`, :meth:`warm_lane`)."""
        return self.last_x is not None and self.polish and self.time_budget_s > 0.0

    def advance(self, legs, out) -> None:
        """The warm state after an accepted warm stage: its variables (a view of ``out``) and ``legs``."""
        self.last_x, self.last_legs = out[:self._n], legs

    def warm_estimate(self, out, elapsed_s: float) -> Estimate:
        """The estimate of an accepted warm stage's output ``out``, which took ``elapsed_s``; read by the
        kernel's slot indices (the I_* layout, as LmOutput names them: one list of floats, no object per field)."""
        n = self._n
        info = out[self._info_at:].tolist()
        cond = info[lm.I_CONDITIONING]
        message = self._warm_message if cond >= NEAR_SINGULAR else \
            f"{self._warm_message}, near a singularity (conditioning {cond:.2g})"
        return Estimate(STATUS_CONVERGED, "warm", out[:n], Pose(out[n:n + 3], out[n + 3:n + local.POSE_OUT]),
                        info[lm.I_FITNESS], int(info[lm.I_NFEV]), elapsed_s, cond, self.solver, message,
                        info[lm.I_MAX_RESIDUAL])

    def finish_warm(self, legs, out, t0: float) -> Estimate:
        """:meth:`estimate` after a warm stage run by the caller (:meth:`warm_lane`) that :func:`warm_accepted`
        declined, ``t0`` = ``time.perf_counter()`` at its start: the search, or the legs' reason (raises)."""
        HOLD.acquire()
        try:
            return self._after_warm(legs, out, t0)
        finally:
            HOLD.release()

    def _after_warm(self, arr, out, t0: float) -> Estimate:
        """The warm stage's output ``out`` for legs ``arr``: the estimate when it converged near the last
        pose (:func:`warm_accepted`), else the search."""
        if out[self._info_at + lm.I_INPUT_OK] == 0.0:
            self.model.check_legs(arr)                  # raises with the reason
        if warm_accepted(out, self._n, self._near_floor):
            e = self.warm_estimate(out, time.perf_counter() - t0)
            if not self._redundant:             # the everyday case, no call more than needed
                self.advance(arr, out)
                return e
            return self._accept(e, arr, float(out[self._info_at + lm.I_LEG_FITNESS]), t0)
        return self._search(arr, t0, self._lm.result(out))

    def _advance(self, x, legs):
        """``x`` (for ``legs``) becomes the warm start of the next input."""
        self.redundant.advanced(self.last_x)
        self.last_x, self.last_legs = x, legs

    def _accept(self, e: Estimate, legs, leg_fitness: float, t0: float) -> Estimate:
        """A converged estimate: the next warm start; with redundant legs, after the consistency test
        (:class:`~glpma_ros.estimation.redundancy.RedundantLegs`), which may turn it into ``inconsistent_legs``."""
        if not self.redundant.active:
            self._advance(e.x, legs)
            return e
        near = math.inf
        if self.last_x is not None:
            near = max(CONTINUITY_FACTOR * float(np.max(np.abs(legs - self.last_legs))), self._near_floor)
        advance = self.redundant.judge(e, legs, leg_fitness, self.last_x, near, deadline=t0 + self.time_budget_s)
        if advance is not None:
            self._advance(advance, legs)
        e.elapsed_s = time.perf_counter() - t0
        return e

    def _run(self, legs, deadline, **init):
        budget = max(deadline - time.perf_counter(), 0.0)
        return solvers.solve(self.solver, self.model, legs, rng=self.rng, tolerance=self.tolerance,
                             budget_s=budget, polish=self.polish, max_evals=self.max_evals,
                             **init, **self.params)

    def _polish(self, x, legs, max_iter=SETTLE_MAX_ITER) -> local.LocalResult:
        """The compiled Levenberg-Marquardt from ``x``; distance from the previous pose."""
        return self._lm.solve(np.ascontiguousarray(x, dtype=float), legs, max_iter=max_iter,
                              rtol=self.leg_rtol, x_ref=self.last_x, stall=STALLED)

    def _settle(self, result, legs, deadline):
        """``(point, status_point, evaluations, settled)`` for a search's result: ``point`` is what the
        estimate reports (with the refinement: the polished end point or refinement point, whichever is
        better; without it: the search's own point, converged by the papers' criterion); ``status_point``
        the polished point the status is decided on; ``settled``: every polish fitted before the deadline
        (those that did not are evaluated where they start, not moved)."""
        starts = [result.x]
        if result.refined_x is not None and not np.array_equal(result.refined_x, result.x):
            starts.append(result.refined_x)
        polished, settled = [], True
        for x in starts:
            if time.perf_counter() + self._settle_s.s > deadline:
                polished.append(self._polish(x, legs, max_iter=0))
                settled = False
                continue
            c = time.thread_time()
            polished.append(self._polish(x, legs))
            self._settle_s.note(time.thread_time() - c)
        nfev = sum(p.nfev for p in polished)
        best = min(polished, key=lambda p: (not p.converged, p.leg_fitness))
        if self.polish:
            return best, best, nfev, settled
        # the search's own point; the polish above only informs the status
        x = np.asarray(result.x, dtype=float)
        at = self._lm.solve(np.ascontiguousarray(x), legs, max_iter=0, rtol=self.leg_rtol, x_ref=self.last_x)
        own = at._replace(x=x, converged=result.success, fitness=float(result.fun),
                          distance=0.0 if self.last_x is None else self.model.distance(x, self.last_x))
        return own, best, nfev + at.nfev, settled

    def _probe(self, legs, deadline):
        """``(result, done)``: the probe's Levenberg-Marquardt from the fixed starts, a few per compiled
        call, each call started only when it is expected to end before ``deadline``; ``result`` the first
        converged solve or the one of least leg fitness (None when no call fitted), ``done`` every start
        was tried or one converged."""
        best, nfev, nit = None, 0, 0
        for k in range(0, PROBE_STARTS, PROBE_CHUNK):
            if time.perf_counter() + self._chunk_s.s > deadline:
                return (None if best is None else best._replace(nfev=nfev, nit=nit)), False
            c = time.thread_time()
            r = self._lm.multistart(self._probe_starts[k:k + PROBE_CHUNK], legs, max_iter=SETTLE_MAX_ITER,
                                    rtol=self.leg_rtol, x_ref=self.last_x, stall=STALLED,
                                    ftol=self.redundant.consistent_fitness)
            self._chunk_s.note(time.thread_time() - c)
            nfev, nit = nfev + r.nfev, nit + r.nit
            if best is None or r.converged or r.leg_fitness < best.leg_fitness:
                best = r
            if r.converged:
                break
        return best._replace(nfev=nfev, nit=nit), True

    def _closed_form(self, legs, deadline):
        """A model with a closed-form forward kinematics (the three-leg Delta's sphere intersection,
        :meth:`~glpma_ros.models.actuated.DeltaTranslation.closed_form`): every mode polished (a polish
        expected to end after ``deadline`` is not run: the mode is evaluated where it is), as candidates
        ``(key, point, "cold")``; the key is the distance from the previous pose, or without one the model's
        preference (its working mode first).  None for the other models."""
        modes = getattr(self.model, "closed_form", None)
        xs = None if modes is None else modes(legs)
        if xs is None:
            return None
        found = []
        for rank, x in enumerate(self.model.preferred_order(xs)):
            fits = time.perf_counter() + self._settle_s.s <= deadline
            p = self._polish(x, legs, max_iter=SETTLE_MAX_ITER if fits else 0)
            found.append((p.distance if self.last_x is not None else float(rank), p, "cold"))
        return found

    def _search(self, legs, t0, warm) -> Estimate:
        """What the legs tell, the population stages, then the decision (``warm``: the warm stage's
        LocalResult, or None)."""
        model = self.model
        deadline = t0 + self.time_budget_s
        if self._bounds is not None:
            unreachable = self._bounds.check(legs)
            if unreachable is not None:
                # reported at the warm stage's point, else evaluated at the warm start or the cold range's
                # centre (one evaluation, when there is time left for it)
                p = warm
                if p is None and time.perf_counter() < deadline:
                    x = self.last_x if self.last_x is not None else 0.5 * (self._cold_range[0] + self._cold_range[1])
                    p = self._polish(x, legs, max_iter=0)
                if p is None:
                    return Estimate(STATUS_NO_SOLUTION, "cold", None, None, math.inf, 0, time.perf_counter() - t0,
                                    0.0, self.solver, f"no real assembly: {unreachable.why}", math.inf)
                return Estimate(STATUS_NO_SOLUTION, "cold", p.x, None, p.fitness, p.nfev, time.perf_counter() - t0,
                                p.conditioning, self.solver, f"no real assembly: {unreachable.why}", p.max_residual)
        # the search's own deadline leaves the deciding work its reserve
        budget = self.time_budget_s
        search_deadline = deadline - min(max(self.decision_reserve_s, DECISION_MIN_SHARE * budget),
                                         DECISION_MAX_SHARE * budget)
        candidates = []           # (distance to previous, point, stage)
        inconsistent = []         # redundant legs: least-squares poses that failed the consistency test
        tried = []                # (status point, stage)
        evaluations = 0
        out_of_time = False
        movement = 0.0
        near = self._near_floor
        stages = []
        consistent = self.redundant.consistent
        if warm is not None:
            evaluations += warm.nfev
            tried.append((warm, "warm"))
            if warm.converged:    # but far from the previous pose: look for a nearer branch
                (candidates if consistent(warm.leg_fitness) else inconsistent).append((warm.distance, warm, "warm"))
        if self.last_x is not None:
            movement = float(np.max(np.abs(legs - self.last_legs)))
            near = max(CONTINUITY_FACTOR * movement, near)
            spread = min(max(movement, MIN_SPREAD * model.scale), MAX_SPREAD * model.scale)
            stages = [("warm", spread), ("widened", WIDEN_FACTOR * spread)]
        stages.append(("cold", None))
        closed = self._closed_form(legs, deadline)
        if closed is not None:    # a closed form gives every mode: no search
            evaluations += sum(p.nfev for _, p, _ in closed)
            tried += [(p, stage) for _, p, stage in closed]
            candidates += [c for c in closed if c[1].converged]
            stages = []
        # a cold-only estimate gets the cold stage's share, i.e. the whole search time
        for (stage, spread), share in zip(stages, STAGE_SHARE[-len(stages):]):
            now = time.perf_counter()
            if now >= search_deadline:
                out_of_time = True
                break
            stage_deadline = now + share * (search_deadline - now)
            if spread is None:
                result = self._run(legs, stage_deadline, init_range=self._cold_range)
            else:
                result = self._run(legs, stage_deadline, center=self.last_x, spread=model.spread_vector(spread))
            point, status_point, nfev, settled = self._settle(result, legs, deadline)
            evaluations += result.nfev + nfev
            out_of_time = out_of_time or result.status == solvers.BUDGET_EXHAUSTED or not settled
            tried.append((status_point, stage))
            if point.converged and not consistent(point.leg_fitness):
                inconsistent.append((point.distance, point, stage))
            elif point.converged:
                candidates.append((point.distance, point, stage))
                if self.last_x is None or point.distance <= near:
                    break
        probe_complete = probe_converged = False
        if not candidates:
            # the probe: the same fixed work on every machine, whatever fitted of the search
            probe, probe_complete = self._probe(legs, deadline)
            if probe is not None:
                evaluations += probe.nfev
                tried.append((probe, "cold"))
                probe_converged = probe.converged
                if probe.converged and self.polish:
                    candidates.append((probe.distance, probe, "cold"))
        elapsed = time.perf_counter() - t0
        if not candidates and inconsistent:     # no pose explains the legs: which one is at fault
            candidates = inconsistent if self.last_x is not None else \
                [min(inconsistent, key=lambda c: c[1].leg_fitness)]
        if candidates:
            _, p, stage = min(candidates, key=lambda c: c[0])
            note = f", near a singularity (conditioning {p.conditioning:.2g})" if p.conditioning < NEAR_SINGULAR else ""
            how = "fitness below tolerance" if not self.polish else \
                "least-squares pose" if self.redundant.active else "leg residuals at round-off"
            return self._accept(Estimate(STATUS_CONVERGED, stage, p.x, Pose(p.position, p.orientation), p.fitness,
                                         evaluations, elapsed, p.conditioning, self.solver,
                                         f"{stage} start{' (closed form)' if closed else ''}, {how}{note}",
                                         p.max_residual), legs, p.leg_fitness, t0)
        if not tried:           # nothing fitted in the budget
            return Estimate(STATUS_BUDGET, "cold", None, None, math.inf, evaluations, elapsed, 0.0, self.solver,
                            "not converged within the budget (no search fitted)", math.inf)
        p, stage = min(tried, key=lambda t: t[0].leg_fitness)
        status, why = classify(p, model, probe_complete=probe_complete, probe_converged=probe_converged,
                               out_of_time=out_of_time)
        return Estimate(status, stage, p.x, None, p.fitness, evaluations, elapsed, p.conditioning, self.solver, why,
                        p.max_residual)
