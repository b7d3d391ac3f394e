"""The node's warm-up: every compiled path of the solvers run once before the first real input
(Numba loads them from its cache, or compiles them on the first start after an install), then
everything loaded so far frozen out of the cyclic garbage collector's scans (``gc.freeze``)."""
from __future__ import annotations

import gc
import time

import numpy as np

from ..estimation.covariance import warm_up as warm_up_covariance
from ..runtime.precompile import cache_counts, describe_cache_use, exercise_readings, warm_up_pose

#: solvers warmed up at start (with the configured one): the papers' real-time solvers
WARM_UP_SOLVERS = ("glpma", "g3pcx", "rcga")
#: a warm-up solve counts as warm once it takes less than this many seconds per millisecond of its
#: budget (three times the budget: the compiled code is loaded, what is left is the solve itself)
WARM_SECONDS_PER_BUDGET_MS = 3e-3
#: the warm-up's legs are those of its pose stretched by this much: a warm start must then
#: search, not stop at its first individual
LEG_STRETCH = 1e-3


def warm_up_variables(model, initial_x) -> np.ndarray:
    """A pose to warm up with: ``initial_x`` (the solver variables of ``initial_pose``), or
    :func:`~glpma_ros.runtime.precompile.warm_up_pose` (clear of the base joints; an actuated family's home)."""
    return initial_x if initial_x is not None else warm_up_pose(model)


class WarmUp:
    """Warms up the solvers of one ``model``: ``build_estimator(values, start)`` builds an
    estimator from parameter values and a warm start (None: cold); ``log``: anything with
    ``info/warning(str)``.  Remembers which solvers it has run (:attr:`warmed`)."""

    def __init__(self, model, build_estimator, log):
        self.model = model
        self._build_estimator = build_estimator
        self.log = log
        self._warmed: set = set()

    @property
    def warmed(self) -> frozenset:
        """The solvers :meth:`run` has warmed up."""
        return frozenset(self._warmed)

    def run(self, params: dict, x, solvers=None, budget_ms: float = 50.0, max_tries: int = 5) -> float:
        """Run every path of each solver -- cold and warm start (from ``x``, solver variables),
        with and without the refinement (without it the evolutionary loops run in the warm stages
        too) -- until it runs within its budget, so that Numba has compiled everything before the
        first real input.  ``params``: the node's parameter values; ``solvers``: default
        :data:`WARM_UP_SOLVERS` and ``params["solver"]``.  Returns the seconds spent."""
        t0 = time.perf_counter()
        if solvers is None:
            solvers = tuple(dict.fromkeys((*WARM_UP_SOLVERS, params["solver"])))
        legs = self.model.inverse_kinematics(x) * (1.0 + LEG_STRETCH)
        if self.model.leg_limits is not None:
            legs = np.clip(legs, *self.model.leg_limits)
        for k, name in enumerate(solvers, 1):
            t_solver = time.perf_counter()
            counts = cache_counts()
            for start in (None, x):
                for polish in (True, False):
                    values = dict(params, solver=name, time_budget_ms=budget_ms, polish=polish)
                    for _ in range(max_tries):
                        t = time.perf_counter()
                        try:
                            estimator = self._build_estimator(values, start)
                            estimator.estimate(legs)
                            exercise_readings(estimator, legs)      # the everyday input's one compiled call
                        except Exception as exc:  # noqa: BLE001 - reported, not fatal
                            self.log.warning(f"warm-up with {name} failed: {exc}")
                            break
                        if time.perf_counter() - t < WARM_SECONDS_PER_BUDGET_MS * budget_ms:
                            break
            self._warmed.add(name)
            loaded, compiled = (after - before for after, before in zip(cache_counts(), counts))
            self._log(name, k, len(solvers), time.perf_counter() - t_solver, loaded, compiled)
        # everything loaded so far lives as long as the node: keep it out of the cyclic
        # collector's scans, whose pauses would otherwise land in the real-time path
        warm_up_covariance()
        gc.collect()
        gc.freeze()
        return time.perf_counter() - t0

    def _log(self, name: str, k: int, n: int, took_s: float, loaded: int, compiled: int) -> None:
        """One line per solver warmed up: what Numba compiled (first start after an install) or
        loaded from its cache, counted (:func:`~glpma_ros.runtime.precompile.cache_counts`), not guessed."""
        how = describe_cache_use(loaded, compiled)
        if compiled:
            how += " (first start; `glpma-fk precompile` does this ahead)"
        self.log.info(f"warm-up [{k}/{n}] {name}: {how} in {took_s:.1f} s")
