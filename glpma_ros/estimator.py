"""The per-message logic of the node: warm start, escalation, branch choice.

Rolland & Chandra (2016, section 5.5) show that an initial population drawn near
one solution isolates that solution; Funes Lora et al. (2018) inject the
previous pose into the population and keep the configuration nearest the
previous one.  For every new set of leg lengths the estimator

1. **warm**: runs the solver from a population around the previous estimate
   (the previous estimate itself included), with a spread equal to how far the
   legs moved, and polishes; accepted when it converges to a solution near the
   previous one;
2. **widened**: if not, the same with a spread ``WIDEN_FACTOR`` times larger;
3. **cold**: if still not, a search from the papers' wide initial range;

and, among the converged candidates, keeps the one nearest the previous pose,
so that it does not jump assembly mode on a continuous trajectory.  Stages share
the time budget (``STAGE_SHARE``): the deadline is hard.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from . import solvers
from .errors import InputError
from .models.base import Pose

#: spread of the widened stage relative to the warm one
WIDEN_FACTOR = 10.0
#: share of the remaining budget each stage may use (warm, widened, cold)
STAGE_SHARE = (0.4, 0.5, 1.0)
#: a converged solution farther than this many leg displacements from the previous
#: pose (in platform-joint distance) triggers the search for a nearer branch
CONTINUITY_FACTOR = 20.0
#: smallest warm-start spread, relative to the geometry's scale
MIN_SPREAD = 1e-6
#: largest warm-start spread, relative to the scale (beyond it the cold stage's range is the better start)
MAX_SPREAD = 10.0
#: an unconverged fitness whose RMS leg residual exceeds this share of the scale
#: means the legs have no real assembly (rather than too little time)
NO_SOLUTION_RMS = 1e-6
#: |J^T r| / (|J| |r|) below which the best point is a stationary point of the fitness
STATIONARY = 1e-2
#: reciprocal condition number of the leg Jacobian below which a pose is near a
#: singularity (assembly modes meet; the seed examples are at 0.02-0.13)
NEAR_SINGULAR = 1e-3
#: an unconverged best point near a singularity counts as "near singular" rather
#: than "no solution" while its RMS residual is below this share of the scale
NEAR_SINGULAR_RMS = 1e-2

STATUS_CONVERGED = "converged"
STATUS_NO_SOLUTION = "no_solution"
STATUS_BUDGET = "budget_exhausted"
STATUS_NEAR_SINGULAR = "near_singular"


@dataclass
class Estimate:
    status: str
    start: str                 # warm | widened | cold
    x: np.ndarray | None       # solver variables (config unit)
    pose: Pose | None
    fitness: float
    evaluations: int
    elapsed_s: float
    conditioning: float        # reciprocal condition number of the leg Jacobian, 0 = singular
    solver: str
    message: str = ""

    @property
    def converged(self) -> bool:
        return self.status == STATUS_CONVERGED

    @property
    def near_singular(self) -> bool:
        return self.conditioning < NEAR_SINGULAR


class Estimator:
    """Keeps the last solution and solves each new set of leg lengths from it."""

    def __init__(self, model, solver="glpma", time_budget_s=0.002, tolerance=solvers.common.DEFAULT_TOLERANCE,
                 seed=0, polish=True, initial_pose=None, population=None, local_population=None,
                 ls_interval=None, ls_intensity=None, max_evals=None):
        self.model = model
        self.time_budget_s = float(time_budget_s)
        self.tolerance = float(tolerance)
        self.polish = bool(polish)
        self.max_evals = max_evals
        self.rng = np.random.default_rng(seed)
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
        if initial_pose is None or len(initial_pose) == 0:
            self.last_x = self.last_legs = None
        else:
            self.last_x = self.model.check_variables(initial_pose)
            self.last_legs = self.model.inverse_kinematics(self.last_x)

    @property
    def has_warm_state(self) -> bool:
        return self.last_x is not None

    def _stationary(self, x, legs) -> bool:
        """The residual is orthogonal to the Jacobian's range at ``x``: a local
        minimum with a nonzero residual (no real assembly there), not a search
        that merely ran out of time."""
        if not np.all(np.isfinite(x)):
            return False
        with np.errstate(over="ignore", invalid="ignore"):   # huge legs: not decidable, not stationary
            r, J = self.model.pose_residuals_jacobian(self.model.pose_state(x), legs)
            J = J * self.model.pose_column_scale
            denominator = float(np.linalg.norm(J) * np.linalg.norm(r))
            gradient = float(np.linalg.norm(J.T @ r))
        return math.isfinite(denominator) and denominator > 0 and gradient <= STATIONARY * denominator

    # -- solving ------------------------------------------------------------------
    def _run(self, legs, deadline, **init):
        budget = max(deadline - time.perf_counter(), 0.0)
        return solvers.solve(self.solver, self.model, legs, rng=self.rng, tolerance=self.tolerance,
                             budget_s=budget, polish=self.polish, max_evals=self.max_evals,
                             **init, **self.params)

    def estimate(self, legs) -> Estimate:
        """Solve one set of leg lengths (config unit); raises :class:`InputError`."""
        legs = self.model.check_legs(legs)
        t0 = time.perf_counter()
        deadline = t0 + self.time_budget_s
        model = self.model
        candidates = []           # (distance to previous, result, stage)
        evaluations = 0
        best = None
        stages = []
        movement = 0.0
        if self.last_x is not None:
            movement = float(np.max(np.abs(legs - self.last_legs)))
            spread = min(max(movement, MIN_SPREAD * model.scale), MAX_SPREAD * model.scale)
            stages = [("warm", spread), ("widened", WIDEN_FACTOR * spread)]
        stages.append(("cold", None))
        # a cold-only estimate gets the cold stage's share, i.e. the whole budget
        for (stage, spread), share in zip(stages, STAGE_SHARE[-len(stages):]):
            now = time.perf_counter()
            if now >= deadline:
                break
            stage_deadline = now + share * (deadline - now)
            if spread is None:
                result = self._run(legs, stage_deadline)
            else:
                result = self._run(legs, stage_deadline, center=self.last_x, spread=model.spread_vector(spread))
            evaluations += result.nfev
            if best is None or result.fun < best[0].fun:
                best = (result, stage)
            if result.success:
                if self.last_x is None:
                    candidates.append((0.0, result, stage))
                    break
                dist = model.distance(result.x, self.last_x)
                candidates.append((dist, result, stage))
                if dist <= max(CONTINUITY_FACTOR * movement, MIN_SPREAD * model.scale):
                    break
        elapsed = time.perf_counter() - t0
        if candidates:
            _, result, stage = min(candidates, key=lambda c: c[0])
            self.last_x, self.last_legs = result.x, legs
            cond = model.conditioning(result.x, legs)
            note = f", near a singularity (conditioning {cond:.2g})" if cond < NEAR_SINGULAR else ""
            return Estimate(STATUS_CONVERGED, stage, result.x, model.pose(result.x), result.fun, evaluations,
                            elapsed, cond, self.solver, f"{stage} start, {result.message}{note}")
        result, stage = best if best is not None else (None, stages[0][0])
        if result is None:
            return Estimate(STATUS_BUDGET, stage, None, None, math.inf, evaluations, elapsed, 0.0, self.solver,
                            "time budget exhausted before a search could start")
        rms = math.sqrt(result.fun / model.n_res) if math.isfinite(result.fun) else math.inf
        cond = model.conditioning(result.x, legs) if np.all(np.isfinite(result.x)) else 0.0
        if cond < NEAR_SINGULAR and rms < NEAR_SINGULAR_RMS * model.scale:
            status, why = STATUS_NEAR_SINGULAR, (f"near a singularity: not converged (conditioning {cond:.2g}, "
                                                 f"RMS residual {rms:.3g} {model.unit})")
        elif rms > NO_SOLUTION_RMS * model.scale and any(
                self._stationary(x, legs) for x in (result.x, result.refined_x) if x is not None):
            status, why = STATUS_NO_SOLUTION, f"no real assembly found (RMS residual {rms:.3g} {model.unit})"
        else:
            status, why = STATUS_BUDGET, f"not converged within the budget (fitness {result.fun:.3g})"
        return Estimate(status, stage, result.x, None, result.fun, evaluations, elapsed, cond, self.solver, why)
