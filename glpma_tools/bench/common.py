"""Shared pieces of the benchmark: run records and their summary, the machine and revision, progress bars."""
from __future__ import annotations

import math
import os
import platform
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from glpma_tools.stats import mean_ci

REPO_ROOT = Path(__file__).resolve().parents[2]
#: the papers' success criterion: best fitness below this
SUCCESS_TOLERANCE = 1e-20
#: the libraries whose versions the report names
LIBRARIES = ("numpy", "numba", "scipy", "pypop7", "pymoo")


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
    if not runs:
        return Summary(0, 0, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan)
    mean, ci = mean_ci([r.nfev for r in runs if r.success])
    walls = np.array([r.wall_s for r in runs]) * 1e3
    return Summary(len(runs), sum(r.success for r in runs), mean, ci, float(np.mean([r.nfev for r in runs])),
                   float(np.median(walls)), float(np.mean(walls)), float(np.median([r.fun for r in runs])))


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


def _version(name):
    try:
        return version(name)
    except PackageNotFoundError:
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
    return {"cpu": cpu_model(), "cores": os.cpu_count(), "os": f"{platform.system()} {platform.release()}",
            "python": platform.python_version(), **{name: _version(name) for name in LIBRARIES}}


def git_revision() -> str:
    def git(*args):
        return subprocess.run(["git", "-C", str(REPO_ROOT), *args], capture_output=True, text=True,
                              timeout=5).stdout.strip()
    try:
        rev, dirty = git("rev-parse", "--short", "HEAD"), git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return rev + (" (with uncommitted changes)" if dirty else "") if rev else "unknown"


def command_line(argv, tool: str = "bench") -> tuple[str, str]:
    """(``glpma-fk <tool> ARGS``, the command line this process was started with)."""
    return shlex.join(["glpma-fk", tool, *argv]), shlex.join(getattr(sys, "orig_argv", sys.argv))
