"""How the transport sections (dds, outputs, its rclpy part) run a node or a stand-in on a private domain
(:func:`node_process`, :func:`match`, the shipped params), and drive it with the simulated controller from
legs written to pose read (:func:`path_latency`, the outputs section's part 2 and the dds section)."""
from __future__ import annotations

import contextlib
import tempfile
import time
from pathlib import Path

import numpy as np

from glpma_ros.config import config_dir
from glpma_ros.node.dds import endpoints
from glpma_ros.node.ros_args import load_params_file
from glpma_ros.testing.matching import compare, pair, split_at_stamp
from glpma_tools.sim.controller import Controller
from glpma_tools.sim.echo_node import legs_of
from glpma_tools.sim.node_process import NODE_MODULE, NodeProcess, node_environment
from glpma_tools.sim.trajectories import Plan
from glpma_tools.stats import distribution

#: input rate and the node's parameters per manipulator (both at 1 kHz, a ros2_control update rate)
END_TO_END = {"planar_3rpr": (1000.0, "params_3rpr.yaml"), "hexapod_66": (1000.0, "params_hexapod.yaml")}
#: the extra outputs the shipped params files switch on
SHIPPED_ON = dict.fromkeys(("publish_tf", "publish_covariance", "publish_twist"), True)
#: every extra output off (the "extra outputs off" process, and what part 1 switches on from)
OFF = dict.fromkeys((*SHIPPED_ON, "publish_markers"), False)
#: the processes part 2 drives: label -> (module, extra --ros-args)
NODE, NODE_OFF, ECHO = "node", "node, extra outputs off", "echo (transport floor)"
TARGETS = {NODE: ("glpma_ros.node.dds.node", ()),
           NODE_OFF: ("glpma_ros.node.dds.node", tuple(a for k in OFF for a in ("-p", f"{k}:=false"))),
           ECHO: ("glpma_tools.sim.echo_node", ())}
#: seconds to wait for the last poses after the last input, and for the node's report after them
TAIL_S = 1.0
DIAGNOSTICS_WAIT_S = 5.0
#: seconds to wait for a process's endpoints to match ours, and to let the discovery settle then
CONNECT_S = 60.0
SETTLE_S = 0.5


def params_file(kind: str) -> Path:
    """The shipped params file of manipulators ``kind``."""
    return config_dir() / END_TO_END[kind][1]


def params_of(kind: str) -> dict:
    """The parameters of the shipped params file of manipulators ``kind`` (the node reads them so)."""
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
    if not endpoints.wait_for_match(endpoints_, CONNECT_S):
        raise TimeoutError(f"{what} did not match within {CONNECT_S:g} s")
    time.sleep(SETTLE_S)


def answers(plan, sent, poses, echo: bool) -> tuple[list, list, int, float | None]:
    """(the index of the input each paired pose answers, those poses, the poses that answer no input or lie
    off its true pose, the largest position error (m; None for an echo, whose poses carry the legs they
    answer)), for part 2, the dds section and the rclpy client."""
    if echo:
        pairs, unpaired = pair(plan.model, sent, poses,
                               legs_of=lambda pose: np.array(legs_of(pose, plan.model.n_legs)) / plan.mpu)
        return [i for i, _, _ in pairs], [p for _, p, _ in pairs], len(unpaired), None
    c = compare(plan.model, sent, poses)
    error = float(c.position_error_m.max()) if c.position_error_m.size else None
    return list(c.index), c.poses, len(c.unpaired) + int(np.sum(~c.on_truth)), error


def path_latency(sc, target: str, seconds: float, domain: int, then=None) -> dict:
    """Part 2 and the dds section: the simulated controller drives ``target`` (a key of :data:`TARGETS`) for
    ``seconds`` at :data:`END_TO_END`'s rate; latency split at the pose's stamp (ms), the process's
    CPU share while driven and RSS before and after, poses that answer no input or a wrong one.  With ``then``:
    the node's /diagnostics report after the run (``diagnostics``), then ``then(domain)`` against the same
    process (``then``; the process's stopped line covers both runs)."""
    plan = Plan(sc.path)
    rate = END_TO_END[plan.model.kind][0]
    module, extra = TARGETS[target]
    with node_process(domain, [*shipped_args(plan.model.kind, sc.path), *extra], module) as proc:
        with contextlib.closing(Controller(plan.model, domain, listen_depth=1000)) as ctl:
            match([ctl.writer, ctl.listener.reader], target)
            rss0, cpu0, wall0 = proc.rss_kb(), proc.cpu_s(), time.perf_counter()
            sent, _ = ctl.send(plan, 0.0, max(1, round(rate * seconds)), rate, 1.0 / rate)
            cpu_share = (proc.cpu_s() - cpu0) / (time.perf_counter() - wall0)
            deadline = time.monotonic() + TAIL_S
            while time.monotonic() < deadline and len(ctl.listener.poses) < len(sent):
                time.sleep(0.01)
            poses, rss1 = list(ctl.listener.poses), proc.rss_kb()
            diagnostics = then and ctl.diagnostics_after(sent[-1].send_ns, DIAGNOSTICS_WAIT_S)
        after = then and then(domain)
        proc.stop()
        summary = proc.stopped_line()
    index, paired, wrong, error = answers(plan, sent, poses, echo=target == ECHO)
    to_node, in_node = split_at_stamp(sent, index, paired)
    return {"manipulator": sc.label, "key": sc.key, "target": target, "rate_hz": rate, "seconds": seconds,
            "sent": len(sent), "paired": len(paired), "wrong": wrong, "total_ms": distribution(to_node + in_node),
            "to_node_ms": distribution(to_node), "in_node_ms": distribution(in_node),
            "cpu_percent": 100.0 * cpu_share, "summary": summary, "position_error_max_m": error,
            "rss_mb": (rss0 / 1024, rss1 / 1024), "diagnostics": diagnostics, "then": after}
