"""GLPMA: global-local population memetic algorithm (Chandra & Rolland 2014,
Algorithm 1).

A master population evolves with the RCGA.  Every ``ls_interval`` master
generations the best master individual (the *meme*) is placed into a local
population (it replaces the local population's worst), which evolves for
``ls_intensity`` G3-PCX generations; the local population's best individual
then replaces the worst master individual, even when it did not improve.
The local population is initialised once and kept between local searches.

With ``polish=True`` the driver adds the Levenberg-Marquardt refinement as a
further local search on the meme (the paper's framework admits any local
search, section 3); ``polish=False`` is the paper's algorithm alone.
"""
from __future__ import annotations

import time

import numpy as np

from . import g3pcx, rcga
from .common import initial_population
from .driver import EvolutionaryState, run_evolution

#: the paper's settings (section 5): 3-RPR (100, 100), 5, 1; 6-6 (200, 200), 5, 85
LS_INTERVAL = 5
LS_INTENSITY = 1


class GLPMAState(EvolutionaryState):
    """The master population, with the local population alongside it.  One
    "generation" of this state is one master generation (plus, every
    ``ls_interval`` of them, one local search).

    A local search may be split across compiled chunks: a chunk of ``n`` master generations
    runs at most ``ceil(n * ls_intensity / ls_interval)`` local generations (its share of the
    work), and a local search cut there resumes at the next chunk, before any further master
    generation -- the same sequence of generations as in one piece, but no chunk outlasts its
    share (the 6-6 hexapod's 85 local generations would otherwise run past a deadline).  Under a
    deadline both kernels also read the clock inside their loops (:mod:`glpma_ros.runtime.clock`): a
    master generation (0.15 ms on the hexapod) stops between two children, a local search between
    two G3-PCX generations, and the next chunk resumes them where they stopped -- again the same
    sequence of generations."""

    name = "glpma"

    def __init__(self, master: rcga.RCGAPopulation, local: g3pcx.G3PCXPopulation, ls_interval, ls_intensity):
        super().__init__(master.problem, master.pop, master.fit, master.rng)
        self.master, self.local = master, local
        self.ls_interval, self.ls_intensity = int(ls_interval), int(ls_intensity)
        if self.ls_interval < 1 or self.ls_intensity < 1:
            raise ValueError("ls_interval and ls_intensity must be at least 1")
        self.since_local_search = 0
        self.local_left = 0             # generations of the local search under way (0: none)

    def evals_in(self, n_generations: int) -> int:
        """``n`` master generations and their share of local generations (see the class docstring)."""
        local_share = -(-n_generations * self.ls_intensity // self.ls_interval)     # ceil
        return n_generations * self.master.evals_per_generation() + local_share * self.local.evals_per_generation()

    def best(self):
        return self.master.best()

    def inject(self, x, f):
        self.master.inject(x, f)

    def advance(self, n_generations, max_evals, tolerance):
        # both kernels read the clock inside their loops: a master generation stops between two children, a
        # local search between two of its generations, at the driver's work deadline, and resume at the next
        # chunk where they stopped; between two calls the clock is read here (a call costs some 20 µs before
        # its work, and a chunk of the 3-RPR's short generations is dozens of calls)
        deadline = self.work_deadline
        self.master.work_deadline = self.local.work_deadline = deadline
        self.out_of_time = False
        gens = evals = 0
        local_share = -(-n_generations * self.ls_intensity // self.ls_interval)     # ceil
        while evals < max_evals:
            if deadline is not None and time.perf_counter() >= deadline:
                self.out_of_time = True
                break
            if self.local_left > 0:
                if local_share <= 0:
                    break               # the chunk's share is spent: resumed at the next chunk
                g, e = self.local.advance(min(self.local_left, local_share), max_evals - evals, tolerance)
                evals += e
                local_share -= g
                self.local_left -= g
                if self.local.out_of_time:
                    self.out_of_time = True
                    break               # the deadline: resumed at the next chunk (if any)
                if g == 0 or self.local.fit.min() < tolerance:
                    self.local_left = 0
                if self.local_left > 0:
                    break               # the chunk's share is spent: resumed at the next chunk
                x, f = self.local.best()
                self.master.inject(x, f)
                continue
            if gens >= n_generations:
                break
            g, e = self.master.advance(min(self.ls_interval - self.since_local_search, n_generations - gens),
                                       max_evals - evals, tolerance)
            gens += g
            evals += e
            self.since_local_search += g
            if self.master.out_of_time:
                self.out_of_time = True
                break                   # the deadline, inside a master generation: resumed at the next chunk
            if g == 0 or self.master.fit.min() < tolerance:
                break
            if self.since_local_search >= self.ls_interval:
                self.since_local_search = 0
                meme, f_meme = self.master.best()
                self.local.inject(meme, f_meme)
                self.local_left = self.ls_intensity
        return gens, evals


def solve(model, legs, *, population=100, local_population=100, rng=None, init_range=(-50.0, 50.0),
          center=None, spread=None, tolerance=1e-20, max_evals=10_000, budget_s=None, start=None, polish=True,
          ls_interval=LS_INTERVAL, ls_intensity=LS_INTENSITY, **params):
    """Minimise the model's fitness with GLPMA (plus the refinement unless ``polish=False``)."""
    rng = np.random.default_rng(rng)

    def make(problem, term):
        pop = initial_population(rng, population, model.n_vars, init_range, center, spread)
        master = rcga.RCGAPopulation(problem, pop, problem.evaluate(pop, term), rng,
                                     width=rcga.mutation_width(init_range, spread, model.n_vars),
                                     max_evals=max_evals)
        lpop = initial_population(rng, local_population, model.n_vars, init_range, center, spread)
        local = g3pcx.G3PCXPopulation(problem, lpop, problem.evaluate(lpop, term), rng, **params)
        return GLPMAState(master, local, ls_interval, ls_intensity)

    return run_evolution("glpma", model, legs, make, rng, tolerance=tolerance, max_evals=max_evals,
                         center=center, budget_s=budget_s, polish=polish, start=start)
