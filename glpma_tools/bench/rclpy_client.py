"""Part 4 of the ``outputs`` section, the rclpy adapter (imported only where rclpy is): :func:`variants` runs
the node in this process under each set-up of :data:`PAIR` and :data:`VARIANTS` against :func:`main`, the
client, in a process of its own: it publishes ``leg_lengths`` along the simulated loop, takes
``pose_estimate`` (and, where asked, ``/tf``, ``pose_estimate_cov`` and ``twist_estimate`` as any TF
listener or RViz does; in most rows another process, :func:`listen`, subscribes to those instead), pairs
each pose with its input and prints inputs sent, poses received, latency p50 and p99 (ms), poses wrong."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import numpy as np
import rclpy
from cyclonedds.util import duration
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, TwistStamped
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage

from glpma_ros.node.dds import cdr, endpoints
from glpma_ros.node.dds import messages as dds_messages
from glpma_ros.node.rcl_publish import RawPublisher
from glpma_ros.node.rcl_take import subscribe_taken_by_thread
from glpma_ros.node.ros_node import FkNode
from glpma_tools import timing
from glpma_tools.bench.transport import END_TO_END, answers, params_of
from glpma_tools.sim.controller import Sent, pose_stamped_fields
from glpma_tools.sim.echo_node import POSE_NUMBERS
from glpma_tools.sim.node_process import PACKAGE_PARENT, node_environment
from glpma_tools.sim.trajectories import Plan

#: seconds to let the discovery settle after the node matched, and to wait for the last poses
SETTLE_S = 1.0
#: seconds between two looks for the node's subscription
POLL_S = 0.1
#: seconds the client may take beyond its run (its start, discovery, the pairing)
CLIENT_SLACK_S = 300.0
#: the listener's keep-last depth per topic (as the rclpy subscriptions of the client: 100) and its wait's timeout (s)
LISTENER_DEPTH, LISTENER_WAIT_S = 100, 1.0
#: an input sent this many periods after its time is late: it reaches the node less than half a period before
#: the next one, which a node still answering the first then takes with it (and answers alone)
LATE_PERIODS = 0.5
#: a process that keeps one core busy (the "one core busy" rows), at normal priority even where the bench runs
#: under a real-time policy (``chrt``, to shield it from other processes): a real-time busy loop would
#: starve its core instead
BUSY_LOOP = "import os\nos.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))\nwhile True:\n    pass\n"
#: the SCHED_FIFO priority of the "thread_priority" row (ros2_control's default for its controller manager)
RT_PRIORITY = 50
#: who subscribes to the shipped extra outputs (/tf, covariance, twist), as a TF listener or RViz does: another
#: process (LISTENER: the usual set-up, the controller reading the pose is not the TF listener), or the
#: client itself (CLIENT: its Python executor then also takes and deserializes three messages per pose,
#: beside the pose it times and the legs it sends), or nobody (None)
LISTENER, CLIENT = "listener", "client"
SUBSCRIBED = {LISTENER: "/tf + cov + twist subscribed by another process",
              CLIENT: "/tf + cov + twist subscribed by the client itself"}
#: (label, variant, who subscribes to the extra outputs, one core busy, parameters over the shipped params file)
#: :data:`PAIR`: the echo floor and the shipped node, side by side in each of the ``runs``;
#: :data:`VARIANTS`: once each after them -- the extra outputs subscribed by the client, both with one core
#: busy, the node also with ``thread_priority`` granted, then the shipped node alone and two other executor
#: set-ups
PAIR = (
    (f"echo (the floor: no solve), {SUBSCRIBED[LISTENER]}", "echo", LISTENER, False, {}),
    (f"shipped, {SUBSCRIBED[LISTENER]}", "shipped", LISTENER, False, {}),
)
VARIANTS = (
    (f"echo (the floor), {SUBSCRIBED[CLIENT]}", "echo", CLIENT, False, {}),
    (f"shipped, {SUBSCRIBED[CLIENT]}", "shipped", CLIENT, False, {}),
    (f"echo (the floor), {SUBSCRIBED[LISTENER]}, one core busy", "echo", LISTENER, True, {}),
    (f"shipped, {SUBSCRIBED[LISTENER]}, one core busy", "shipped", LISTENER, True, {}),
    (f"shipped, {SUBSCRIBED[LISTENER]}, one core busy, thread_priority {RT_PRIORITY}", "shipped", LISTENER, True,
     {"thread_priority": RT_PRIORITY}),
    ("input thread on the input alone, newest input solved in it (shipped), nothing else subscribed",
     "shipped", None, False, {}),
    ("SingleThreadedExecutor, hand-off to a solver thread", "submit", None, False, {}),
    ("MultiThreadedExecutor(2), reentrant group, solve in the callback", "multi", None, False, {}),
)


class Echo(Node):
    """The transport floor on rclpy: ``leg_lengths`` taken raw, the newest read with ``struct``, a
    ``pose_estimate`` carrying its legs published as bytes -- the rclpy node's path without the solve
    (:mod:`glpma_tools.sim.echo_node` on Cyclone DDS); with ``extras``, then ``/tf``, ``pose_estimate_cov``
    and ``twist_estimate`` of that pose written as the node writes them (bytes through ``rcl``), so that
    their subscribers cost the machine the same beside the floor as beside the node.  Counts as the
    node's statistics do."""

    def __init__(self, depth: int, frame_id: str, child_frame_id: str, extras: bool):
        super().__init__("glpma_fk")
        self.handled = self.dropped = 0
        encode, pub = cdr.Encoder(), self.create_publisher(PoseStamped, "pose_estimate", depth)
        writers = [RawPublisher(self.create_publisher(t, topic, depth)) for t, topic in
                   ((TFMessage, "/tf"), (PoseWithCovarianceStamped, "pose_estimate_cov"),
                    (TwistStamped, "twist_estimate"))] if extras else []
        still, no_covariance = (0.0, 0.0, 0.0), (0.0,) * 36

        def on_legs(data, passed_over):
            self.dropped += passed_over
            self.handled += 1
            numbers = (cdr.float64_multi_array_data(data) + (0.0,) * POSE_NUMBERS)[:POSE_NUMBERS]
            stamp_ns, position, orientation = time.time_ns(), numbers[:3], numbers[3:]
            pub.publish(encode.pose_stamped(stamp_ns, frame_id, position, orientation))
            if writers:
                for writer, data in zip(writers, (
                        encode.tf_message(stamp_ns, frame_id, child_frame_id, position, orientation),
                        encode.pose_with_covariance_stamped(stamp_ns, frame_id, position, orientation, no_covariance),
                        encode.twist_stamped(stamp_ns, frame_id, still, still))):
                    writer.publish(data)

        # taken as the node takes its input: by a thread waiting on the subscription alone (rcl_take)
        self.input_sub, self.input_thread = subscribe_taken_by_thread(
            self.create_subscription, Float64MultiArray, "leg_lengths", depth, self.context, on_legs)

    def destroy_node(self):
        self.input_thread.stop()
        return super().destroy_node()


def _node(variant: str, values: dict, extras: bool):
    """The node of ``variant``: the echo, or the node with ``values``, its input taken as shipped or, for
    ``submit`` / ``multi``, by a callback that hands it to the solver thread / solves in a reentrant group."""
    if variant == "echo":
        return Echo(values["qos_depth"], values["frame_id"], values["child_frame_id"], extras)
    node = FkNode(parameter_overrides=[Parameter(n, value=v) for n, v in values.items() if v != []])
    if variant in ("submit", "multi"):
        node.endpoints.input_thread.stop()
        node.destroy_subscription(node.endpoints.input_sub)
        loop = node.endpoints.loop
        solve = loop.start().submit if variant == "submit" else loop.offer
        node.create_subscription(Float64MultiArray, "leg_lengths",
                                 lambda msg: solve(tuple(msg.data), node.get_clock().now().nanoseconds),
                                 values["qos_depth"],
                                 callback_group=ReentrantCallbackGroup() if variant == "multi" else None)
    return node


def run_variant(sc, seconds: float, domain: int, variant: str, extras: str | None, busy: bool, values: dict) -> dict:
    """One row of part 4: the node of ``variant`` with ``values`` in this process on ROS domain ``domain``, the
    client process publishing ``sc``'s legs at the DDS section's rate for ``seconds``; ``extras``: who
    subscribes to the extra outputs (:data:`LISTENER`, :data:`CLIENT` or None)."""
    rate_hz = END_TO_END[sc.model.kind][0]
    env = node_environment(domain)
    rclpy.init()
    node = _node(variant, values, extras is not None)
    executor = MultiThreadedExecutor(2) if variant == "multi" else SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    hog = subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) if busy else None
    listener = (subprocess.Popen([sys.executable, "-m", __name__, LISTENER], env=env, cwd=PACKAGE_PARENT)
                if extras == LISTENER else None)
    cpu0, steal0 = time.process_time(), timing.steal_s()
    try:
        out = subprocess.run([sys.executable, "-m", __name__, sc.path, str(rate_hz), str(seconds),
                              "extras" if extras == CLIENT else "-", variant], env=env, capture_output=True,
                             text=True, timeout=seconds + CLIENT_SLACK_S, cwd=PACKAGE_PARENT)
        cpu_s = time.process_time() - cpu0          # this process = the node under test
        sent, poses, p50, p99, wrong, late = map(float, out.stdout.split())
        st = node if variant == "echo" else node.service.stats
        return {"sent": int(sent), "received": st.handled + st.dropped, "poses": int(poses),
                "answered": poses / max(sent, 1), "dropped": st.dropped, "wrong": int(wrong), "p50": p50,
                "p99": p99, "cpu_us_per_input": cpu_s / max(sent, 1) * 1e6, "client_late": int(late),
                "steal_ms": None if steal0 is None else 1e3 * (timing.steal_s() - steal0)}
    finally:
        for process in (hog, listener):
            if process is not None:
                process.kill()
                process.wait()
        executor.shutdown()
        spinner.join()
        node.destroy_node()
        rclpy.try_shutdown()


def variants(sc, seconds: float, domain, runs: int = 1) -> tuple[dict, list[dict]]:
    """Part 4: legs published by the client process at the DDS section's rate -> pose received, for
    :data:`PAIR` in each of ``runs`` runs, then each row of :data:`VARIANTS` (``sc``'s shipped params);
    ``domain()`` claims a fresh ROS domain for each; the set-up says the load average (1 min) at the start and
    end, and how the bench was scheduled.  Each row of a node is set against the floor measured
    beside it (``floor_p50`` / ``floor_p99``: the echo of its run, or of the first run, idle or with one core
    busy as the row).  Returns
    (the set-up, the rows)."""
    shipped = {**params_of(sc.model.kind), "manipulator_config": sc.path}
    load_start, policy = os.getloadavg()[0], scheduling()
    plan = [(run, spec) for run in range(1, runs + 1) for spec in PAIR] + [(None, spec) for spec in VARIANTS]
    rows, floors = [], {}
    for run, (label, variant, extras, busy, overrides) in plan:
        row = {"variant": label, "run": run, "busy": busy,
               **run_variant(sc, seconds, domain(), variant, extras, busy, {**shipped, **overrides})}
        if variant == "echo":
            floors[(run, busy)] = row
        else:               # the rows after the runs: the first run's floor, or their own (one core busy)
            floor = floors.get((run, busy), floors.get((1, busy)))
            row.update(floor_p50=floor and floor["p50"], floor_p99=floor and floor["p99"])
        rows.append(row)
    return {"manipulator": sc.label, "rate": END_TO_END[sc.model.kind][0], "seconds": seconds, "runs": runs,
            "load": (load_start, os.getloadavg()[0]), "policy": policy}, rows


def scheduling() -> str:
    """How this process (the node under test; the client inherits it) is scheduled, for the report."""
    if os.sched_getscheduler(0) == os.SCHED_FIFO:
        priority = os.sched_getparam(0).sched_priority
        return f"SCHED_FIFO priority {priority} (shielded from the machine's other processes)"
    return "normal scheduling"


def subscribe_extras(node) -> None:
    """Subscribe ``node`` to ``/tf``, ``pose_estimate_cov`` and ``twist_estimate`` (messages deserialized, then
    dropped), as a TF listener or RViz does."""
    for msg_type, topic in ((TFMessage, "/tf"), (PoseWithCovarianceStamped, "pose_estimate_cov"),
                            (TwistStamped, "twist_estimate")):
        node.create_subscription(msg_type, topic, lambda m: None, 100)


def listen() -> int:
    """The other process that subscribes to the extra outputs (:data:`LISTENER`), until killed: a Cyclone DDS
    reader per topic (ROS 2's names, types and QoS, as the DDS twin's), its samples taken raw in batches on each
    wake-up.  For the node a matched subscriber costs the same whatever the subscriber does with the samples
    (each is serialized, written and delivered over loopback); an rclpy subscriber would also spend about a
    tenth of a core per topic at 1 kHz in its own Python executor, taken from the two cores the node, the floor
    and the client share."""
    participant = endpoints.Participant()
    readers = [participant.reader(topic, msg_type, LISTENER_DEPTH) for topic, msg_type in (
        (endpoints.TF, dds_messages.TFMessage), (endpoints.POSE_ESTIMATE_COV, dds_messages.PoseWithCovarianceStamped),
        (endpoints.TWIST_ESTIMATE, dds_messages.TwistStamped))]
    waitset, _ = endpoints.reader_waitset(participant, readers)
    while True:
        waitset.wait(duration(seconds=LISTENER_WAIT_S))
        for reader in readers:
            cdr.take_raw(reader, LISTENER_DEPTH)


def main(argv=None) -> int:
    """The client process: ``python -m glpma_tools.bench.rclpy_client CONFIG RATE_HZ SECONDS EXTRAS VARIANT``
    (``EXTRAS`` = ``extras``: also subscribe to ``/tf``, ``pose_estimate_cov`` and ``twist_estimate``;
    ``VARIANT`` = ``echo``: the poses carry the legs they answer); ``... rclpy_client listener``: :func:`listen`.

    A controller that keeps its period, as far as a Python process can: every input serialized beforehand
    and written as bytes through ``rcl`` (:class:`~glpma_ros.node.rcl_publish.RawPublisher`, the interpreter
    lock released), the poses taken as bytes by a thread of their own (:mod:`glpma_ros.node.rcl_take`, each
    one, its receive time at once) rather than by the executor, whose Python per message would hold the
    lock when an input is due and send it late, in a burst with the next one (the node under test then
    answers the newest of the two).  Prints inputs sent, poses received, latency p50 and p99 (ms), poses
    wrong and the inputs sent more than :data:`LATE_PERIODS` late."""
    argv = argv or sys.argv[1:]
    if argv[:1] == [LISTENER]:
        return listen()
    config, rate, seconds, extras, variant = argv[:5]
    rate, plan = float(rate), Plan(config)
    samples = [plan.sample(i / rate) for i in range(int(rate * float(seconds)))]
    messages = [serialize_message(Float64MultiArray(data=[float(v) for v in legs * plan.mpu]))
                for legs, _, _ in samples]
    rclpy.init()
    node = rclpy.create_node("glpma_fk_bench_client")
    received = []

    def take(data, _passed_over):
        received.append((time.time_ns(), *pose_stamped_fields(data)))

    pose_sub, pose_thread = subscribe_taken_by_thread(node.create_subscription, PoseStamped, "pose_estimate", 100,
                                                      node.context, take, newest_only=False)
    if extras == "extras":
        subscribe_extras(node)
    pub = node.create_publisher(Float64MultiArray, "leg_lengths", 10)
    writer = RawPublisher(pub)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    while pub.get_subscription_count() == 0:
        time.sleep(POLL_S)
    time.sleep(SETTLE_S)
    sent, late, t0 = [], 0, time.perf_counter()
    for i, ((legs, position, quaternion), data) in enumerate(zip(samples, messages)):
        delay = t0 + i / rate - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        elif delay < -LATE_PERIODS / rate:
            late += 1
        sent.append(Sent(time.time_ns(), legs, position, quaternion))
        writer.publish(data)
    time.sleep(SETTLE_S)
    pose_thread.stop()
    index, paired, wrong, _ = answers(plan, sent, list(received), variant == "echo")
    latency = [(p[0] - sent[i].send_ns) * 1e-6 for i, p in zip(index, paired)]
    print(len(sent), len(received), *np.percentile(latency, [50, 99]), wrong, late, flush=True)
    executor.shutdown()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
