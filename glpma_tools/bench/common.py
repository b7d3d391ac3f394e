"""Shared pieces of the benchmark: run records and their summary, the machine and revision, progress bars."""
from __future__ import annotations

import math
import os
import platform
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glpma_tools.stats import mean_ci

REPO_ROOT = Path(__file__).resolve().parents[2]
#: the papers' success criterion: best fitness below this
SUCCESS_TOLERANCE = 1e-20


@dataclass
class Run:
    """One independent search."""

    success: bool
    nfev: int            # evaluations to success, or all evaluations spent
    wall_s: float        # wall time around the call
    fun: float           # best fitness reached
    history: list = field(default_factory=list)  # (evaluations, best fitness so far)


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


def progress_bar(iterable, desc, progress: bool, total=None):
    """``iterable`` with a tqdm progress bar when ``progress``."""
    if not progress:
        return iterable
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, total=total, leave=False, dynamic_ncols=True)


def load_average() -> str:
    try:
        return "/".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "n/a"


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


def command_line(argv, tool: str = "bench") -> tuple[str, str]:
    """(``glpma-fk <tool> ARGS``, the command line this process was started with)."""
    import shlex
    canonical = shlex.join(["glpma-fk", tool, *argv])
    invoked = shlex.join(getattr(sys, "orig_argv", sys.argv))
    return canonical, invoked
