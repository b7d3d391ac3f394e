"""Shared pieces of the benchmark: run records, statistics, machine description."""
from __future__ import annotations

import math
import os
import platform
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]
SUCCESS_TOLERANCE = 1e-20


@dataclass
class Run:
    """One independent search."""

    success: bool
    nfev: int            # evaluations to success, or all evaluations spent
    wall_s: float        # wall time around the call
    fun: float           # best fitness reached
    history: list = field(default_factory=list)  # (evaluations, best fitness so far)


def t_critical(n: int) -> float:
    """Two-sided 95% Student t quantile for ``n`` samples (normal above 30)."""
    if n < 2:
        return math.nan
    try:
        from scipy.stats import t
        return float(t.ppf(0.975, n - 1))
    except Exception:  # noqa: BLE001 - scipy is optional here
        return 1.96


def mean_ci(values):
    """(mean, 95% confidence half-width) of ``values``; NaN when undefined."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return math.nan, math.nan
    if v.size == 1:
        return float(v[0]), math.nan
    return float(v.mean()), t_critical(v.size) * float(v.std(ddof=1)) / math.sqrt(v.size)


@dataclass
class Summary:
    runs: int
    successes: int
    evals_mean: float      # over successful runs
    evals_ci: float
    evals_all_mean: float  # over all runs (failures count their whole budget)
    time_median_ms: float
    time_mean_ms: float
    fun_median: float

    @property
    def success_pct(self) -> float:
        return 100.0 * self.successes / self.runs if self.runs else math.nan


def summarize(runs: list[Run]) -> Summary:
    ok = [r.nfev for r in runs if r.success]
    mean, ci = mean_ci(ok)
    walls = np.array([r.wall_s for r in runs]) * 1e3
    return Summary(len(runs), len(ok), mean, ci,
                   float(np.mean([r.nfev for r in runs])) if runs else math.nan,
                   float(np.median(walls)) if runs else math.nan,
                   float(np.mean(walls)) if runs else math.nan,
                   float(np.median([r.fun for r in runs])) if runs else math.nan)


def percentiles_ms(seconds) -> dict:
    a = np.asarray(seconds, dtype=float) * 1e3
    if a.size == 0:
        return {"p50": math.nan, "p99": math.nan, "max": math.nan, "mean": math.nan}
    return {"p50": float(np.percentile(a, 50)), "p99": float(np.percentile(a, 99)),
            "max": float(a.max()), "mean": float(a.mean())}


def involuntary_switches() -> int:
    """Involuntary context switches of this thread so far (Linux; 0 elsewhere).

    A timed call during which this count grows was preempted by another process:
    on a shared machine that, not the solver, explains most outliers."""
    try:
        import resource
        who = getattr(resource, "RUSAGE_THREAD", resource.RUSAGE_SELF)
        return int(resource.getrusage(who).ru_nivcsw)
    except Exception:  # noqa: BLE001
        return 0


def load_average() -> str:
    try:
        return "/".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "n/a"


# -- formatting -------------------------------------------------------------------
def fmt(v, digits=3, unit=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    if isinstance(v, (int, np.integer)):
        return f"{v:,}{unit}"
    a = abs(v)
    if a != 0 and (a >= 1e5 or a < 1e-3):
        return f"{v:.{max(digits - 1, 1)}e}{unit}"
    if a >= 100:
        return f"{v:,.0f}{unit}"
    return f"{v:.{digits}g}{unit}"


def fmt_ci(mean, ci):
    if not math.isfinite(mean):
        return "—"
    if not math.isfinite(ci):
        return f"{mean:,.0f}"
    return f"{mean:,.0f} ± {ci:,.0f}"


def ratio(a, b, digits=2):
    try:
        if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) or b == 0:
            return "—"
    except TypeError:
        return "—"
    r = a / b
    return f"{r:.{digits}g}×" if r < 100 else f"{r:,.0f}×"


def table(header: list[str], rows: list[list]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for row in rows:
        out.append("| " + " | ".join(str(c) for c in row) + " |")
    return "\n".join(out)


# -- machine ---------------------------------------------------------------------------
def _version(name):
    try:
        from importlib.metadata import version
        return version(name)
    except Exception:  # noqa: BLE001
        return "not installed"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict:
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "numba": _version("numba"),
        "scipy": _version("scipy"),
        "pypop7": _version("pypop7"),
        "pymoo": _version("pymoo"),
    }


def git_revision() -> str:
    try:
        rev = subprocess.run(["git", "-C", str(REPO_ROOT), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO_ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return rev + (" (with uncommitted changes)" if dirty else "") if rev else "unknown"
    except Exception:  # noqa: BLE001
        return "unknown"


def command_line(argv) -> tuple[str, str]:
    import shlex
    canonical = shlex.join(["glpma-fk", "bench", *argv])
    invoked = shlex.join(getattr(sys, "orig_argv", sys.argv))
    return canonical, invoked
