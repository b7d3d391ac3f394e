"""Real-coded genetic algorithm: the master population of GLPMA
(Chandra & Rolland 2014, section 3) and the GA of Chandra, Zhang & Rolland (2009).

Generational.  Each generation:

* **elitism** -- the best individual is copied unchanged;
* **roulette-wheel selection** of two parents with weights ``w_i = 1 / f_i``
  (floored at ``MIN_FITNESS``): the papers do not state their transform; the
  reciprocal keeps selection pressure while the fitness falls through twenty
  orders of magnitude (``1 / (1 + f)`` flattens to uniform selection below
  f ~ 1 and stalls the search there; BENCHMARKS.md, "Design measurements");
* **Wright's heuristic crossover** (Wright 1991) with probability
  ``crossover_rate``: ``child = better + u (better - worse)``, ``u ~ U(0, 1)``;
  otherwise the child is a copy of the first parent;
* **non-uniform mutation** (Michalewicz 1992) with probability
  ``mutation_rate`` per child: one random variable moves by
  ``+/- width (1 - v^((1 - t/T)^b))``, ``v ~ U(0, 1)``, where ``width`` is the
  initial range of that variable, ``t`` the generation and ``T`` the last
  generation the evaluation cap allows (004's "pivot" mutation is not
  specified, so this documented standard operator stands in for it).

Children identical to their parent are not re-evaluated and not counted.  Each child is
evaluated as soon as it is made (the evaluation draws no random number: the same
generation as evaluating them all at its end), so that under a deadline a generation
can stop between two children and resume there.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..models.kernels import fitness_one
from ..runtime.clock import kernel_end, reached
from ..runtime.compat import NUMBA_INLINE
from .common import kernel_array
from .driver import GenerationInProgress, solve_population

#: the papers' rates (Chandra & Rolland 2014; Chandra, Zhang & Rolland 2009)
CROSSOVER_RATE = 0.9
MUTATION_RATE = 0.1
#: floor of the fitness in the roulette weights 1 / f (an exact solution is not infinitely likely)
MIN_FITNESS = 1e-300
#: non-uniform mutation's shape parameter (Michalewicz 1992)
MUTATION_B = 5.0
#: children between two reads of the clock under a deadline: a few microseconds of work (a child's evaluation
#: is 0.3-1 µs on the 3-RPR and the hexapod), while a read costs about 0.1 µs
CLOCK_STRIDE = 8


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def roulette(cum, rng):
    """Roulette-wheel selection: the first index whose cumulative weight ``cum`` exceeds a uniform draw
    in [0, ``cum[-1]``), by bisection."""
    u = rng.random() * cum[-1]
    lo, hi = 0, cum.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cum[mid] < u:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def roulette_cumulative(fit, cum):
    """Cumulative roulette weights ``1 / f`` (floored at ``MIN_FITNESS``) into ``cum``."""
    s = 0.0
    for i in range(fit.shape[0]):
        s += 1.0 / max(fit[i], MIN_FITNESS)
        cum[i] = s


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def start_generation(pop, fit, cum, new, new_f, tolerance):
    """Elitism and roulette wheel of a new generation: the best individual into slot 0 of
    ``new`` and the cumulative weights into ``cum``.  False when the best is below ``tolerance``
    (converged: no new generation)."""
    best = np.argmin(fit)
    if fit[best] < tolerance:
        return False
    roulette_cumulative(fit, cum)
    new[0] = pop[best]
    new_f[0] = fit[best]
    return True


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def wright_crossover(pop, fit, a, b, rng, out):
    """Wright's heuristic crossover of ``pop[a]`` and ``pop[b]`` into ``out``:
    ``better + u (better - worse)``, ``u ~ U(0, 1)`` (one draw)."""
    better, worse = (a, b) if fit[a] <= fit[b] else (b, a)
    u = rng.random()
    out[:] = pop[better] + u * (pop[better] - pop[worse])


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def crossover_or_copy(pop, fit, cum, rng, crossover_rate, out):
    """Two roulette parents and, with probability ``crossover_rate`` (distinct parents), Wright's crossover of
    them into ``out``; otherwise a copy of the first parent.  Returns the parent copied, or -1 when ``out`` is a
    crossover child (a new point: it needs an evaluation)."""
    a = roulette(cum, rng)
    b = roulette(cum, rng)
    if rng.random() < crossover_rate and a != b:
        wright_crossover(pop, fit, a, b, rng, out)
        return -1
    out[:] = pop[a]
    return a


@njit(cache=True, error_model="numpy", inline=NUMBA_INLINE)
def make_child(pop, fit, cum, rng, i, t, crossover_rate, mutation_rate, mutation_b, width, new, new_f):
    """Child ``i`` of the generation in progress into ``new[i]``: :func:`crossover_or_copy` (a copy takes its
    parent's fitness into ``new_f[i]``), then the non-uniform mutation at generation share ``t``.  True when
    the child differs from its parent (it needs an evaluation)."""
    n = pop.shape[1]
    parent = crossover_or_copy(pop, fit, cum, rng, crossover_rate, new[i])
    changed = parent < 0
    if not changed:
        new_f[i] = fit[parent]
    if rng.random() < mutation_rate:
        k = rng.integers(0, n)
        step = width[k] * (1.0 - rng.random() ** ((1.0 - t) ** mutation_b))
        new[i, k] += step if rng.random() < 0.5 else -step
        changed = True
    return changed


@njit(cache=True, error_model="numpy")
def rcga_generations(pop, fit, new, new_f, cum, progress, r, rng, n_generations, max_evals, tolerance, end,
                     generation, last_generation, crossover_rate, mutation_rate, mutation_b, width, kind, data, legs):
    """Evolve ``pop``/``fit`` in place, child by child; returns (generations completed, evaluations).

    ``new``/``new_f`` hold the generation in progress and ``progress[0]`` its next child (0: none started;
    a generation starts only when its ``N - 1`` evaluations fit in ``max_evals``).  The clock is read every
    :data:`CLOCK_STRIDE` children and the call stops there once it reads ``end`` (the kernels' clock,
    :func:`~glpma_ros.runtime.clock.kernel_end`; ``inf``: never); the next call resumes the same generation
    with the same random stream, so the generations are those of one long call.  ``r`` is scratch space for
    the residuals."""
    N = pop.shape[0]
    gens = 0
    evals = 0
    made = 0
    while True:
        if progress[0] == 0:
            if gens >= n_generations or evals + N - 1 > max_evals:
                break
            if not start_generation(pop, fit, cum, new, new_f, tolerance):
                break
            progress[0] = 1
        if made % CLOCK_STRIDE == 0 and reached(end):
            break
        i = progress[0]
        t = min((generation + gens) / max(last_generation, 1.0), 1.0)
        if make_child(pop, fit, cum, rng, i, t, crossover_rate, mutation_rate, mutation_b, width, new, new_f):
            new_f[i] = fitness_one(new[i], kind, data, legs, r)
            evals += 1
        made += 1
        progress[0] = i + 1
        if progress[0] == N:
            pop[:] = new
            fit[:] = new_f
            progress[0] = 0
            gens += 1
    return gens, evals


class RCGAPopulation(GenerationInProgress):
    """The population, with the generation in progress alongside it (a compiled call may stop inside a
    generation at the deadline; the next resumes it)."""

    name = "rcga"

    def __init__(self, problem, pop, fit, rng, *, width, max_evals, crossover_rate=CROSSOVER_RATE,
                 mutation_rate=MUTATION_RATE, mutation_b=MUTATION_B):
        super().__init__(problem, pop, fit, rng)
        self.width = kernel_array(np.broadcast_to(np.asarray(width, dtype=float), (pop.shape[1],)))
        self.crossover_rate, self.mutation_rate = float(crossover_rate), float(mutation_rate)
        self.mutation_b = float(mutation_b)
        self.generation = 0
        self.last_generation = max(float(max_evals) / len(pop), 1.0)
        self.new = np.empty_like(self.pop)
        self.new_f = np.empty_like(self.fit)
        self.cum = np.empty_like(self.fit)
        self.progress = np.zeros(1, dtype=np.int64)      # next child of the generation in progress (0: none)
        self.residuals = np.empty(problem.n_res)

    def advance(self, n_generations, max_evals, tolerance):
        p = self.problem
        gens, evals = rcga_generations(self.pop, self.fit, self.new, self.new_f, self.cum, self.progress,
                                       self.residuals, self.rng, n_generations, max_evals, tolerance,
                                       kernel_end(self.work_deadline), float(self.generation), self.last_generation,
                                       self.crossover_rate, self.mutation_rate, self.mutation_b, self.width,
                                       p.kind, p.data, p.legs)
        self.generation += gens
        # stopped inside a generation: only the clock does that
        self.out_of_time = bool(self.progress[0])
        return gens, evals


def mutation_width(init_range, spread, n_vars):
    """Per-variable width of the non-uniform mutation: the initial range, or
    six standard deviations of a warm-start spread."""
    if spread is not None:
        return np.broadcast_to(6.0 * np.asarray(spread, dtype=float), (n_vars,))
    low, high = init_range
    return np.broadcast_to(np.asarray(high, dtype=float) - np.asarray(low, dtype=float), (n_vars,))


def solve(model, legs, *, population=100, rng=None, init_range=(-50.0, 50.0), center=None, spread=None,
          tolerance=1e-20, max_evals=10_000, budget_s=None, start=None, polish=True, **params):
    """Minimise the model's fitness with the RCGA (plus the refinement unless
    ``polish=False``).  ``params``: ``crossover_rate``, ``mutation_rate``, ``mutation_b``."""
    return solve_population("rcga", model, legs, lambda problem, pop, fit, rng, term: RCGAPopulation(
        problem, pop, fit, rng, width=mutation_width(init_range, spread, model.n_vars), max_evals=max_evals, **params),
                            population=population, rng=rng, init_range=init_range, center=center, spread=spread,
                            tolerance=tolerance, max_evals=max_evals, budget_s=budget_s, polish=polish, start=start)
