"""Launch test (launch_testing, on a real ROS 2 Jazzy with robot_state_publisher): ``fk.launch.py
robot_description:=true`` beside the mock publisher, for the 3-RPR and the hexapod.  A tf2 ``Buffer``
fed by robot_state_publisher (the URDF of ``glpma-fk urdf``, the node's ``~/mechanism_joint_states``)
gives ``base_link -> platform_link`` at each pose's stamp equal to the pose, every leg's end link at its
platform joint with the platform's orientation, its tube at its base joint pointing along the leg and
its rod at the leg length of the pose's inverse kinematics; the node's own ``/tf`` is off (one publisher
per transform).  Skipped where launch_testing or robot_state_publisher is not installed."""
import unittest

import numpy as np
import pytest

pytest.importorskip(
    "launch_testing", reason="launch_testing is not importable (ROS 2 Jazzy not sourced): the launch tests run "
                             "under colcon test on a real Jazzy")
from ament_index_python.packages import PackageNotFoundError, get_package_prefix

try:
    get_package_prefix("robot_state_publisher")
except PackageNotFoundError:
    pytest.skip("robot_state_publisher is not installed (ROS 2 Jazzy without it)", allow_module_level=True)

import launch_testing.actions
import launch_testing.asserts

from glpma_ros.config import load_manipulator, resolve_config
from glpma_ros.models.rotations import matrix_from_quaternion
from glpma_ros.testing import MANIPULATOR_CONFIGS, fk_with_mock
from launch import LaunchDescription
from launch_support import HANG_S, TestNode, params_file

#: inputs per second of the mock (a busy 2-core machine answers them all)
RATE_HZ = 20.0
#: poses whose transforms are checked
POSES = 20
#: robot_state_publisher composes each leg's transforms from the joint states (KDL, doubles) and tf2
#: returns them at the stamp they were published with: round-off of metre-size numbers, far below this
TOL = 1e-9


@launch_testing.parametrize("manipulator", ["3rpr", "hexapod"])
@pytest.mark.launch_test
def generate_test_description(manipulator):
    return LaunchDescription([
        # the mock starts once the node subscribes (no TrackingMonitor here: not waiting for one)
        *fk_with_mock(manipulator, rate_hz=RATE_HZ, params_file=params_file(manipulator),
                      mock_parameters={"wait_for_monitor": False}, launch_arguments={"robot_description": "true"}),
        launch_testing.actions.ReadyToTest(),
    ])


def _vector(t):
    return np.array([t.translation.x, t.translation.y, t.translation.z])


def _rotation(t):
    return matrix_from_quaternion([t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w])


class TestRobotDescription(unittest.TestCase):
    def test_every_link_is_where_the_pose_puts_it(self, manipulator):
        import tf2_ros
        from geometry_msgs.msg import PoseStamped
        from rclpy.time import Time
        model = load_manipulator(resolve_config(MANIPULATOR_CONFIGS[manipulator]))
        metres = model.metres_per_unit
        planar = model.platform.shape[1] == 2
        base_m = np.asarray(model.base, dtype=float) * metres
        platform_m = np.asarray(model.platform, dtype=float) * metres
        if planar:
            base_m, platform_m = (np.hstack((a, np.zeros((len(a), 1)))) for a in (base_m, platform_m))
        frames = ["platform_link", *(f"leg{i + 1}_{part}" for i in range(model.n_legs)
                                     for part in ("cylinder", "rod", "end"))]
        with TestNode() as t:
            poses = []
            t.node.create_subscription(PoseStamped, "pose_estimate", poses.append, 100)
            buffer = tf2_ros.Buffer()
            tf2_ros.TransformListener(buffer, t.node, spin_thread=False)
            self.assertTrue(t.spin_until(lambda: len(poses) >= POSES, HANG_S), f"{len(poses)} poses came")
            for msg in poses[:POSES]:
                self.assertEqual(msg.header.frame_id, "base_link")
                stamp = Time.from_msg(msg.header.stamp)
                p = np.array([msg.pose.position.x, msg.pose.position.y, msg.pose.position.z])
                o = msg.pose.orientation
                R = matrix_from_quaternion([o.x, o.y, o.z, o.w])
                B = p + platform_m @ R.T
                x = model.variables_from_pose(p / metres, [o.x, o.y, o.z, o.w])
                legs_m = model.inverse_kinematics(x) * metres
                self.assertTrue(t.spin_until(lambda stamp=stamp: all(buffer.can_transform("base_link", frame, stamp)
                                                                     for frame in frames), HANG_S))
                tf = buffer.lookup_transform("base_link", "platform_link", stamp).transform
                self.assertLess(np.abs(_vector(tf) - p).max(), TOL)
                self.assertLess(np.abs(_rotation(tf) - R).max(), TOL)
                for i in range(model.n_legs):
                    end = buffer.lookup_transform("base_link", f"leg{i + 1}_end", stamp).transform
                    self.assertLess(np.abs(_vector(end) - B[i]).max(), TOL, f"leg {i + 1}")
                    self.assertLess(np.abs(_rotation(end) - R).max(), TOL, f"leg {i + 1}")
                    tube = buffer.lookup_transform("base_link", f"leg{i + 1}_cylinder", stamp).transform
                    rod = buffer.lookup_transform("base_link", f"leg{i + 1}_rod", stamp).transform
                    self.assertLess(np.abs(_vector(tube) - base_m[i]).max(), TOL)
                    self.assertLess(np.abs(_vector(rod) - B[i]).max(), TOL)
                    along = _rotation(tube)[:, 0 if planar else 2]          # the actuator's axis
                    self.assertLess(np.abs(along * legs_m[i] - (B[i] - base_m[i])).max(), TOL)
            # the node's own /tf is off: its default frames are not in the tree
            self.assertNotIn("platform:", buffer.all_frames_as_yaml().replace("platform_link:", ""))


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_processes_exit_0(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info)
