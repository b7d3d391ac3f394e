"""Launch test (launch_testing, run by ``colcon test`` on a real ROS 2 Jazzy): ``fk.launch.py manipulator:=delta``
beside ``ros2 run glpma_ros mock_publisher`` driving the rotary Delta (three arm angles, radians, on
``actuator_positions``).  Every pose is on its input's true pose (1e-9 m), its orientation the identity (the
platform only translates), ``pose_estimate_cov`` carries the covariance of the arms' angle noise (x, y, z
block positive definite, rotation block zero) and ``twist_estimate`` comes with the poses; the node and the mock
exit 0 when the launch shuts down.  Skipped where launch_testing is not importable (no ROS 2 sourced)."""
import unittest

import numpy as np
import pytest

pytest.importorskip(
    "launch_testing", reason="launch_testing is not importable (ROS 2 Jazzy not sourced): the launch tests run "
                             "under colcon test on a real Jazzy; the node's logic is tested over Cyclone DDS")
import launch_testing.actions
import launch_testing.asserts

from glpma_ros.testing import TrackingMonitor, fk_with_mock
from launch import LaunchDescription
from launch_support import HANG_S, TestNode, params_file

#: inputs per second of the mock: well within what a busy 2-core machine answers
RATE_HZ = 20.0
#: poses checked against the truth (2.5 s of the loop at RATE_HZ)
POSES = 50
#: the published orientation is the identity written as doubles: exactly (0, 0, 0, 1)
IDENTITY = (0.0, 0.0, 0.0, 1.0)


@pytest.mark.launch_test
def generate_test_description():
    return LaunchDescription([
        *fk_with_mock("delta", rate_hz=RATE_HZ, params_file=params_file("delta", publish_covariance=True,
                                                                          publish_twist=True)),
        launch_testing.actions.ReadyToTest(),
    ])


class TestDeltaTracking(unittest.TestCase):
    def test_poses_covariance_and_twist(self):
        from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
        with TestNode() as t:
            monitor = TrackingMonitor(t.node, "delta", "float64_multi_array")
            covs, twists = [], []
            t.node.create_subscription(PoseWithCovarianceStamped, "pose_estimate_cov", covs.append, 100)
            t.node.create_subscription(TwistStamped, "twist_estimate", twists.append, 100)
            self.assertTrue(monitor.spin_until(t.executor, POSES, HANG_S), f"{len(monitor.poses)} poses came")
            c = monitor.assert_tracking(min_poses=POSES)
            for _, _, frame_id, _, q in c.poses[:POSES]:
                self.assertEqual(frame_id, "base")
                self.assertEqual(tuple(float(v) for v in q), IDENTITY)
            self.assertTrue(t.spin_until(lambda: len(covs) >= 2 and len(twists) >= 1, HANG_S))
            for msg in covs:
                cov = np.array(msg.pose.covariance).reshape(6, 6)
                self.assertTrue(np.all(np.linalg.eigvalsh(cov[:3, :3]) > 0.0))
                self.assertTrue(np.all(cov[3:, :] == 0.0) and np.all(cov[:, 3:] == 0.0))
            for msg in twists:
                w = msg.twist.angular
                self.assertEqual((w.x, w.y, w.z), (0.0, 0.0, 0.0))


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_node_and_mock_exit_0(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info)
