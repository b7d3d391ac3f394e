"""The ``dds`` section: a node process with its shipped parameters on a private domain, driven at a robot
controller's rate as the outputs section's part 2 drives it, then with assembly-mode requests while streaming;
and how the transport sections run a node or a stand-in (:func:`node_process`, :func:`match`, the params)."""
from __future__ import annotations

import contextlib
import tempfile
import time
from pathlib import Path

from glpma_ros.config import config_dir
from glpma_tools import mock_controller
from glpma_tools.sim.domains import claim_domain
from glpma_tools.sim.node_process import NODE_MODULE, NodeProcess, node_environment
from glpma_tools.tables import fmt, table

#: seconds between two assembly-modes requests in the second run
MODES_PERIOD_S = 0.5
#: input rate and the node's parameters per manipulator (both at 1 kHz, a ros2_control update rate)
END_TO_END = {"planar_3rpr": (1000.0, "params_3rpr.yaml"), "hexapod_66": (1000.0, "params_hexapod.yaml")}
#: the extra outputs the shipped params files switch on
SHIPPED_ON = dict.fromkeys(("publish_tf", "publish_covariance", "publish_twist"), True)
#: figures read from the node's /diagnostics report after the run: result key -> the report's name
DIAGNOSTICS = {"dropped": "inputs dropped", "deadline_misses": "deadline misses",
               "node_solve_p99_ms": "solve time p99 (ms)"}
#: seconds of driving with --quick
QUICK_S = 2.0
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


def bench_end_to_end(sc, seconds: float, domain: int) -> dict:
    """The node's run of the outputs section's part 2 (:func:`.outputs.path_latency`: latency, poses, CPU
    share, RSS, position error, the node's drops and solve time from its /diagnostics report after the run),
    then the mock controller's run with assembly-mode requests against the same process."""
    from .outputs import NODE, path_latency

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
    from .report import md_blocks, prose
    if not res.get("dds"):
        return []
    return md_blocks("## DDS end to end (node + mock controller)", prose("dds"), *(
        f"### {label}\n\n" + table(["quantity", "value"], list(_cells(r))) if isinstance(r, dict)
        else f"- {label}: not run ({r})" for label, r in res["dds"].items()))
