"""Load -- or, the first time, compile -- the solvers' machine code before it is timed.

The hot loops are Numba functions with ``cache=True``: the first call after an install
compiles them (about a minute per manipulator on two cores) and writes the machine code to
the cache (``__pycache__`` beside the sources, or the user's cache directory when that is
read-only); every later process loads it from there in about a second.  Neither cost belongs
to a solve, so ``glpma-fk solve`` runs :func:`exercise` (untimed) before its timed solve and
reports it as ``load_s``, and ``glpma-fk precompile`` (run by the install scripts) fills the
cache for every solver and both manipulator kinds ahead of time, printing a line per solver.
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np
from numba.core.registry import CPUDispatcher

from .. import solvers
from ..config import load_manipulator, resolve_config
from ..estimation.estimator import Estimator
from ..models.base import lengths_from_readings
from ..modes import homotopy
from ..modes.monodromy import has_start_system
from ..modes.multistart import solve_all
from ..node.dds.cdr import Encoder
from ..node.pose_lane import PoseLane

#: the package whose compiled functions :func:`cache_counts` counts
PACKAGE = __name__.partition(".")[0]
#: the shipped configs, one per manipulator kind
SHIPPED_CONFIGS = ("planar_3rpr_seed", "hexapod_66_rolland")
#: evaluation cap of each warm-up solve: every code path runs, and once compiled it is quick
WARM_UP_EVALS = 2000
#: the warm-up legs are the warm-up pose's scaled by this: a warm start must search, not stop at once
WARM_UP_LEG_STRETCH = 1.0 + 1e-3
#: equal legs this share of the geometry's scale have no real assembly unless base and platform are
#: nearly congruent (the platform joints cannot all come that close to the base joints): the
#: warm-up's search that does not converge (and so runs every generation's code)
INFEASIBLE_SCALE = 0.05
#: time budget of a warm-up solve (s): the evaluation cap, not the clock, ends it
WARM_UP_BUDGET_S = 60.0
#: solve_all G3-PCX runs and multistart starts of the warm-up of ``glpma-fk solve-all``, ``map`` and of
#: the node's assembly modes (one batch of the multistart runs every compiled path)
SOLVE_ALL_RUNS = 2
SOLVE_ALL_STARTS = 64


def warm_up_pose(model) -> np.ndarray:
    """Solver variables of a pose clear of the base joints (platform lifted by the scale); an actuated
    family's home pose (:meth:`~glpma_ros.models.actuated.ActuatedLegs.home_variables`, else the solve of its
    reference legs), inside its workspace."""
    home = getattr(model, "home_variables", None)
    if home is not None:
        x = home()
        if x is not None:
            return x
        e = Estimator(model, seed=0).estimate(model.reference_legs())
        if e.x is None:
            raise ValueError(f"{model.kind}: no assembly at the actuators' mid-range; give known_solutions")
        return np.array(e.x, dtype=float)
    s = model.scale
    return model.variables_from_pose([0.25 * s, 0.25 * s, s], [0.0, 0.0, 0.0, 1.0])


def warm_up_legs(model) -> np.ndarray:
    """Leg lengths near :func:`warm_up_pose` (within the config's ``leg_limits``)."""
    legs = model.inverse_kinematics(warm_up_pose(model)) * WARM_UP_LEG_STRETCH
    if model.leg_limits is not None:
        legs = np.clip(legs, *model.leg_limits)
    return legs


def exercise(model, solver: str) -> float:
    """Run every path of ``solver`` on ``model`` once -- cold and warm start, with and without
    the refinement, on legs with and without a real assembly (a search that does not converge
    at once reaches the code a quick one never does, e.g. GLPMA's local search), through the
    Estimator and on its own -- so that every compiled function it uses is loaded (or compiled):
    the first timed solve after it loads nothing (test_first_solve.py).  The results are thrown
    away; returns the seconds spent."""
    t0 = time.perf_counter()
    feasible = warm_up_legs(model)
    infeasible = np.full(model.n_legs, INFEASIBLE_SCALE * model.scale)
    if model.leg_vector_size != model.n_legs:        # an actuated family: the rods of its leg vector
        infeasible = np.concatenate((infeasible, feasible[model.n_legs:]))
    if model.leg_limits is not None:
        infeasible = np.clip(infeasible, *model.leg_limits)
    for legs in (feasible, infeasible):
        for start in (None, warm_up_pose(model)):
            for polish in (True, False):
                estimator = Estimator(model, solver=solver, time_budget_s=WARM_UP_BUDGET_S, polish=polish,
                                      initial_pose=start, max_evals=WARM_UP_EVALS)
                estimator.estimate(legs)
                exercise_readings(estimator, legs)
        # the solver called on its own (the papers' settings, as the bench and solve-all call it), which a model
        # with a closed form never reaches through the Estimator
        for polish in (True, False):
            solvers.solve(solver, model, legs, rng=0, budget_s=WARM_UP_BUDGET_S, max_evals=WARM_UP_EVALS,
                          polish=polish)
    return time.perf_counter() - t0


def exercise_readings(estimator, legs) -> None:
    """Load the node's everyday-input path for ``legs`` (leg lengths, config unit): a message's readings
    converted on their own (:func:`~glpma_ros.models.base.lengths_from_readings`, what the node's input
    conversion calls) and with the warm stage (:meth:`Estimator.estimate_readings
    <glpma_ros.estimation.estimator.Estimator.estimate_readings>`, which does nothing without a warm start
    or for an actuated family's leg vector), and a ``leg_lengths`` message to its pose's in one compiled call
    (:class:`~glpma_ros.node.pose_lane.PoseLane`).  The readings' unit, band and offsets are neutral ones: the
    compiled code is the same whatever they are."""
    values = np.array(legs, dtype=float).reshape(-1)
    offsets = np.zeros(values.size)
    lengths_from_readings(values, 1.0, -math.inf, math.inf, offsets, np.empty(values.size))
    estimator.estimate_readings(tuple(values.tolist()), 1.0, -math.inf, math.inf, offsets)
    # ... and the node's leg_lengths message in one compiled call (its result thrown away: no state changes)
    warm = estimator.warm_lane()
    if warm is not None:
        PoseLane(values.size, estimator.warm_output_size).run(
            Encoder().float64_multi_array(values), 0, (1.0, -math.inf, math.inf, offsets), warm, "exercise", 1.0)


def exercise_solve_all(model, methods=("homotopy", "multistart", "g3pcx")) -> float:
    """Load what :func:`~glpma_ros.modes.multistart.solve_all` uses for ``methods`` (default the homotopy,
    the multistart and the G3-PCX runs); returns the seconds spent."""
    t0 = time.perf_counter()
    legs = warm_up_legs(model)
    if "homotopy" in methods and has_start_system(model):
        homotopy.solve(model, legs, seed=0)         # the tracker (the polish is the multistart's code)
        solve_all(model, legs, method="multistart", max_starts=1, seed=0)
    if "multistart" in methods:
        solve_all(model, legs, method="multistart", max_starts=SOLVE_ALL_STARTS, seed=0)
    if "g3pcx" in methods:
        solve_all(model, legs, method="g3pcx", runs=SOLVE_ALL_RUNS, seed=0)
    return time.perf_counter() - t0


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def cache_counts() -> tuple[int, int]:
    """``(loaded, compiled)``: how many compiled functions of this package Numba has loaded from its
    cache and how many it has compiled (cache misses) in this process so far, from each
    dispatcher's own statistics (``Dispatcher.stats``)."""
    seen, loaded, compiled = set(), 0, 0
    for name, module in list(sys.modules.items()):
        if not name.startswith(PACKAGE) or module is None:
            continue
        for obj in list(vars(module).values()):
            if isinstance(obj, CPUDispatcher) and id(obj) not in seen:
                seen.add(id(obj))
                loaded += sum(obj.stats.cache_hits.values())
                compiled += sum(obj.stats.cache_misses.values())
    return loaded, compiled


def describe_cache_use(loaded: int, compiled: int) -> str:
    """What :func:`cache_counts`' differences over a step say, in words."""
    if compiled:
        return f"compiled {compiled} function{'s' if compiled != 1 else ''}" + (f", loaded {loaded}" if loaded else "")
    if loaded:
        return f"loaded {loaded} compiled function{'s' if loaded != 1 else ''} from the cache"
    return "nothing new to load"


def precompile(configs=SHIPPED_CONFIGS, solver_names=None, say=_say) -> float:
    """Fill the compiled-code cache for every solver (default: all registered) on each config,
    and for solve_all; ``say`` gets one progress line per step: what Numba compiled or loaded in
    it (counted by :func:`cache_counts`, not guessed from the time) and how long it took.  No
    estimate of the time left: most of the compiled code is shared, so what a step still has to
    compile is not known before it runs.  Returns the seconds spent."""
    names = list(solver_names or solvers.SOLVERS)
    models = [load_manipulator(resolve_config(c)) for c in configs]
    steps = [(m, n) for m in models for n in names] + [(m, "solve-all") for m in models]
    t0 = time.perf_counter()
    say(f"precompile: {len(steps)} steps ({len(names)} solvers and solve-all on {len(models)} manipulators); "
        f"a first run compiles (minutes on two cores), later runs load the cache (seconds)")
    total_loaded = total_compiled = 0
    for k, (model, name) in enumerate(steps, 1):
        loaded0, compiled0 = cache_counts()
        t = exercise_solve_all(model) if name == "solve-all" else exercise(model, name)
        loaded1, compiled1 = cache_counts()
        loaded, compiled = loaded1 - loaded0, compiled1 - compiled0
        total_loaded, total_compiled = total_loaded + loaded, total_compiled + compiled
        say(f"precompile: [{k}/{len(steps)}] {model.kind} {name}: {describe_cache_use(loaded, compiled)} in {t:.1f} s")
    total = time.perf_counter() - t0
    say(f"precompile: done in {total:.1f} s ({describe_cache_use(total_loaded, total_compiled)})")
    return total
