"""The papers' experiments: their tables (001 Tables 5 and 8), the peers' G3-PCX, the larger-cap diagnostics, all
assembly modes (002) and the baselines (004 Table II, 003's DE).  Each returns plain data; ``report`` turns it into
tables.  Timing experiments: :mod:`.tracking`, :mod:`.timing`, :mod:`.dds`."""
from __future__ import annotations

import gc
import math
import time
from dataclasses import dataclass, field

import numpy as np

from glpma_ros import solvers
from glpma_ros.solve_all import solve_all, wide_range
from glpma_tools.timing import progress_bar as _bar

from .common import Run
from .papers import PUBLISHED
from .peers import PEER_SOLVERS, available


# -- the papers' tables ----------------------------------------------------------------
@dataclass
class Config:
    solver: str
    population: int
    local_population: int | None
    polish: bool

    @property
    def key(self):
        return (self.solver, self.population, self.local_population)

    @property
    def pop_label(self):
        return f"({self.population}, {self.local_population})" if self.local_population else str(self.population)

    @property
    def mode(self):
        return "default (polish)" if self.polish else "pure"


@dataclass
class TableRow:
    config: Config
    runs: list = field(default_factory=list)


def timed_solve(solver, model, legs, seed, **options) -> Run:
    """One search of ours, timed with the wall clock."""
    t0 = time.perf_counter()
    r = solvers.solve(solver, model, legs, rng=seed, **options)
    return Run(r.success, int(r.nfev), time.perf_counter() - t0, float(r.fun), list(r.history))


def table_row(sc, cfg: Config, n: int, progress) -> TableRow:
    """``n`` searches (seeds 0..n-1) of one configuration, after one short solve in which Numba compiles (or loads
    from its cache) everything the configuration calls."""
    options = {"population": cfg.population, "polish": cfg.polish,
               **({"local_population": cfg.local_population} if cfg.local_population else {})}
    solvers.solve(cfg.solver, sc.model, sc.legs, rng=12345, max_evals=50 * cfg.population, **options)
    gc.collect()
    return TableRow(cfg, [timed_solve(cfg.solver, sc.model, sc.legs, seed, **options)
                          for seed in _bar(range(n), f"{sc.label} {cfg.solver} {cfg.pop_label} {cfg.mode}", progress)])


def paper_tables(sc, runs_pure, runs_polished, progress) -> list[TableRow]:
    """Every row of the paper's table, pure and with the refinement."""
    return [table_row(sc, Config(solver, pop, local, polish), runs_polished if polish else runs_pure, progress)
            for polish in (False, True) for solver, pop, local in PUBLISHED[sc.model.kind]]


# -- peers: pure G3-PCX -----------------------------------------------------------------
@dataclass
class PeerRow:
    name: str
    runs: list = field(default_factory=list)
    status: str = "run"        # run | not installed | skipped
    note: str = ""


def peer_g3pcx(sc, runs_by_peer: dict, progress) -> list[PeerRow]:
    """Each peer's runs (seeds 0..) on the paper's protocol, after one short run that imports and compiles."""
    kw = {k: solvers.PAPER_SETTINGS[sc.model.kind][k] for k in ("population", "init_range", "max_evals")}
    out = []
    for name, fn in PEER_SOLVERS.items():
        n, why = runs_by_peer.get(name, 0), available(name)
        if why is not None:
            print(f"bench: {name} {why}; its rows are marked 'not installed'")
            out.append(PeerRow(name, status="not installed", note=why))
            continue
        if n <= 0:
            out.append(PeerRow(name, status="skipped", note=runs_by_peer.get(f"{name}_why", "0 runs requested")))
            continue
        fn(sc.model, sc.legs, seed=999, **{**kw, "max_evals": 200})
        out.append(PeerRow(name, [fn(sc.model, sc.legs, seed=seed, **kw)
                                  for seed in _bar(range(n), f"{sc.label} peer {name}", progress)]))
    return out


# -- all solutions -------------------------------------------------------------------------
@dataclass
class AllSolutionsResult:
    runs: int
    repeats: list             # (seed, count, elapsed_s, evaluations)
    init_range: tuple
    deviations: list          # per published solution: (index, nearest found, max coordinate deviation)
    unmatched_found: int


def all_solutions(sc, runs, repeats, progress) -> AllSolutionsResult:
    """``repeats`` times ``solve_all`` (seeds 0..), and how close the first repeat's solutions come to the published
    ones (hexapod: largest coordinate difference in the canonical form; 3-RPR: the model's distance)."""
    from .report import FOUND_MM
    model = sc.model
    solve_all(model, sc.legs, runs=2, seed=999)       # warm-up
    reps, first = [], None
    for seed in _bar(range(repeats), f"{sc.label} solve_all", progress):
        gc.collect()
        res = solve_all(model, sc.legs, runs=runs, seed=seed)
        reps.append((seed, len(res.solutions), res.elapsed_s, res.evaluations))
        first = [s.x for s in res.solutions] if first is None else first
    devs = []
    for i, pub in enumerate(sc.published):
        d = [float(np.max(np.abs(model.canonical(x) - model.canonical(pub)))) if sc.key == "hexapod"
             else model.distance(x, pub) for x in first]
        devs.append((i, int(np.argmin(d)), min(d)) if d else (i, None, math.inf))
    matched = {j for _, j, d in devs if d < FOUND_MM}
    return AllSolutionsResult(runs, reps, wide_range(model, sc.legs), devs, len(first) - len(matched))


# -- the gap between the papers' pure G3-PCX and faithful implementations --------------------
@dataclass
class GapDiagnostics:
    caps: dict               # max_evals -> list of Run (our pure G3-PCX, paper population)


def gap_diagnostics(sc, runs, progress) -> GapDiagnostics:
    """Our pure G3-PCX with larger evaluation caps: 2 x 10,000 + population (the cap if the paper had counted
    generations of two children) and 100,000 (how many evaluations a run needs to reach 1e-20 at all)."""
    settings = solvers.PAPER_SETTINGS[sc.model.kind]
    pop, cap = settings["population"], settings["max_evals"]
    return GapDiagnostics({max_evals: [timed_solve("g3pcx", sc.model, sc.legs, seed, polish=False, max_evals=max_evals)
                                       for seed in _bar(range(runs), f"{sc.label} G3-PCX cap {max_evals}", progress)]
                           for max_evals in (2 * cap + pop, 10 * cap)})


# -- the baselines: 004 Table II (SA, GA, GA-SA) and 003's DE on 001's protocols ---------
#: 004 Table II rows reproduced: (solver, solver parameters); SA at each published chain length
TABLE2_CONFIGS = (("sa", {"chain_length": 20}), ("sa", {"chain_length": 50}), ("sa", {"chain_length": 100}),
                  ("rcga", {}), ("gasa", {}))


@dataclass
class Baselines:
    table2: list     # protocols.Table2Result
    de: dict         # scenario key -> [TableRow] (pure, default)


def baselines(scenarios, table2_runs, runs, hex_runs, progress) -> Baselines:
    """004's Table II protocol on the 3-RPR; DE/rand/1/bin (003) on 001's protocols."""
    from .protocols import table2_protocol
    table2 = []
    if "3rpr" in scenarios and table2_runs > 0:
        table2 = [table2_protocol(scenarios["3rpr"].model, name, runs=table2_runs, **params)
                  for name, params in _bar(TABLE2_CONFIGS, "004 Table II", progress)]
    de = {key: [table_row(sc, Config("de", solvers.DEFAULT_POPULATION["de"](sc.model), None, polish),
                          hex_runs if key == "hexapod" and not polish else runs, progress) for polish in (False, True)]
          for key, sc in scenarios.items()}
    return Baselines(table2, de)
