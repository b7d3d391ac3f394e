"""The papers' experiments and their sections of the report: 001 Tables 5 and 8, the peers' pure G3-PCX and why
the papers' figures for it do not reproduce, all assembly modes (002), the baselines (004 Table II and its protocol,
003's DE).  Each experiment returns plain data; its ``*_section`` renders it, with prose from ``templates/``."""
from __future__ import annotations

import gc
import math
import time
from collections import namedtuple

import numpy as np

from glpma_ros import solvers
from glpma_ros.modes.multistart import solve_all, wide_range
from glpma_tools.stats import Z_95, mean_ci
from glpma_tools.tables import MISSING, fmt, fmt_ci, ratio, table
from glpma_tools.timing import progress_bar as _bar

from .common import Run, summarize
from .markdown import SOLVER_LABEL, figure_link, md_blocks, pct, prose
from .papers import ALL_SOLUTIONS, FAITHFUL_3RPR, PUBLISHED, TABLE2, TABLE2_PROTOCOL, TABLE_NAME
from .peers import PEER_LABEL, PEER_SOLVERS, PYMOO_BOUND_FACTOR, available

#: the success thresholds of the peers' table: the papers' and looser ones
THRESHOLDS = (1e-20, 1e-16, 1e-12, 1e-8)
#: a published solution counts as found when one found is this close (mm)
FOUND_MM = 5.0
#: the columns of a row of runs (:func:`summary_cells`)
SUMMARY_HEAD = ["runs", "success", "evals to success", "mean evals (all runs)", "time median ms", "time mean ms",
                "median final f"]
#: the rows of the peers' table: our pure G3-PCX, then the peers'
LABELS = {"ours": "ours `g3pcx` (pure)", **PEER_LABEL}


class Config(namedtuple("Config", "solver population local_population polish")):
    """A row of the papers' tables: a solver, its population(s) (local: GLPMA's, else None), pure or refined."""

    @property
    def pop_label(self):
        return f"({self.population}, {self.local_population})" if self.local_population else str(self.population)

    @property
    def mode(self):
        return "default (polish)" if self.polish else "pure"


#: a row of the papers' tables (or of DE's): its :class:`Config` and its runs (:class:`.common.Run`)
TableRow = namedtuple("TableRow", "config runs")


def timed_solve(solver, model, legs, seed, **options) -> Run:
    """One search of ours, timed with the wall clock."""
    t0 = time.perf_counter()
    r = solvers.solve(solver, model, legs, rng=seed, **options)
    return Run(r.success, int(r.nfev), time.perf_counter() - t0, float(r.fun), list(r.history))


def table_row(sc, cfg: Config, n: int, progress) -> TableRow:
    """``n`` searches (seeds 0..n-1) of one configuration, after a short untimed one that compiles what it calls."""
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


#: a peer's runs; status "run", or why it did not: "not installed (...)", "skipped ..."
PeerRow = namedtuple("PeerRow", "name runs status")


def peer_g3pcx(sc, runs_by_peer: dict, progress) -> list[PeerRow]:
    """Each peer's runs (seeds 0..) on the paper's protocol, after one short run that imports and compiles."""
    kw = {k: solvers.PAPER_SETTINGS[sc.model.kind][k] for k in ("population", "init_range", "max_evals")}
    out = []
    for name, fn in PEER_SOLVERS.items():
        n = runs_by_peer.get(name, 0)
        why = available(name) or (None if n > 0 else runs_by_peer.get(f"{name}_why", "skipped: 0 runs requested"))
        if why:
            print(f"bench: {name} not run: {why}")
            out.append(PeerRow(name, [], why))
            continue
        fn(sc.model, sc.legs, seed=999, **{**kw, "max_evals": 200})
        out.append(PeerRow(name, [fn(sc.model, sc.legs, seed=seed, **kw)
                                  for seed in _bar(range(n), f"{sc.label} peer {name}", progress)], "run"))
    return out


def gap_diagnostics(sc, runs, progress) -> dict:
    """Our pure G3-PCX with larger evaluation caps, {cap: runs}: 2 x 10,000 + population (the cap if the paper had
    counted generations of two children) and 100,000 (how many evaluations a run needs to reach 1e-20 at all)."""
    pop, cap = (solvers.PAPER_SETTINGS[sc.model.kind][k] for k in ("population", "max_evals"))
    return {max_evals: [timed_solve("g3pcx", sc.model, sc.legs, seed, polish=False, max_evals=max_evals)
                        for seed in _bar(range(runs), f"{sc.label} G3-PCX cap {max_evals}", progress)]
            for max_evals in (2 * cap + pop, 10 * cap)}


#: ``solve_all`` repeated: runs per call, per repeat (seed, count, elapsed_s, evaluations), the initial range, per
#: published solution (index, nearest found, max coordinate deviation), the found ones matching no published one
AllSolutionsResult = namedtuple("AllSolutionsResult", "runs repeats init_range deviations unmatched_found")


def all_solutions(sc, runs, repeats, progress) -> AllSolutionsResult:
    """``repeats`` times ``solve_all`` (seeds 0..), and how close the first repeat's solutions come to the published
    ones (hexapod: largest coordinate difference in the canonical form; 3-RPR: the model's distance)."""
    solve_all(sc.model, sc.legs, runs=2, seed=999)       # warm-up
    reps, first = [], None
    for seed in _bar(range(repeats), f"{sc.label} solve_all", progress):
        gc.collect()
        res = solve_all(sc.model, sc.legs, runs=runs, seed=seed)
        reps.append((seed, len(res.solutions), res.elapsed_s, res.evaluations))
        first = [s.x for s in res.solutions] if first is None else first
    devs = []
    for i, pub in enumerate(sc.published):
        d = [float(np.max(np.abs(sc.model.canonical(x) - sc.model.canonical(pub)))) if sc.key == "hexapod"
             else sc.model.distance(x, pub) for x in first]
        devs.append((i, int(np.argmin(d)), min(d)) if d else (i, None, math.inf))
    matched = {j for _, j, d in devs if d < FOUND_MM}
    return AllSolutionsResult(runs, reps, wide_range(sc.model, sc.legs), devs, len(first) - len(matched))


#: 004 has no cap on the iterations: this one, far above every published mean (GA-SA, the costliest, about 18
#: generations x 36 annealed children x 10,000 proposals = 6.5 M evaluations), only stops runs that stall
TABLE2_MAX_EVALS = 20_000_000
#: evaluation cap of the untimed call that loads the compiled kernels
WARMUP_EVALS = 1_000
#: 004 Table II rows reproduced: (solver, solver parameters); SA at each published chain length
TABLE2_CONFIGS = (("sa", {"chain_length": 20}), ("sa", {"chain_length": 50}), ("sa", {"chain_length": 100}),
                  ("rcga", {}), ("gasa", {}))


def published_row(solver_name, chain_length=None) -> dict | None:
    """The Table II row that ``solver_name`` reproduces (SA: by Markov chain length), or None."""
    chain = solvers.sa.CHAIN_LENGTH if chain_length is None else int(chain_length)
    return next((row for row in TABLE2 if row["solver"] == solver_name
                 and (solver_name != "sa" or row["markov_chain"] == chain)), None)


#: one solver's runs on 004's protocol: its Table II row (or None), then per run the iterations, evaluations, final
#: fitness and seconds, and the fitness below which a run succeeded (the protocol's unless overridden)
Table2Result = namedtuple("Table2Result", "solver published iterations evaluations fitness seconds tolerance",
                          defaults=(TABLE2_PROTOCOL["tolerance"],))


def table2_protocol(model, solver_name, runs=TABLE2_PROTOCOL["runs"], seed0=0, **params) -> Table2Result:
    """``runs`` runs (seeds ``seed0, seed0 + 1, ...``) of ``solver_name`` on 004's protocol, unrefined, with ``model``'s
    example legs; ``params`` go to the solver (e.g. ``chain_length=50`` for SA, ``max_evals``, ``population``)."""
    legs, p = model.example_leg_lengths, TABLE2_PROTOCOL
    settings = {"population": solvers.sa.POPULATION if solver_name == "sa" else p["population"],
                "init_range": tuple(p["init_range"]), "tolerance": p["tolerance"], "max_evals": TABLE2_MAX_EVALS,
                "polish": False, **params}
    # load the compiled kernels before the clock matters (004 times the search alone)
    solvers.solve(solver_name, model, legs, rng=seed0, **{**settings, "max_evals": WARMUP_EVALS})
    done = [solvers.solve(solver_name, model, legs, rng=seed0 + k, **settings) for k in range(runs)]
    return Table2Result(solver_name, published_row(solver_name, params.get("chain_length")), [r.nit for r in done],
                        [r.nfev for r in done], [r.fun for r in done], [r.elapsed_s for r in done],
                        settings["tolerance"])


def baselines(scenarios, table2_runs, runs, hex_runs, progress) -> dict:
    """004's Table II protocol on the 3-RPR (``table2``: a :class:`Table2Result` per row); DE/rand/1/bin (003) on
    001's protocols (``de``: scenario key -> [TableRow] pure, default)."""
    table2 = []
    if "3rpr" in scenarios and table2_runs > 0:
        table2 = [table2_protocol(scenarios["3rpr"].model, name, runs=table2_runs, **params)
                  for name, params in _bar(TABLE2_CONFIGS, "004 Table II", progress)]
    de = {key: [table_row(sc, Config("de", solvers.DEFAULT_POPULATION["de"](sc.model), None, polish),
                          hex_runs if key == "hexapod" and not polish else runs, progress) for polish in (False, True)]
          for key, sc in scenarios.items()}
    return {"table2": table2, "de": de}


def summary_cells(runs, ours=None) -> list:
    """The cells of :data:`SUMMARY_HEAD` for ``runs``; with ``ours`` (a summary), time and evaluations against ours."""
    s = summarize(runs)
    cells = [s.runs, pct(s.success_pct), fmt_ci(s.evals_mean, s.evals_ci), fmt(s.evals_all_mean),
             fmt(s.time_median_ms), fmt(s.time_mean_ms), fmt(s.fun_median, 2)]
    return cells if ours is None else cells + [ratio(s.time_mean_ms, ours.time_mean_ms),
                                               ratio(s.evals_all_mean, ours.evals_all_mean)]


def paper_tables_section(res, md_path) -> list[str]:
    """001 Tables 5 and 8: our rows, pure and refined, beside the published figures."""
    out = md_blocks("## The papers' tables (001 Tables 5 and 8)")
    for key, rows in res["tables"].items():
        sc = res["scenarios"][key]
        kind, st = sc.model.kind, solvers.PAPER_SETTINGS[sc.model.kind]
        body = []
        for c, s, runs in ((r.config, summarize(r.runs), r.runs) for r in rows):
            p = PUBLISHED[kind][(c.solver, c.population, c.local_population)]
            body.append([SOLVER_LABEL[c.solver], c.pop_label, c.mode, *summary_cells(runs),
                         fmt(p["success"], unit=" %"), fmt_ci(p["evals"], p["evals_pm"]),
                         ratio(s.evals_mean, p["evals"]), fmt(p["time_s"] * 1e3),
                         ratio(s.time_mean_ms, p["time_s"] * 1e3)])
        glpma = " " + prose("tables", "glpma", intensity=st["ls_intensity"]) if "ls_intensity" in st else ""
        out += md_blocks(f"### {sc.label}: {TABLE_NAME[kind]}",
                         prose("tables", low=f"{st['init_range'][0]:g}", high=f"{st['init_range'][1]:g}",
                               n=sc.model.n_vars, cap=f"{st['max_evals']:,}") + glpma,
                         table(["method", "pop", "mode", *SUMMARY_HEAD, "paper success", "paper evals",
                                "evals ours/paper", "paper ms", "time ours/paper"], body))
    return out


def figures_section(res, md_path) -> list[str]:
    """The links to the success-vs-evaluations figures (none when they were not drawn)."""
    links = [figure_link(res, name, md_path) for name in res["figures"] if name.startswith("success_")]
    return md_blocks("## Success vs evaluations", prose("figures"), *links) if links else []


def g3pcx_runs(res, key) -> dict:
    """The pure G3-PCX runs on manipulator ``key`` by implementation ("ours" at the paper's population, if the
    tables ran, then each peer that ran)."""
    pop = solvers.PAPER_SETTINGS[res["scenarios"][key].model.kind]["population"]
    ours = [r.runs for r in res["tables"].get(key, []) if r.config == Config("g3pcx", pop, None, False) and r.runs]
    peers = {r.name: r.runs for r in res["peers"].get(key, []) if r.status == "run"}
    return ({"ours": ours[0]} if ours else {}) | peers


def spread_cells(runs) -> list:
    """The share of ``runs`` below each of :data:`THRESHOLDS` at their end; the median and 90th percentile of the
    evaluations of the successful ones (dashes without runs)."""
    if not runs:
        return [MISSING] * (len(THRESHOLDS) + 2)
    evals = [r.nfev for r in runs if r.success]
    q = np.percentile(evals, [50, 90]) if evals else [math.nan] * 2
    return [pct(100.0 * sum(r.fun < t for r in runs) / len(runs)) for t in THRESHOLDS] + [fmt(float(v)) for v in q]


def peers_section(res, md_path) -> list[str]:
    """Pure G3-PCX per manipulator: ours, the peers', the larger caps (3-RPR) and the paper's row."""
    out = md_blocks("## Pure G3-PCX against peer implementations",
                    prose("peers", bound_factor=f"{PYMOO_BOUND_FACTOR:g}"))
    head = ["implementation", *SUMMARY_HEAD, "time vs ours", "evals vs ours", *(f"f < {t:.0e}" for t in THRESHOLDS),
            "evals to success: median", "90th percentile"]
    for key, data in res["peers"].items():
        sc, series = res["scenarios"][key], g3pcx_runs(res, key)
        caps = {f"ours, cap {c:,}": runs for c, runs in (res.get("gap") or {}).items()} if key == "3rpr" else {}
        p = PUBLISHED[sc.model.kind][("g3pcx", solvers.PAPER_SETTINGS[sc.model.kind]["population"], None)]
        body = [[LABELS.get(name, name), *summary_cells(runs, summarize(series.get("ours", []))), *spread_cells(runs)]
                for name, runs in (series | caps).items()]
        body += [[PEER_LABEL[r.name], MISSING, r.status] + [MISSING] * (len(head) - 3)
                 for r in data if r.status != "run"]
        body.append([f"paper ({TABLE_NAME[sc.model.kind]})", 100, fmt(p["success"], unit=" %"),
                     fmt_ci(p["evals"], p["evals_pm"]), MISSING, MISSING, fmt(p["time_s"] * 1e3)]
                    + [MISSING] * (len(head) - 7))
        out += md_blocks(f"### {sc.label}", table(head, body),
                         caps and prose("peers", "caps", generation_cap=f"{min(res['gap']):,}",
                                        large_cap=f"{max(res['gap']):,}"))
    return out


def gap_section(res, md_path) -> list[str]:
    """Why the papers' pure G3-PCX rates do not reproduce, written from the measured rates."""
    if "3rpr" not in res["peers"]:
        return []
    pop, cap = (solvers.PAPER_SETTINGS["planar_3rpr"][k] for k in ("population", "max_evals"))
    measured = {name: summarize(runs).success_pct for name, runs in g3pcx_runs(res, "3rpr").items()}
    rates = ", ".join(f"{name} {pct(rate)}" for name, rate in measured.items()) or "none run"
    spread = max(measured.values(), default=0) - min(measured.values(), default=0)
    far = measured and max(measured.values()) < 50      # every implementation far below the paper's 90 %
    text = [prose("gap", "reading", cap=f"{cap:,}", rates=rates,
                  far=prose("gap", "far", spread=f"{spread:.0f}") if far else "")]
    caps = res.get("gap")
    if caps:
        s2, s10 = summarize(caps[min(caps)]), summarize(caps[max(caps)])
        text.append(prose("gap", "reading_caps", cap2=f"{min(caps):,}", success2=f"{s2.success_pct:.0f}",
                          cap10=f"{max(caps):,}", success10=f"{s10.success_pct:.0f}", evals=f"{s10.evals_mean:,.0f}",
                          ratio=ratio(s10.evals_mean, PUBLISHED["planar_3rpr"][("g3pcx", pop, None)]["evals"])))
    text.append(prose("gap", "unknowns"))
    sums = [summarize(r.runs) for r in res["tables"].get("3rpr", []) if r.config.polish]
    if sums:
        lo, hi = min(x.success_pct for x in sums), max(x.success_pct for x in sums)
        text.append(prose("gap", "reading_refined", rate=f"{lo:.0f} %" if lo == hi else f"{lo:.0f}–{hi:.0f} %",
                          fewest=f"{min(x.evals_mean for x in sums):,.0f}",
                          most=f"{max(x.evals_mean for x in sums):,.0f}"))
    return md_blocks("## Why the papers' pure G3-PCX figures do not reproduce",
                     prose("gap", population=pop, cap=f"{cap:,}", rates=rates,
                           reference=", ".join(f"{k} {v} %" for k, v in FAITHFUL_3RPR.items())), " ".join(text))


def all_solutions_section(res, md_path) -> list[str]:
    """002's all-solutions experiment: the modes found per repeat against the published ones."""
    body = []
    for key, r in res["all_solutions"].items():
        sc, times, devs = res["scenarios"][key], [t for _, _, t, _ in r.repeats], [d for _, _, d in r.deviations]
        low, high = ALL_SOLUTIONS["init_range"]
        paper = (f"{ALL_SOLUTIONS['count']} from {ALL_SOLUTIONS['runs']} runs, U[{low}, {high}]^9, "
                 f"< {ALL_SOLUTIONS['time_s']:g} s, {' – '.join(map(str, ALL_SOLUTIONS['accuracy_mm']))} mm from exact"
                 if key == "hexapod" else "2 (001 section 5.3; 004 Table IV)")
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
    """004 Table II (means over the successful runs, as the paper's) and DE on 001's protocols."""
    rows = []
    for r in res["baselines"]["table2"]:
        p = r.published or {}
        ok = [k for k, f in enumerate(r.fitness) if f < r.tolerance]     # Table II's means: over these
        rows.append([r.solver, fmt(p.get("markov_chain")), len(r.fitness), pct(100.0 * len(ok) / len(r.fitness)),
                     pct(100.0 * p["successes"] / p["runs"]) if p else MISSING,
                     fmt_ci(*mean_ci([r.iterations[k] for k in ok], Z_95)),
                     fmt_ci(p.get("iterations"), p.get("iterations_ci")),
                     fmt_ci(*mean_ci([r.evaluations[k] for k in ok], Z_95)), fmt(float(np.mean(r.fitness))),
                     fmt(p.get("fitness")), fmt(1e3 * float(np.mean(r.seconds))), fmt(1e3 * p["cpu_s"] if p else None)])
    de = [[res["scenarios"][key].label, row.config.mode, row.config.population, *summary_cells(row.runs)]
          for key, rows_de in res["baselines"]["de"].items() for row in rows_de]
    return md_blocks(
        "## Baselines: 004 Table II (SA, GA, GA-SA) and 003's DE",
        rows and prose("baselines", "table2"),
        rows and table(["solver", "chain", "runs", "success", "paper", "iterations (ours)", "iterations (paper)",
                        "evaluations (ours)", "mean f", "paper f", "time ms", "paper ms"], rows),
        de and prose("baselines", "de"),
        de and table(["manipulator", "mode", "Np", *SUMMARY_HEAD], de))
