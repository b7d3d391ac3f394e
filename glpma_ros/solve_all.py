"""Every distinct real assembly mode: independent polished G3-PCX searches from a
wide initial range, de-duplicated by distance (Rolland & Chandra 2016,
section 5.5.2 collect the 16 hexapod solutions with 100 runs from
U[-2000, 2000]^9)."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from . import solvers

#: two polished solutions closer than this share of the scale are the same mode
DEDUP_RELATIVE = 1e-4
#: half-width of the initial range in units of the geometry's size (longest leg or joint spread)
RANGE_FACTOR = 2.0


@dataclass
class AllSolutions:
    solutions: list       # SolveResult per distinct mode, sorted by variables
    runs: int
    elapsed_s: float
    evaluations: int


def wide_range(model, legs) -> tuple[float, float]:
    half = RANGE_FACTOR * max(model.scale, float(np.max(legs)))
    return -half, half


def solve_all(model, legs, *, runs=200, seed=0, solver="g3pcx", max_evals=None) -> AllSolutions:
    t0 = time.perf_counter()
    legs = model.check_legs(legs)
    rng = np.random.default_rng(seed)
    found = []
    evaluations = 0
    for _ in range(runs):
        r = solvers.solve(solver, model, legs, rng=rng, init_range=wide_range(model, legs), polish=True,
                          max_evals=max_evals)
        evaluations += r.nfev
        if not r.success:
            continue
        if all(model.distance(r.x, s.x) > DEDUP_RELATIVE * model.scale for s in found):
            found.append(r)
    found.sort(key=lambda s: tuple(np.round(s.x, 6)))
    return AllSolutions(found, runs, time.perf_counter() - t0, evaluations)
