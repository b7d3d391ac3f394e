"""Launch test (launch_testing, run by ``colcon test`` on a real ROS 2 Jazzy): the managed node
(``fk.launch.py managed:=true``) walked through its lifecycle with ``ros2 lifecycle set``, beside
``mock_publisher``, with a params file that overrides the QoS of ``/leg_lengths``.

configure (the overridden QoS shows in ``ros2 topic info -v``; inputs arrive, no pose) -> activate
(poses on the truth) -> deactivate (no pose; inputs counted as dropped) -> activate (poses again)
-> shutdown (finalized); the node exits 0 when the launch ends.  Skipped where launch_testing is
not importable (no ROS 2 sourced)."""
import time
import unittest

import pytest

pytest.importorskip(
    "launch_testing", reason="launch_testing is not importable (ROS 2 Jazzy not sourced): the launch tests run "
                             "under colcon test on a real Jazzy; the node's logic is tested over Cyclone DDS")
import launch_testing.actions
import launch_testing.asserts

from glpma_ros.testing import TrackingMonitor, fk_with_mock
from launch import LaunchDescription
from launch_support import HANG_S, Diagnostics, TestNode, counters, params_file, ros2

RATE_HZ = 20.0
#: poses checked in each active phase
POSES = 40
#: inputs the mock sends while the node is inactive (none may give a pose)
INACTIVE_INPUTS = 20
#: the QoS override of the test's params file (rclpy's key layout)
LEG_QOS = {"/leg_lengths": {"subscription": {"reliability": "best_effort", "depth": 5}}}


@pytest.mark.launch_test
def generate_test_description():
    return LaunchDescription([
        *fk_with_mock("3rpr", managed=True, rate_hz=RATE_HZ, params_file=params_file("3rpr", qos_overrides=LEG_QOS)),
        launch_testing.actions.ReadyToTest(),
    ])


def lifecycle(*args) -> str:
    """``ros2 lifecycle ARGS /glpma_fk`` (retried while the node is not discovered yet); its output."""
    deadline = time.monotonic() + HANG_S
    while True:
        verb, rest = args[0], args[1:]
        r = ros2("lifecycle", verb, "/glpma_fk", *rest)
        if "Node not found" not in (r.stdout + r.stderr) or time.monotonic() > deadline:
            return r.stdout + r.stderr


class TestLifecycleWalk(unittest.TestCase):
    def test_walk(self):
        with TestNode() as t:
            monitor = TrackingMonitor(t.node, "planar_3rpr_seed")
            diagnostics = Diagnostics(t.node)
            self.assertIn("unconfigured", lifecycle("get"))
            self.assertIn("Transitioning successful", lifecycle("set", "configure"))
            self.assertIn("inactive", lifecycle("get"))

            info = ros2("topic", "info", "-v", "/leg_lengths").stdout
            block = info[info.index("Node name: glpma_fk"):]
            self.assertIn("Reliability: BEST_EFFORT", block.split("Node name:")[1], info)

            # inactive: the mock (waiting for a subscriber) starts now; no pose comes
            self.assertTrue(t.spin_until(lambda: len(monitor.truths) >= INACTIVE_INPUTS, HANG_S))
            self.assertEqual(monitor.poses, [])

            self.assertIn("Transitioning successful", lifecycle("set", "activate"))
            self.assertTrue(monitor.spin_until(t.executor, POSES, HANG_S))
            monitor.assert_tracking(min_poses=POSES)

            self.assertIn("Transitioning successful", lifecycle("set", "deactivate"))
            off_ns = t.node.get_clock().now().nanoseconds
            self.assertTrue(t.spin_until(lambda: sum(s.send_ns > off_ns for s in monitor.truths) >= INACTIVE_INPUTS,
                                         HANG_S))
            self.assertEqual([p for p in monitor.poses if p[1] > off_ns], [], "a pose while inactive")

            self.assertIn("Transitioning successful", lifecycle("set", "activate"))
            on_ns = t.node.get_clock().now().nanoseconds
            self.assertTrue(t.spin_until(lambda: sum(p[1] > on_ns for p in monitor.judged()) >= POSES, HANG_S))
            monitor.assert_tracking(min_poses=2 * POSES)
            self.assertTrue(t.spin_until(lambda: diagnostics.after(on_ns) is not None, HANG_S))
            c = counters(diagnostics.after(on_ns)[3])
            self.assertGreaterEqual(c["dropped"], 1, c)         # the inputs that came while inactive
            self.assertGreaterEqual(c["received"], c["solved"] + c["dropped"], c)

            self.assertIn("Transitioning successful", lifecycle("set", "shutdown"))
            self.assertIn("finalized", lifecycle("get"))


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_node_and_mock_exit_0(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info)

