"""The per-message logic of the node: warm start, escalation, branch choice, status.

Rolland & Chandra (2016, section 5.5) show that an initial population drawn near
one solution isolates that solution; Funes Lora et al. (2018) inject the
previous pose into the population and keep the configuration nearest the
previous one.  For every new set of leg lengths the estimator

1. **warm** (with the refinement on, the node's everyday case): one compiled
   Levenberg-Marquardt call from the previous estimate
   (:mod:`glpma_ros.solvers.lm`); accepted when it converges to a solution near
   the previous one;
2. otherwise the population stages: **warm** (the solver's population around the
   previous estimate, with a spread equal to how far the legs moved; without the
   refinement this is the first stage), **widened** (the same with a spread
   ``WIDEN_FACTOR`` times larger), **cold** (the papers' wide initial range);

and, among the converged candidates, keeps the one nearest the previous pose,
so that it does not jump assembly mode on a continuous trajectory.  The
population stages share the time budget (``STAGE_SHARE``): the deadline is hard.

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
ends on is polished by the compiled Levenberg-Marquardt without a deadline
(microseconds, bounded by its iteration cap): a polish that meets the leg
criterion is ``converged`` however little of the search fitted in the budget.
When none does, a *probe* runs: the same Levenberg-Marquardt from
``PROBE_STARTS`` fixed starts in the papers' initial range (a fixed seed, so the
same work on every machine), stopping at the first that converges (reported as
a ``cold`` start).  If the probe fails too, the best polished point decides: ``near_singular`` (leg Jacobian
nearly singular, small residual), ``no_solution`` (a residual that the polish
cannot lower: a stationary point of the fitness, or a polish that stalled; no
real assembly there); only when neither holds is
the status ``budget_exhausted`` (the time ran out) or ``max_evals`` (the
evaluation caps did).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .. import solvers
from ..config import UNIT_TO_METRES
from ..errors import InputError
from ..models.base import Pose
from ..solvers import lm, local
from ..solvers.driver import POLISH_MAX_ITER
from . import redundancy

#: spread of the widened stage relative to the warm one
WIDEN_FACTOR = 10.0
#: share of the remaining budget each population stage may use (warm, widened, cold)
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
#: iteration cap of the polish that settles a search's end point (no deadline: microseconds)
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
#: seed of the probe's starts (fixed: the probe is the same work on every machine)
PROBE_SEED = 0
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
STATUS_INCONSISTENT = "inconsistent_legs"


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
    kept)."""
    low, high = solvers.PAPER_SETTINGS[model.kind]["init_range"]
    factor = UNIT_TO_METRES[PAPER_UNIT] / UNIT_TO_METRES.get(model.unit, UNIT_TO_METRES[PAPER_UNIT])
    f = np.array([1.0 if name in ANGLE_VARIABLES else factor for name in model.variable_names])
    return low * f, high * f


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
    ``inconsistent_legs``
    with the leg most likely at fault, and, when ``exclude_faulty_leg`` and the other legs determine
    the pose consistently, the pose without it (:mod:`glpma_ros.estimation.redundancy`)."""

    def __init__(self, model, solver="glpma", time_budget_s=0.002, tolerance=solvers.common.DEFAULT_TOLERANCE,
                 seed=0, polish=True, initial_pose=None, population=None, local_population=None,
                 ls_interval=None, ls_intensity=None, max_evals=None, leg_rtol=lm.LEG_RTOL, init_range=None,
                 leg_noise_std=None, exclude_faulty_leg=True):
        self.model = model
        self.leg_noise_std = redundancy.leg_noise(model, leg_noise_std)
        self.exclude_faulty_leg = bool(exclude_faulty_leg)
        self._isolator = redundancy.FaultIsolator(model) if model.redundancy > 0 else None
        self.consistency_limit = redundancy.chi2_limit(model.redundancy)
        #: the largest sum of squared leg residuals (config unit squared) of a consistent pose
        self._consistent_fitness = self.consistency_limit * self.leg_noise_std ** 2 if model.redundancy else math.inf
        self.time_budget_s = float(time_budget_s)
        self.tolerance = float(tolerance)
        self.leg_rtol = float(leg_rtol)
        self.polish = bool(polish)
        self.max_evals = max_evals
        self.rng = np.random.default_rng(seed)
        self._lm = local.LocalSolver(model)
        self._n = model.n_vars
        self._warm_settings = None          # the warm stage's kernel settings, built on first use
        self._near_floor = MIN_SPREAD * model.scale
        self._cold_range = cold_range(model) if init_range is None else \
            tuple(np.full(model.n_vars, float(v)) for v in init_range)
        self._probe_starts = np.ascontiguousarray(
            np.random.default_rng(PROBE_SEED).uniform(*self._cold_range, size=(PROBE_STARTS, model.n_vars)))
        self._lm.prepare()        # compiled code loaded now, not on the first input that needs it
        self.set_solver(solver, population=population, local_population=local_population,
                        ls_interval=ls_interval, ls_intensity=ls_intensity)
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
        self.prev_x = None                  # the estimate before last_x (redundant legs: the prediction)
        self._inputs = self._advanced_at = 0    # redundant legs: inputs seen, and when last_x was set
        self.excluded = None                # the leg left out of the last pose (redundant legs)
        if initial_pose is None or len(initial_pose) == 0:
            self.last_x = self.last_legs = None
        else:
            self.last_x = np.array(self.model.check_variables(initial_pose), dtype=float)
            self.last_legs = np.ascontiguousarray(self.model.inverse_kinematics(self.last_x), dtype=float)

    @property
    def has_warm_state(self) -> bool:
        return self.last_x is not None

    @property
    def warm_x(self):
        """The solver variables the next input starts from (None: a cold start)."""
        return self.last_x

    # -- solving ------------------------------------------------------------------
    def estimate(self, legs) -> Estimate:
        """Solve one set of leg lengths (config unit); raises :class:`InputError`."""
        t0 = time.perf_counter()
        model = self.model
        if self._isolator is not None:
            self._inputs += 1
        if self.last_x is None or not self.polish:
            return self._search(np.array(model.check_legs(legs), dtype=float), t0, None)
        try:
            arr = np.array(legs, dtype=float)           # a copy: kept as the next warm start's legs
        except (TypeError, ValueError, OverflowError):
            model.check_legs(legs)                      # raises with the reason
            raise
        if arr.shape != self.last_legs.shape:
            arr = np.array(model.check_legs(arr), dtype=float)
        # the warm stage: one compiled call (checks the legs, solves, measures)
        settings = self._warm_settings
        if settings is None or self._warm_key != (model.leg_limits, self.leg_rtol):
            settings = self._warm_settings = local.make_settings(model, max_iter=WARM_MAX_ITER, rtol=self.leg_rtol)
            self._warm_key = (model.leg_limits, self.leg_rtol)
        solver = self._lm
        out = np.empty(solver.n_out)
        lm.lm_kernel(solver.kind, solver.data, solver.platform, solver.frame, arr, self.last_x, self.last_x,
                     self.last_legs, settings, out, solver.work)
        n = self._n
        info = out[n + 7:].tolist()
        if info[lm.I_INPUT_OK] == 0.0:
            model.check_legs(arr)                       # raises with the reason
        if info[lm.I_CONVERGED] == 1.0 and \
                info[lm.I_DISTANCE] <= max(CONTINUITY_FACTOR * info[lm.I_MOVEMENT], self._near_floor):
            x = out[:n]
            cond = info[lm.I_CONDITIONING]
            note = "" if cond >= NEAR_SINGULAR else f", near a singularity (conditioning {cond:.2g})"
            isolator = self._isolator
            how = "leg residuals at round-off" if isolator is None else "least-squares pose"
            e = Estimate(STATUS_CONVERGED, "warm", x, Pose(out[n:n + 3], out[n + 3:n + 7]), info[lm.I_FITNESS],
                         int(info[lm.I_NFEV]), time.perf_counter() - t0, cond, self.solver, f"warm start, {how}{note}",
                         info[lm.I_MAX_RESIDUAL])
            if isolator is None:             # the everyday case, no call more than needed
                self.last_x, self.last_legs = x, arr
                return e
            return self._accept(e, arr, info[lm.I_LEG_FITNESS], t0)
        return self._search(arr, t0, solver.result(out))

    # -- redundant legs ---------------------------------------------------------------
    def _consistent(self, point) -> bool:
        """A converged point passes the consistency test (always without redundant legs)."""
        return point.leg_fitness <= self._consistent_fitness

    def _advance(self, x, legs):
        """``x`` (for ``legs``) becomes the warm start of the next input."""
        self.prev_x, self.last_x, self.last_legs = self.last_x, x, legs
        self._advanced_at = self._inputs

    def _accept(self, e: Estimate, legs, leg_fitness: float, t0: float) -> Estimate:
        """A converged estimate: the next warm start; with redundant legs, after the consistency test
        (:mod:`glpma_ros.estimation.redundancy`), which may turn it into ``inconsistent_legs``."""
        if self._isolator is None:
            self._advance(e.x, legs)
            return e
        T = leg_fitness / self.leg_noise_std ** 2
        e.consistency, e.consistency_limit = T, self.consistency_limit
        if T <= self.consistency_limit:
            self.excluded = None
            self._advance(e.x, legs)
            e.message += f", legs consistent (chi-square {T:.3g} <= {self.consistency_limit:.3g})"
            return e
        return self._inconsistent(e, legs, t0)

    def _inconsistent(self, e: Estimate, legs, t0: float) -> Estimate:
        """The least-squares pose failed the consistency test: name the leg most likely at fault and,
        when the other legs determine the pose consistently, give that pose (left-out leg named)."""
        model = self.model
        predicted, near = None, math.inf
        if self.last_x is not None:
            # constant velocity per input from the last two estimates, over the inputs since the last one
            # (an input that gave no pose leaves the history behind by one more step)
            steps = max(self._inputs - self._advanced_at, 1)
            predicted = self.last_x if self.prev_x is None else self.last_x + steps * (self.last_x - self.prev_x)
            near = max(CONTINUITY_FACTOR * float(np.max(np.abs(legs - self.last_legs))), self._near_floor)
        iso = self._isolator.isolate(legs, self.last_x, self.leg_noise_std, predicted, near, first=self.excluded,
                                     starts=self._probe_starts)
        e.status, e.suspect_leg = STATUS_INCONSISTENT, iso.leg
        e.evaluations += iso.evaluations
        head = f"legs inconsistent (chi-square {e.consistency:.3g} > {e.consistency_limit:.3g})"
        x_ls = e.x
        e.pose = None
        if iso.leg is None:
            e.message = f"{head}; {iso.reason}"
        elif not iso.isolated:
            e.message = f"{head}; leg {iso.leg + 1} most likely at fault ({iso.reason})"
        else:
            r = iso.result
            self.excluded = iso.leg
            self._advance(r.x, legs)
            if self.exclude_faulty_leg:
                e.x, e.pose, e.excluded_leg = r.x, Pose(r.position, r.orientation), iso.leg
                e.conditioning, e.max_residual = r.conditioning, r.max_residual
                e.fitness = r.fitness          # the papers' fitness of the legs the pose used
                e.message = (f"{head}; leg {iso.leg + 1} most likely at fault, left out: pose from the other "
                             f"{model.n_legs - 1} legs")
            else:
                e.message = f"{head}; leg {iso.leg + 1} most likely at fault (exclude_faulty_leg off: no pose)"
        if e.pose is None:
            e.x = x_ls
        e.elapsed_s = time.perf_counter() - t0
        return e

    def _run(self, legs, deadline, **init):
        budget = max(deadline - time.perf_counter(), 0.0)
        return solvers.solve(self.solver, self.model, legs, rng=self.rng, tolerance=self.tolerance,
                             budget_s=budget, polish=self.polish, max_evals=self.max_evals,
                             **init, **self.params)

    def _polish(self, x, legs) -> local.LocalResult:
        """The compiled Levenberg-Marquardt from ``x``, without a deadline; distance from the previous pose."""
        return self._lm.solve(np.ascontiguousarray(x, dtype=float), legs, max_iter=SETTLE_MAX_ITER,
                              rtol=self.leg_rtol, x_ref=self.last_x, stall=STALLED)

    def _settle(self, result, legs):
        """``(point, status_point, evaluations)`` for a search's result: ``point`` is what the estimate
        reports (with the refinement: the polished end point or refinement point, whichever is better;
        without it: the search's own point, converged by the papers' criterion); ``status_point`` the
        polished point the status is decided on."""
        starts = [result.x]
        if result.refined_x is not None and not np.array_equal(result.refined_x, result.x):
            starts.append(result.refined_x)
        polished = [self._polish(x, legs) for x in starts]
        nfev = sum(p.nfev for p in polished)
        best = min(polished, key=lambda p: (not p.converged, p.leg_fitness))
        if self.polish:
            return best, best, nfev
        # the search's own point; the polish above only informs the status
        x = np.asarray(result.x, dtype=float)
        at = self._lm.solve(np.ascontiguousarray(x), legs, max_iter=0, rtol=self.leg_rtol, x_ref=self.last_x)
        own = at._replace(x=x, converged=result.success, fitness=float(result.fun),
                          distance=0.0 if self.last_x is None else self.model.distance(x, self.last_x))
        return own, best, nfev + at.nfev

    def _search(self, legs, t0, warm) -> Estimate:
        """The population stages, then the decision (``warm``: the warm stage's LocalResult, or None)."""
        model = self.model
        deadline = t0 + self.time_budget_s
        candidates = []           # (distance to previous, point, stage)
        inconsistent = []         # redundant legs: least-squares poses that failed the consistency test
        tried = []                # (status point, stage)
        evaluations = 0
        out_of_time = False
        movement = 0.0
        near = self._near_floor
        stages = []
        if warm is not None:
            evaluations += warm.nfev
            tried.append((warm, "warm"))
            if warm.converged:    # but far from the previous pose: look for a nearer branch
                (candidates if self._consistent(warm) else inconsistent).append((warm.distance, warm, "warm"))
        if self.last_x is not None:
            movement = float(np.max(np.abs(legs - self.last_legs)))
            near = max(CONTINUITY_FACTOR * movement, near)
            spread = min(max(movement, MIN_SPREAD * model.scale), MAX_SPREAD * model.scale)
            stages = [("warm", spread), ("widened", WIDEN_FACTOR * spread)]
        stages.append(("cold", None))
        # a cold-only estimate gets the cold stage's share, i.e. the whole budget
        for (stage, spread), share in zip(stages, STAGE_SHARE[-len(stages):]):
            now = time.perf_counter()
            if now >= deadline and tried:   # the first search runs even when the budget is gone
                out_of_time = True
                break
            stage_deadline = now + share * max(deadline - now, 0.0)
            if spread is None:
                result = self._run(legs, stage_deadline, init_range=self._cold_range)
            else:
                result = self._run(legs, stage_deadline, center=self.last_x, spread=model.spread_vector(spread))
            point, status_point, nfev = self._settle(result, legs)
            evaluations += result.nfev + nfev
            out_of_time = out_of_time or result.status == solvers.BUDGET_EXHAUSTED
            tried.append((status_point, stage))
            if point.converged and not self._consistent(point):
                inconsistent.append((point.distance, point, stage))
            elif point.converged:
                candidates.append((point.distance, point, stage))
                if self.last_x is None or point.distance <= near:
                    break
        probe = None
        if not candidates:
            # the probe: the same fixed work on every machine, whatever fitted in the budget
            probe = self._lm.multistart(self._probe_starts, legs, max_iter=SETTLE_MAX_ITER, rtol=self.leg_rtol,
                                        x_ref=self.last_x, stall=STALLED, ftol=self._consistent_fitness)
            evaluations += probe.nfev
            tried.append((probe, "cold"))
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
                "leg residuals at round-off" if self._isolator is None else "least-squares pose"
            return self._accept(Estimate(STATUS_CONVERGED, stage, p.x, Pose(p.position, p.orientation), p.fitness,
                                         evaluations, elapsed, p.conditioning, self.solver,
                                         f"{stage} start, {how}{note}", p.max_residual), legs, p.leg_fitness, t0)
        p, stage = min(tried, key=lambda t: t[0].leg_fitness)
        rms = math.sqrt(p.leg_fitness / model.n_legs)
        cond = p.conditioning
        if cond < NEAR_SINGULAR and rms < NEAR_SINGULAR_RMS * model.scale:
            status, why = STATUS_NEAR_SINGULAR, (f"near a singularity: not converged (conditioning {cond:.2g}, "
                                                 f"RMS residual {rms:.3g} {model.unit})")
        elif rms > NO_SOLUTION_RMS * model.scale and not probe.converged and \
                (p.stationarity <= STATIONARY or p.progress < STALLED):
            status, why = STATUS_NO_SOLUTION, f"no real assembly found (RMS residual {rms:.3g} {model.unit})"
        elif out_of_time:
            status, why = STATUS_BUDGET, f"not converged within the budget (RMS residual {rms:.3g} {model.unit})"
        else:
            status, why = STATUS_MAX_EVALS, (f"not converged within the evaluation cap "
                                             f"(RMS residual {rms:.3g} {model.unit})")
        return Estimate(status, stage, p.x, None, p.fitness, evaluations, elapsed, cond, self.solver, why,
                        p.max_residual)
