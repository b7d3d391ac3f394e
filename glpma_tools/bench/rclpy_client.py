"""The rclpy client of the outputs section's part 4 (:func:`glpma_tools.bench.outputs.rclpy_variants`),
run as its own process: ``python -m glpma_tools.bench.rclpy_client CONFIG RATE_HZ SECONDS EXTRAS ECHO``.

Publishes ``leg_lengths`` (metres) along the simulated loop at ``RATE_HZ`` for ``SECONDS``, takes
``pose_estimate``, pairs every pose with the input it answers (:func:`glpma_tools.bench.outputs.answers`)
and prints one line: inputs sent, poses received, latency p50 and p99 (ms), poses unpaired or off
the truth.  ``EXTRAS`` = ``extras``: ``/tf`` and ``pose_estimate_cov`` are subscribed too, as any TF
listener or RViz does (the node then builds and publishes them); ``ECHO`` = ``echo``: the other side is
the echo floor.  Importable only where rclpy is.
"""
from __future__ import annotations

import sys
import threading
import time

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage

from glpma_tools.bench.outputs import answers
from glpma_tools.sim.controller import Sent
from glpma_tools.sim.trajectories import Plan

#: seconds to let the discovery settle after the node matched, and to wait for the last poses
SETTLE_S = 1.0
#: seconds between two looks for the node's subscription
POLL_S = 0.1


def main(argv=None) -> int:
    config, rate, seconds, extras, echo = (argv or sys.argv[1:])[:5]
    rate, seconds, extras, echo = float(rate), float(seconds), extras == "extras", echo == "echo"
    plan = Plan(config)
    samples = [plan.sample(i / rate) for i in range(int(rate * seconds))]
    rclpy.init()
    node = rclpy.create_node("glpma_fk_bench_client")
    received = []

    def take(m):
        p, q, stamp = m.pose.position, m.pose.orientation, m.header.stamp
        received.append((time.time_ns(), stamp.sec * 1_000_000_000 + stamp.nanosec, m.header.frame_id,
                         np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])))

    node.create_subscription(PoseStamped, "pose_estimate", take, 100)
    if extras:
        node.create_subscription(TFMessage, "/tf", lambda m: None, 100)
        node.create_subscription(PoseWithCovarianceStamped, "pose_estimate_cov", lambda m: None, 100)
    pub = node.create_publisher(Float64MultiArray, "leg_lengths", 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    while pub.get_subscription_count() == 0:
        time.sleep(POLL_S)
    time.sleep(SETTLE_S)
    sent, t0 = [], time.perf_counter()
    for i, (legs, position, quaternion) in enumerate(samples):
        time.sleep(max(0.0, t0 + i / rate - time.perf_counter()))
        msg = Float64MultiArray(data=[float(v) for v in legs * plan.mpu])
        sent.append(Sent(time.time_ns(), legs, position, quaternion))
        pub.publish(msg)
    time.sleep(SETTLE_S)
    index, paired, wrong = answers(plan, sent, list(received), echo)
    latency = np.array([(p[0] - sent[i].send_ns) * 1e-6 for i, p in zip(index, paired)])
    print(len(sent), len(received), np.percentile(latency, 50), np.percentile(latency, 99), wrong, flush=True)
    executor.shutdown()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
