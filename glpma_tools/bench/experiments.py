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
from glpma_tools.tables import MISSING, fmt, fmt_ci, ratio, table
from glpma_tools.timing import progress_bar as _bar

from .common import Run, summarize
from .papers import ALL_SOLUTIONS, FAITHFUL_3RPR, PUBLISHED, TABLE_NAME, Published
from .peers import PEER_LABEL, PEER_SOLVERS, PYMOO_BOUND_FACTOR, available
from .protocols import PublishedRow
from .report import SOLVER_LABEL, figure_link, md_blocks, pct, prose


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


# -- the report's sections ----------------------------------------------------------------------------
GAP_THRESHOLDS = (1e-20, 1e-16, 1e-12, 1e-8)


FOUND_MM = 5.0


UNPUBLISHED = Published(*[math.nan] * 5)


def paper_tables_section(res, md_path) -> list[str]:
    out = md_blocks("## The papers' tables (001 Tables 5 and 8)")
    for key, rows in res["tables"].items():
        sc = res["scenarios"][key]
        kind, st = sc.model.kind, solvers.PAPER_SETTINGS[sc.model.kind]
        runs = {polish: "/".join(map(str, sorted({len(r.runs) for r in rows if r.config.polish == polish})))
                for polish in (False, True)}
        body = [[SOLVER_LABEL[row.config.solver], row.config.pop_label, row.config.mode, s.runs, pct(s.success_pct),
                 fmt(p.success, unit=" %"), fmt_ci(s.evals_mean, s.evals_ci), fmt_ci(p.evals, p.evals_pm),
                 ratio(s.evals_mean, p.evals), fmt(s.time_median_ms), fmt(s.time_mean_ms), fmt(p.time_s * 1e3),
                 ratio(s.time_mean_ms, p.time_s * 1e3), fmt(s.fun_median, 2)]
                for row in rows for s, p in [(summarize(row.runs), PUBLISHED[kind].get(row.config.key, UNPUBLISHED))]]
        out += md_blocks(
            f"### {sc.label}: {TABLE_NAME[kind]}",
            f"Init U[{st['init_range'][0]:g}, {st['init_range'][1]:g}]^{sc.model.n_vars}, unbounded search, success = "
            f"fitness < 1e-20 within {st['max_evals']:,} evaluations; {runs[False]} runs per pure row and {runs[True]} "
            "per default row (the paper: 100)."
            + (f" GLPMA: ls_interval 5, ls_intensity {st['ls_intensity']}." if "ls_intensity" in st else ""),
            table(["method", "pop", "mode", "runs", "success", "paper", "evals (ours)", "evals (paper)",
                   "evals ours/paper", "time median ms", "time mean ms", "paper ms", "time ours/paper",
                   "median final f"], body))
    return out


def figures_section(res, md_path) -> list[str]:
    links = [figure_link(res, name, md_path) for name in res["figures"] if name.startswith("success_")]
    return md_blocks("## Success vs evaluations", prose("figures"), *links) if links else []


def _ours_pure_g3pcx(res, key):
    """Our pure G3-PCX runs at the paper's population, or None."""
    pop = solvers.PAPER_SETTINGS[res["scenarios"][key].model.kind]["population"]
    rows = [r.runs for r in res["tables"].get(key, []) if r.config.key == ("g3pcx", pop, None) and not r.config.polish]
    return rows[0] if rows else None


def _peer_row(label, s, ours) -> list:
    """A row of the peers' table: the summary ``s`` of the runs of ``label``, its time and evaluations against
    ``ours`` (None: not run)."""
    return [label, s.runs, pct(s.success_pct), fmt_ci(s.evals_mean, s.evals_ci), fmt(s.evals_all_mean),
            fmt(s.fun_median, 2), fmt(s.time_mean_ms), ratio(s.time_mean_ms, ours and ours.time_mean_ms),
            ratio(s.evals_all_mean, ours and ours.evals_all_mean)]


def peers_section(res, md_path) -> list[str]:
    out = md_blocks("## Pure G3-PCX against peer implementations",
                    prose("peers", bound_factor=f"{PYMOO_BOUND_FACTOR:g}"))
    for key, data in res["peers"].items():
        sc = res["scenarios"][key]
        runs = _ours_pure_g3pcx(res, key)
        ours = summarize(runs) if runs else None
        p = PUBLISHED[sc.model.kind][("g3pcx", solvers.PAPER_SETTINGS[sc.model.kind]["population"], None)]
        body = ([_peer_row("ours `g3pcx` (pure)", ours, ours)] if ours else []) + [
            _peer_row(PEER_LABEL[r.name], summarize(r.runs), ours) if r.status == "run"
            else [PEER_LABEL[r.name], MISSING, r.status] + [MISSING] * 6 for r in data]
        body.append([f"paper ({TABLE_NAME[sc.model.kind]})", 100, fmt(p.success, unit=" %"),
                     fmt_ci(p.evals, p.evals_pm), MISSING, MISSING, fmt(p.time_s * 1e3), MISSING, MISSING])
        notes = [f"{PEER_LABEL[r.name]}: {r.note}" for r in data if r.status != "run" and r.note]
        out += md_blocks(f"### {sc.label}",
                         table(["implementation", "runs", "success", "evals to success", "mean evals (all runs)",
                                "median final f", "time/run ms", "time vs ours", "evals vs ours"], body),
                         notes and "Not run: " + "; ".join(notes) + ".")
    return out


def gap_section(res, md_path) -> list[str]:
    if not (res["peers"] or res["gap"]) or ("3rpr" not in res["peers"] and "3rpr" not in res["tables"]):
        return []
    pop, cap = (solvers.PAPER_SETTINGS["planar_3rpr"][k] for k in ("population", "max_evals"))
    ours = _ours_pure_g3pcx(res, "3rpr") if "3rpr" in res["scenarios"] else None
    series = {"ours": ours} if ours else {}
    series.update({PEER_LABEL[r.name]: r.runs for r in res["peers"].get("3rpr", []) if r.status == "run"})
    measured = {label: 100.0 * sum(r.success for r in runs) / len(runs) for label, runs in series.items()}

    def rate(label):
        return pct(measured[label]) if label in measured else "not run"
    out = md_blocks(
        "## Why the papers' pure G3-PCX figures do not reproduce",
        prose("gap", population=pop, cap=f"{cap:,}", ours=rate("ours"), pypop7=rate(PEER_LABEL["pypop7"]),
              pymoo=rate(PEER_LABEL["pymoo"]), reference=", ".join(f"{k} {v} %" for k, v in FAITHFUL_3RPR.items())),
        prose("gap", "thresholds"),
        table(["implementation", "runs"] + [f"f < {t:.0e}" for t in GAP_THRESHOLDS],
              [[label, len(runs)] + [pct(100.0 * sum(r.fun < t for r in runs) / len(runs)) for t in GAP_THRESHOLDS]
               for label, runs in series.items()]))
    # the conclusion, written from the measured figures
    far = measured and max(measured.values()) < 50      # every implementation far below the paper's 90 %
    text = [prose("gap", "reading", cap=f"{cap:,}", rates=", ".join(f"{k} {v:.0f} %" for k, v in measured.items())
                  or "n/a", far=prose("gap", "far", spread=f"{max(measured.values()) - min(measured.values()):.0f}")
                  if far else "")]
    diag = res.get("gap")
    if diag:
        rows = []
        for max_evals, runs in diag.caps.items():
            s = summarize(runs)
            q = np.percentile([r.nfev for r in runs if r.success], [50, 90]) if s.successes else (math.nan,) * 2
            rows.append([f"{max_evals:,}", s.runs, pct(s.success_pct), fmt_ci(s.evals_mean, s.evals_ci),
                         fmt(float(q[0])), fmt(float(q[1]))])
        out += md_blocks(prose("gap", "caps", generation_cap=f"{2 * cap + pop:,}", large_cap=f"{10 * cap:,}"),
                         table(["cap", "runs", "success", "evals to success", "median", "90th percentile"], rows))
        s2, s10 = summarize(diag.caps[min(diag.caps)]), summarize(diag.caps[max(diag.caps)])
        text.append(prose("gap", "reading_caps", cap2=f"{min(diag.caps):,}", success2=f"{s2.success_pct:.0f}",
                          cap10=f"{max(diag.caps):,}", success10=f"{s10.success_pct:.0f}",
                          evals=f"{s10.evals_mean:,.0f}",
                          ratio=ratio(s10.evals_mean, PUBLISHED["planar_3rpr"][("g3pcx", pop, None)].evals)))
    text.append(prose("gap", "unknowns"))
    sums = [summarize(r.runs) for r in res["tables"].get("3rpr", []) if r.config.polish]
    if sums:
        lo, hi = min(x.success_pct for x in sums), max(x.success_pct for x in sums)
        text.append(prose("gap", "reading_refined", rate=f"{lo:.0f} %" if lo == hi else f"{lo:.0f}–{hi:.0f} %",
                          fewest=f"{min(x.evals_mean for x in sums):,.0f}",
                          most=f"{max(x.evals_mean for x in sums):,.0f}"))
    return out + md_blocks(" ".join(text))


def all_solutions_section(res, md_path) -> list[str]:
    body = []
    for key, r in res["all_solutions"].items():
        sc = res["scenarios"][key]
        times = [t for _, _, t, _ in r.repeats]
        devs = [d for _, _, d in r.deviations]
        paper = (f"{ALL_SOLUTIONS['count']} from {ALL_SOLUTIONS['runs']} runs, U[-2000, 2000]^9, "
                 f"< {ALL_SOLUTIONS['time_s']:g} s, 0.15 – 2.5 mm from exact" if key == "hexapod"
                 else "2 (001 section 5.3; 004 Table IV)")
        body.append([sc.label, r.runs, f"U[{r.init_range[0]:g}, {r.init_range[1]:g}]", len(r.repeats),
                     "/".join(str(c) for _, c, _, _ in r.repeats),
                     f"{np.median(times):.3f} ({min(times):.3f} – {max(times):.3f})",
                     f"{sum(d < FOUND_MM for d in devs)}/{len(sc.published)}",
                     f"{min(devs):.3g} – {max(devs):.3g}" if devs and all(map(math.isfinite, devs)) else MISSING,
                     r.unmatched_found, paper])
    return md_blocks("## All real assembly modes (002 section 5.5.2)", prose("all_solutions"),
                     table(["manipulator", "runs", "init range", "repeats", "distinct found (per repeat)",
                            "wall s median (min – max)", f"published matched (< {FOUND_MM:g} mm)",
                            "deviation mm (min – max)", "found, not published", "paper"], body),
                     "hexapod" in res["all_solutions"] and prose("all_solutions", "hexapod"))


def baselines_section(res, md_path) -> list[str]:
    b = res["baselines"]
    rows = []
    for r in b.table2 or []:
        p = r.published or PublishedRow("", None, *[math.nan] * 6, 0, 0)      # no row in Table II: dashes
        rows.append([r.solver, p.markov_chain or MISSING, r.runs, f"{100 * r.success_rate:.0f} %",
                     f"{100 * p.successes / p.runs:.0f} %" if p.runs else MISSING,
                     fmt_ci(r.mean_iterations, r.iterations_ci), fmt_ci(p.iterations, p.iterations_ci),
                     fmt_ci(r.mean_evaluations, r.evaluations_ci), fmt(r.mean_fitness), fmt(p.fitness),
                     fmt(r.mean_time_s * 1e3), fmt(p.cpu_s * 1e3)])
    de = [[res["scenarios"][key].label, row.config.mode, row.config.population, s.runs, f"{s.success_pct:.0f} %",
           fmt_ci(s.evals_mean, s.evals_ci), fmt(s.time_median_ms), fmt(s.fun_median)]
          for key, trows in (b.de or {}).items() for row in trows for s in [summarize(row.runs)]]
    return md_blocks(
        "## Baselines: 004 Table II (SA, GA, GA-SA) and 003's DE",
        rows and prose("baselines", "table2"),
        rows and table(["solver", "chain", "runs", "success", "paper", "iterations (ours)", "iterations (paper)",
                        "evaluations (ours)", "mean f", "paper f", "time ms", "paper ms"], rows),
        de and prose("baselines", "de"),
        de and table(["manipulator", "mode", "Np", "runs", "success", "evals to success", "time median ms",
                      "median final f"], de))
