"""Solvers: one module per algorithm, one result type (:class:`SolveResult`)."""

import time

from ..runtime.collector import HOLD
from . import de, g3pcx, gasa, glpma, rcga, refine, sa
from .common import BUDGET_EXHAUSTED, CONVERGED, MAX_EVALS, SolveResult, Termination

SOLVERS = {"glpma": glpma.solve, "g3pcx": g3pcx.solve, "rcga": rcga.solve,
           "sa": sa.solve, "gasa": gasa.solve, "de": de.solve}

#: solvers whose own paper sizes the population differently from 001's PAPER_SETTINGS:
#: SA a single chain (004), GA-SA 40 (004), DE 10 D (003 Eq. 23); functions of the model
DEFAULT_POPULATION = {"sa": sa.default_population, "gasa": gasa.default_population,
                      "de": de.default_population}

#: the options every solver takes
COMMON_OPTIONS = frozenset({"population", "rng", "init_range", "center", "spread", "tolerance", "max_evals",
                            "budget_s", "polish"})
#: each solver's own options (its module documents them)
OPTIONS = {
    "glpma": COMMON_OPTIONS | {"local_population", "ls_interval", "ls_intensity",
                               "mu", "lam", "r", "sigma_zeta", "sigma_eta"},
    "g3pcx": COMMON_OPTIONS | {"mu", "lam", "r", "sigma_zeta", "sigma_eta"},
    "rcga": COMMON_OPTIONS | {"crossover_rate", "mutation_rate", "mutation_b"},
    "sa": COMMON_OPTIONS | {"t0", "chain_length", "cooling_rate", "neighbour_fraction"},
    "gasa": COMMON_OPTIONS | {"t0", "sa_iterations", "chain_length", "cooling_rate", "crossover_rate", "sa_rate",
                              "neighbour_fraction"},
    "de": COMMON_OPTIONS | {"f_low", "f_high", "cr_low", "cr_high"},
}

#: the papers' population sizes per manipulator (Chandra & Rolland 2014, section 5)
PAPER_SETTINGS = {
    "planar_3rpr": {"population": 100, "local_population": 100, "ls_interval": 5, "ls_intensity": 1,
                    "init_range": (-50.0, 50.0), "max_evals": 10_000},
    "hexapod_66": {"population": 200, "local_population": 200, "ls_interval": 5, "ls_intensity": 85,
                   "init_range": (-1000.0, 1000.0), "max_evals": 500_000},
}


def paper_kind(model) -> str:
    """The manipulator whose papers' settings ``model`` takes: its own, or for an actuated family
    (:mod:`glpma_ros.models.actuated`) the one with as many solver variables (``settings_like``)."""
    return getattr(model, "settings_like", model.kind)


def solve(name, model, legs, **kwargs):
    """Run solver ``name`` with the paper's settings for ``model`` overridden by ``kwargs``
    (options of :data:`OPTIONS`; ``None`` keeps the default).  ``budget_s`` counts from this call:
    the settings and the solver's setup are inside it."""
    start = time.perf_counter()
    if kwargs.get("budget_s") is None:
        return _solve(name, model, legs, start, kwargs)
    HOLD.acquire()          # under a deadline the garbage collector waits until the solve returns
    try:
        return _solve(name, model, legs, start, kwargs)
    finally:
        HOLD.release()


def _solve(name, model, legs, start, kwargs):
    if name not in SOLVERS:
        raise ValueError(f"unknown solver {name!r}; choose one of {', '.join(SOLVERS)}")
    unknown = sorted(set(kwargs) - OPTIONS[name])
    if unknown:
        raise ValueError(f"solver {name!r} takes no option {', '.join(unknown)}")
    # the papers' settings the solver has (GLPMA's local search ones go to GLPMA alone)
    settings = {k: v for k, v in PAPER_SETTINGS[paper_kind(model)].items() if k in OPTIONS[name]}
    if name in DEFAULT_POPULATION:
        settings["population"] = DEFAULT_POPULATION[name](model)
    settings.update({k: v for k, v in kwargs.items() if v is not None})
    return SOLVERS[name](model, legs, start=start, **settings)


__all__ = ["SOLVERS", "OPTIONS", "PAPER_SETTINGS", "solve", "SolveResult", "Termination",
           "CONVERGED", "BUDGET_EXHAUSTED", "MAX_EVALS", "g3pcx", "rcga", "glpma", "refine",
           "sa", "gasa", "de"]
