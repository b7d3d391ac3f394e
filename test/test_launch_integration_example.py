# The example of README, "Testing your integration", as this repository runs it: the same file but
# for the first import (this repository's tests claim a ROS domain of their own; launch_support.py).
import unittest

import pytest

pytest.importorskip("launch_testing", reason="launch_testing is not importable (ROS 2 not sourced)")
# --- README example from here ---------------------------------------------------------------------
import launch_testing.actions
import launch_testing.asserts
import rclpy
from rclpy.executors import SingleThreadedExecutor

import launch_support  # noqa: F401 - this repository only: a claimed ROS domain, loopback discovery
from glpma_ros.testing import TrackingMonitor, fk_with_mock
from launch import LaunchDescription


@pytest.mark.launch_test
def generate_test_description():
    # the glpma_fk node (fk.launch.py, the 3-RPR's params file) and the mock publisher at 20 Hz
    return LaunchDescription([*fk_with_mock("3rpr", rate_hz=20.0), launch_testing.actions.ReadyToTest()])


class TestTracking(unittest.TestCase):
    def test_every_pose_is_on_the_truth(self):
        rclpy.init()
        node = rclpy.create_node("my_integration_test")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            monitor = TrackingMonitor(node, "planar_3rpr_seed")
            # 50 poses (the first start may compile the solvers: minutes; this only bounds a hang)
            self.assertTrue(monitor.spin_until(executor, poses=50, timeout_s=600.0))
            c = monitor.assert_tracking(min_poses=50)     # every pose within 1e-9 m / 1e-9 rad of the truth
            print(f"{len(c.index)} poses, worst position error {c.position_error_m.max():.2e} m")
        finally:
            executor.shutdown()
            node.destroy_node()
            rclpy.shutdown()


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_exit_codes(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info)       # the node and the mock exit 0
