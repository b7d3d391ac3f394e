"""``glpma-fk map --exact K``: a spot check of a finished map against certified counts.

K grid points with valid legs, without a double mode (a point on a singularity, whose count is decided by
round-off, see :func:`.grid.double_modes`) and not marked uncertified by the homotopy are drawn at random (a
``numpy.random.Generator`` seeded by the map's seed, so the same map checks the same points) and their real
assembly modes are counted again by :func:`glpma_ros.modes.multistart.solve_all` with ``method="exact"``
(msolve's real root isolation, :mod:`glpma_ros.modes.exact`). A point whose map count differs is listed with
both counts; the command then exits 1. This certifies the sample, not the whole map: the homotopy's counts are
certified by its root count point by point (an independent check of the method), the multistart's are
statements about basins of attraction (see :mod:`glpma_ros.modes.multistart`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from glpma_ros.errors import GlpmaError, InputError
from glpma_ros.modes.exact import ExactUnavailableError, msolve_executable
from glpma_ros.modes.multistart import solve_all

from .grid import OUTSIDE, MapSpec, pose_variables

#: stream of the sample, apart from the points' own seeds (point_seed uses [seed, index])
SAMPLE_STREAM = 0x6578616374      # "exact"


@dataclass
class ExactCheck:
    points: list                  # grid indices checked
    agree: int = 0
    disagree: list = field(default_factory=list)   # {"index", "coordinates", "map", "exact"}
    skipped: list = field(default_factory=list)    # {"index", "reason"}: msolve could not decide (degenerate)
    elapsed_s: float = 0.0

    def as_dict(self) -> dict:
        return {"points": [int(i) for i in self.points], "agree": self.agree, "disagree": self.disagree,
                "skipped": self.skipped, "elapsed_s": self.elapsed_s}

    def text(self) -> str:
        lines = [f"  exact check (msolve) of {len(self.points)} points: {self.agree} agree, "
                 f"{len(self.disagree)} differ, {len(self.skipped)} undecided in {self.elapsed_s:.1f} s"]
        lines += [f"    differs at {d['coordinates']}: map {d['map']}, certified {d['exact']}" for d in self.disagree]
        lines += [f"    undecided at index {s['index']}: {s['reason']}" for s in self.skipped]
        return "\n".join(lines)


def require_exact() -> None:
    """:class:`InputError` (exit 2) before the map is computed when msolve is missing."""
    try:
        msolve_executable()
    except ExactUnavailableError as exc:
        raise InputError(f"--exact: {exc}") from None


def sample(spec: MapSpec, counts: np.ndarray, k: int, double: np.ndarray | None = None,
           certified: np.ndarray | None = None) -> np.ndarray:
    """Up to ``k`` distinct grid indices with valid legs, no double mode (``double``: the map's
    ``double_modes``) and not marked uncertified by the homotopy (``certified`` 0), drawn without replacement."""
    regular = counts.reshape(-1) != OUTSIDE
    if double is not None:
        regular &= double.reshape(-1) == 0
    if certified is not None:
        regular &= certified.reshape(-1) != 0
    valid = np.flatnonzero(regular)
    rng = np.random.default_rng([spec.seed, SAMPLE_STREAM])
    return np.sort(rng.choice(valid, size=min(k, valid.size), replace=False))


def exact_check(model, spec: MapSpec, counts: np.ndarray, k: int, double: np.ndarray | None = None,
                certified: np.ndarray | None = None) -> ExactCheck:
    """Certified counts at ``k`` sampled points (none with a double mode or uncertified) compared with the map's
    ``counts``."""
    t0 = time.perf_counter()
    flat = counts.reshape(-1)
    check = ExactCheck(list(sample(spec, counts, k, double, certified)))
    for index in check.points:
        coords = spec.coordinates(index)
        legs = model.inverse_kinematics(pose_variables(model, coords))
        try:
            exact = len(solve_all(model, legs, method="exact").solutions)
        except GlpmaError as exc:           # degenerate system, or a certified root that does not polish
            check.skipped.append({"index": int(index), "reason": str(exc)})
            continue
        if exact == int(flat[index]):
            check.agree += 1
        else:
            check.disagree.append({"index": int(index), "coordinates": coords, "map": int(flat[index]),
                                   "exact": exact})
    check.elapsed_s = time.perf_counter() - t0
    return check
