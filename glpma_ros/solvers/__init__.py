"""Solvers: one module per algorithm, one result type (:class:`SolveResult`)."""
from . import g3pcx, glpma, rcga, refine
from .common import BUDGET_EXHAUSTED, CONVERGED, MAX_EVALS, SolveResult, Termination

SOLVERS = {"glpma": glpma.solve, "g3pcx": g3pcx.solve, "rcga": rcga.solve}

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
    if name != "glpma":
        for key in ("local_population", "ls_interval", "ls_intensity"):
            settings.pop(key)
    settings.update({k: v for k, v in kwargs.items() if v is not None})
    return SOLVERS[name](model, legs, **settings)


__all__ = ["SOLVERS", "PAPER_SETTINGS", "solve", "SolveResult", "Termination",
           "CONVERGED", "BUDGET_EXHAUSTED", "MAX_EVALS", "g3pcx", "rcga", "glpma", "refine"]
