"""``glpma-fk demo``: the main job.

Starts the ``glpma_fk`` node as its own process over Cyclone DDS, drives it with
the mock controller along a trajectory, shows live progress (inputs, poses,
latency, tracking error), prints a summary table and writes a figure: the true
and the estimated path, and the end-to-end latency histogram.  Exits non-zero
when tracking failed (fewer than ``MIN_POSE_RATIO`` of the inputs answered, or a
pose farther than the tolerance from the truth).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from glpma_tools import mock_controller
from glpma_ros.config import config_dir
from glpma_tools.sim.node_process import NodeProcess, node_environment

#: ``glpma-fk demo --help`` (plain text: no reST markup)
DESCRIPTION = ("The main job: start the glpma_fk node over Cyclone DDS, drive it with the mock controller "
               "along a trajectory, show live progress, print a summary and write a figure. Exits non-zero "
               "when tracking failed.")
MANIPULATORS = {
    "3rpr": {"config": "planar_3rpr_seed", "params": "params_3rpr.yaml", "rate": 200.0},
    "hexapod": {"config": "hexapod_66_rolland", "params": "params_hexapod.yaml", "rate": 100.0},
}
#: share of inputs that must produce a pose (issue: at least 95 %)
MIN_POSE_RATIO = 0.95
#: largest tracking error accepted (REP 103 units)
MAX_POSITION_ERROR_M = 1e-6
MAX_ORIENTATION_ERROR_RAD = 1e-6


def _parser() -> argparse.ArgumentParser:
    from glpma_ros.solvers import SOLVERS
    p = argparse.ArgumentParser(prog="glpma-fk demo", description=DESCRIPTION)
    p.add_argument("--manipulator", choices=sorted(MANIPULATORS), default="3rpr",
                   help="which shipped manipulator to drive (default 3rpr)")
    p.add_argument("--rate", type=float, default=None, help="input rate in Hz (3rpr 200, hexapod 100)")
    p.add_argument("--duration", type=float, default=10.0, help="seconds of driving (default 10)")
    p.add_argument("--solver", choices=list(SOLVERS), default="glpma", help="the node's solver parameter")
    p.add_argument("--budget-ms", type=float, default=None, help="the node's time_budget_ms")
    p.add_argument("--out", default="demo_out", help="directory of the figure and the JSON summary")
    p.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: a private one)")
    return p


def _figure(summary: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    s = summary["samples"]
    true = np.array(s["true_position_m"]) * 1e3
    est = np.array(s["estimated_position_m"]) * 1e3
    lat = np.array(s["latency_ms"])
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5))
    ax1.plot(true[:, 0], true[:, 1], "-", color="0.6", lw=4, label="true (from the controller)")
    if len(est):
        ax1.plot(est[:, 0], est[:, 1], ".", ms=2, color="tab:blue", label="estimated (pose_estimate)")
    ax1.set_xlabel("platform x [mm]")
    ax1.set_ylabel("platform y [mm]")
    ax1.set_title(f"{summary['manipulator']}: path of the platform origin")
    ax1.axis("equal")
    ax1.legend(loc="best")
    if len(lat):
        ax2.hist(lat, bins=60, color="tab:orange")
        for q, style in ((50, "--"), (99, ":")):
            v = float(np.percentile(lat, q))
            ax2.axvline(v, color="k", ls=style, label=f"p{q} = {v:.2f} ms")
        ax2.legend()
    ax2.set_xlabel("end-to-end latency, legs published -> pose received [ms]")
    ax2.set_ylabel("inputs")
    ax2.set_title(f"{summary['inputs_sent']} inputs at {summary['rate_hz']:g} Hz")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _table(summary: dict, ok: bool) -> str:
    te, lat = summary["tracking_error"], summary["latency_ms"]

    def f(v, spec):
        return "n/a" if v is None else format(v, spec)
    rows = [
        ("manipulator", summary["manipulator"]),
        ("inputs sent", str(summary["inputs_sent"])),
        ("poses received (matched)", f"{summary['poses_received']} ({100 * summary['pose_ratio']:.1f} %)"),
        ("position error max", f"{f(te['position_m']['max'], '.2e')} m"),
        ("orientation error max", f"{f(te['orientation_rad']['max'], '.2e')} rad"),
        ("latency p50 / p99 / max", f"{f(lat['p50'], '.3f')} / {f(lat['p99'], '.3f')} / {f(lat['max'], '.3f')} ms"),
        ("tracking", "OK" if ok else "FAILED"),
    ]
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"  {k:<{width}}  {v}" for k, v in rows)


def tracking_ok(summary: dict) -> bool:
    te = summary["tracking_error"]
    pos, ang = te["position_m"]["max"], te["orientation_rad"]["max"]
    return (summary["pose_ratio"] >= MIN_POSE_RATIO and pos is not None and pos <= MAX_POSITION_ERROR_M
            and ang is not None and ang <= MAX_ORIENTATION_ERROR_RAD)


def main(argv=None) -> int:
    import json

    from tqdm import tqdm

    args = _parser().parse_args(argv)
    if args.duration <= 0 or (args.rate is not None and args.rate <= 0):
        print("error: --rate and --duration must be positive", file=sys.stderr)
        return 2
    spec = MANIPULATORS[args.manipulator]
    rate = args.rate or spec["rate"]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    domain = args.domain_id if args.domain_id is not None else 1 + os.getpid() % 200
    ros_args = ["--params-file", str(config_dir() / spec["params"]), "-p", f"solver:={args.solver}"]
    if args.budget_ms is not None:
        ros_args += ["-p", f"time_budget_ms:={args.budget_ms}"]
    node = NodeProcess(ros_args, node_environment(domain), out)

    print(f"glpma_ros demo: {args.manipulator}, solver {args.solver}, {rate:g} Hz for {args.duration:g} s, "
          f"ROS_DOMAIN_ID={domain}")
    print("starting the glpma_fk node (Cyclone DDS; the first run compiles the solvers) ...", flush=True)
    try:
        node.start()
    except RuntimeError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    n = int(round(rate * args.duration))
    bar = tqdm(total=n, unit="input", desc="driving", dynamic_ncols=True)

    def progress(i, total, partial):
        bar.update(i - bar.n)
        bar.set_postfix_str(f"poses {partial['poses_received']}, latency p50 {partial['latency_p50_ms']:.2f} ms, "
                            f"error max {partial['position_error_max_m']:.1e} m")
    try:
        summary = mock_controller.run(spec["config"], rate, args.duration, progress=progress, samples=True)
    except TimeoutError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    else:
        bar.update(n - bar.n)
    finally:
        bar.close()
        node.stop()
    ok = tracking_ok(summary)
    figure = out / f"demo_{args.manipulator}.png"
    _figure(summary, figure)
    summary.pop("samples")
    (out / f"demo_{args.manipulator}.json").write_text(json.dumps(summary, indent=1))
    print("\nsummary")
    print(_table(summary, ok))
    print(f"\nfigure: {figure}\nnode log: {node.stderr}")
    return 0 if ok else 1
