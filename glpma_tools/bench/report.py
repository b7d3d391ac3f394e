"""BENCHMARKS.md from the measurements: the header, the summary and each section from one
experiment's data, ours beside the papers' and the peers' figures, in the report's order
(:func:`render`).  The prose lives in ``templates/*.md`` (see :func:`~.markdown.prose`).  The root of the
bench's modules: only this module imports the sections."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from glpma_tools.stress import report as stress
from glpma_tools.stress import session as ses
from glpma_tools.tables import table
from glpma_tools.timing import DEADLINE_MARGIN_MS, WARM_UP_QUIET

from . import dds, experiments, modes, offline, outputs, timing, waits
from .common import summarize
from .markdown import SOLVER_LABEL, md_blocks, prose
from .papers import TABLE_NAME
from .scenarios import LATENCY_TARGET_MS
from .timing import all_overruns, calm_distribution, share_on_time, worst_overrun

#: sections measured by scripts of their own (``tools/bench_gough.py --markdown doc/bench/gough.md``,
#: ``tools/bench_families.py --markdown doc/bench/families.md``), kept
#: in BENCHMARKS.md when the benchmark rewrites it
APART = ("doc/bench/gough.md", "doc/bench/families.md")


def header(res) -> list[str]:
    """The title, the command, the machine and the conditions of the measurements."""
    canonical, invoked = res["command"]
    loads = "; ".join(f"{name} {load}" for name, load in res.get("load", []))
    return md_blocks(prose("header", **res["machine"], date=res["date"], minutes=f"{res['wall_s'] / 60:.1f}",
                           command=canonical, invoked=f" (invoked as `{invoked}`)" if invoked else "",
                           revision=res["revision"], loads=loads),
                     res.get("quick") and prose("header", "quick"))


def summary_section(res, md_path) -> list[str]:
    """The headline figures of the sections that ran: the papers' success rates, warm tracking, all solutions,
    deadlines."""
    label = {key: sc.label for key, sc in res["scenarios"].items()}
    lines = [f"- {label[key]} ({TABLE_NAME[res['scenarios'][key].model.kind]} protocol): " + "; ".join(
        f"{SOLVER_LABEL[c.solver]} {c.pop_label} {c.mode}: {summarize(r.runs).success_pct:.0f} %"
        for r in rows for c in [r.config]) + "." for key, rows in res["tables"].items()]
    for key, t in res["tracking"].items():
        st, calm = t.stats, calm_distribution(t.latency_s, t.preempted)
        lines.append(f"- {label[key]} warm tracking: p50 {st['p50']:.3f} ms, p99 {st['p99']:.3f} ms "
                     f"({calm['p99']:.3f} ms over the {int(np.sum(~t.preempted))} steps not preempted; "
                     f"target ≤ {LATENCY_TARGET_MS[key]:g}), max error {np.max(t.errors):.1e} mm.")
    lines += [f"- {label[key]} all solutions: {r.repeats[0][1]} distinct in {r.repeats[0][2]:.2f} s ({r.runs} runs)."
              for key, r in res["all_solutions"].items()]
    if res["deadline"]:
        total, calm = all_overruns(res["deadline"])
        calm_part = (f"; without the disturbed solves (preempted, off their core, collected) "
                     f"{share_on_time(calm):.2f} %, worst {worst_overrun(calm)} ms")
        lines.append(f"- Deadlines: {share_on_time(total):.2f} % within budget + {DEADLINE_MARGIN_MS} ms, worst "
                     f"overrun {worst_overrun(total)} ms{calm_part if calm.size else ''}.")
    return ["## Summary", "", *lines, ""]


def reliability_section(res: dict | None, source=None) -> list[str]:
    """The Reliability section from the figures ``glpma-fk stress`` wrote as JSON (``doc/bench/reliability.json``
    after a full run: the stress test measures, the benchmark writes; :func:`glpma_tools.stress.report.read_json`);
    without them, a note of where ``glpma-fk stress`` puts them."""
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
    paths = [Path(os.path.dirname(os.path.abspath(md_path)), name) for name in APART]
    return md_blocks(*(p.read_text(encoding="utf-8").rstrip() for p in paths if p.is_file()))


def render(res, md_path, reliability=None, reliability_source=None) -> str:
    """The whole report; ``reliability``: the figures ``glpma-fk stress`` wrote to the JSON file
    ``reliability_source`` (None: there are none yet)."""
    # the sections in the report's order, each with the measurements it renders (None: it looks for them itself)
    sections = ((None, summary_section), ("tables", experiments.paper_tables_section),
                (None, experiments.figures_section), ("peers", experiments.peers_section),
                (None, experiments.gap_section), ("all_solutions", experiments.all_solutions_section),
                ("modes_comparison", modes.section), ("tracking", timing.tracking_section),
                ("deadline", timing.deadline_section),
                ("baselines", experiments.baselines_section), (None, dds.section), (None, outputs.section),
                ("waits", waits.section), ("offline", offline.offline_section))
    parts = header(res)
    for key, section in sections:
        parts += section(res, md_path) if key is None or res.get(key) else []
    parts += reliability_section(reliability, reliability_source) + md_blocks("## Design measurements", prose("design"))
    return "\n".join(parts + measured_apart(md_path)).rstrip() + "\n"
