"""What every solver shares: the result type, termination (tolerance, evaluation
cap, wall-clock deadline), the evaluation counter and the initial population.

Evaluation counting (documented, tested): one fitness evaluation of one
individual counts one; in the refinement one residual-vector evaluation
(with its Jacobian, computed together) counts one.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

CONVERGED = "converged"
BUDGET_EXHAUSTED = "budget_exhausted"
MAX_EVALS = "max_evals"

#: the papers' success threshold (Chandra & Rolland 2014, section 5)
DEFAULT_TOLERANCE = 1e-20


@dataclass
class SolveResult:
    """Outcome of one solve (the shape of ``scipy.optimize.OptimizeResult``)."""

    x: np.ndarray               # solver variables
    fun: float                  # fitness: sum of squared residuals
    nfev: int                   # evaluations, counted as documented above
    nit: int                    # generations (or refinement iterations)
    elapsed_s: float
    status: str                 # converged | budget_exhausted | max_evals
    solver: str
    polished: bool = False      # the refinement produced the final x
    message: str = ""
    history: list = field(default_factory=list)  # (nfev, best fitness) per chunk
    refined_x: np.ndarray | None = None  # best point the refinement reached (None: it did not run)

    @property
    def success(self) -> bool:
        return self.status == CONVERGED


class Termination:
    """Tolerance, evaluation cap and a hard wall-clock deadline.

    The deadline is checked by the solvers' driver loop between compiled chunks
    whose length is sized to a fraction of the remaining budget.  ``start``: the
    ``time.perf_counter()`` value the budget counts from (default: now), so that a
    solver's setup before its termination is built is inside the budget."""

    def __init__(self, tolerance=DEFAULT_TOLERANCE, max_evals=10_000, budget_s=None, start=None):
        if not tolerance > 0:
            raise ValueError("tolerance must be positive")
        if max_evals < 1:
            raise ValueError("max_evals must be at least 1")
        self.tolerance = float(tolerance)
        self.max_evals = int(max_evals)
        self.budget_s = None if budget_s is None else float(budget_s)
        self.start = time.perf_counter() if start is None else float(start)
        self.deadline = None if budget_s is None else self.start + self.budget_s
        self.nfev = 0

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def out_of_time(self) -> bool:
        return self.deadline is not None and time.perf_counter() >= self.deadline

    def evals_left(self) -> int:
        return max(self.max_evals - self.nfev, 0)

    def status(self, best: float) -> str | None:
        """Reason to stop now, or None."""
        if best < self.tolerance:
            return CONVERGED
        if self.out_of_time():
            return BUDGET_EXHAUSTED
        if self.nfev >= self.max_evals:
            return MAX_EVALS
        return None

    def final_status(self, best: float) -> str:
        return self.status(best) or MAX_EVALS


def kernel_array(a) -> np.ndarray:
    """``a`` as the one array type the compiled kernels are loaded for: float64, C-contiguous, aligned and
    writable (copied only when it is not).  Numba compiles a function once per type of its arguments, and an
    array's type includes whether it is read-only: a read-only view (``np.broadcast_to``, an array over a
    message's buffer) would load -- or, the first time, compile -- other machine code on its first use, tens of
    milliseconds inside the solve that brings it, which the start-up's warm-up never touched."""
    return np.require(a, dtype=np.float64, requirements="CAW")


def initial_population(rng: np.random.Generator, size: int, n_vars: int, init_range=None,
                       center=None, spread=None) -> np.ndarray:
    """Uniform in ``init_range = (low, high)`` (the papers' protocol) or normal
    around ``center`` with per-variable standard deviation ``spread``; in the
    second case the centre itself is the first individual (warm start)."""
    if center is not None:
        center = np.asarray(center, dtype=float)
        spread = np.broadcast_to(np.asarray(spread, dtype=float), center.shape)
        pop = center + spread * rng.standard_normal((size, n_vars))
        pop[0] = center
        return pop
    low, high = init_range
    return rng.uniform(low, high, size=(size, n_vars))

