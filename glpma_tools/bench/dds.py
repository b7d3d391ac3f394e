"""DDS end to end: a node process on a private domain driven by the mock controller at the
rate a robot controller would use, with and without assembly-mode requests while streaming, and
the report's section of it; :func:`node_process`, how the bench runs a node (or a stand-in)."""
from __future__ import annotations

import contextlib
import tempfile
import time
from pathlib import Path

from glpma_ros.config import config_dir, load_manipulator, resolve_config
from glpma_tools import mock_controller
from glpma_tools.sim.domains import claim_domain
from glpma_tools.sim.node_process import NODE_MODULE, NodeProcess, node_environment
from glpma_tools.tables import fmt, table

#: seconds between two assembly-modes requests in the second run
MODES_PERIOD_S = 0.5
#: input rate and the node's parameters per manipulator (both at 1 kHz, a ros2_control update rate)
END_TO_END = {"planar_3rpr": (1000.0, "params_3rpr.yaml"), "hexapod_66": (1000.0, "params_hexapod.yaml")}
#: seconds of driving with --quick
QUICK_S = 2.0
#: figures read from the node's last /diagnostics report: result key -> the report's name
DIAGNOSTICS = {"dropped": "inputs dropped", "deadline_misses": "deadline misses",
               "node_solve_p99_ms": "solve time p99 (ms)"}


def params_file(kind: str) -> Path:
    """The shipped params file of manipulators ``kind``."""
    return config_dir() / END_TO_END[kind][1]


def shipped_args(kind: str, config) -> list[str]:
    """The ``--ros-args`` of the node with the shipped params file of manipulators ``kind``, on ``config``."""
    return ["--params-file", str(params_file(kind)), "-p", f"manipulator_config:={config}"]


@contextlib.contextmanager
def node_process(domain: int, ros_args=(), module: str = NODE_MODULE):
    """``python -m module --ros-args ros_args`` on ROS domain ``domain``, its logs in a temporary
    directory: started (ready), stopped when the block ends."""
    with tempfile.TemporaryDirectory(prefix="glpma_bench_") as logs:
        proc = NodeProcess(list(ros_args), node_environment(domain), Path(logs), module=module)
        proc.start()
        try:
            yield proc
        finally:
            proc.stop()


def bench_end_to_end(config: str, steps: int | None = None, quick: bool = False, duration_s: float = 60.0) -> dict:
    """Start a node process over DDS on a private domain, drive it for the config's manipulator
    and return flat figures: input published -> pose received latency, inputs, poses, drops, the
    node's solve time, its CPU share while streaming, and its RSS after warm-up and after the run."""
    model = load_manipulator(resolve_config(config))
    rate = END_TO_END[model.kind][0]
    duration = QUICK_S if quick else (steps / rate if steps else duration_s)
    with claim_domain() as claim, node_process(claim.domain_id, shipped_args(model.kind, config)) as node:
        rss_before = node.rss_kb()
        cpu_before, wall_before = node.cpu_s(), time.perf_counter()
        summary = mock_controller.run(str(config), rate, duration, domain_id=claim.domain_id)
        cpu_share = (node.cpu_s() - cpu_before) / (time.perf_counter() - wall_before)
        rss_after = node.rss_kb()
        with_modes = mock_controller.run(str(config), rate, duration, domain_id=claim.domain_id,
                                         modes_period_s=MODES_PERIOD_S)
    lat, diag = summary["latency_ms"], (summary.get("node_diagnostics") or {}).get("values", {})
    m = with_modes["assembly_modes"]
    return {"rate_hz": rate, "duration_s": duration, "inputs": summary["inputs_sent"],
            "poses": summary["poses_matched"], "pose_ratio": summary["pose_ratio"],
            "poses_wrong": summary["poses_wrong"], "p50_ms": lat["p50"], "p99_ms": lat["p99"], "max_ms": lat["max"],
            **{key: float(diag[name]) if name in diag else None for key, name in DIAGNOSTICS.items()},
            "node_cpu_percent_of_one_core": 100.0 * cpu_share,
            "position_error_max_m": summary["tracking_error"]["position_m"]["max"],
            "rss_after_warm_up_mb": rss_before / 1024, "rss_after_run_mb": rss_after / 1024,
            "rss_growth_mb": (rss_after - rss_before) / 1024,
            "assembly_modes": {"requests answered": m["answers"],
                               "modes per answer": ", ".join(map(str, m["modes_per_answer"])),
                               "answer time p50 (s)": m["answer_s"]["p50"],
                               "pose latency p99 while answering (ms)": m["pose_latency_during_requests_ms"]["p99"],
                               "pose latency p99 whole run (ms)": with_modes["latency_ms"]["p99"]}}


def dds_end_to_end(scenarios, steps, quick) -> dict:
    """:func:`bench_end_to_end` for each scenario; a scenario that cannot run says why."""
    results = {}
    for sc in scenarios:
        try:
            t0 = time.perf_counter()
            stats = bench_end_to_end(sc.path, steps=steps, quick=quick)
            results[sc.label] = {"status": "run", "stats": stats, "wall_s": time.perf_counter() - t0}
        except Exception as exc:  # noqa: BLE001 - reported in the table, never fatal
            results[sc.label] = {"status": "not run", "reason": f"{type(exc).__name__}: {exc}"}
    return {"status": "run", "function": "glpma_tools.bench.dds.bench_end_to_end", "results": results}


def _cells(stats: dict, prefix: str = ""):
    """(dotted name, value) of each figure of ``stats`` and of the dicts in it; numbers formatted."""
    for key, v in stats.items():
        if isinstance(v, dict):
            yield from _cells(v, f"{prefix}{key}.")
        else:
            yield [f"{prefix}{key}", fmt(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)]


def section(res, md_path=None) -> list[str]:
    """The section of BENCHMARKS.md from ``res["dds"]`` (nothing when it was not asked for)."""
    d = res.get("dds")
    if d is None:
        return []
    out = ["## DDS end to end (node + mock controller)", ""]
    if d.get("status") != "run":
        return out + [f"Skipped: {d.get('reason', 'not requested')}.", ""]
    out += [f"From `{d['function']}`.", ""]
    for label, r in d["results"].items():
        out += ([f"### {label}", "", table(["quantity", "value"], list(_cells(r["stats"]))), ""]
                if r["status"] == "run" else [f"- {label}: not run ({r['reason']})"])
    return out + [""]
