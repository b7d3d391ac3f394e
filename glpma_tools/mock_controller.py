"""A simulated manipulator controller for the ``glpma_fk`` node, over Cyclone DDS.

It moves the platform along the loop of :mod:`glpma_tools.sim.trajectories` around one of the
config's known solutions, publishes the leg lengths of each pose on ``leg_lengths`` at a fixed
rate (or, with ``--input joint_state``, on ``joint_states`` among other joints, shuffled, for a node
run with ``input_type:=joint_state``), listens to ``pose_estimate``, pairs every pose with the
input it answers (:mod:`glpma_ros.testing.matching`) and compares it with the true pose.

Verdict: a pose is wrong when it answers no input sent (it reproduces no input's legs) or is
farther than 1e-6 m / 1e-6 rad from its input's true pose; the node's counters must add up
(received = solved + rejected + dropped).  How many inputs get an answer depends on how busy the
machine is -- the node drops an input when a newer one arrives first -- so the share answered and
the latency are reported, with what made the machine look busy, but do not fail the run.

A faulty sensor (``--fault LEG METRES``, for a config with redundant legs): from the middle of the
run on, leg LEG is sent that much too long; the true pose stays the truth, so the node must leave
the leg out and go on publishing right poses, and the summary has what ``/diagnostics`` said of the
legs (``leg_health``: the leg left out, failed legs).

Command line: ``python -m glpma_tools.mock_controller --config planar_3rpr_seed --rate 200
--duration 5 [--input joint_state [--joint-names A B C]] [--fault LEG METRES] [--json]``; exit status 0 when every
pose is right, 1 when a pose is wrong, no pose came back or no node answered, 2 for bad
arguments.  As a library: :func:`run` returns the summary, :func:`verdict` judges it.
"""
from __future__ import annotations

import json
import math
import os
import sys
import time

import numpy as np

from glpma_ros.cli.api import OneLineParser, command_main
from glpma_ros.errors import GlpmaError
from glpma_ros.node.params import INPUT_FLOAT64_MULTI_ARRAY, INPUT_JOINT_STATE, INPUT_TYPES
from glpma_ros.testing.matching import ORIENTATION_TOL_RAD, POSITION_TOL_M, compare
from glpma_tools.sim.controller import Controller, counters, diff
from glpma_tools.sim.trajectories import Plan
from glpma_tools.stats import distribution
from glpma_tools.tables import spread

#: a 1-minute load average at or above this many runnable processes per core: the machine was busy
BUSY_LOAD_PER_CORE = 1.0
#: what /diagnostics says of redundant legs (glpma_ros.node.leg_health), kept in a faulty run's summary
LEG_HEALTH_KEYS = ("inputs with inconsistent legs", "leg left out last", "legs left out", "failed legs")


def run(config: str = "planar_3rpr_seed", rate_hz: float = 200.0, duration_s: float = 5.0, *,
        domain_id: int | None = None, qos_depth: int = 10, solution: int | None = None,
        amplitude: float = 1.0, connect_timeout_s: float = 30.0, settle_s: float = 0.3,
        tail_s: float = 1.0, diagnostics_wait_s: float = 5.0, progress=None, samples: bool = False,
        input_type: str = INPUT_FLOAT64_MULTI_ARRAY, joint_names=None, modes_period_s: float | None = None,
        fault=None) -> dict:
    """Drive the node for ``duration_s`` at ``rate_hz`` and return the summary (a JSON-able dict).

    ``progress(i, n, summary_so_far)`` is called about once a second while sending, if given;
    ``summary_so_far`` has ``poses_received``, ``latency_p50_ms`` and ``position_error_max_m``.
    With ``samples=True`` the summary also holds the per-input series (``samples``: true and
    estimated positions in metres, latency in ms) for plotting.  With ``modes_period_s`` a
    ``~/request_assembly_modes`` is sent every so many seconds while streaming (the next once
    the previous is answered); the summary's ``assembly_modes`` has the answers and the pose
    latency of the inputs sent while a request was being answered.
    Before sending, waits up to ``diagnostics_wait_s`` for the node's counters; after sending, up
    to ``tail_s`` for the last poses and up to ``diagnostics_wait_s`` for the node's
    ``/diagnostics`` to report it idle after the last input (``node_diagnostics``); the summary's
    ``node_counters`` are the differences over the run.
    ``fault``: ``(leg from 1, metres)``, a step error on that leg from the middle of the run on.
    Raises :class:`TimeoutError` when no node answers within ``connect_timeout_s``."""
    plan = Plan(config, solution, amplitude,
                fault=None if fault is None else (int(fault[0]) - 1, float(fault[1]), 0.5 * duration_s))
    model = plan.model
    ctl = Controller(model, domain_id, qos_depth, max(qos_depth, 1000), input_type, joint_names,
                     modes=modes_period_s is not None)
    modes = ctl.modes
    sent: list = []
    late = 0
    try:
        ctl.wait_for_node(connect_timeout_s)
        time.sleep(settle_s)
        before = ctl.counters_before(diagnostics_wait_s)
        n = max(1, int(round(rate_hz * duration_s)))
        next_progress = [time.perf_counter() + 1.0]

        def each(i, sent_so_far):
            if modes is not None:
                modes.poll(sent_so_far[-1].send_ns, modes_period_s)
            if progress is not None and time.perf_counter() >= next_progress[0]:
                next_progress[0] += 1.0
                c = compare(model, sent_so_far, list(ctl.listener.poses), ctl.joint_state)
                progress(i + 1, n, {"poses_received": len(ctl.listener.poses),
                                    "latency_p50_ms": float(np.median(c.latency_ms)) if c.latency_ms.size else math.nan,
                                    "position_error_max_m": float(c.position_error_m.max())
                                    if c.position_error_m.size else math.nan})
        t_send = time.perf_counter()
        sent, late = ctl.send(plan, 0.0, n, rate_hz, 1.0 / rate_hz, each=each)
        sending_s = time.perf_counter() - t_send
        deadline = time.monotonic() + tail_s
        while time.monotonic() < deadline and len(ctl.listener.poses) < len(sent):
            time.sleep(0.01)
        time.sleep(min(0.05, tail_s))
        idle = ctl.diagnostics_after(sent[-1].send_ns, diagnostics_wait_s)
        if modes is not None:
            modes.poll(time.time_ns(), None)
        poses = list(ctl.listener.poses)
        latest = ctl.listener.diagnostics
    finally:
        ctl.close()

    c = compare(model, sent, poses, input_type == INPUT_JOINT_STATE)
    wrong = len(c.unpaired) + int(np.sum(~c.on_truth))
    node_counts = diff(counters(idle), before) if idle is not None and before is not None else None
    summary = {
        "manipulator": model.kind,
        "config": str(plan.path),
        "solution": plan.solution,
        "input_type": input_type,
        "rate_hz": rate_hz,
        "duration_s": duration_s,
        "sending_s": sending_s,
        "inputs_sent": len(sent),
        "poses_received": len(poses),
        "poses_matched": len(c.poses),
        "poses_unpaired": len(c.unpaired),
        "poses_wrong": wrong,
        "pose_ratio": len(c.poses) / len(sent) if sent else 0.0,
        "late_sends": late,
        "frame_ids": sorted({p[2] for p in poses}),
        "tracking_error": {"position_m": distribution(c.position_error_m),
                           "orientation_rad": distribution(c.orientation_error_rad)},
        "legs_residual_max_m": float(c.legs_residual_m.max()) if c.legs_residual_m.size else None,
        "latency_ms": distribution(c.latency_ms),
        "node_diagnostics": {"values": idle} if idle is not None else latest,
        "node_counters": node_counts,
        "counters_add_up": None if node_counts is None else
        node_counts["received"] == node_counts["solved"] + node_counts["rejected"] + node_counts["dropped"],
        "lost_in_transport": None if node_counts is None else len(sent) - node_counts["received"],
        "load_average": list(os.getloadavg()),
        "cores": os.cpu_count(),
    }
    if fault is not None:
        values = (summary["node_diagnostics"] or {}).get("values") or {}
        summary["fault"] = {"leg": int(fault[0]), "step_m": float(fault[1]), "from_s": 0.5 * duration_s}
        summary["leg_health"] = {key: values.get(key) for key in LEG_HEALTH_KEYS}
    if modes is not None:
        busy = [lat for i, lat in zip(c.index, c.latency_ms) if modes.busy_at(sent[i].send_ns)]
        summary["assembly_modes"] = {"requests": modes.requested, "answers": len(modes.answers),
                                     "modes_per_answer": sorted({m for m, _ in modes.answers}),
                                     "answer_s": distribution([t for _, t in modes.answers]),
                                     "pose_latency_during_requests_ms": distribution(busy)}
    if samples:
        summary["samples"] = {
            "true_position_m": [[float(v) for v in s.position_m] for s in sent],
            "estimated_position_m": [[float(v) for v in pose[3]] for pose in c.poses],
            "latency_ms": [float(v) for v in c.latency_ms],
        }
    return summary


def verdict(s: dict) -> tuple[bool, list[str]]:
    """(every pose right and something came back, the lines that say so and why)."""
    lines, ok = [], True
    if s["poses_received"] == 0:
        ok = False
        n, values = s["node_counters"], (s["node_diagnostics"] or {}).get("values", {})
        why = (f" (the node rejected {n['rejected']}; last: {values.get('last rejection', '?')})"
               if n and n["rejected"] else "")
        lines.append(f"FAILED: no pose came back for {s['inputs_sent']} inputs{why}")
    if s["poses_wrong"]:
        ok = False
        lines.append(f"FAILED: {s['poses_wrong']} of {s['poses_received']} poses wrong ({s['poses_unpaired']} "
                     f"answer no input sent; the others are farther than {POSITION_TOL_M:g} m or "
                     f"{ORIENTATION_TOL_RAD:g} rad from the true pose)")
    if s["counters_add_up"] is False:
        ok = False
        n = s["node_counters"]
        lines.append(f"FAILED: the node's counters do not add up: received {n['received']} != solved {n['solved']} "
                     f"+ rejected {n['rejected']} + dropped {n['dropped']}")
    if ok:
        lines.append(f"every pose right: {s['poses_matched']} of {s['inputs_sent']} inputs answered "
                     f"({100 * s['pose_ratio']:.1f} %), latency p50 / p99 / max {spread(s['latency_ms'])} ms")
    if "fault" in s:
        f, h = s["fault"], s["leg_health"]
        lines.append(f"leg {f['leg']} sent {f['step_m']:g} m too long from {f['from_s']:g} s on: the node's "
                     f"/diagnostics says " + ", ".join(f"{k} {h[k]}" for k in LEG_HEALTH_KEYS))
    busy = busy_signs(s)
    unanswered = s["inputs_sent"] - s["poses_matched"]
    if unanswered > 0 and s["poses_received"]:
        # only what happened: the inputs without a pose, and what may explain them
        why = ("; the machine looked busy (" + "; ".join(busy) + "): the node answers the newest input and drops "
               "the ones it had no time for") if busy else ""
        lines.append(f"{unanswered} of {s['inputs_sent']} inputs got no pose{why}")
    elif busy:
        lines.append("the machine looked busy (" + "; ".join(busy) + "), and every input got its pose")
    return ok, lines


def busy_signs(s: dict) -> list[str]:
    """What in the summary says the machine was busy: load average, late sends, drops, losses."""
    signs = []
    load, cores = s["load_average"][0], s["cores"] or 1
    if load >= BUSY_LOAD_PER_CORE * cores:
        signs.append(f"load average {load:.2f} on {cores} cores")
    if s["late_sends"]:
        signs.append(f"the controller sent {s['late_sends']} inputs late")
    n = s["node_counters"]
    if n and n["dropped"]:
        signs.append(f"the node dropped {n['dropped']} inputs for newer ones")
    if s["lost_in_transport"]:
        signs.append(f"{s['lost_in_transport']} inputs overwritten in transport (DDS keep-last)")
    return signs


def format_summary(s: dict) -> str:
    """A few human-readable lines."""
    te, n = s["tracking_error"], s["node_counters"]
    node = ("no idle /diagnostics report" if n is None else
            f"received {n['received']} = solved {n['solved']} + rejected {n['rejected']} + dropped {n['dropped']}")
    return "\n".join([
        f"{s['manipulator']} at {s['rate_hz']:g} Hz for {s['duration_s']:g} s: "
        f"{s['inputs_sent']} inputs sent, {s['poses_received']} poses received, "
        f"{s['poses_matched']} answer an input ({100 * s['pose_ratio']:.1f} %)",
        f"  node                        {node}",
        f"  error position p50/p99/max  {spread(te['position_m'], '.3g')} m",
        f"  error orientation           {spread(te['orientation_rad'], '.3g')} rad",
        f"  end-to-end latency          {spread(s['latency_ms'])} ms",
    ])


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="mock_controller", description=__doc__.split("\n\n")[0])
    p.add_argument("--config", default="planar_3rpr_seed",
                   help="manipulator YAML or shipped config name (the node's manipulator_config)")
    p.add_argument("--rate", type=float, default=200.0, help="inputs per second (default 200)")
    p.add_argument("--duration", type=float, default=5.0, help="seconds of sending (default 5)")
    p.add_argument("--solution", type=int, default=None, help="index of the config's known solution to move around")
    p.add_argument("--amplitude", type=float, default=1.0, help="scale of the motion (default 1)")
    p.add_argument("--qos-depth", type=int, default=10)
    p.add_argument("--input", choices=INPUT_TYPES, default=INPUT_FLOAT64_MULTI_ARRAY,
                   help="publish leg_lengths (default) or joint_states (legs among other joints, "
                        "shuffled; run the node with input_type:=joint_state)")
    p.add_argument("--joint-names", nargs="+", default=None, metavar="NAME",
                   help="--input joint_state: the legs' joint names in leg order (default leg_1 .. leg_n)")
    p.add_argument("--fault", nargs=2, type=float, default=None, metavar=("LEG", "METRES"),
                   help="a faulty sensor: from the middle of the run on, leg LEG (from 1) is sent METRES too long "
                        "(a config with redundant legs isolates it)")
    p.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for the node")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on stdout")
    return p


@command_main
def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.rate <= 0 or args.duration <= 0:
        print("mock_controller: error: --rate and --duration must be positive", file=sys.stderr)
        return 2
    if args.fault is not None and not float(args.fault[0]).is_integer():
        print("mock_controller: error: --fault LEG must be a leg number", file=sys.stderr)
        return 2

    def progress(i, n, partial):
        print(f"sent {i}/{n}, poses received {partial['poses_received']}", file=sys.stderr, flush=True)

    try:
        summary = run(args.config, args.rate, args.duration, solution=args.solution, amplitude=args.amplitude,
                      qos_depth=args.qos_depth, connect_timeout_s=args.timeout,
                      progress=None if args.json else progress, input_type=args.input,
                      joint_names=args.joint_names, fault=args.fault)
    except (GlpmaError, TimeoutError, ValueError) as exc:
        print(f"mock_controller: error: {exc}", file=sys.stderr)
        return 1 if isinstance(exc, TimeoutError) else 2
    ok, lines = verdict(summary)
    if args.json:
        print(json.dumps(summary))
        print("\n".join(lines), file=sys.stderr)
    else:
        print(format_summary(summary) + "\n" + "\n".join(lines))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
