"""Peer implementations of pure G3-PCX, pypop7's and pymoo's (benchmark-only dependencies, imported lazily), on the
identical fitness: the compiled one of our solvers through :class:`CountingFitness`, so that evaluations are counted
the same way for everyone.  :func:`available` also tells :mod:`.timing` (warm tracking) whether scipy, its warm
peer, imports."""
from __future__ import annotations

import importlib
import math
import time
import warnings

import numpy as np

from glpma_ros.models.kernels import population_fitness

from .common import SUCCESS_TOLERANCE, Run

#: pymoo needs bounds (its PM mutation scales with them): this many init half-widths around the init range's centre,
#: so that every solution is well inside
PYMOO_BOUND_FACTOR = 10.0
#: the module each peer needs
PEER_MODULES = {"pypop7": "pypop7.optimizers.ga.g3pcx", "pymoo": "pymoo.algorithms.soo.nonconvex.g3pcx",
                "scipy": "scipy.optimize"}


def available(name: str) -> str | None:
    """None if the peer can be imported, else the reason."""
    try:
        importlib.import_module(PEER_MODULES[name])
    except ImportError as exc:
        return f"not installed ({exc})"
    return None


class CountingFitness:
    """The model's fitness, counting evaluations in call order: the best so far (a history point each time it halves)
    and the first evaluation below :data:`SUCCESS_TOLERANCE` within ``max_evals``."""

    def __init__(self, model, legs, max_evals):
        self.args = (model.kind_id, model.data, np.ascontiguousarray(legs, dtype=float), model.n_res)
        self.max_evals, self.n, self.best, self.first_success, self.history = max_evals, 0, math.inf, None, []

    def one(self, x) -> float:
        return float(self.many(np.asarray(x, dtype=float).reshape(1, -1))[0])

    def many(self, X) -> np.ndarray:
        F = population_fitness(np.ascontiguousarray(X, dtype=float), *self.args)
        for f in F:
            self.n += 1
            if f < self.best:
                self.best = float(f)
                if not self.history or self.best < 0.5 * self.history[-1][1]:
                    self.history.append((self.n, self.best))
                if self.first_success is None and f < SUCCESS_TOLERANCE and self.n <= self.max_evals:
                    self.first_success = self.n
        return F

    def run(self, optimize) -> Run:
        """``optimize()`` timed, its warnings silenced: the run it made through this fitness."""
        t0 = time.perf_counter()
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            optimize()
        wall_s = time.perf_counter() - t0
        self.history.append((self.n, self.best))
        ok = self.first_success is not None
        return Run(ok, self.first_success if ok else self.n, wall_s, self.best, self.history)


def pypop7_g3pcx(model, legs, *, seed, population, init_range, max_evals) -> Run:
    """pypop7's ``G3PCX`` (Deb's defaults: 3 parents, 2 offspring, sigma 0.1), unbounded search, initial population
    uniform in ``init_range``."""
    from pypop7.optimizers.ga.g3pcx import G3PCX  # the bench extra: optional, imported where used
    fit, n = CountingFitness(model, legs, max_evals), model.n_vars
    problem = {"fitness_function": fit.one, "ndim_problem": n,
               "lower_boundary": np.full(n, float(init_range[0])), "upper_boundary": np.full(n, float(init_range[1]))}
    options = {"max_function_evaluations": int(max_evals),
               "fitness_threshold": float(np.nextafter(SUCCESS_TOLERANCE, 0.0)),  # pypop7 stops at <=
               "seed_rng": int(seed), "n_individuals": int(population), "verbose": 0, "saving_fitness": 0}
    return fit.run(lambda: G3PCX(problem, options).optimize())


def pymoo_g3pcx(model, legs, *, seed, population, init_range, max_evals) -> Run:
    """pymoo's ``G3PCX`` as shipped (PCX plus its polynomial mutation), initial population uniform in ``init_range``,
    bounds ``PYMOO_BOUND_FACTOR`` times wider."""
    from pymoo.algorithms.soo.nonconvex.g3pcx import G3PCX  # the bench extra: optional, imported where used
    from pymoo.config import Config
    from pymoo.core.problem import Problem
    from pymoo.optimize import minimize
    from pymoo.termination import collection, fmin, max_eval
    Config.warnings["not_compiled"] = False
    fit, n = CountingFitness(model, legs, max_evals), model.n_vars
    low, high = (float(v) for v in init_range)
    centre, bound = 0.5 * (low + high), PYMOO_BOUND_FACTOR * 0.5 * (high - low)

    class FK(Problem):
        def _evaluate(self, X, out, *args, **kwargs):
            out["F"] = fit.many(X)[:, None]

    problem = FK(n_var=n, n_obj=1, xl=np.full(n, centre - bound), xu=np.full(n, centre + bound))
    X0 = np.random.default_rng(seed).uniform(low, high, size=(population, n))
    termination = collection.TerminationCollection(max_eval.MaximumFunctionCallTermination(int(max_evals)),
                                                   fmin.MinimumFunctionValueTermination(SUCCESS_TOLERANCE))
    return fit.run(lambda: minimize(problem, G3PCX(pop_size=int(population), sampling=X0), termination,
                                    seed=int(seed), verbose=False))


PEER_SOLVERS = {"pypop7": pypop7_g3pcx, "pymoo": pymoo_g3pcx}
PEER_LABEL = {"pypop7": "pypop7 G3PCX", "pymoo": "pymoo G3PCX"}
