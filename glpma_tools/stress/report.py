"""The stress test's figures as tables: the rows the terminal output here and the benchmark's
Reliability section (:func:`glpma_tools.bench.report.reliability_section`) share, and the JSON file that carries
the figures from the one to the other."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from glpma_tools.tables import MISSING, fmt, spread, table
from glpma_tools.timing import DEADLINE_MARGIN_MS

DEADLINE_HEAD = ["start", "budget ms", "solves", f"within budget + {DEADLINE_MARGIN_MS} ms", "p50 elapsed ms",
                 "p99 elapsed ms", "worst overrun ms", "preempted", "GC ran", "within, undisturbed",
                 "worst overrun, undisturbed", "statuses"]
FLOOD_SECTIONS = ("overload", "burst")


def check_result(section: dict) -> str:
    """``pass``, or ``FAIL:`` and the checks that failed; then the expectations (which depend on
    how busy the machine was) that were missed."""
    failed = [k for k, v in section.get("checks", {}).items() if not v]
    missed = [k for k, v in section.get("expectations", {}).items() if not v]
    return ("pass" if not failed else "FAIL: " + "; ".join(failed)) + (
        "; missed on this machine: " + "; ".join(missed) if missed else "")


def _starts(d: dict) -> str:
    return "{warm}/{widened}/{cold}".format(**d)


def flood_rows(secs: dict) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of the overload and burst figures, one column per phase."""
    keys = [k for k in FLOOD_SECTIONS if k in secs]
    head = ["quantity"] + [f"overload, {secs[k]['rate_hz']:g} Hz for {secs[k]['duration_s']:g} s"
                           if k == "overload" else f"burst of {secs[k]['inputs']:,}" for k in keys]
    quantities = [
        ("inputs written", lambda s: fmt(s["inputs"])),
        ("write rate achieved (Hz)", lambda s: fmt(s["send_rate_hz"])),
        ("received by the node", lambda s: fmt(s["received"])),
        ("lost in transport (DDS keep-last)", lambda s: fmt(s["lost_in_transport"])),
        ("solved (pose published)", lambda s: fmt(s["solved"])),
        ("dropped (replaced by a newer input)", lambda s: fmt(s["dropped"])),
        ("rejected", lambda s: fmt(s["rejected"])),
        ("deadline misses", lambda s: fmt(s["deadline_misses"])),
        ("starts warm / widened / cold", lambda s: _starts(s["starts"]).replace("/", " / ")),
        ("poses received", lambda s: fmt(s["poses"])),
        ("poses answering no input sent", lambda s: fmt(s.get("unpaired"))),
        ("latency write -> pose p50 / p99 / max (ms)", lambda s: spread(s["latency_ms"])),
        ("node latency arrival -> solved p50 / p99 / max (ms)", lambda s: spread(s["node_latency_ms"])),
        ("max leg residual of a pose (m)", lambda s: fmt(s["residual_max_m"])),
        ("poses on the trajectory's assembly mode", lambda s: fmt(s["on_trajectory_mode"])),
        ("node RSS before / after (MB)", lambda s: f"{s['rss_before_mb']:.1f} / {s['rss_after_mb']:.1f}"),
        ("RSS growth (MB)", lambda s: f"{s['rss_growth_mb']:+.2f}"),
    ]
    return head, [[label] + [fn(secs[k]) for k in keys] for label, fn in quantities]


def restart_rows(secs: dict) -> list[list[str]]:
    """[scenario, what happened, checks] for the controller restart, the jump and the node restart."""
    rows = []
    if "controller_restart" in secs:
        s = secs["controller_restart"]
        rows.append(["controller restart (new participant)",
                     f"{s['inputs_before']} inputs, participant deleted, new one matched in {s['discovery_s']:.2f} s; "
                     f"{s['poses_after']} poses for its {s['inputs_after']} inputs, first in "
                     f"{fmt(s['first_pose_latency_ms'])} ms; starts warm/widened/cold {_starts(s['starts_after'])}; "
                     f"rejected {s['after']['rejected']}; residual max {fmt(s['residual_max_m'])} m",
                     check_result(s)])
    if "large_jump" in secs:
        s = secs["large_jump"]
        rows.append([f"large jump (to known solution {s['to_solution']})",
                     f"before: {s['before']['on_trajectory_mode']} of {s['before']['poses']} poses on the mode "
                     f"of the trajectory followed; legs jump {s['jump_legs_max']:.3g} {s['unit']} "
                     f"({100 * s['jump_relative']:.0f} % of the scale, one step is "
                     f"~{s['step_legs_max']:.2g} {s['unit']}); first pose after {s['inputs_until_first_pose']} inputs "
                     f"({fmt(s['first_pose_latency_ms'])} ms); {s['poses']} poses for {s['inputs']} inputs, "
                     f"{s['rejected']} rejected, {s['dropped']} dropped; starts warm/widened/cold "
                     f"{_starts(s['starts'])}; {s['poses_on_requested_mode']} poses on the requested mode; "
                     f"residual max {fmt(s['residual_max_m'])} m; last start {s['last_start']}", check_result(s)])
    if "node_restart" in secs:
        s = secs["node_restart"]
        fr, fi = s["first_report"], s["final"]
        rows.append(["node restart (SIGINT mid-trajectory, started again)",
                     f"exit status {s['exit_status']}; back in {s['downtime_s']:.1f} s "
                     f"(start-up {s['startup_s']:.1f} s, first pose {fmt(s['first_pose_after_ready_s'])} s after "
                     "ready); first report with an answer: "
                     + (f"starts warm/widened/cold {_starts(fr['starts'])}" if fr["starts"] else "none")
                     + f"; at the end {fi['solved']} solved, starts warm/widened/cold {_starts(fi['starts'])}, "
                     f"last start {fi['last start']}; {s['poses_on_trajectory_mode']} of {s['poses_after']} poses "
                     f"on the trajectory's mode; residual max {fmt(s['residual_max_m'])} m", check_result(s)])
    return rows


def deadline_rows(rows) -> list[list[str]]:
    """Rows under :data:`DEADLINE_HEAD`."""
    def pct(v):
        return MISSING if v is None else f"{v:.2f} %"

    def ms(v):
        return MISSING if v is None else f"{v:+.3f}"
    return [[r["case"], f"{r['budget_ms']:g}", fmt(r["solves"]), pct(r["on_time_pct"]),
             f"{r['elapsed_p50_ms']:.3f}", f"{r['elapsed_p99_ms']:.3f}", ms(r["worst_overrun_ms"]),
             fmt(r["preempted"]), fmt(r.get("gc", 0)), pct(r.get("on_time_undisturbed_pct")),
             ms(r.get("worst_overrun_undisturbed_ms")),
             ", ".join(f"{k} {v}" for k, v in sorted(r["statuses"].items()))] for r in rows]


def format_table(res: dict) -> str:
    """The figures as plain-text tables, for the terminal."""
    secs = res["sections"]
    out = []
    if "node" in res:
        startup = ", ".join(f"{v:.1f}" for v in res["node"].get("startup_s", []))
        out.append(f"node: {res['node']['manipulator']}, budget {res['node']['time_budget_ms']:g} ms, "
                   f"qos depth {res['node']['qos_depth']}, start-up {startup} s")
    if any(k in secs for k in FLOOD_SECTIONS):
        out += ["", table(*flood_rows(secs), markdown=False)]
        out += [f"{k}: {check_result(secs[k])}" for k in FLOOD_SECTIONS if k in secs]
    r = restart_rows(secs)
    if r:
        out += [""] + [f"{name}: {result}\n  {text}" for name, text, result in r]
    if "deadline" in secs:
        out += ["", f"deadline ({secs['deadline']['manipulator']}, in-process Estimator, legs without a real "
                    "assembly):", table(DEADLINE_HEAD, deadline_rows(secs["deadline"]["rows"]), markdown=False)]
    met = res.get("expectations_met", True)
    out += ["", f"{'all checks passed' if res['passed'] else 'SOME CHECKS FAILED'}"
                f"{'' if met else ' (some expectations missed: the machine was busy)'} "
                f"({res['wall_s'] / 60:.1f} min; load average {res['load_average_start'][0]:.2f} at the start, "
                f"{res['load_average_end'][0]:.2f} at the end, {res['machine']['cores']} cores)"]
    return "\n".join(out)


def json_default(o):
    """JSON for NumPy scalars and paths."""
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return str(o)


def to_json(res: dict, indent: int | None = None) -> str:
    return json.dumps(res, default=json_default, indent=indent)


def write_json(path, res: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(to_json(res, indent=1) + "\n")
    return path


def read_json(path) -> dict | None:
    """The figures :func:`write_json` wrote to ``path``, or None when there is no such file."""
    path = Path(path)
    return json.loads(path.read_text()) if path.exists() else None
