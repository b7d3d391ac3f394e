"""``glpma-fk modes``: ask a running ``glpma_fk`` node for every real assembly mode of its last
input, from the command line, over Cyclone DDS (no ROS 2 installation needed).

It publishes ``std_msgs/Empty`` on ``~/request_assembly_modes`` and waits for the node's
``geometry_msgs/PoseArray`` on ``~/assembly_modes`` (latched: an answer published before this
client existed is recognised by its stamp and skipped).  When the node cannot answer (no input
received yet, an invalid last input) it says why on ``/diagnostics`` (``assembly modes last
failure``): that reason is printed and the exit status is 1.  Same discovery settings as the
node: ``ROS_DOMAIN_ID``, ``CYCLONEDDS_URI``.  With ROS 2 the same is
``ros2 topic pub --once /glpma_fk/request_assembly_modes std_msgs/msg/Empty`` and
``ros2 topic echo /glpma_fk/assembly_modes``.
"""
from __future__ import annotations

import json
import sys
import time

#: seconds to find the node's endpoints
DISCOVERY_S = 10.0
#: seconds for the latched (old) answer, if any, to arrive before the request is sent
SETTLE_S = 0.3
#: seconds to wait for a /diagnostics report before the request (the failure counter's baseline)
BASELINE_S = 3.0
#: polling period while waiting (s)
POLL_S = 0.02


class ModesError(Exception):
    """No answer: the message says why (no node found, the node's reason, time-out)."""


def _node_status(samples, node_name: str) -> dict | None:
    """The newest ``/diagnostics`` values of node ``node_name`` among ``samples``."""
    found = None
    for sample in samples:
        for status in getattr(sample, "status", None) or ():
            if status.name.startswith(f"{node_name}:"):
                found = {kv.key: kv.value for kv in status.values}
    return found


def request_modes(node_name: str = "glpma_fk", timeout_s: float = 120.0) -> dict:
    """Ask node ``node_name`` for its assembly modes; returns ``{"node", "frame_id", "stamp_ns",
    "modes": [{"position": [x, y, z], "orientation": [qx, qy, qz, qw]}], "wait_s"}`` (metres).
    :class:`ModesError` with the reason when there is no answer."""
    from . import endpoints  # these need cyclonedds, optional: main() says when it is missing
    from .messages import DiagnosticArray, Empty, PoseArray

    participant = endpoints.Participant()
    request = participant.writer(f"{node_name}/request_assembly_modes", Empty)
    answers = participant.reader(f"{node_name}/assembly_modes", PoseArray, depth=1, transient_local=True)
    diagnostics = participant.reader(endpoints.DIAGNOSTICS, DiagnosticArray, depth=100)
    if not endpoints.wait_for_match([request, answers], DISCOVERY_S):
        raise ModesError(f"no node {node_name!r} found on ROS domain {participant.domain_id} within "
                         f"{DISCOVERY_S:g} s (is it running, with the same ROS_DOMAIN_ID and CYCLONEDDS_URI?)")
    time.sleep(SETTLE_S)
    old = {s.header.stamp.to_ns() for s in answers.take(10) if hasattr(s, "poses")}
    baseline = None
    deadline = time.monotonic() + BASELINE_S
    while baseline is None and time.monotonic() < deadline:
        baseline = _node_status(diagnostics.take(100), node_name)
        time.sleep(POLL_S)
    failed_before = int(baseline.get("assembly modes failed", 0)) if baseline else None

    t0 = time.monotonic()
    request.write(Empty())
    deadline = t0 + timeout_s
    while time.monotonic() < deadline:
        for msg in answers.take(10):
            if hasattr(msg, "poses") and msg.header.stamp.to_ns() not in old:
                return {"node": node_name, "frame_id": msg.header.frame_id, "stamp_ns": msg.header.stamp.to_ns(),
                        "modes": [{"position": [p.position.x, p.position.y, p.position.z],
                                   "orientation": [p.orientation.x, p.orientation.y, p.orientation.z,
                                                   p.orientation.w]} for p in msg.poses],
                        "wait_s": time.monotonic() - t0}
        status = _node_status(diagnostics.take(100), node_name)
        if status is not None and failed_before is not None \
                and int(status.get("assembly modes failed", 0)) > failed_before:
            raise ModesError(f"node {node_name!r} could not compute the assembly modes: "
                             f"{status.get('assembly modes last failure', 'no reason given')}")
        time.sleep(POLL_S)
    raise ModesError(f"no answer from node {node_name!r} within {timeout_s:g} s (its log says why; "
                     f"raise --timeout for a large assembly_modes_runs)")


def main(args) -> int:
    """``glpma-fk modes`` with parsed ``args`` (``node``, ``timeout``, ``json``)."""
    try:
        import cyclonedds  # noqa: F401 - only to say what is missing
    except ImportError:
        print("error: glpma-fk modes needs the cyclonedds Python package (pip install cyclonedds); with ROS 2: "
              "ros2 topic pub --once /glpma_fk/request_assembly_modes std_msgs/msg/Empty", file=sys.stderr)
        return 2
    try:
        answer = request_modes(args.node, args.timeout)
    except ModesError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(answer))
        return 0
    modes = answer["modes"]
    print(f"{len(modes)} real assembly modes of the last input of {answer['node']} "
          f"(frame {answer['frame_id']!r}; position in metres, orientation as quaternion x y z w):")
    for k, mode in enumerate(modes, 1):
        print(f"  {k:2d}: position " + " ".join(f"{v:+.9f}" for v in mode["position"])
              + "   orientation " + " ".join(f"{v:+.9f}" for v in mode["orientation"]))
    return 0
