"""glpma-fk demo: the glpma_fk node tracking a simulated manipulator, end to end.

Starts the node as its own process over Cyclone DDS, drives it with the mock controller along
a loop (:mod:`glpma_tools.mock_controller`), shows live progress, prints a summary table and
writes a figure (the true and the estimated path, and the end-to-end latency histogram) and the
summary as JSON.

Exit status 1 when a published pose is wrong, the node died, no pose came back or the node's
counters do not add up; 0 otherwise.  The share of inputs answered and the latency depend on
how busy the machine is: they are reported, with what made it look busy, not judged.
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

from glpma_ros.cli.api import OneLineParser, command_main
from glpma_ros.config import config_dir
from glpma_ros.errors import GlpmaError
from glpma_ros.node.params import SOLVER_CHOICES
from glpma_tools import mock_controller
from glpma_tools.sim.domains import claim_domain
from glpma_tools.sim.node_process import NodeProcess, node_environment
from glpma_tools.stats import distribution
from glpma_tools.tables import fmt, spread, table

MANIPULATORS = {
    "3rpr": {"config": "planar_3rpr_seed", "params": "params_3rpr.yaml", "rate": 200.0},
    "hexapod": {"config": "hexapod_66_rolland", "params": "params_hexapod.yaml", "rate": 100.0},
    "delta": {"config": "delta_irb360", "params": "params_delta.yaml", "rate": 100.0},
}
#: a manipulator config given by path (or shipped name) runs with the params file of its kind
KIND_SPEC = {"planar_3rpr": "3rpr", "hexapod_66": "hexapod", "delta": "delta", "rus_6": "hexapod",
             "planar_3rrr": "3rpr", "linear_delta": "delta", "pus_6": "hexapod", "planar_3prr": "3rpr"}
#: ``--manipulator`` by an actuated family's name: its shipped config
FAMILY_CONFIGS = {"rus_6": "rus6_simulator", "planar_3rrr": "planar_3rrr_symmetric",
                  "linear_delta": "linear_delta_kossel_mini", "pus_6": "pus6_rail_hexapod",
                  "planar_3prr": "planar_3prr_triangle"}


def manipulator_spec(name: str) -> tuple[str, dict]:
    """``(label, spec)`` of ``--manipulator``: a shipped pair (3rpr, hexapod) or a manipulator config
    (a path or a shipped config's name), driven with its kind's params file and ``manipulator_config``
    set to it; :class:`~glpma_ros.errors.ConfigError` for an unreadable or invalid config."""
    if name in MANIPULATORS:
        return name, MANIPULATORS[name]
    name = FAMILY_CONFIGS.get(name, name)
    from glpma_ros.config import load_document, model_from_dict, resolve_config
    from glpma_ros.models.rotations import quaternion_from_matrix
    from glpma_tools.sim.trajectories import start_pose
    path = resolve_config(name)
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    p0, R0 = start_pose(model, doc)       # where the mock controller starts: the node starts warm there
    x0 = model.variables_from_pose(p0, quaternion_from_matrix(R0))
    spec = dict(MANIPULATORS[KIND_SPEC[model.kind]], config=str(path.resolve()))
    spec["extra_args"] = ["-p", f"manipulator_config:={path.resolve()}", "-p", "joint_names:=[]",
                          "-p", "initial_pose:=[" + ", ".join(repr(float(v)) for v in x0) + "]"]
    return path.stem, spec


def _parser() -> OneLineParser:
    what = __doc__.split("\n\n")[0].split(": ", 1)[1]
    p = OneLineParser(prog="glpma-fk demo", description=what[0].upper() + what[1:])
    p.add_argument("--manipulator", default="3rpr",
                   help="which manipulator to drive: 3rpr (default), hexapod or delta (the shipped seed 3-RPR, "
                        "Rolland's 6-6 and the IRB 360-size rotary Delta), an actuated family by name (rus_6, "
                        "planar_3rrr, linear_delta, pus_6, planar_3prr: its shipped config), or a manipulator config "
                        "(a path, or a shipped config's name such as hexapod_7legs)")
    p.add_argument("--rate", type=float, default=None, help="input rate in Hz (3rpr 200, hexapod and delta 100)")
    p.add_argument("--duration", type=float, default=10.0, help="seconds of driving (default 10)")
    p.add_argument("--solver", choices=SOLVER_CHOICES, default="glpma", help="the node's solver parameter")
    p.add_argument("--budget-ms", type=float, default=None, help="the node's time_budget_ms")
    p.add_argument("--fault", nargs=2, type=float, default=None, metavar=("LEG", "METRES"),
                   help="a faulty sensor: from the middle of the run on, leg LEG (from 1) is sent METRES too long; "
                        "with redundant legs (e.g. --manipulator hexapod_7legs) the node leaves it out")
    p.add_argument("--out", default="demo_out", help="directory of the figure and the JSON summary")
    p.add_argument("--domain-id", type=int, default=None,
                   help="ROS_DOMAIN_ID (default: one this demo claims, that no other run on the host uses)")
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
        d = distribution(lat)
        for key, style in (("p50", "--"), ("p99", ":")):
            ax2.axvline(d[key], color="k", ls=style, label=f"{key} = {d[key]:.2f} ms")
        ax2.legend()
    ax2.set_xlabel("end-to-end latency, legs published -> pose received [ms]")
    ax2.set_ylabel("inputs")
    ax2.set_title(f"{summary['inputs_sent']} inputs at {summary['rate_hz']:g} Hz")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _table(summary: dict, node_alive: bool) -> str:
    te, n = summary["tracking_error"], summary["node_counters"]
    rows = [
        ("manipulator", summary["manipulator"]),
        ("inputs sent", fmt(summary["inputs_sent"])),
        ("poses received", fmt(summary["poses_received"])),
        ("inputs answered", f"{summary['poses_matched']} ({100 * summary['pose_ratio']:.1f} %)"),
        ("poses wrong", fmt(summary["poses_wrong"])),
        ("node received / solved / rejected / dropped",
         "no idle report" if n is None else f"{n['received']} / {n['solved']} / {n['rejected']} / {n['dropped']}"),
        ("position error max", f"{fmt(te['position_m']['max'])} m"),
        ("orientation error max", f"{fmt(te['orientation_rad']['max'])} rad"),
        ("latency p50 / p99 / max", f"{spread(summary['latency_ms'])} ms"),
        ("load average (1 min)", f"{summary['load_average'][0]:.2f} on {summary['cores']} cores"),
        ("node", "running" if node_alive else "DIED"),
    ]
    return table(None, [("  " + k, v) for k, v in rows], markdown=False)


@command_main
def main(argv=None) -> int:
    from tqdm import tqdm

    args = _parser().parse_args(argv)
    if args.duration <= 0 or (args.rate is not None and args.rate <= 0):
        print("error: glpma-fk demo: --rate and --duration must be positive", file=sys.stderr)
        return 2
    if args.fault is not None and not float(args.fault[0]).is_integer():
        print("error: glpma-fk demo: --fault LEG must be a leg number", file=sys.stderr)
        return 2
    try:
        label, spec = manipulator_spec(args.manipulator)
    except GlpmaError as exc:
        print(f"error: glpma-fk demo: --manipulator: {exc}", file=sys.stderr)
        return 2
    if args.fault is not None:
        from glpma_ros.config import load_manipulator, resolve_config
        n_legs = load_manipulator(resolve_config(spec["config"])).n_legs
        if not 1 <= args.fault[0] <= n_legs:
            print(f"error: glpma-fk demo: --fault LEG must be 1 to {n_legs}, got {args.fault[0]:g}", file=sys.stderr)
            return 2
    rate = args.rate or spec["rate"]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    claim = None if args.domain_id is not None else claim_domain()     # held until the demo exits
    domain = args.domain_id if claim is None else claim.domain_id
    ros_args = ["--params-file", str(config_dir() / spec["params"]), "-p", f"solver:={args.solver}",
                *spec.get("extra_args", ())]
    if args.budget_ms is not None:
        ros_args += ["-p", f"time_budget_ms:={args.budget_ms}"]
    node = NodeProcess(ros_args, node_environment(domain), out)

    print(f"glpma_ros demo: {label}, solver {args.solver}, {rate:g} Hz for {args.duration:g} s, "
          f"ROS_DOMAIN_ID={domain}")
    print("starting the glpma_fk node (Cyclone DDS; the first run compiles the solvers) ...", flush=True)
    try:
        node.start()
    except RuntimeError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    n = int(round(rate * args.duration))
    # on stderr, and only on a terminal: a log file gets no carriage-return frames
    bar = tqdm(total=n, unit="input", desc="driving", dynamic_ncols=True, file=sys.stderr, disable=None)

    def show(sent, poses_received, latency_p50_ms, position_error_max_m):
        bar.update(sent - bar.n)
        bar.set_postfix_str(f"poses received {poses_received:,}, latency p50 {latency_p50_ms:.2f} ms, "
                            f"error max {position_error_max_m:.1e} m")

    def progress(i, total, partial):
        show(i, partial["poses_received"], partial["latency_p50_ms"], partial["position_error_max_m"])
    t0 = time.perf_counter()
    try:
        summary = mock_controller.run(spec["config"], rate, args.duration, progress=progress, samples=True,
                                      fault=args.fault)
    except (TimeoutError, GlpmaError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    else:
        # the bar ends on the summary's figures (the last poses arrive after the last input is sent)
        p50, error = summary["latency_ms"]["p50"], summary["tracking_error"]["position_m"]["max"]
        show(summary["inputs_sent"], summary["poses_received"], math.nan if p50 is None else p50,
             math.nan if error is None else error)
    finally:
        bar.close()
        alive = node.alive()
        node.stop()
    ok, lines = mock_controller.verdict(summary)
    if not alive:
        ok = False
        lines.insert(0, f"FAILED: the node died during the run (see {node.stderr})")
    summary["node_alive"] = alive
    summary["ok"] = ok
    figure = out / f"demo_{label}.png"
    _figure(summary, figure)
    summary.pop("samples")
    (out / f"demo_{label}.json").write_text(json.dumps(summary, indent=1))
    print(f"\nsent {summary['inputs_sent']:,} inputs in {summary['sending_s']:.1f} s; the run took "
          f"{time.perf_counter() - t0:.1f} s with connecting to the node before and collecting the last poses and "
          f"the node's counters after")
    print("\nsummary")
    print(_table(summary, alive))
    print("\n" + "\n".join(lines))
    print(f"\nfigure: {figure}\nnode log: {node.stderr}")
    return 0 if ok else 1
