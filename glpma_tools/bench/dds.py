"""DDS end to end: a node process on a private domain driven by the mock controller at the
rate a robot controller would use, with and without assembly-mode requests while streaming."""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

from glpma_ros.config import config_dir, load_manipulator, resolve_config
from glpma_tools import mock_controller
from glpma_tools.sim.domains import claim_domain
from glpma_tools.sim.node_process import NodeProcess, node_environment

#: seconds between two assembly-modes requests in the second run
MODES_PERIOD_S = 0.5
#: input rate and the node's parameters per manipulator (both at 1 kHz, a ros2_control update rate)
END_TO_END = {"planar_3rpr": (1000.0, "params_3rpr.yaml"), "hexapod_66": (1000.0, "params_hexapod.yaml")}
#: seconds of driving with --quick
QUICK_S = 2.0


def bench_end_to_end(config: str, steps: int | None = None, quick: bool = False, duration_s: float = 60.0) -> dict:
    """Start a node process over DDS on a private domain, drive it for the config's manipulator
    and return flat figures: input published -> pose received latency, inputs, poses, drops, the
    node's solve time, its CPU share while streaming, and its RSS after warm-up and after the run."""
    model = load_manipulator(resolve_config(config))
    rate, params = END_TO_END[model.kind]
    duration = QUICK_S if quick else (steps / rate if steps else duration_s)
    with claim_domain() as claim, tempfile.TemporaryDirectory(prefix="glpma_e2e_") as logs:
        domain = claim.domain_id
        node = NodeProcess(["--params-file", str(config_dir() / params), "-p", f"manipulator_config:={config}"],
                           node_environment(domain), Path(logs))
        node.start()
        try:
            rss_before = node.rss_kb()
            cpu_before, wall_before = node.cpu_s(), time.perf_counter()
            summary = mock_controller.run(str(config), rate, duration, domain_id=domain)
            cpu_share = (node.cpu_s() - cpu_before) / (time.perf_counter() - wall_before)
            rss_after = node.rss_kb()
            with_modes = mock_controller.run(str(config), rate, duration, domain_id=domain,
                                             modes_period_s=MODES_PERIOD_S)
        finally:
            node.stop()
    lat, diag = summary["latency_ms"], (summary.get("node_diagnostics") or {}).get("values", {})

    def number(key):
        return float(diag[key]) if key in diag else None
    m = with_modes["assembly_modes"]
    return {"rate_hz": rate, "duration_s": duration, "inputs": summary["inputs_sent"],
            "poses": summary["poses_matched"], "pose_ratio": summary["pose_ratio"],
            "poses_wrong": summary["poses_wrong"],
            "p50_ms": lat["p50"], "p99_ms": lat["p99"], "max_ms": lat["max"],
            "dropped": number("inputs dropped"), "deadline_misses": number("deadline misses"),
            "node_solve_p99_ms": number("solve time p99 (ms)"),
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
