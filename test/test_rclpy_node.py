"""The rclpy transport (``ros2 run glpma_ros fk_node``): runs only where ROS 2 Jazzy is sourced."""
import math
import time

import pytest

rclpy = pytest.importorskip(
    "rclpy", reason="rclpy is not importable (ROS 2 Jazzy not sourced): the rclpy transport is tested only "
                    "where ROS 2 is installed; the same service is tested over Cyclone DDS in test_dds_integration")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from conftest import GENEROUS_BUDGET_MS, RPR_YAML  # noqa: E402

SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]


@pytest.fixture
def ros():
    rclpy.init()
    try:
        yield
    finally:
        rclpy.try_shutdown()


@pytest.fixture
def fk_node(ros):
    from glpma_ros.node.ros_node import FkNode
    node = FkNode(parameter_overrides=[Parameter("manipulator_config", value=str(RPR_YAML)),
                                       Parameter("initial_pose", value=SEED_X),
                                       Parameter("frame_id", value="robot_base"),
                                       Parameter("time_budget_ms", value=GENEROUS_BUDGET_MS)])
    try:
        yield node
    finally:
        node.destroy_node()


def test_parameters_are_declared_with_descriptions_and_ranges(fk_node):
    d = fk_node.describe_parameter("time_budget_ms")
    assert d.description and d.floating_point_range[0].to_value == 60000.0
    assert fk_node.describe_parameter("manipulator_config").read_only
    assert "glpma" in fk_node.describe_parameter("solver").additional_constraints
    assert list(fk_node.get_parameter("initial_pose").value) == pytest.approx(SEED_X)


def test_parameter_changes_go_through_the_service(fk_node):
    bad = fk_node.set_parameters([Parameter("solver", value="simplex")])[0]
    assert not bad.successful and "one of" in bad.reason
    assert fk_node.get_parameter("solver").value == "glpma"
    assert not fk_node.set_parameters([Parameter("qos_depth", value=3)])[0].successful
    good = fk_node.set_parameters([Parameter("solver", value="g3pcx")])[0]
    assert good.successful and fk_node.service.params["solver"] == "g3pcx"


def test_leg_lengths_in_pose_out(fk_node):
    client = rclpy.create_node("glpma_fk_test_client")
    poses = []
    pub = client.create_publisher(Float64MultiArray, "leg_lengths", 10)
    client.create_subscription(PoseStamped, "pose_estimate", poses.append, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(fk_node)
    executor.add_node(client)
    try:
        deadline = time.monotonic() + 120        # a bound for a hang, not a timing figure
        while not poses and time.monotonic() < deadline:
            pub.publish(Float64MultiArray(data=[0.100, 0.120, 0.150]))
            executor.spin_once(timeout_sec=0.1)
        assert poses, "no pose_estimate received"
        msg = poses[0]
        assert msg.header.frame_id == "robot_base"
        assert msg.pose.position.x == pytest.approx(SEED_X[0] / 1000, abs=1e-9)
        assert msg.pose.position.y == pytest.approx(SEED_X[1] / 1000, abs=1e-9)
        assert msg.pose.orientation.z == pytest.approx(math.sin(SEED_X[2] / 2), abs=1e-9)
    finally:
        executor.shutdown()
        client.destroy_node()
