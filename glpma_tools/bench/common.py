"""Shared pieces of the benchmark: the record of one search and the summary of a row of them."""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from glpma_tools.stats import mean_ci

#: the papers' success criterion: best fitness below this
SUCCESS_TOLERANCE = 1e-20


class Run(NamedTuple):
    """One independent search."""

    success: bool
    nfev: int            # evaluations to success, or all evaluations spent
    wall_s: float        # wall time around the call
    fun: float           # best fitness reached
    history: list        # (evaluations, best fitness so far)


class Summary(NamedTuple):
    """A row of runs as the report's tables give it."""

    runs: int
    success_pct: float
    evals_mean: float      # over successful runs
    evals_ci: float
    evals_all_mean: float  # over all runs (failures count their whole budget)
    time_median_ms: float
    time_mean_ms: float
    fun_median: float


def summarize(runs: list[Run]) -> Summary:
    """The figures of a row of runs (NaN where there are none)."""
    if not runs:
        return Summary(0, *[math.nan] * 7)
    walls = np.array([r.wall_s for r in runs]) * 1e3
    return Summary(len(runs), 100.0 * sum(r.success for r in runs) / len(runs),
                   *mean_ci([r.nfev for r in runs if r.success]), float(np.mean([r.nfev for r in runs])),
                   float(np.median(walls)), float(np.mean(walls)), float(np.median([r.fun for r in runs])))
