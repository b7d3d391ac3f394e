"""The ``dds`` section: a node process with its shipped parameters on a private domain, driven at a robot
controller's rate as the outputs section's part 2 drives it (:func:`.transport.path_latency`), then with
assembly-mode requests while streaming."""
from __future__ import annotations

from glpma_tools import mock_controller
from glpma_tools.sim.domains import claim_domain
from glpma_tools.tables import fmt, table

from .markdown import md_blocks, prose
from .transport import END_TO_END, NODE, path_latency

#: seconds between two assembly-modes requests in the second run
MODES_PERIOD_S = 0.5
#: figures read from the node's /diagnostics report after the run: result key -> the report's name
DIAGNOSTICS = {"dropped": "inputs dropped", "deadline_misses": "deadline misses",
               "node_solve_p99_ms": "solve time p99 (ms)"}
#: seconds of driving with --quick
QUICK_S = 2.0


def bench_end_to_end(sc, seconds: float, domain: int) -> dict:
    """The node's run of the outputs section's part 2 (:func:`.transport.path_latency`: latency, poses, CPU
    share, RSS, position error, the node's drops and solve time from its /diagnostics report after the run),
    then the mock controller's run with assembly-mode requests against the same process."""
    def with_modes(domain_id: int) -> dict:
        return mock_controller.run(str(sc.path), END_TO_END[sc.model.kind][0], seconds, domain_id=domain_id,
                                   modes_period_s=MODES_PERIOD_S)
    row = path_latency(sc, NODE, seconds, domain, then=with_modes)
    diag, (rss0, rss1), m = row["diagnostics"] or {}, row["rss_mb"], row["then"]["assembly_modes"]
    return {**{k: row[k] for k in ("rate_hz", "seconds", "sent", "paired", "wrong", "total_ms", "to_node_ms",
                                   "in_node_ms", "cpu_percent", "position_error_max_m")},
            "pose_ratio": row["paired"] / max(row["sent"], 1),
            **{key: float(diag[name]) if name in diag else None for key, name in DIAGNOSTICS.items()},
            "rss_after_warm_up_mb": rss0, "rss_after_run_mb": rss1, "rss_growth_mb": rss1 - rss0,
            "assembly_modes": {"requests answered": m["answers"],
                               "modes per answer": ", ".join(map(str, m["modes_per_answer"])),
                               "answer time p50 (s)": m["answer_s"]["p50"],
                               "pose latency p99 while answering (ms)": m["pose_latency_during_requests_ms"]["p99"],
                               "pose latency p99 whole run (ms)": row["then"]["latency_ms"]["p99"]}}


def dds_end_to_end(scenarios, steps, quick) -> dict:
    """``res["dds"]``: per scenario label, :func:`bench_end_to_end`'s figures (``steps`` inputs, or
    :data:`QUICK_S` with ``quick``) on a domain of its own, or why it could not run."""
    results = {}
    for sc in scenarios:
        seconds = QUICK_S if quick else steps / END_TO_END[sc.model.kind][0]
        try:
            with claim_domain() as claim:
                results[sc.label] = bench_end_to_end(sc, seconds, claim.domain_id)
        except Exception as exc:  # noqa: BLE001 - reported in the section, never fatal
            results[sc.label] = f"{type(exc).__name__}: {exc}"
    return results


def _cells(stats: dict, prefix: str = ""):
    """(dotted name, value) of each figure of ``stats`` and of the dicts in it; numbers formatted."""
    for key, v in stats.items():
        if isinstance(v, dict):
            yield from _cells(v, f"{prefix}{key}.")
        else:
            yield [f"{prefix}{key}", fmt(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)]


def section(res, md_path=None) -> list[str]:
    """The section of BENCHMARKS.md from ``res["dds"]`` (nothing when it did not run)."""
    if not res.get("dds"):
        return []
    return md_blocks("## DDS end to end (node + mock controller)", prose("dds"), *(
        f"### {label}\n\n" + table(["quantity", "value"], list(_cells(r))) if isinstance(r, dict)
        else f"- {label}: not run ({r})" for label, r in res["dds"].items()))
