"""Simulated annealing: the SA baseline of Chandra, Zhang & Rolland (2009),
"Solving the forward kinematics of the 3RPR planar parallel manipulator using
a hybrid meta-heuristic paradigm", CIRA 2009 (paper 004: section II.A and
section IV.A item 1, Table II; after Kirkpatrick, Gelatt & Vecchi 1983 and
Metropolis et al. 1953).

004's settings: initial temperature ``T0 = 100``, Markov chain length ``L`` of
20, 50 or 100, cooling rate 0.01, and a neighbour made "by adding a small real
random number [-b, b]" to each variable.  What the paper leaves open, and what
is used here:

* **Cooling rate** ``alpha = 0.01`` is geometric: after each Markov chain
  ``T <- T (1 - alpha)``, so the ``k``-th chain (k = 0, 1, ...) runs at
  ``T_k = T0 (1 - alpha)^k``.
* **One "iteration" (004 Table II's "No. Itera") = one Markov chain** at one
  temperature: ``L`` neighbour proposals, each one fitness evaluation, each
  accepted with the Metropolis probability ``min(1, exp(-(f_new - f) / T))``.
  004's iteration counts hardly change with ``L`` (1130, 1066, 1073 for
  L = 20, 50, 100) while its CPU times grow with ``L``: the iteration is the
  temperature step, not the proposal.  One driver "generation" is one such
  iteration.
* **Neighbourhood width** ``b`` (per variable, 004 does not give it): at
  ``T0`` it is half the width of the initial range (``b0 = 10`` for
  U[-10, 10]^3: the first chains roam the whole initial box), and it shrinks
  with the temperature as ``b(T) = b0 sqrt(T / T0)`` -- the spread of the
  Boltzmann distribution ``exp(-f / T)`` in a quadratic basin scales as
  ``sqrt(T)``, so the proposals keep the size of the thermal fluctuations.
  A fixed ``b`` cannot both cross the initial box and land in the basin
  ``f < 1e-4`` (the three compared on 004's protocol: BENCHMARKS.md, "Design
  measurements").
  Under a warm start the width is six standard deviations of the spread
  (:func:`rcga.mutation_width`), so ``b0`` is three of them.
* The annealer remembers the **best point visited**; that is what it returns
  (and what the driver reports, so the reported best never gets worse).
* ``population > 1`` runs that many independent chains side by side at the
  same temperature (004's SA is the single chain, ``population = 1``).

The search stops the moment the best fitness falls below ``tolerance`` (even in
the middle of a chain; that chain counts as one iteration), or when a whole
round of chains would exceed the evaluation cap.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..models.kernels import fitness_one
from .driver import EvolutionaryState, solve_population
from .rcga import mutation_width

#: 004 section IV.A item 1: "initial temperature of 100"
T0 = 100.0
#: 004 section IV.A item 1: Markov chain lengths 20, 50 and 100 (20 is Table II's first row)
CHAIN_LENGTH = 20
#: 004 section IV.A item 1: "cooling rate of 0.01", read as T <- T (1 - 0.01) per chain
COOLING_RATE = 0.01
#: neighbourhood half-width at T0 as a fraction of the initial range's width
#: (004 leaves b open; chosen and measured as documented above)
NEIGHBOUR_FRACTION = 0.5
#: 004 runs SA as a single-solution method
POPULATION = 1

@njit(cache=True, error_model="numpy")
def neighbour_width(b0, temperature, t0):
    """``b(T) = b0 sqrt(T / T0)`` per variable."""
    return b0 * math.sqrt(max(temperature, 0.0) / t0)


@njit(cache=True, error_model="numpy")
def markov_chain(x, f, best_x, best_f, temperature, b, chain_length, max_evals, tolerance, rng,
                 kind, data, legs, r, y):
    """One Markov chain at ``temperature``: up to ``chain_length`` proposals
    ``y = x + U[-b, b]`` (per variable), Metropolis acceptance.  ``x`` and
    ``best_x`` are updated in place; ``r`` and ``y`` are scratch arrays.
    Stops early when ``best_f < tolerance`` or ``max_evals`` proposals are made.
    Returns ``(f, best_f, evaluations)``."""
    n = x.shape[0]
    evals = 0
    for _ in range(chain_length):
        if evals >= max_evals or best_f < tolerance:
            break
        for q in range(n):
            y[q] = x[q] + b[q] * (2.0 * rng.random() - 1.0)
        fy = fitness_one(y, kind, data, legs, r)
        evals += 1
        delta = fy - f
        if delta <= 0.0 or rng.random() < math.exp(-delta / temperature):
            x[:] = y
            f = fy
            if f < best_f:
                best_f = f
                best_x[:] = x
    return f, best_f, evals


@njit(cache=True, error_model="numpy")
def anneal(x, f, best_x, best_f, temperature, t0, b0, n_chains, chain_length, cooling_rate, max_evals,
           tolerance, rng, kind, data, legs, n_res):
    """``n_chains`` Markov chains from ``temperature``, cooling after each one
    (004 Algorithm 1's SA operator).  Returns ``(f, best_f, evaluations,
    temperature after the last chain)``; ``x``/``best_x`` updated in place."""
    r = np.empty(n_res)
    y = np.empty(x.shape[0])
    evals = 0
    for _ in range(n_chains):
        if evals >= max_evals or best_f < tolerance:
            break
        b = neighbour_width(b0, temperature, t0)
        f, best_f, e = markov_chain(x, f, best_x, best_f, temperature, b, chain_length, max_evals - evals,
                                    tolerance, rng, kind, data, legs, r, y)
        evals += e
        temperature *= 1.0 - cooling_rate
    return f, best_f, evals, temperature


@njit(cache=True, error_model="numpy")
def sa_generations(current, current_f, best, best_f, rng, n_generations, max_evals, tolerance, temperature,
                   t0, b0, chain_length, cooling_rate, kind, data, legs, n_res):
    """Advance every chain by ``n_generations`` temperature steps (one Markov
    chain each).  ``current``/``best`` rows are the chains' states and best
    visited points, updated in place.  Returns (generations, evaluations,
    temperature)."""
    P, n = current.shape
    r = np.empty(n_res)
    y = np.empty(n)
    gens = 0
    evals = 0
    done = np.min(best_f) < tolerance
    while gens < n_generations and evals + P * chain_length <= max_evals and not done:
        b = neighbour_width(b0, temperature, t0)
        for p in range(P):
            f, bf, e = markov_chain(current[p], current_f[p], best[p], best_f[p], temperature, b, chain_length,
                                    max_evals - evals, tolerance, rng, kind, data, legs, r, y)
            current_f[p] = f
            best_f[p] = bf
            evals += e
            if bf < tolerance:
                done = True
                break
        temperature *= 1.0 - cooling_rate
        gens += 1
    return gens, evals, temperature


class SAState(EvolutionaryState):
    """``pop``/``fit`` hold each chain's best visited point (what the driver
    reports and polishes); ``current``/``current_fit`` the chains' states."""

    name = "sa"

    def __init__(self, problem, pop, fit, rng, *, width, t0=T0, chain_length=CHAIN_LENGTH,
                 cooling_rate=COOLING_RATE, neighbour_fraction=NEIGHBOUR_FRACTION):
        super().__init__(problem, pop, fit, rng)
        self.current = self.pop.copy()
        self.current_fit = self.fit.copy()
        self.t0 = float(t0)
        self.temperature = self.t0
        self.chain_length = int(chain_length)
        self.cooling_rate = float(cooling_rate)
        width = np.broadcast_to(np.asarray(width, dtype=float), (pop.shape[1],))
        self.b0 = np.ascontiguousarray(float(neighbour_fraction) * width)
        if not (self.t0 > 0 and self.chain_length >= 1 and 0 <= self.cooling_rate < 1):
            raise ValueError("SA needs t0 > 0, chain_length >= 1 and 0 <= cooling_rate < 1")

    def inject(self, x, f):
        """Restart the chain with the worst best point from ``x``."""
        i = int(np.argmax(self.fit))
        self.pop[i] = x
        self.fit[i] = f
        self.current[i] = x
        self.current_fit[i] = f

    def evals_per_generation(self) -> int:
        return len(self.pop) * self.chain_length

    def advance(self, n_generations, max_evals, tolerance):
        p = self.problem
        gens, evals, self.temperature = sa_generations(
            self.current, self.current_fit, self.pop, self.fit, self.rng, n_generations, max_evals, tolerance,
            self.temperature, self.t0, self.b0, self.chain_length, self.cooling_rate,
            p.kind, p.data, p.legs, p.n_res)
        return gens, evals


def default_population(model) -> int:
    """004's SA is a single chain."""
    return POPULATION


def solve(model, legs, *, population=POPULATION, rng=None, init_range=(-50.0, 50.0), center=None, spread=None,
          tolerance=1e-20, max_evals=10_000, budget_s=None, start=None, polish=True, **params):
    """Minimise the model's fitness by simulated annealing (plus the refinement
    unless ``polish=False``).  ``params``: ``t0``, ``chain_length``,
    ``cooling_rate``, ``neighbour_fraction``."""
    return solve_population("sa", model, legs, lambda problem, pop, fit, rng, term: SAState(
        problem, pop, fit, rng, width=mutation_width(init_range, spread, model.n_vars), **params),
                            population=population, rng=rng, init_range=init_range, center=center, spread=spread,
                            tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, polish=polish, start=start)
