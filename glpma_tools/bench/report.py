"""BENCHMARKS.md from the measurements: the header, the summary and each section from one
experiment's data, ours beside the papers' and the peers' figures, in the report's order
(:func:`render`).  The prose lives in ``templates/*.md`` (see :func:`prose`)."""
from __future__ import annotations

import functools
import json
import math
import os
import re
from datetime import datetime, timezone
from importlib.resources import files
from pathlib import Path
from string import Template

import numpy as np

from glpma_ros import solvers
from glpma_tools.sim import trajectories as traj
from glpma_tools.stats import distribution
from glpma_tools.tables import MISSING, fmt, fmt_ci, ratio, table
from glpma_tools.timing import DEADLINE_MARGIN_MS, STOP_AFTER, STOP_OVERRUN_FACTOR

from .common import summarize
from .papers import ALL_SOLUTIONS, FAITHFUL_3RPR, PUBLISHED, TABLE_NAME, Published
from .peers import PEER_LABEL, PYMOO_BOUND_FACTOR
from .protocols import PublishedRow
from .scenarios import LATENCY_TARGET_MS

SOLVER_LABEL = {"rcga": "RCGA", "g3pcx": "G3-PCX", "glpma": "GLPMA", "de": "DE"}
_BLOCK = re.compile(r"^<!-- (\w+) -->$", re.M)
#: looser success thresholds of the gap section
GAP_THRESHOLDS = (1e-20, 1e-16, 1e-12, 1e-8)
#: a published solution counts as found when one found is this close (mm)
FOUND_MM = 5.0
#: sections measured by scripts of their own (``tools/bench_gough.py --markdown doc/bench/gough.md``), kept
#: in BENCHMARKS.md when the benchmark rewrites it
APART = ("doc/bench/gough.md",)
#: the papers' figures of a row they do not print: every cell a dash
UNPUBLISHED = Published(*[math.nan] * 5)


@functools.lru_cache(maxsize=None)
def _blocks(section: str) -> dict:
    parts = _BLOCK.split((files(__package__) / "templates" / f"{section}.md").read_text(encoding="utf-8"))
    return {name: text.strip() for name, text in zip(parts[1::2], parts[2::2])}


def prose(section: str, block: str = "intro", **values) -> str:
    """The paragraph ``block`` of ``templates/<section>.md`` with its ``$name`` fields filled in."""
    return Template(_blocks(section)[block]).substitute(values)


def md_blocks(*blocks) -> list[str]:
    """Lines of Markdown: each block (a heading, paragraph or table; empty or None: left out) and a blank line."""
    return [line for block in blocks if block for line in (block, "")]


def _figure(res, name, md_path, alt=None) -> str | None:
    """The image link of the figure ``name`` (alt text: its file name), None when it was not drawn."""
    path = res["figures"].get(name)
    link = path and os.path.relpath(path, os.path.dirname(os.path.abspath(md_path)))    # from the report's directory
    return link and f"![{alt or os.path.basename(path)}]({link})"


def timestamp() -> str:
    return datetime.now(timezone.utc).astimezone().strftime("%Y-%m-%d %H:%M %Z")


def pct(v, digits: int = 3) -> str:
    return fmt(v, digits) + " %"


def _calm(latency_s, preempted) -> dict:
    """The distribution (ms) of the calls not preempted (all of them when every one was)."""
    return distribution(latency_s[~preempted] if np.any(~preempted) else latency_s, 1e3)


def _overruns(rows) -> tuple[np.ndarray, np.ndarray]:
    """The overruns (ms) of every deadline solve, and of those not preempted."""
    return np.concatenate([r.overrun_ms for r in rows]), np.concatenate([r.overrun_ms[~r.preempted] for r in rows])


def _on_time(over) -> float:
    """The share (%) of the overruns ``over`` (ms) within the margin."""
    return 100.0 * float(np.mean(over <= DEADLINE_MARGIN_MS))


def _worst(over) -> str:
    return f"{float(np.max(over)):+.3f}"


def header(res) -> list[str]:
    canonical, invoked = res["command"]
    loads = "; ".join(f"{name} {load}" for name, load in res.get("load", []))
    return md_blocks(prose("header", **res["machine"], date=res["date"], minutes=f"{res['wall_s'] / 60:.1f}",
                           command=canonical, invoked=f" (invoked as `{invoked}`)" if invoked else "",
                           revision=res["revision"], loads=loads),
                     res.get("quick") and prose("header", "quick"))


def summary_section(res, md_path) -> list[str]:
    scenarios = res["scenarios"]
    lines = [f"- {scenarios[key].label} ({TABLE_NAME[scenarios[key].model.kind]} protocol): " + "; ".join(
        f"{SOLVER_LABEL[r.config.solver]} {r.config.pop_label} {r.config.mode}: {summarize(r.runs).success_pct:.0f} %"
        for r in rows) + "." for key, rows in res["tables"].items()]
    for key, t in res["tracking"].items():
        st, calm = t.stats, _calm(t.latency_s, t.preempted)
        lines.append(f"- {scenarios[key].label} warm tracking: p50 {st['p50']:.3f} ms, p99 {st['p99']:.3f} ms "
                     f"({calm['p99']:.3f} ms over the {int(np.sum(~t.preempted))} steps not preempted; "
                     f"target ≤ {LATENCY_TARGET_MS[key]:g}), max error {np.max(t.errors):.1e} mm.")
    lines += [f"- {scenarios[key].label} all solutions: {r.repeats[0][1]} distinct in {r.repeats[0][2]:.2f} s "
              f"({r.runs} runs)." for key, r in res["all_solutions"].items()]
    if res["deadline"]:
        total, calm = _overruns(res["deadline"])
        lines.append(f"- Deadlines: {_on_time(total):.2f} % within budget + {DEADLINE_MARGIN_MS} ms, worst overrun "
                     f"{_worst(total)} ms" + (f"; without the preempted solves {_on_time(calm):.2f} %, worst "
                                              f"{_worst(calm)} ms." if calm.size else "."))
    return ["## Summary", "", *lines, ""]


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
    links = [_figure(res, name, md_path) for name in res["figures"] if name.startswith("success_")]
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


def tracking_section(res, md_path) -> list[str]:
    scales = {sc.model.kind: (sc.model.scale, sc.model.unit) for sc in res["scenarios"].values()}

    def size(kind, share):
        """A size of the loop: in the config's unit when its scenario ran, else as a share of the scale."""
        return (f"{share * scales[kind][0]:.3g} {scales[kind][1]}" if kind in scales
                else f"{100 * share:g} % of the scale")
    body = []
    for key, t in res["tracking"].items():
        st, calm, target = t.stats, _calm(t.latency_s, t.preempted), LATENCY_TARGET_MS[key]
        verdict = "met" if st["p99"] <= target else (
            "**missed** (met without preemption)" if calm["p99"] <= target else "**missed**")
        body.append([res["scenarios"][key].label, t.steps, f"{t.budget_ms:g}", fmt(st["p50"]), fmt(st["p99"]),
                     fmt(st["max"]), int(np.sum(t.preempted)), fmt(calm["p99"]), fmt(calm["max"]), f"≤ {target:g}",
                     verdict, f"{np.max(t.errors):.2e}", f"{np.max(t.leg_residual):.2e}",
                     ", ".join(f"{k} {v}" for k, v in sorted(t.statuses.items())),
                     ", ".join(f"{k} {v}" for k, v in sorted(t.stages.items())), fmt(float(np.mean(t.evaluations)))])
    return md_blocks("## Warm tracking latency (solve only)",
                     prose("tracking", planar_radius=size("planar_3rpr", traj.PLANAR_RADIUS),
                           planar_swing=f"{math.degrees(traj.PLANAR_SWING_RAD):.2g}",
                           spatial_radius=size("hexapod_66", traj.SPATIAL_RADIUS),
                           spatial_rise=size("hexapod_66", traj.SPATIAL_RISE),
                           spatial_twist=f"{math.degrees(traj.SPATIAL_TWIST_RAD):.2g}"),
                     table(["manipulator", "steps", "budget ms", "p50 ms", "p99 ms", "max ms", "preempted steps",
                            "p99 ms not preempted", "max ms not preempted", "target p99", "",
                            "max error mm", "max leg residual mm", "status", "stage", "mean evals"], body),
                     *(_figure(res, f"latency_{key}", md_path, f"{res['scenarios'][key].label} latency")
                       for key in res["tracking"]))


def _scipy_row(label, ours, latency_s, preempted, residual, evals) -> list:
    """A row of the scipy table: the latency (ms, and of the calls not preempted unless ``preempted`` is None),
    the leg residuals and evaluations of ``label``, its latency against ``ours``."""
    s = distribution(latency_s, 1e3)
    calm = s if preempted is None else distribution(latency_s[~preempted], 1e3)
    return [label, fmt(s["p50"]), fmt(s["p99"]), fmt(calm["p99"]), fmt(s["mean"]), f"{np.median(residual):.1e}",
            f"{np.max(residual):.1e}", fmt(float(np.mean(evals))), ratio(ours["p50"], s["p50"]),
            ratio(ours["p99"], s["p99"])]


def scipy_section(res, md_path) -> list[str]:
    out = md_blocks("## Warm solve against `scipy.optimize.least_squares`", prose("scipy"))
    for key, rows in res["scipy"].items():
        t = res["tracking"][key]
        ours = distribution(t.latency_s, 1e3)
        labels = ["plain NumPy Newton" if r.method == "newton" else f"scipy `{r.method}`, {r.jac}" for r in rows]
        body = [_scipy_row("ours: Estimator (warm: compiled LM)", ours, t.latency_s, t.preempted, t.leg_residual,
                           t.evaluations)]
        body += [_scipy_row(label, ours, r.latency_s, r.preempted, r.leg_residual, r.nfev) if r.status == "run"
                 else [label] + [MISSING] * 7 + [r.status, ""] for label, r in zip(labels, rows)]
        out += md_blocks(f"### {res['scenarios'][key].label} ({t.steps} steps)",
                         table(["solver", "p50 ms", "p99 ms", "p99 ms not preempted", "mean ms",
                                "median max leg residual", "worst max leg residual", "mean evals", "ours/row (p50)",
                                "ours/row (p99)"], body))
    return out + md_blocks(prose("scipy", "note"))


def deadline_section(res, md_path) -> list[str]:
    rows = res["deadline"]

    def on_time(over):
        return fmt(_on_time(over), 4) + " %" if over.size else MISSING
    body = [[r.case, r.solver, f"{r.budget_ms:g}", f"{len(over)} (stopped)" if r.stopped_early else len(over),
             on_time(over), fmt(distribution(r.elapsed_s, 1e3)["p99"]), _worst(over), int(np.sum(r.preempted)),
             on_time(calm), _worst(calm) if calm.size else MISSING]
            for r in rows for over, calm in [(r.overrun_ms, r.overrun_ms[~r.preempted])]]
    total, calm = _overruns(rows)
    late = sorted({r.solver for r in rows if np.any(r.overrun_ms[~r.preempted] > DEADLINE_MARGIN_MS)})
    return md_blocks(
        "## Deadline honouring",
        prose("deadline", margin=DEADLINE_MARGIN_MS, stop_after=STOP_AFTER, stop_factor=f"{STOP_OVERRUN_FACTOR:g}"),
        calm.size and f"Overall: {on_time(total)} of {total.size} solves on time, worst overrun {_worst(total)} ms; "
        f"{total.size - calm.size} solves were preempted by other processes, and without them {on_time(calm)} are "
        f"on time, worst overrun {_worst(calm)} ms.",
        late and "Late without preemption (the solver itself overran): " + ", ".join(f"`{x}`" for x in late) + ".",
        table(["case", "solver", "budget ms", "solves", "on time", "p99 elapsed ms", "worst overrun ms", "preempted",
               "on time, not preempted", "worst overrun, not preempted"], body),
        _figure(res, "deadline", md_path, "deadline overruns"))


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


def offline_section(res, md_path) -> list[str]:
    """``glpma-fk bag``: throughput, where the time goes, a fleet on each engine; ``glpma-fk map``: the
    default 3-RPR map and a 6-6 slice on each engine, the counting methods compared (:mod:`.offline`)."""
    o = res["offline"]
    bag, fleet, methods = o["bag"], o["fleet"], o["methods"]
    out = md_blocks(
        "## Offline: bag processing and workspace maps", prose("offline"),
        table(["glpma-fk bag (3-RPR, MCAP)", "value"],
              [[k, fmt(v) if isinstance(v, float) else str(v)] for k, v in bag["run"].items()]),
        table(["where the CPU time of one input goes", "µs"],
              [[k, fmt(v)] for k, v in bag["CPU µs per input"].items()]
              + [["the whole run (the parts above plus the loop itself)", fmt(bag["whole run CPU µs per input"])]]),
        table([f"glpma-fk bag --out-dir ({fleet['bags']} bags of {fleet['inputs per bag']:,} inputs)", "wall s",
               "converged"], [[r["engine"], fmt(r["wall s"]), fmt(r["converged"])] for r in fleet["runs"]]),
        f"Same statuses on every engine: {'yes' if fleet['same statuses on every engine'] else 'NO'}.")
    for mp in filter(None, (o["map"], o.get("hexapod map"))):
        first = mp["runs"][0]
        sing = first.get("on_singularity") or {}
        singular = (f"; on a singularity (a double mode): {sum(sing.values()):,} ("
                    + ", ".join(f"{k} distinct: {v:,}" for k, v in sing.items()) + ")") if sing else ""
        out += md_blocks(
            table([f"glpma-fk map {mp['config']} ({mp['grid']}{', ' + mp['at'] if mp['at'] else ''})", "wall s",
                   "points/s", "speed-up"],
                  [[r["engine"], fmt(r["wall s"]), fmt(r["points/s"]), fmt(r["speed-up"])] for r in mp["runs"]]),
            "Mode counts (points per count, first engine): "
            + ", ".join(f"{k}: {v:,}" for k, v in first["modes"].items())
            + f"{singular}; identical on every engine: {'yes' if mp['identical counts'] else 'NO'}.")
    out += md_blocks(table([f"counting methods, seed 3-RPR map {methods['grid']}", "value"],
                           [[k, fmt(v) if isinstance(v, (int, float)) else str(v)]
                            for k, v in methods.items() if k != "grid"]))
    return out + (calibration_section(o["calibration"]) if o.get("calibration") else [])


def calibration_section(rows) -> list[str]:
    """``glpma-fk calibrate``: time for 200 and 10,000 measurements, accuracy before and after."""
    from .offline import CALIBRATION_FK_POSES, CALIBRATION_REPEATS
    body = [[r["manipulator"], f"{r['measurements']:,} ({r['fitted']:,} fitted)", fmt(r["wall s median"]),
             fmt(r["cpu s median"]), fmt(r["identify s median"] * 1e3), r["iterations"],
             f"{fmt(r['held-out RMS before mm'])} -> {fmt(r['held-out RMS after mm'])}",
             " / ".join(fmt(v) for v in r["FK error nominal mm (median / max)"]),
             " / ".join(fmt(v) for v in r["FK error calibrated mm (median / max)"]), r["weak directions"]]
            for r in rows]
    return md_blocks("### Calibration", prose("offline", "calibration", repeats=CALIBRATION_REPEATS,
                                              fk_poses=CALIBRATION_FK_POSES),
                     table(["config", "measurements", "command wall s", "command CPU s", "identification ms",
                            "Gauss-Newton iterations", "held-out leg RMS mm, before -> after",
                            "FK error nominal mm (median / max)", "FK error calibrated mm (median / max)",
                            "weak directions"], body))


def load_reliability(path) -> dict | None:
    """The stress figures in ``path``, or None when there is no such file."""
    path = Path(path)
    return json.loads(path.read_text()) if path.exists() else None


def reliability_section(res: dict | None, source=None) -> list[str]:
    """The Reliability section from the figures ``glpma-fk stress`` wrote as JSON (``doc/bench/reliability.json``
    after a full run: the stress test measures, the benchmark writes); without them, a note of where
    ``glpma-fk stress`` puts them."""
    from glpma_tools.stress import report as stress
    from glpma_tools.stress import session as ses
    from glpma_tools.timing import WARM_UP_QUIET
    if res is None:
        return md_blocks("## Reliability", prose("reliability", "missing", path=source or "doc/bench/reliability.json"))
    secs, node, d = res["sections"], res.get("node"), res["sections"].get("deadline")
    floods = [k for k in stress.FLOOD_SECTIONS if k in secs]
    restarts = stress.restart_rows(secs)
    return md_blocks(
        "## Reliability",
        prose("reliability", **res["machine"], command=res.get("command") or "glpma-fk stress", date=res["date"],
              minutes=f"{res['wall_s'] / 60:.1f}", revision=res["revision"],
              load_start=f"{res['load_average_start'][0]:.2f}", load_end=f"{res['load_average_end'][0]:.2f}",
              checks="all passed" if res["passed"] else "some failed (see below)",
              expectations="all met" if res.get("expectations_met", True) else "some missed (see below)"),
        res.get("quick") and prose("reliability", "quick"),
        node and prose("reliability", "node", command=node["command"], manipulator=node["manipulator"],
                       budget=f"{node['time_budget_ms']:g}", depth=node["qos_depth"], warmup=f"{ses.WARMUP_S:g}"),
        floods and table(*stress.flood_rows(secs)),
        "\n".join(f"- {k}: {stress.check_result(secs[k])}" for k in floods),
        floods and prose("reliability", "flood", rss_slack=f"{ses.RSS_SLACK_MB:g}",
                         lost_slack=f"{100 * ses.LOST_SLACK:g}"),
        restarts and "### Restarts and a jump",
        restarts and table(["scenario", "what happened", "checks"], restarts),
        restarts and prose("reliability", "restarts"),
        d and "### Deadlines (in-process Estimator)",
        d and prose("reliability", "deadline", manipulator=d["manipulator"], quiet=WARM_UP_QUIET),
        d and table(stress.DEADLINE_HEAD, stress.deadline_rows(d["rows"])))


def measured_apart(md_path) -> list[str]:
    """The Markdown of :data:`APART` that exists beside ``md_path`` (the repository root's BENCHMARKS.md)."""
    if md_path is None:
        return []
    paths = [Path(os.path.dirname(os.path.abspath(md_path)), name) for name in APART]
    return md_blocks(*(p.read_text(encoding="utf-8").rstrip() for p in paths if p.is_file()))


def render(res, md_path, reliability=None, reliability_source=None) -> str:
    """The whole report; ``reliability``: the figures ``glpma-fk stress`` wrote to the JSON file
    ``reliability_source`` (None: there are none yet)."""
    from . import dds, modes, outputs, waits
    # the sections in the report's order, each with the measurements it renders (None: it looks for them itself)
    sections = ((None, summary_section), ("tables", paper_tables_section), (None, figures_section),
                ("peers", peers_section), (None, gap_section), ("all_solutions", all_solutions_section),
                ("modes_comparison", modes.section), ("tracking", tracking_section), ("scipy", scipy_section),
                ("deadline", deadline_section), ("baselines", baselines_section), (None, dds.section),
                (None, outputs.section), ("waits", waits.section), ("offline", offline_section))
    parts = header(res)
    for key, section in sections:
        parts += section(res, md_path) if key is None or res.get(key) else []
    parts += reliability_section(reliability, reliability_source) + md_blocks("## Design measurements", prose("design"))
    return "\n".join(parts + measured_apart(md_path)).rstrip() + "\n"
