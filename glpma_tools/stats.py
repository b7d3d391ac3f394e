"""Summary statistics of measured series, for every tool: the distribution of a sample
(p50, p99, max, mean) and a mean with its 95 % confidence half-width."""
from __future__ import annotations

import math

import numpy as np

#: keys of :func:`distribution`
KEYS = ("p50", "p99", "max", "mean")
#: two-sided 95 % quantile of the normal distribution (004's confidence intervals; the t quantile without scipy)
Z_95 = 1.959964


def distribution(values, scale: float = 1.0) -> dict:
    """``{"p50", "p99", "max", "mean"}`` of ``values`` times ``scale`` (e.g. 1e3 for seconds to
    milliseconds); every entry None when there are no values, so that the result is JSON-able."""
    a = np.asarray(values, dtype=float).ravel() * scale
    if a.size == 0:
        return dict.fromkeys(KEYS)
    p50, p99 = np.percentile(a, [50, 99])
    return {"p50": float(p50), "p99": float(p99), "max": float(a.max()), "mean": float(a.mean())}


def t_critical(n: int) -> float:
    """Two-sided 95 % Student t quantile for ``n`` samples (the normal quantile without scipy)."""
    if n < 2:
        return math.nan
    try:
        from scipy.stats import t  # optional for the tools: the normal quantile without it
        return float(t.ppf(0.975, n - 1))
    except ImportError:
        return Z_95


def mean_ci(values, quantile: float | None = None) -> tuple[float, float]:
    """(mean, 95 % confidence half-width) of ``values``: ``quantile`` times the standard error
    (default the Student t quantile of the sample size); NaN where undefined."""
    v = np.asarray(values, dtype=float).ravel()
    if v.size == 0:
        return math.nan, math.nan
    if v.size == 1:
        return float(v[0]), math.nan
    q = t_critical(v.size) if quantile is None else quantile
    return float(v.mean()), q * float(v.std(ddof=1)) / math.sqrt(v.size)
