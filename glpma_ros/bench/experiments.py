"""The experiments.  Each returns plain data; ``report`` turns it into tables."""
from __future__ import annotations

import gc
import importlib
import inspect
import math
import time
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from .. import solvers
from ..estimator import Estimator
from ..solve_all import solve_all, wide_range
from .common import Run, involuntary_switches, percentiles_ms
from .papers import PUBLISHED
from .peers import PEER_SOLVERS, SCIPY_VARIANTS, NumpyNewton, PeerMissing, ScipyWarm, available


def _bar(iterable, desc, progress, total=None):
    return tqdm(iterable, desc=desc, total=total, disable=not progress, leave=False, dynamic_ncols=True)


# -- 1. the papers' tables ----------------------------------------------------------------
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


def paper_configs(model) -> list[Config]:
    """Every row of the paper's table, pure and with the refinement."""
    out = []
    for polish in (False, True):
        for solver, pop, local in PUBLISHED[model.kind]:
            out.append(Config(solver, pop, local, polish))
    return out


def run_ours(model, legs, cfg: Config, seed: int) -> Run:
    kwargs = {"population": cfg.population}
    if cfg.local_population:
        kwargs["local_population"] = cfg.local_population
    t0 = time.perf_counter()
    r = solvers.solve(cfg.solver, model, legs, rng=seed, polish=cfg.polish, **kwargs)
    wall = time.perf_counter() - t0
    return Run(r.success, int(r.nfev), wall, float(r.fun), list(r.history))


def warm_up(model, legs, cfg: Config):
    """Compile (or load from Numba's cache) everything this configuration calls."""
    kwargs = {"population": cfg.population, "max_evals": 50 * cfg.population}
    if cfg.local_population:
        kwargs["local_population"] = cfg.local_population
    solvers.solve(cfg.solver, model, legs, rng=12345, polish=cfg.polish, **kwargs)


def paper_tables(sc, runs_pure, runs_polished, progress) -> list[TableRow]:
    rows = []
    for cfg in paper_configs(sc.model):
        n = runs_polished if cfg.polish else runs_pure
        warm_up(sc.model, sc.legs, cfg)
        gc.collect()
        row = TableRow(cfg)
        for seed in _bar(range(n), f"{sc.label} {cfg.solver} {cfg.pop_label} {cfg.mode}", progress):
            row.runs.append(run_ours(sc.model, sc.legs, cfg, seed))
        rows.append(row)
    return rows


# -- 3a. peers: pure G3-PCX -----------------------------------------------------------------
@dataclass
class PeerRow:
    name: str
    runs: list = field(default_factory=list)
    status: str = "run"        # run | not installed | skipped
    note: str = ""


def peer_g3pcx(sc, runs_by_peer: dict, progress) -> list[PeerRow]:
    settings = solvers.PAPER_SETTINGS[sc.model.kind]
    out = []
    for name, fn in PEER_SOLVERS.items():
        n = runs_by_peer.get(name, 0)
        why = available(name)
        if why is not None:
            print(f"bench: {name} {why}; its rows are marked 'not installed'")
            out.append(PeerRow(name, status="not installed", note=why))
            continue
        if n <= 0:
            out.append(PeerRow(name, status="skipped", note=runs_by_peer.get(f"{name}_why", "0 runs requested")))
            continue
        row = PeerRow(name)
        kw = {"population": settings["population"], "init_range": settings["init_range"],
              "max_evals": settings["max_evals"]}
        try:
            fn(sc.model, sc.legs, seed=999, **{**kw, "max_evals": 200})   # import and compile
            for seed in _bar(range(n), f"{sc.label} peer {name}", progress):
                row.runs.append(fn(sc.model, sc.legs, seed=seed, **kw))
        except PeerMissing as exc:
            row.status, row.note = "not installed", str(exc)
        out.append(row)
    return out


# -- 4 + 3b. warm tracking, and scipy from the same warm starts -------------------------------
@dataclass
class Tracking:
    steps: int
    budget_ms: float
    latency_s: np.ndarray
    errors: np.ndarray            # distance to the true pose (config unit)
    leg_residual: np.ndarray      # max |IK(x) - legs| per step
    statuses: dict
    stages: dict
    evaluations: np.ndarray
    starts: np.ndarray            # the warm start of each step (previous estimate)
    legs: np.ndarray
    truth: np.ndarray
    preempted: np.ndarray         # the step was preempted by another process (involuntary context switch)

    @property
    def stats(self):
        return percentiles_ms(self.latency_s)


def max_leg_residual(model, x, legs) -> float:
    return float(np.max(np.abs(model.inverse_kinematics(x) - legs)))


def tracking(sc, steps, budget_ms, progress) -> Tracking:
    from .scenarios import trajectory
    model = sc.model
    traj = trajectory(sc, steps)
    legs_all = np.array([model.inverse_kinematics(x) for x in traj])
    # warm-up on a copy of the first steps (compiles the warm path)
    est = Estimator(model, initial_pose=traj[0], time_budget_s=budget_ms / 1e3)
    for legs in legs_all[1:20]:
        est.estimate(legs)
    est = Estimator(model, initial_pose=traj[0], time_budget_s=budget_ms / 1e3)
    lat, err, res, evals, starts, pre = [], [], [], [], [], []
    statuses, stages = {}, {}
    gc.collect()
    for k in _bar(range(1, steps + 1), f"{sc.label} tracking", progress):
        legs = legs_all[k]
        starts.append(np.array(est.last_x, dtype=float))
        c0 = involuntary_switches()
        t0 = time.perf_counter()
        e = est.estimate(legs)
        lat.append(time.perf_counter() - t0)
        pre.append(involuntary_switches() > c0)
        statuses[e.status] = statuses.get(e.status, 0) + 1
        stages[e.start] = stages.get(e.start, 0) + 1
        evals.append(e.evaluations)
        if e.x is not None and np.all(np.isfinite(e.x)):
            err.append(model.distance(e.x, traj[k]))
            res.append(max_leg_residual(model, e.x, legs))
        else:
            err.append(math.inf)
            res.append(math.inf)
    return Tracking(steps, budget_ms, np.array(lat), np.array(err), np.array(res), statuses, stages,
                    np.array(evals), np.array(starts), legs_all[1:], traj[1:], np.array(pre, dtype=bool))


@dataclass
class ScipyRow:
    method: str
    jac: str
    latency_s: np.ndarray = None
    leg_residual: np.ndarray = None
    nfev: np.ndarray = None
    preempted: np.ndarray = None
    status: str = "run"
    note: str = ""


def scipy_warm(sc, trk: Tracking, progress) -> list[ScipyRow]:
    """scipy's variants and a plain NumPy Newton iteration, each from the Estimator's warm starts."""
    model = sc.model
    solvers_ = [NumpyNewton(model)]
    why = available("scipy")
    if why is None:
        solvers_ += [ScipyWarm(model, method, jac) for method, jac in SCIPY_VARIANTS]
    else:
        print(f"bench: scipy {why}; its rows are marked 'not installed'")
    out = []
    for solver in solvers_:
        method, jac = solver.method, solver.jac
        for k in range(min(10, len(trk.legs))):      # warm-up
            solver.solve(trk.starts[k], trk.legs[k])
        lat, res, nfev, pre = [], [], [], []
        gc.collect()
        for k in _bar(range(len(trk.legs)), f"{sc.label} scipy {method}/{jac}", progress):
            c0 = involuntary_switches()
            t0 = time.perf_counter()
            x, n = solver.solve(trk.starts[k], trk.legs[k])
            lat.append(time.perf_counter() - t0)
            pre.append(involuntary_switches() > c0)
            res.append(max_leg_residual(model, x, trk.legs[k]))
            nfev.append(n)
        out.append(ScipyRow(method, jac, np.array(lat), np.array(res), np.array(nfev), np.array(pre, dtype=bool)))
    if why is not None:
        out += [ScipyRow(m, j, status="not installed", note=why) for m, j in SCIPY_VARIANTS]
    return out


# -- 5. deadlines --------------------------------------------------------------------------------
@dataclass
class DeadlineRow:
    case: str
    solver: str
    budget_ms: float
    elapsed_s: np.ndarray
    short: str = ""
    preempted: np.ndarray = None
    stopped_early: bool = False

    @property
    def label(self):
        return f"{self.short} | {self.solver}"

    @property
    def overrun_ms(self):
        return self.elapsed_s * 1e3 - self.budget_ms


#: margin a solve may take beyond its budget and still count as on time
DEADLINE_MARGIN_MS = 0.5
#: a cell stops after this many solves if every one overran by more than STOP_OVERRUN_FACTOR x budget
STOP_AFTER = 10
STOP_OVERRUN_FACTOR = 10.0


def _timed_cell(call, n, budget_ms, desc, progress):
    """``n`` timed calls; returns (elapsed seconds, preempted flags, stopped early)."""
    el, pre = [], []
    for i in _bar(range(n), desc, progress):
        c0 = involuntary_switches()
        t0 = time.perf_counter()
        call(i)
        el.append(time.perf_counter() - t0)
        pre.append(involuntary_switches() > c0)
        if i + 1 == STOP_AFTER and n > STOP_AFTER and min(el) * 1e3 > (1.0 + STOP_OVERRUN_FACTOR) * budget_ms:
            return np.array(el), np.array(pre, dtype=bool), True
    return np.array(el), np.array(pre, dtype=bool), False


def infeasible_legs(sc):
    """Leg lengths with no real assembly (the platform cannot reach the base joints)."""
    if sc.key == "3rpr":
        return np.array([10.0, 10.0, 400.0])
    return np.full(6, 100.0)


def deadlines(scenarios, budgets_ms, n, progress, names=None) -> list[DeadlineRow]:
    rows = []
    names = list(names or solvers.SOLVERS)
    for sc in scenarios:
        model = sc.model
        cases = [(f"{sc.label}, infeasible legs, default (polish)", f"{sc.label} infeasible", infeasible_legs(sc),
                  True)]
        if sc.key == "hexapod":
            cases.insert(0, (f"{sc.label}, feasible legs, pure (cannot converge in ms)", f"{sc.label} pure",
                             sc.legs, False))
        for case, short, legs, polish in cases:
            for solver in names:
                solvers.solve(solver, model, legs, rng=1, polish=polish, budget_s=0.002, max_evals=10**9)
                for b in budgets_ms:
                    def call(seed, solver=solver, legs=legs, polish=polish, b=b):
                        solvers.solve(solver, model, legs, rng=seed, polish=polish, budget_s=b / 1e3,
                                      max_evals=10**9)
                    el, pre, stopped = _timed_cell(call, n, b, f"deadline {short} {solver} {b:g} ms", progress)
                    rows.append(DeadlineRow(case, solver, b, el, short, pre, stopped))
        # the estimator, cold, on legs without a solution: every stage runs until the deadline
        case = f"{sc.label}, infeasible legs, Estimator (GLPMA, cold, its default evaluation cap)"
        for b in budgets_ms:
            est = Estimator(model, time_budget_s=b / 1e3)
            est.estimate(infeasible_legs(sc))

            def call(_, est=est, legs=infeasible_legs(sc)):
                est.reset()
                est.estimate(legs)
            el, pre, stopped = _timed_cell(call, n, b, f"deadline {sc.label} Estimator {b:g} ms", progress)
            rows.append(DeadlineRow(case, "Estimator", b, el, f"{sc.label} infeasible, cold", pre, stopped))
    return rows


# -- 2. all solutions -------------------------------------------------------------------------
@dataclass
class AllSolutionsResult:
    runs: int
    repeats: list             # (seed, count, elapsed_s, evaluations)
    solutions: list           # variables of the first repeat
    init_range: tuple
    deviations: list          # per published solution: (index, nearest found, max coordinate deviation)
    unmatched_found: int


def all_solutions(sc, runs, repeats, progress) -> AllSolutionsResult:
    model = sc.model
    solve_all(model, sc.legs, runs=2, seed=999)       # warm-up
    reps, first = [], None
    for seed in _bar(range(repeats), f"{sc.label} solve_all", progress):
        gc.collect()
        res = solve_all(model, sc.legs, runs=runs, seed=seed)
        reps.append((seed, len(res.solutions), res.elapsed_s, res.evaluations))
        if first is None:
            first = [s.x for s in res.solutions]
    devs = []
    matched = set()
    for i, pub in enumerate(sc.published):
        if not first:
            devs.append((i, None, math.inf))
            continue
        d = [float(np.max(np.abs(model.canonical(x) - model.canonical(pub)))) if sc.key == "hexapod"
             else model.distance(x, pub) for x in first]
        j = int(np.argmin(d))
        devs.append((i, j, d[j]))
        if d[j] < 5.0:
            matched.add(j)
    return AllSolutionsResult(runs, reps, first or [], wide_range(model, sc.legs), devs,
                              len(first or []) - len(matched))


# -- 6. DDS end to end (another module's experiment) -------------------------------------------
HOOK_NAMES = ("bench_end_to_end", "run_bench", "benchmark")


def dds_end_to_end(scenarios, steps, quick):
    """Call ``glpma_ros.mock_controller.bench_end_to_end`` if it exists.

    Expected: ``bench_end_to_end(config=<yaml path>, steps=<int>, quick=<bool>) -> dict``
    of latency statistics (any scalar values, e.g. ``p50_ms``, ``p99_ms``, ``max_ms``,
    ``sent``, ``received``); keyword arguments it does not accept are not passed."""
    try:
        mc = importlib.import_module("glpma_ros.mock_controller")
    except Exception as exc:  # noqa: BLE001 - reported, never fatal
        return {"status": "skipped", "reason": f"glpma_ros.mock_controller not importable ({exc})"}
    fn = next((getattr(mc, n) for n in HOOK_NAMES if callable(getattr(mc, n, None))), None)
    if fn is None:
        return {"status": "skipped",
                "reason": f"glpma_ros.mock_controller has no {' / '.join(HOOK_NAMES)}() function"}
    try:
        params = inspect.signature(fn).parameters
        accepts_any = any(p.kind == p.VAR_KEYWORD for p in params.values())
    except (TypeError, ValueError):
        params, accepts_any = {}, True
    results = {}
    for sc in scenarios:
        kwargs = {"config": sc.path, "steps": steps, "quick": quick}
        kwargs = {k: v for k, v in kwargs.items() if accepts_any or k in params}
        try:
            t0 = time.perf_counter()
            stats = fn(**kwargs)
            results[sc.label] = {"status": "run", "stats": dict(stats or {}),
                                 "wall_s": time.perf_counter() - t0}
        except Exception as exc:  # noqa: BLE001
            results[sc.label] = {"status": "not run", "reason": f"{type(exc).__name__}: {exc}"}
    return {"status": "run", "function": f"glpma_ros.mock_controller.{fn.__name__}", "results": results}


# -- the gap between the papers' pure G3-PCX and faithful implementations --------------------
@dataclass
class GapDiagnostics:
    caps: dict               # max_evals -> list of Run (our pure G3-PCX, paper population)
    thresholds: tuple = (1e-20, 1e-16, 1e-12, 1e-8)


def gap_diagnostics(sc, runs, progress) -> GapDiagnostics:
    """Our pure G3-PCX with larger evaluation caps: 2 x 10,000 + population (the cap
    if the paper had counted generations of two children) and 100,000 (how many
    evaluations a run needs to reach 1e-20 at all)."""
    settings = solvers.PAPER_SETTINGS[sc.model.kind]
    pop, cap = settings["population"], settings["max_evals"]
    caps = {}
    for max_evals in (2 * cap + pop, 10 * cap):
        out = []
        for seed in _bar(range(runs), f"{sc.label} G3-PCX cap {max_evals}", progress):
            t0 = time.perf_counter()
            r = solvers.solve("g3pcx", sc.model, sc.legs, rng=seed, polish=False, max_evals=max_evals)
            out.append(Run(r.success, int(r.nfev), time.perf_counter() - t0, float(r.fun), list(r.history)))
        caps[max_evals] = out
    return GapDiagnostics(caps)


# -- 7. the baselines: 004 Table II (SA, GA, GA-SA) and 003's DE on 001's protocols ---------
#: 004 Table II rows reproduced: (solver, solver parameters); SA at each published chain length
TABLE2_CONFIGS = (("sa", {"chain_length": 20}), ("sa", {"chain_length": 50}), ("sa", {"chain_length": 100}),
                  ("rcga", {}), ("gasa", {}))


@dataclass
class Baselines:
    table2: list = field(default_factory=list)   # solvers.protocols.Table2Result
    de: dict = field(default_factory=dict)       # scenario key -> [TableRow] (pure, default)


def baselines(scenarios, table2_runs, runs, hex_runs, progress) -> Baselines:
    """004's Table II protocol on the 3-RPR; DE/rand/1/bin (003) on 001's protocols."""
    from ..solvers.protocols import table2_protocol
    out = Baselines()
    if "3rpr" in scenarios and table2_runs > 0:
        model = scenarios["3rpr"].model
        for name, params in _bar(TABLE2_CONFIGS, "004 Table II", progress):
            out.table2.append(table2_protocol(model, name, runs=table2_runs, **params))
    for key, sc in scenarios.items():
        population = solvers.DEFAULT_POPULATION["de"](sc.model)
        rows = []
        for polish in (False, True):
            cfg = Config("de", population, None, polish)
            n = hex_runs if key == "hexapod" and not polish else runs
            warm_up(sc.model, sc.legs, cfg)
            row = TableRow(cfg)
            for seed in _bar(range(n), f"{sc.label} DE {cfg.mode}", progress):
                row.runs.append(run_ours(sc.model, sc.legs, cfg, seed))
            rows.append(row)
        out.de[key] = rows
    return out
