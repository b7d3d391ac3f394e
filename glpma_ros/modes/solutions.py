"""The answer of :func:`~glpma_ros.modes.multistart.solve_all` and what every method of it shares: when two
polished poses are one mode (:data:`DEDUP_RELATIVE`), when a mode is double (:data:`DOUBLE_CONDITIONING`), when
a local solve has reached a mode (:data:`LOCAL_RESIDUAL_RELATIVE`), the consistency limit of a mode of
redundant legs (:func:`consistent_fitness`) and the order the modes are reported in (:func:`order`).  Plain
Python + NumPy: no ROS import."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..estimation.redundancy import chi2_limit, leg_noise

#: two polished solutions closer than this share of the scale are the same mode
DEDUP_RELATIVE = 1e-4
#: a local solve has converged when its leg residuals' root sum of squares is below this share of the scale
#: (the final polish takes every mode to round-off afterwards)
LOCAL_RESIDUAL_RELATIVE = 1e-9
#: a mode whose leg Jacobian's reciprocal condition number, once the mode is polished to round-off, is
#: below this is double: two real modes met at a singularity (a double root), counted once.  Polished,
#: a double root is left about sqrt(machine epsilon) of the scale from the exact one (the residual grows
#: with the square of the distance), where the conditioning is of that order.  2**-20 = 64 sqrt(epsilon)
#: leaves a margin both ways: above the double roots' conditioning, below the closest distinct modes'
#: (both measured on the seed maps: BENCHMARKS.md, "Design measurements")
DOUBLE_CONDITIONING = 2.0 ** -20


@dataclass
class AllSolutions:
    solutions: list       # SolveResult per distinct mode, sorted by variables
    runs: int             # G3-PCX runs / multistart starts used / 0 (exact)
    elapsed_s: float
    evaluations: int      # residual(-and-Jacobian) evaluations, counted as in solvers.common
    method: str = "g3pcx"
    starts: int = 0                      # multistart: starts used (= runs)
    miss_probability: float | None = None  # not estimable by the multistart (module docstring): None
    good_turing: float | None = None     # multistart: Good-Turing chance that the next start finds a new mode
    unseen_share_bound: float | None = None  # multistart: 95 % bound on the share of starts leading to unseen modes
    complex_solutions: int | None = None  # exact: complex solutions (with multiplicity)
    stop_reason: str = ""                # multistart: stalled | max_starts | budget_exhausted | unreachable
    stall: int = 0                       # multistart: consecutive starts at the end that found nothing new
    hits: tuple = ()                     # multistart: starts that converged to each mode (order of solutions)
    partner_starts: int = 0              # multistart: local solves of the partner search (module docstring)
    parity_starts: int = 0               # multistart: random starts added by the parity rule (among ``starts``)
    conditioning: tuple = ()             # multistart, homotopy: each mode's conditioning (order of solutions)
    complete: bool | None = None         # homotopy / exact: every real mode certainly found
    paths: int = 0                       # homotopy: paths tracked (the family's generic root count)
    paths_failed: tuple = ()             # homotopy, incomplete: the paths without a solution of their own
    fallback: str = ""                   # homotopy, incomplete: "exact" when msolve's modes replaced its own
    retracked: int = 0                   # homotopy: path trackings repeated (another gamma / more care)
    steps: int = 0                       # homotopy: predictor-corrector steps over every path

    @property
    def real_solutions(self) -> int:
        """Distinct real assembly modes (the solutions' count)."""
        return len(self.solutions)

    @property
    def double_modes(self) -> int:
        """Multistart, homotopy: the modes that are double at the solver's tolerance (``DOUBLE_CONDITIONING``)."""
        return sum(c < DOUBLE_CONDITIONING for c in self.conditioning)


def consistent_fitness(model, leg_noise_std=None) -> float:
    """Redundant legs: the largest sum of squared leg residuals (config unit squared) of a mode, the
    estimator's consistency limit for the leg noise ``leg_noise_std`` (config unit; default the
    node's default, :func:`~glpma_ros.estimation.redundancy.leg_noise`); 0 without redundant legs."""
    if not model.redundancy:
        return 0.0
    return chi2_limit(model.redundancy) * leg_noise(model, leg_noise_std) ** 2


def leg_fitness(model, x, legs) -> float:
    """Sum of squared leg residuals of the solver variables ``x`` at ``legs``."""
    return float(np.sum((model.inverse_kinematics(x) - legs) ** 2))


def order(model, found: list) -> list:
    """Indices of ``found`` (SolveResults, their ``x`` made canonical here) sorted by variables."""
    for s in found:
        s.x = model.canonical(s.x)
    return sorted(range(len(found)), key=lambda k: tuple(np.round(found[k].x, 6)))


def sorted_modes(model, found: list) -> list:
    """``found`` in the order of :func:`order`."""
    return [found[k] for k in order(model, found)]
