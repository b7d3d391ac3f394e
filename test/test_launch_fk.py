"""Launch test (launch_testing, run by ``colcon test`` on a real ROS 2 Jazzy): ``fk.launch.py`` for the
3-RPR (``leg_lengths`` input), for the hexapod (``joint_states`` input) and for the 3-RPR's managed
node (``managed:=true autostart:=true``) beside ``ros2 run glpma_ros mock_publisher``.  Every pose is on its input's
true pose (1e-9 m, 1e-9 rad),
``/tf`` resolves through a tf2 ``Buffer`` at the poses' stamps, ``/diagnostics`` reports OK, and the
node and the mock exit 0 when the launch shuts down.  Skipped where launch_testing is not importable
(no ROS 2 sourced)."""
import math
import unittest

import pytest

pytest.importorskip(
    "launch_testing", reason="launch_testing is not importable (ROS 2 Jazzy not sourced): the launch tests run "
                             "under colcon test on a real Jazzy; the node's logic is tested over Cyclone DDS")
import launch_testing.actions
import launch_testing.asserts

from glpma_ros.testing import MANIPULATOR_CONFIGS, TrackingMonitor, fk_with_mock
from launch import LaunchDescription
from launch_support import HANG_S, Diagnostics, TestNode, params_file

#: inputs per second of the mock: well within what a busy 2-core machine answers
RATE_HZ = 20.0
#: poses checked against the truth per manipulator (5 s of the loop at RATE_HZ)
POSES = 100
#: /tf at a pose's stamp is that pose: the buffer stores the transform's doubles and a lookup at a
#: stored stamp interpolates with weight 0 (round-off of unit-size numbers at most)
TF_TOL = 1e-12
#: (manipulator, input, managed:=true autostart:=true): both kinds, both inputs, and the managed node
#: brought up by the launch file itself
CASES = [("3rpr", "float64_multi_array", False), ("hexapod", "joint_state", False), ("3rpr", "joint_state", True)]


@launch_testing.parametrize("manipulator, input_type, managed", CASES)
@pytest.mark.launch_test
def generate_test_description(manipulator, input_type, managed):
    return LaunchDescription([
        *fk_with_mock(manipulator, input_type=input_type, managed=managed, autostart=managed, rate_hz=RATE_HZ,
                      params_file=params_file(manipulator)),
        launch_testing.actions.ReadyToTest(),
    ])


class TestTracking(unittest.TestCase):
    def test_poses_tf_and_diagnostics(self, manipulator, input_type, managed):
        import tf2_ros
        from rclpy.time import Time
        with TestNode() as t:
            monitor = TrackingMonitor(t.node, MANIPULATOR_CONFIGS[manipulator], input_type)
            buffer = tf2_ros.Buffer()
            tf2_ros.TransformListener(buffer, t.node, spin_thread=False)
            diagnostics = Diagnostics(t.node)
            self.assertTrue(monitor.spin_until(t.executor, POSES, HANG_S), f"{len(monitor.poses)} poses came")
            c = monitor.assert_tracking(min_poses=POSES)
            first_stamp = c.poses[0][1]
            for _, stamp_ns, frame_id, position, q in c.poses[:POSES]:
                self.assertEqual(frame_id, "base")
                stamp = Time(nanoseconds=stamp_ns)
                self.assertTrue(t.spin_until(lambda stamp=stamp: buffer.can_transform("base", "platform", stamp),
                                             HANG_S))
                tf = buffer.lookup_transform("base", "platform", stamp).transform
                got = (tf.translation.x, tf.translation.y, tf.translation.z,
                       tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w)
                self.assertLessEqual(max(abs(a - b) for a, b in zip(got, (*position, *q))), TF_TOL)
            # a report after the poses began, without problems (a period with a dropped input on a
            # busy machine is a warning: a later one is OK)
            self.assertTrue(t.spin_until(lambda: any(r[0] > first_stamp and r[1] == 0 and r[2] == "tracking"
                                                     for r in diagnostics.reports), HANG_S),
                            diagnostics.reports[-3:])
            ok = next(r for r in diagnostics.reports if r[0] > first_stamp and r[1] == 0)
            values = ok[3]
            self.assertGreaterEqual(int(values["inputs solved"]), 1)
            self.assertEqual(int(values["inputs rejected"]), 0)
            self.assertTrue(math.isfinite(float(values["residual RMS max (m)"])))


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_node_and_mock_exit_0(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info)
