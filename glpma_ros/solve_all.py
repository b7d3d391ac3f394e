"""Every distinct real assembly mode of a manipulator for given leg lengths.

Three methods (``solve_all(model, legs, method=...)``):

``"multistart"`` (default) -- many cheap local solves from starts spread over the pose space.
  Each start is a pose drawn at random (seeded ``numpy.random.Generator``): an orientation
  uniform on SO(3) (a normalised 4-D Gaussian, i.e. a uniform unit quaternion; 3-RPR: an
  angle uniform on (-pi, pi]) and a platform centre uniform in the region the legs can reach,
  the intersection of the balls around the base joints ``A_i`` of radius
  ``L_i + |b_i - c|`` (``c`` the centroid of the platform joints ``b_i``; any assembly has its
  centre there, so an empty intersection proves there is none).  From each start one
  Levenberg-Marquardt solve in pose space (:func:`_local_solve`) with an iteration cap
  ``LOCAL_MAX_ITER``: a start that has not converged by then is dropped.  A converged pose
  farther than ``DEDUP_RELATIVE`` of the scale from every mode found so far is a new mode.

  Stopping rule: after ``n`` starts of which the last new mode was found at start ``n_new``,
  stop once ``n - n_new >= max(STALL_MIN, STALL_FACTOR * n_new)`` -- the search has gone on at
  least ``STALL_FACTOR`` times as long as it took to find everything seen, and at least
  ``STALL_MIN`` starts, without finding anything new -- or at ``max_starts`` starts, or when
  ``budget_s`` runs out.  Reported with the result:

  * ``miss_probability``: the Good-Turing estimate of the probability that one more start
    would find a mode not yet seen, ``n1 / n`` with ``n1`` the number of modes found by
    exactly one start (Good 1953, "The population frequencies of species and the estimation
    of population parameters", Biometrika 40);
  * ``unseen_share_bound``: a 95 % upper confidence bound on the total share of the starts
    that lead to modes not seen, from the final run of ``k`` starts that found nothing new:
    ``1 - 0.05 ** (1 / k)`` (about ``3 / k``, the "rule of three").

  Both are statements about the basins of this start distribution, not a proof: a mode whose
  basin is tiny can be missed.  Use ``"exact"`` for a certificate.

``"g3pcx"`` -- the papers' method: ``runs`` independent polished G3-PCX searches from the wide
  initial range ``U[-2R, 2R]^n`` (Rolland & Chandra 2016, section 5.5.2 collect the 16 hexapod
  solutions with 100 runs from U[-2000, 2000]^9), de-duplicated the same way.

``"exact"`` -- the certified count (:mod:`glpma_ros.exact`, msolve's real root isolation of
  the rational polynomial system; the optional ``exact`` extra): every real solution,
  polished, and the number of complex solutions.

Every mode returned is polished to round-off by the model's refinement
(:func:`glpma_ros.solvers.refine.polish`).  With redundant legs (more than the degrees of freedom) a
mode is a least-squares pose whose leg residuals pass the estimator's consistency test
(:func:`consistent_fitness`: chi-square against the default leg noise); the exact method refuses them.
Plain Python + NumPy: no ROS import.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from . import solvers
from .errors import GlpmaError
from .solvers import refine
from .solvers.common import CONVERGED, SolveResult
from .solvers.local import LocalSolver

METHODS = ("multistart", "g3pcx", "exact")

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
#: multistart: starts drawn (and solved) per batch; the stopping rule is checked per start, so the
#: result does not depend on it
BATCH = 64
#: multistart: default cap on the number of starts
MAX_STARTS = 20_000
#: confidence of ``unseen_share_bound``
UNSEEN_CONFIDENCE = 0.95
#: rejection sampling of the reachable region: candidate rounds before falling back to its bounding box
REJECTION_ROUNDS = 20

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
    miss_probability: float | None = None  # multistart: Good-Turing chance that one more start finds a new mode
    unseen_share_bound: float | None = None  # multistart: 95 % bound on the share of starts leading to unseen modes
    complex_solutions: int | None = None  # exact: complex solutions (with multiplicity)
    stop_reason: str = ""                # multistart: stalled | max_starts | budget_exhausted | unreachable
    stall: int = 0                       # multistart: consecutive starts at the end that found nothing new
    hits: tuple = ()                     # multistart: starts that converged to each mode (order of solutions)


def consistent_fitness(model) -> float:
    """Redundant legs: the largest sum of squared leg residuals (config unit squared) of a mode, the
    estimator's consistency limit for the default leg noise; 0 without redundant legs."""
    if not model.redundancy:
        return 0.0
    from .estimator import DEFAULT_LEG_NOISE_M
    from .redundancy import chi2_limit
    sigma = DEFAULT_LEG_NOISE_M / getattr(model, "metres_per_unit", 1e-3)
    return chi2_limit(model.redundancy) * sigma * sigma


def _leg_fitness(model, x, legs) -> float:
    return float(np.sum((model.inverse_kinematics(x) - legs) ** 2))


def wide_range(model, legs) -> tuple[float, float]:
    half = RANGE_FACTOR * max(model.scale, float(np.max(legs)))
    return -half, half


def solve_all(model, legs, *, method=None, runs=None, seed=0, solver="g3pcx", max_evals=None,
              max_starts=None, budget_s=None) -> AllSolutions:
    """Every distinct real assembly mode of ``model`` at ``legs`` (config unit) by ``method``
    (module docstring; default ``"multistart"``, or ``"g3pcx"`` when ``runs`` is given, as
    before the multistart existed).  ``runs``: G3-PCX runs (default ``G3PCX_RUNS``);
    ``solver``, ``max_evals``: of those runs; ``max_starts`` (default ``MAX_STARTS``) and
    ``budget_s`` (seconds, default none): limits of the multistart; ``seed``: the random stream."""
    legs = model.check_legs(legs)
    if method is None:
        method = "g3pcx" if runs is not None else "multistart"
    if runs is not None and method != "g3pcx":
        raise GlpmaError(f"runs counts G3-PCX searches (method g3pcx); {method} does not take it")
    if (max_starts is not None or budget_s is not None) and method != "multistart":
        raise GlpmaError(f"max_starts and budget_s limit the multistart; {method} does not take them")
    if method == "multistart":
        return multistart(model, legs, seed=seed, max_starts=MAX_STARTS if max_starts is None else max_starts,
                          budget_s=budget_s)
    if method == "g3pcx":
        return g3pcx_runs(model, legs, runs=G3PCX_RUNS if runs is None else runs, seed=seed, solver=solver,
                          max_evals=max_evals)
    if method == "exact":
        return exact_modes(model, legs, seed=seed)
    raise GlpmaError(f"unknown solve_all method {method!r}; choose one of {', '.join(METHODS)}")


def _order(model, found: list) -> list:
    """Indices of ``found`` (SolveResults, their ``x`` made canonical here) sorted by variables."""
    for s in found:
        s.x = model.canonical(s.x)
    return sorted(range(len(found)), key=lambda k: tuple(np.round(found[k].x, 6)))


def _sorted(model, found: list) -> list:
    return [found[k] for k in _order(model, found)]


# -- the papers' method ---------------------------------------------------------------------------
def g3pcx_runs(model, legs, *, runs, seed=0, solver="g3pcx", max_evals=None) -> AllSolutions:
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    found = []
    evaluations = 0
    for _ in range(runs):
        r = solvers.solve(solver, model, legs, rng=rng, init_range=wide_range(model, legs), polish=True,
                          max_evals=max_evals)
        evaluations += r.nfev
        if not r.success or (model.redundancy and _leg_fitness(model, r.x, legs) > consistent_fitness(model)):
            continue
        if all(model.distance(r.x, s.x) > DEDUP_RELATIVE * model.scale for s in found):
            found.append(r)
    return AllSolutions(_sorted(model, found), runs, time.perf_counter() - t0, evaluations, method="g3pcx")


# -- multistart -------------------------------------------------------------------------------------
def _local_solve(local: LocalSolver, x0, legs, tolerance):
    """The local solve of the multistart (one start): the compiled Levenberg-Marquardt in pose
    space from solver variables ``x0``, at most ``LOCAL_MAX_ITER`` iterations.  Returns
    ``(x, leg_fitness, nfev)``; converged when ``leg_fitness < tolerance``."""
    r = local.solve(x0, legs, max_iter=LOCAL_MAX_ITER)
    return r.x, r.leg_fitness, r.nfev


class StartSampler:
    """Random starting poses (solver variables) over the region the legs can reach
    (module docstring).  ``empty``: the bounding box of that region is empty, which proves that
    no assembly exists."""

    def __init__(self, model, legs):
        self.model = model
        self.planar = model.platform.shape[1] == 2
        self.centroid = model.platform.mean(axis=0)
        radius = legs + np.linalg.norm(model.platform - self.centroid, axis=1)
        self.centres, self.radii = model.base, radius
        self.low = np.max(model.base - radius[:, None], axis=0)
        self.high = np.min(model.base + radius[:, None], axis=0)
        self.empty = bool(np.any(self.low > self.high))

    def _inside(self, P) -> np.ndarray:
        d2 = ((P[:, None, :] - self.centres[None]) ** 2).sum(axis=2)
        return np.all(d2 <= self.radii ** 2, axis=1)

    def centres_in_reach(self, rng, m) -> np.ndarray:
        """``m`` platform centres uniform in the intersection of the balls (rejection from its
        bounding box; after ``REJECTION_ROUNDS`` rounds the rest are taken from the box)."""
        dim = self.low.size
        out = np.empty((0, dim))
        for _ in range(REJECTION_ROUNDS):
            P = rng.uniform(self.low, self.high, size=(max(m, 16), dim))
            out = np.vstack((out, P[self._inside(P)]))
            if len(out) >= m:
                return out[:m]
        return np.vstack((out, rng.uniform(self.low, self.high, size=(m - len(out), dim))))

    def draw(self, rng, m) -> np.ndarray:
        P = self.centres_in_reach(rng, m)
        if self.planar:
            theta = rng.uniform(-math.pi, math.pi, size=m)
            c, s = np.cos(theta), np.sin(theta)
            cx, cy = self.centroid
            origin = P - np.column_stack((c * cx - s * cy, s * cx + c * cy))
            return np.column_stack((origin, theta))
        q = rng.standard_normal((m, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        x, y, z, w = q.T
        R = np.empty((m, 3, 3))
        R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
        R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
        R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
        # platform joints B_k = P + R (b_k - c) for the model's three frame joints (the variables)
        return (P[:, None, :] + np.einsum("mij,kj->mki", R, self.model.frame - self.centroid)).reshape(m, -1)


def _signature(model, x) -> np.ndarray:
    """The points ``model.distance`` compares (3-RPR: its first three joints; hexapod: the frame
    joints, its variables)."""
    return np.asarray(model.joints(x)[list(model.frame_joints)], dtype=float)


def multistart(model, legs, *, seed=0, max_starts=MAX_STARTS, budget_s=None) -> AllSolutions:
    """The multistart of the module docstring (``legs`` already checked)."""
    if max_starts < 1:
        raise GlpmaError("max_starts must be at least 1")
    if budget_s is not None and not budget_s > 0:
        raise GlpmaError("budget_s must be positive")
    t0 = time.perf_counter()
    deadline = None if budget_s is None else t0 + budget_s
    rng = np.random.default_rng(seed)
    tolerance = max((LOCAL_RESIDUAL_RELATIVE * model.scale) ** 2, consistent_fitness(model))
    dedup = DEDUP_RELATIVE * model.scale
    sampler = StartSampler(model, legs)
    local = LocalSolver(model)
    modes, signatures, hits = [], np.empty((0, 3, model.base.shape[1])), []
    starts = evaluations = last_new = 0
    reason = UNREACHABLE if sampler.empty else ""
    while not reason:
        for x0 in sampler.draw(rng, min(BATCH, max_starts - starts)):
            x, f, nfev = _local_solve(local, np.ascontiguousarray(x0), legs, tolerance)
            starts += 1
            evaluations += nfev
            if f < tolerance:
                sig = _signature(model, x)
                d = np.sqrt(((signatures - sig) ** 2).sum(axis=2)).max(axis=1) if len(modes) else np.empty(0)
                j = int(np.argmin(d)) if d.size else -1
                if j >= 0 and d[j] <= dedup:
                    hits[j] += 1
                else:
                    modes.append(x)
                    signatures = np.concatenate((signatures, sig[None]))
                    hits.append(1)
                    last_new = starts
            if starts - last_new >= max(STALL_MIN, STALL_FACTOR * last_new):
                reason = STALLED
            elif starts >= max_starts:
                reason = MAX_STARTS_REACHED
            elif deadline is not None and time.perf_counter() >= deadline:
                reason = BUDGET_EXHAUSTED
            if reason:
                break
    polish_rng = np.random.default_rng(seed)
    found = []
    for x in modes:
        t1 = time.perf_counter()
        xp, fp, nfev, _ = refine.polish(model, x, legs, polish_rng)
        evaluations += nfev
        found.append(SolveResult(xp, fp, nfev, 0, time.perf_counter() - t1, CONVERGED, "multistart",
                                 polished=True))
    order = _order(model, found)
    stall = starts - last_new
    singletons = sum(1 for h in hits if h == 1)
    return AllSolutions([found[k] for k in order], starts, time.perf_counter() - t0, evaluations,
                        method="multistart", starts=starts,
                        miss_probability=singletons / starts if starts else None,
                        unseen_share_bound=1.0 - (1.0 - UNSEEN_CONFIDENCE) ** (1.0 / stall) if stall else 1.0,
                        stop_reason=reason, stall=stall, hits=tuple(hits[k] for k in order))


# -- certified ----------------------------------------------------------------------------------
def exact_modes(model, legs, *, seed=0) -> AllSolutions:
    """Every real mode certified by msolve (:mod:`glpma_ros.exact`), each polished."""
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
                        complex_solutions=sol.complex_solutions)
