"""Shared pieces of the benchmark: the record of one search and the summary of a row of them."""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from glpma_tools.stats import mean_ci

#: the papers' success criterion: best fitness below this
SUCCESS_TOLERANCE = 1e-20

#: one independent search: success, evaluations (to success, or all spent), wall time around the call (s), the best
#: fitness reached, its history [(evaluations, best fitness so far)]
Run = namedtuple("Run", "success nfev wall_s fun history")
#: a row of runs as the report's tables give it: evaluations over the successful runs (mean, 95 % half-width) and
#: over all runs (failures count their whole budget), wall times (ms), the median final fitness
Summary = namedtuple("Summary", "runs success_pct evals_mean evals_ci evals_all_mean time_median_ms time_mean_ms "
                                "fun_median")


def summarize(runs: list[Run]) -> Summary:
    """The figures of a row of runs (NaN where there are none)."""
    if not runs:
        return Summary(0, *[math.nan] * 7)
    walls = np.array([r.wall_s for r in runs]) * 1e3
    return Summary(len(runs), 100.0 * sum(r.success for r in runs) / len(runs),
                   *mean_ci([r.nfev for r in runs if r.success]), float(np.mean([r.nfev for r in runs])),
                   float(np.median(walls)), float(np.mean(walls)), float(np.median([r.fun for r in runs])))
