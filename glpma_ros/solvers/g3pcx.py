"""G3-PCX: generalised generation gap model with parent-centric crossover.

Deb, Anand & Joshi (2002), "A computationally efficient evolutionary algorithm
for real-parameter optimization", Evolutionary Computation 10(4); used for the
3-RPR and 6-6 forward kinematics in Chandra & Rolland (2014, Algorithm 2) and
Rolland & Chandra (2016).

Steady state.  Each generation:

1. parents: the best individual (the index parent ``x_p``) and ``mu - 1`` others
   drawn at random;
2. ``lam`` children by PCX around ``x_p``:
   ``child = x_p + w_zeta d + w_eta D_bar e``, ``d = x_p - g`` (``g`` the parents'
   centroid), ``D_bar`` the mean distance of the other parents to the line
   through ``g`` along ``d``, ``w_zeta ~ N(0, sigma_zeta^2)`` and ``e`` a standard
   normal vector with its component along ``d`` removed, scaled by
   ``w_eta ~ N(0, sigma_eta^2)`` per direction;
3. ``r`` individuals of the population drawn at random;
4. the best ``r`` of those and the children replace them (elitist: the best
   individual can only be replaced by a better one).

Degenerate case ``|d| = 0``: the child is an isotropic perturbation of ``x_p``
scaled by the parents' spread (or, if all parents coincide, by the population's
spread), never a division by zero.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from ..models.kernels import population_fitness
from ..runtime.clock import kernel_end, monotonic_s, reached
from ..runtime.compat import NUMBA_INLINE
from .driver import EvolutionaryState, solve_population

#: Deb et al. (2002) defaults; the papers use "two kids, a family of two parents"
MU = 3
LAMBDA = 2
R_REPLACE = 2
SIGMA_ZETA = 0.1
SIGMA_ETA = 0.1


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def _argmin(f):
    b = 0
    for i in range(1, f.shape[0]):
        if f[i] < f[b]:
            b = i
    return b


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def pcx_children(parents, lam, sigma_zeta, sigma_eta, rng, pop):
    """``lam`` PCX children of ``parents`` (row 0 is the index parent); ``pop``
    gives the fallback scale when all parents coincide."""
    mu, n = parents.shape
    g = np.zeros(n)
    for k in range(mu):
        g += parents[k]
    g /= mu
    d = parents[0] - g
    dn = math.sqrt(np.sum(d * d))
    # mean perpendicular distance of the other parents to the line through g along d
    D_bar = 0.0
    for k in range(1, mu):
        e = parents[k] - g
        e2 = np.sum(e * e)
        if dn > 0.0:
            proj = np.sum(e * d) / dn
            e2 = e2 - proj * proj
        D_bar += math.sqrt(max(e2, 0.0))
    D_bar /= max(mu - 1, 1)
    children = np.empty((lam, n))
    for c in range(lam):
        eta = rng.standard_normal(n)
        if dn > 0.0:
            dhat = d / dn
            eta -= np.sum(eta * dhat) * dhat
            w_zeta = sigma_zeta * rng.standard_normal()
            children[c] = parents[0] + w_zeta * d + sigma_eta * D_bar * eta
        else:
            scale = D_bar if D_bar > 0.0 else _population_spread(pop)
            children[c] = parents[0] + sigma_eta * scale * eta
    return children


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def _population_spread(pop):
    n = pop.shape[1]
    s = 0.0
    for j in range(n):
        s += np.std(pop[:, j])
    s /= n
    if s == 0.0:  # collapsed population: a relative round-off step keeps it moving
        s = 1e-15 * (1.0 + np.max(np.abs(pop[0])))
    return s


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def _draw_distinct(rng, N, out, start):
    """Fill ``out[start:]`` with population indices drawn at random, all
    different from each other and from ``out[:start]``."""
    k = start
    while k < out.shape[0]:
        c = rng.integers(0, N)
        fresh = True
        for q in range(k):
            if out[q] == c:
                fresh = False
        if fresh:
            out[k] = c
            k += 1


@njit(cache=True, error_model="numpy")
def g3pcx_generations(pop, fit, rng, n_generations, max_evals, tolerance, end,
                      mu, lam, r, sigma_zeta, sigma_eta, kind, data, legs, n_res):
    """Evolve ``pop``/``fit`` in place; returns (generations, evaluations, stopped by the clock, the kernels'
    clock on entry).  The clock is read on entry and before each generation (a few microseconds of work) and
    the call stops there once it reads ``end`` (the kernels' clock, :func:`~glpma_ros.runtime.clock.kernel_end`;
    ``inf``: never, and the clock is never read: entry 0)."""
    N, n = pop.shape
    entered = 0.0 if end == math.inf else monotonic_s()
    timed_out = False
    idx = np.empty(mu, dtype=np.int64)
    parents = np.empty((mu, n))
    pool = np.empty((r + lam, n))
    pool_f = np.empty(r + lam)
    slots = np.empty(r, dtype=np.int64)
    best = _argmin(fit)
    gens = 0
    evals = 0
    while gens < n_generations and evals + lam <= max_evals and fit[best] >= tolerance:
        if reached(end):
            timed_out = True
            break
        idx[0] = best
        _draw_distinct(rng, N, idx, 1)
        for k in range(mu):
            parents[k] = pop[idx[k]]
        children = pcx_children(parents, lam, sigma_zeta, sigma_eta, rng, pop)
        child_f = population_fitness(children, kind, data, legs, n_res)
        evals += lam
        # r distinct random members compete with the children for their slots
        _draw_distinct(rng, N, slots, 0)
        for k in range(r):
            pool[k] = pop[slots[k]]
            pool_f[k] = fit[slots[k]]
        for c in range(lam):
            pool[r + c] = children[c]
            pool_f[r + c] = child_f[c]
        order = np.argsort(pool_f)
        for k in range(r):
            pop[slots[k]] = pool[order[k]]
            fit[slots[k]] = pool_f[order[k]]
        best = _argmin(fit)
        gens += 1
    return gens, evals, timed_out, entered


class G3PCXPopulation(EvolutionaryState):
    """A G3-PCX population that can be advanced generation by generation
    (GLPMA keeps one between local searches)."""

    name = "g3pcx"
    #: the kernel reads the clock before each generation (two children: a few microseconds)
    stops_itself = True

    def __init__(self, problem, pop, fit, rng, *, mu=MU, lam=LAMBDA, r=R_REPLACE,
                 sigma_zeta=SIGMA_ZETA, sigma_eta=SIGMA_ETA):
        super().__init__(problem, pop, fit, rng)
        self.mu, self.lam, self.r = int(mu), int(lam), int(r)
        self.sigma_zeta, self.sigma_eta = float(sigma_zeta), float(sigma_eta)
        if not (2 <= self.mu <= len(pop) and self.lam >= 1 and 1 <= self.r <= len(pop)):
            raise ValueError("G3-PCX needs 2 <= mu <= population, lam >= 1, 1 <= r <= population")

    def evals_per_generation(self) -> int:
        return self.lam

    def advance(self, n_generations, max_evals, tolerance):
        p = self.problem
        end = kernel_end(self.work_deadline)
        called = time.monotonic()           # the kernels' clock, read by Python
        gens, evals, self.out_of_time, entered = g3pcx_generations(
            self.pop, self.fit, self.rng, n_generations, max_evals, tolerance, end, self.mu, self.lam, self.r,
            self.sigma_zeta, self.sigma_eta, p.kind, p.data, p.legs, p.n_res)
        self.entry_s = entered - called if end != math.inf else 0.0
        return gens, evals


def solve(model, legs, *, population=100, rng=None, init_range=(-50.0, 50.0), center=None, spread=None,
          tolerance=1e-20, max_evals=10_000, budget_s=None, start=None, polish=True, **params):
    """Minimise the model's fitness with G3-PCX (plus the refinement unless
    ``polish=False``).  ``params``: ``mu``, ``lam``, ``r``, ``sigma_zeta``, ``sigma_eta``."""
    return solve_population("g3pcx", model, legs,
                            lambda problem, pop, fit, rng, term: G3PCXPopulation(problem, pop, fit, rng, **params),
                            population=population, rng=rng, init_range=init_range, center=center, spread=spread,
                            tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, polish=polish, start=start)
