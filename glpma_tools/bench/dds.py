"""The ``dds`` section: a node process on a private domain driven by the mock controller at a robot
controller's rate, with and without assembly-mode requests while streaming; and how the transport
sections run a node (or a stand-in) with its shipped parameters (:func:`node_process`, :func:`match`)."""
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
#: seconds to wait for a process's endpoints to match ours, and to let the discovery settle then
CONNECT_S = 60.0
SETTLE_S = 0.5


def params_file(kind: str) -> Path:
    """The shipped params file of manipulators ``kind``."""
    return config_dir() / END_TO_END[kind][1]


def params_of(kind: str) -> dict:
    """The parameters of the shipped params file of manipulators ``kind`` (the node reads them so)."""
    from glpma_ros.node.ros_args import load_params_file
    return load_params_file(str(params_file(kind)))


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


def match(endpoints_, what: str) -> None:
    """Wait until ``endpoints_`` matched ``what``'s, then let the discovery settle."""
    from glpma_ros.node.dds import endpoints
    if not endpoints.wait_for_match(endpoints_, CONNECT_S):
        raise TimeoutError(f"{what} did not match within {CONNECT_S:g} s")
    time.sleep(SETTLE_S)


def bench_end_to_end(config: str, steps: int | None = None, quick: bool = False, duration_s: float = 60.0) -> dict:
    """Drive a node process for the config's manipulator; flat figures: input published -> pose
    received latency, inputs, poses, drops, the node's solve time, its CPU share while streaming,
    its RSS after warm-up and after the run, and a second run with assembly-mode requests."""
    model = load_manipulator(resolve_config(config))
    rate = END_TO_END[model.kind][0]
    duration = QUICK_S if quick else (steps / rate if steps else duration_s)
    with claim_domain() as claim, node_process(claim.domain_id, shipped_args(model.kind, config)) as node:
        rss_before, cpu_before, wall_before = node.rss_kb(), node.cpu_s(), time.perf_counter()
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
    """``res["dds"]``: per scenario label, :func:`bench_end_to_end`'s figures, or why it could not run."""
    results = {}
    for sc in scenarios:
        try:
            results[sc.label] = bench_end_to_end(sc.path, steps=steps, quick=quick)
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
    from .report import md_blocks, prose
    if not res.get("dds"):
        return []
    return md_blocks("## DDS end to end (node + mock controller)", prose("dds"), *(
        f"### {label}\n\n" + table(["quantity", "value"], list(_cells(r))) if isinstance(r, dict)
        else f"- {label}: not run ({r})" for label, r in res["dds"].items()))
