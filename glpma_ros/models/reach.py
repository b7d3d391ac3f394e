"""Leg vectors no pose can reach, told from the legs alone (before any search).

For any pose of any of the models (planar or spatial), legs ``i`` and ``j`` close a loop of four
points: base joint ``A_i``, platform joint ``B_i``, platform joint ``B_j``, base joint ``A_j``.  Its
sides are the legs ``l_i = |A_i B_i|``, ``l_j = |A_j B_j|`` and two lengths fixed by the geometry,
``a_ij = |A_i A_j|`` (base) and ``d_ij = |B_i B_j|`` (platform, rigid).  In a closed polygon each side
is at most the sum of the others (the triangle inequality applied twice, in any dimension), i.e.::

    a_ij <= l_i + d_ij + l_j        d_ij <= l_i + a_ij + l_j
    l_i  <= a_ij + d_ij + l_j       l_j  <= a_ij + d_ij + l_i

or, in two lines, ``|a_ij - d_ij| <= l_i + l_j`` (the two legs together span the difference of the
joints' distances) and ``|l_i - l_j| <= a_ij + d_ij``.  A leg vector that breaks one of them for one
pair has no real assembly: the estimator answers ``no_solution`` at once, without a search.  The test is
necessary, not sufficient (legs that pass may still have no assembly: the search and the probe decide
those), and costs ``n (n - 1) / 2`` pairs of four comparisons.

Legs exactly on a bound are a fully stretched (or folded) loop: a singular but real assembly.  A bound
counts as broken only beyond :data:`REACH_RTOL` times the reference length, so that round-off in the
legs or the joints never turns such an assembly into ``no_solution``.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: a bound is broken when exceeded by more than this share of ``max(scale, max leg)``: far above the
#: round-off of the joints' distances (1e-16 relative) and far below any leg error that matters
REACH_RTOL = 1e-9


class Unreachable(NamedTuple):
    """The first pair of legs (0-based) whose loop cannot close, and by how much (config unit)."""

    i: int
    j: int
    excess: float          # how far the broken bound is exceeded
    why: str               # the bound in words, legs numbered from 1


class PairBounds:
    """The loop bounds of every pair of legs of one model (the joints' distances computed once)."""

    def __init__(self, model):
        base = np.asarray(model.base, dtype=float)
        platform = np.asarray(model.platform, dtype=float)
        n = base.shape[0]
        self.i, self.j = np.triu_indices(n, 1)
        self.a = np.linalg.norm(base[self.i] - base[self.j], axis=1)
        self.d = np.linalg.norm(platform[self.i] - platform[self.j], axis=1)
        self.scale = float(model.scale)

    def check(self, legs) -> Unreachable | None:
        """The first pair whose loop cannot close with ``legs`` (config unit), or None when every pair can."""
        legs = np.asarray(legs, dtype=float)
        li, lj = legs[self.i], legs[self.j]
        span = np.abs(self.a - self.d) - (li + lj)          # > 0: the legs are too short to close the loop
        spread = np.abs(li - lj) - (self.a + self.d)        # > 0: one leg too long for the other
        excess = np.maximum(span, spread)
        k = int(np.argmax(excess))
        if not excess[k] > REACH_RTOL * max(self.scale, float(np.max(legs))):
            return None
        i, j = int(self.i[k]), int(self.j[k])
        if span[k] >= spread[k]:
            why = (f"legs {i + 1} and {j + 1} ({li[k]:.6g} + {lj[k]:.6g}) cannot span the difference "
                   f"{abs(self.a[k] - self.d[k]):.6g} of their joints' distances (base {self.a[k]:.6g}, "
                   f"platform {self.d[k]:.6g})")
        else:
            why = (f"legs {i + 1} and {j + 1} differ by {abs(li[k] - lj[k]):.6g}, more than their joints' "
                   f"distances allow ({self.a[k]:.6g} + {self.d[k]:.6g})")
        return Unreachable(i, j, float(excess[k]), why)
