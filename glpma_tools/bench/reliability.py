"""The Reliability section of BENCHMARKS.md, from the figures ``glpma-fk stress`` wrote as JSON
(``doc/bench/reliability.json`` after a full run): the stress test measures, the benchmark writes."""
from __future__ import annotations

import json
from pathlib import Path

from glpma_tools.stress.report import DEADLINE_HEAD, FLOOD_SECTIONS, check_result, deadline_rows, flood_rows, \
    restart_rows
from glpma_tools.tables import table
from .report import prose
from .timing import WARM_UP_QUIET

HEADING = "## Reliability"


def load(path) -> dict | None:
    """The stress figures in ``path``, or None when there is no such file."""
    path = Path(path)
    return json.loads(path.read_text()) if path.exists() else None


def reliability_section(res: dict | None, source=None) -> list[str]:
    """The section's lines; without figures, a note of where ``glpma-fk stress`` puts them."""
    from glpma_tools.stress import session as ses
    out = [HEADING, ""]
    if res is None:
        return out + [prose("reliability", "missing", path=source or "doc/bench/reliability.json"), ""]
    secs, m = res["sections"], res["machine"]
    out += [prose("reliability", command=res.get("command") or "glpma-fk stress", date=res["date"],
                  minutes=f"{res['wall_s'] / 60:.1f}", revision=res["revision"], cpu=m["cpu"], cores=m["cores"],
                  load_start=f"{res['load_average_start'][0]:.2f}", load_end=f"{res['load_average_end'][0]:.2f}",
                  checks="all passed" if res["passed"] else "some failed (see below)",
                  expectations="all met" if res.get("expectations_met", True) else "some missed (see below)"), ""]
    if res.get("quick"):
        out += [prose("reliability", "quick"), ""]
    if "node" in res:
        n = res["node"]
        out += [prose("reliability", "node", command=n["command"], manipulator=n["manipulator"],
                      budget=f"{n['time_budget_ms']:g}", depth=n["qos_depth"], warmup=f"{ses.WARMUP_S:g}"), ""]
    if any(k in secs for k in FLOOD_SECTIONS):
        out += [table(*flood_rows(secs)), ""]
        out += [f"- {k}: {check_result(secs[k])}" for k in FLOOD_SECTIONS if k in secs]
        out += ["", prose("reliability", "flood", rss_slack=f"{ses.RSS_SLACK_MB:g}",
                          lost_slack=f"{100 * ses.LOST_SLACK:g}"), ""]
    rows = restart_rows(secs)
    if rows:
        out += ["### Restarts and a jump", "", table(["scenario", "what happened", "checks"], rows), "",
                prose("reliability", "restarts"), ""]
    if "deadline" in secs:
        d = secs["deadline"]
        out += ["### Deadlines (in-process Estimator)", "",
                prose("reliability", "deadline", manipulator=d["manipulator"], quiet=WARM_UP_QUIET), "",
                table(DEADLINE_HEAD, deadline_rows(d["rows"])), ""]
    return out
