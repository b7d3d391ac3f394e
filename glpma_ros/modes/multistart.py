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

``"multistart"`` -- many cheap local solves from random starts within the legs' reach, with a stopping
  rule, a partner search near folds and a parity rule (:mod:`glpma_ros.modes.multistart_search`);
  not a certificate.

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
method refuses them.  The modes and what every method shares: :mod:`glpma_ros.modes.solutions`.
Plain Python + NumPy: no ROS import.
"""
from __future__ import annotations

import time

import numpy as np

from .. import solvers
from ..errors import GlpmaError
from ..estimation.redundancy import leg_noise
from ..solvers import refine
from ..solvers.common import CONVERGED, SolveResult
from . import exact, homotopy
from .monodromy import has_start_system
from .multistart_search import MAX_STARTS, multistart
from .solutions import (
    DEDUP_RELATIVE,
    LOCAL_RESIDUAL_RELATIVE,
    AllSolutions,
    consistent_fitness,
    leg_fitness,
    sorted_modes,
)

METHODS = ("homotopy", "multistart", "g3pcx", "exact", "closed_form")

#: half-width of the G3-PCX initial range in units of the geometry's size (longest leg or joint spread)
RANGE_FACTOR = 2.0
#: default number of G3-PCX runs (the papers' 100, doubled: one run misses a mode now and then)
G3PCX_RUNS = 200


def wide_range(model, legs) -> tuple[float, float]:
    half = RANGE_FACTOR * max(model.scale, float(np.max(model.rods_of(legs))))
    return -half, half


def solve_all(model, legs, *, method=None, runs=None, seed=0, solver="g3pcx", max_evals=None,
              max_starts=None, budget_s=None, polish=True, leg_noise_std=None, threads=None) -> AllSolutions:
    """Every distinct real assembly mode of ``model`` at ``legs`` (config unit) by ``method``
    (module docstring; default ``"homotopy"`` where the model's family has a start system, else
    ``"multistart"``; ``"g3pcx"`` when ``runs`` is given, and the
    multistart when one of its limits or ``polish=False`` is).  ``runs``: G3-PCX runs (default ``G3PCX_RUNS``);
    ``solver``, ``max_evals``: of those runs; ``max_starts`` (default ``MAX_STARTS``) and
    ``budget_s`` (seconds, default none): limits of the multistart, ``polish=False``: its modes as
    found (counting only); ``seed``: the random stream; ``leg_noise_std`` (config unit, default the
    node's default): redundant legs, the noise of the consistency test of a mode; ``threads``: the homotopy's
    path-tracking threads (default the cores this process may run on, one per 8 paths at most; the modes do not
    depend on it)."""
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
    if threads is not None:
        if method != "homotopy":
            raise GlpmaError(f"threads counts the homotopy's path-tracking threads; {method} does not take it")
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise GlpmaError(f"threads must be a positive integer, not {threads!r}")
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
        return homotopy_modes(model, legs, seed=seed, leg_noise_std=leg_noise_std, threads=threads)
    raise GlpmaError(f"unknown solve_all method {method!r}; choose one of {', '.join(METHODS)}")


def default_method(model) -> str:
    """``"closed_form"`` where the model has one (the Delta), ``"homotopy"`` where the model's family has a
    start system, else ``"multistart"``."""
    if has_closed_form(model):
        return "closed_form"
    return "homotopy" if has_start_system(model) else "multistart"

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
        if not r.success or (model.redundancy and leg_fitness(model, r.x, legs) > limit):
            continue
        if all(model.distance(r.x, s.x) > DEDUP_RELATIVE * model.scale for s in found):
            found.append(r)
    return AllSolutions(sorted_modes(model, found), runs, time.perf_counter() - t0, evaluations, method="g3pcx")


# -- certified ----------------------------------------------------------------------------------
def exact_modes(model, legs, *, seed=0) -> AllSolutions:
    """Every real mode certified by msolve (:mod:`glpma_ros.modes.exact`), each polished."""
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
    return AllSolutions(sorted_modes(model, found), 0, time.perf_counter() - t0, evaluations, method="exact",
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
    return AllSolutions(sorted_modes(model, found), 0, time.perf_counter() - t0, evaluations, method="closed_form")


# -- homotopy -------------------------------------------------------------------------------------
def homotopy_modes(model, legs, *, seed=0, leg_noise_std=None, fallback=True, threads=None) -> AllSolutions:
    """Every real mode by the parameter homotopy (:mod:`glpma_ros.modes.homotopy`), each polished with every
    leg; redundant legs: those the polish leaves consistent (:func:`consistent_fitness`).  Incomplete: the real
    double roots the paths met as well (polished; ``conditioning`` says they are double) and, with ``fallback``
    and msolve installed (not with redundant legs), msolve's modes instead, ``fallback = "exact"``.  ``threads``:
    the path-tracking threads (:func:`glpma_ros.modes.homotopy.solve`)."""
    t0 = time.perf_counter()
    res = homotopy.solve(model, legs, seed=seed, threads=threads)
    rng = np.random.default_rng(seed)
    limit = max((LOCAL_RESIDUAL_RELATIVE * model.scale) ** 2, consistent_fitness(model, leg_noise_std))
    found, evaluations = [], 0
    for x in list(res.real) + list(res.singular):
        t1 = time.perf_counter()
        xp, fp, nfev, _ = refine.polish(model, x, legs, rng)
        evaluations += nfev
        if leg_fitness(model, xp, legs) > limit:
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
    found = sorted_modes(model, found)
    return AllSolutions(found, 0, time.perf_counter() - t0, evaluations, method="homotopy",
                        complex_solutions=complex_solutions, complete=complete, paths=res.paths,
                        paths_failed=tuple(res.paths_failed), fallback=used, retracked=res.retracked,
                        steps=res.steps, conditioning=tuple(float(model.conditioning(s.x, legs)) for s in found))
