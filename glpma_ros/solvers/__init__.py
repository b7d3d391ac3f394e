"""Solvers: one module per algorithm, one result type (:class:`SolveResult`)."""
import inspect

from . import de, g3pcx, gasa, glpma, rcga, refine, sa
from .common import BUDGET_EXHAUSTED, CONVERGED, MAX_EVALS, SolveResult, Termination

SOLVERS = {"glpma": glpma.solve, "g3pcx": g3pcx.solve, "rcga": rcga.solve,
           "sa": sa.solve, "gasa": gasa.solve, "de": de.solve}

#: solvers whose own paper sizes the population differently from 001's PAPER_SETTINGS:
#: SA a single chain (004), GA-SA 40 (004), DE 10 D (003 Eq. 23); functions of the model
DEFAULT_POPULATION = {"sa": sa.default_population, "gasa": gasa.default_population,
                      "de": de.default_population}

#: the keyword arguments each solver takes
_KEYWORDS = {name: frozenset(inspect.signature(f).parameters) for name, f in SOLVERS.items()}

#: the papers' population sizes per manipulator (Chandra & Rolland 2014, section 5)
PAPER_SETTINGS = {
    "planar_3rpr": {"population": 100, "local_population": 100, "ls_interval": 5, "ls_intensity": 1,
                    "init_range": (-50.0, 50.0), "max_evals": 10_000},
    "hexapod_66": {"population": 200, "local_population": 200, "ls_interval": 5, "ls_intensity": 85,
                   "init_range": (-1000.0, 1000.0), "max_evals": 500_000},
}


def solve(name, model, legs, **kwargs):
    """Run solver ``name`` with the paper's settings for ``model`` overridden by ``kwargs``."""
    if name not in SOLVERS:
        raise ValueError(f"unknown solver {name!r}; choose one of {', '.join(SOLVERS)}")
    settings = dict(PAPER_SETTINGS[model.kind])
    # keep only the settings the solver names (GLPMA-only keys go to GLPMA alone)
    settings = {k: v for k, v in settings.items() if k in _KEYWORDS[name]}
    if name in DEFAULT_POPULATION:
        settings["population"] = DEFAULT_POPULATION[name](model)
    settings.update({k: v for k, v in kwargs.items() if v is not None})
    return SOLVERS[name](model, legs, **settings)


__all__ = ["SOLVERS", "PAPER_SETTINGS", "solve", "SolveResult", "Termination",
           "CONVERGED", "BUDGET_EXHAUSTED", "MAX_EVALS", "g3pcx", "rcga", "glpma", "refine",
           "sa", "gasa", "de"]
