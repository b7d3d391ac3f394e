"""The DDS transport's ``~/mechanism_joint_states`` (rt/glpma_fk/mechanism_joint_states), read over Cyclone DDS."""
import os
import time

import numpy as np
import pytest
import yaml

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")
yourdfpy = pytest.importorskip("yourdfpy")

from test_urdf import TOL, load, model_platform_m, trajectory, urdf_of  # noqa: E402

from conftest import CONFIG, GENEROUS_BUDGET_MS  # noqa: E402
from glpma_ros.config import load_manipulator, resolve_config  # noqa: E402
from glpma_ros.description.mechanism import Mechanism  # noqa: E402
from glpma_ros.models.rotations import matrix_from_quaternion  # noqa: E402
from glpma_ros.node.dds import endpoints  # noqa: E402
from glpma_ros.node.dds.messages import Float64MultiArray, JointState, PoseStamped  # noqa: E402
from test_dds_integration import start_node  # noqa: E402,F401 - fixture


def test_dds_node_publishes_every_joint_of_the_urdf(start_node, tmp_path):  # noqa: F811 - the fixture
    """The DDS transport: the hexapod's 36 joints beside each pose (same stamp), closing every leg on its
    platform joint through yourdfpy's transforms; with the second pose the twist gives the rates."""
    name = "hexapod_66_rolland"
    doc = yaml.safe_load((CONFIG / "params_hexapod.yaml").read_text())
    x0 = doc["glpma_fk"]["ros__parameters"]["initial_pose"]
    start_node("--params-file", str(CONFIG / "params_hexapod.yaml"), "-p", f"time_budget_ms:={GENEROUS_BUDGET_MS}",
               "-p", "publish_joint_states:=true")
    model = load_manipulator(resolve_config(name))
    robot = load(urdf_of(name, tmp_path))
    p = endpoints.Participant(int(os.environ["ROS_DOMAIN_ID"]))
    writer = p.writer("leg_lengths", Float64MultiArray)
    poses = p.reader("pose_estimate", PoseStamped, depth=10)
    joints = p.reader(endpoints.MECHANISM_JOINT_STATES, JointState, depth=10)
    assert endpoints.wait_for_match([writer, poses, joints], 60.0), "the node's endpoints were not discovered"
    got_poses, got_joints = [], []
    for k, x in enumerate(trajectory(model, x0)[:2]):
        writer.write(Float64MultiArray(data=list(model.inverse_kinematics(x) * 1e-3)))
        deadline = time.monotonic() + 60.0
        while len(got_joints) < k + 1 and time.monotonic() < deadline:
            got_poses += [s for s in poses.take(10) if isinstance(s, PoseStamped)]
            got_joints += [s for s in joints.take(10) if isinstance(s, JointState)]
            time.sleep(0.01)
    assert len(got_poses) == len(got_joints) == 2
    for pose, js in zip(got_poses, got_joints):
        assert js.header.stamp.to_ns() == pose.header.stamp.to_ns() and js.header.frame_id == "base"
        assert list(js.name) == list(Mechanism(model).joint_names) and len(js.name) == 36
        robot.update_cfg(dict(zip(js.name, js.position)))
        o = pose.pose.orientation
        R = matrix_from_quaternion([o.x, o.y, o.z, o.w])
        B = np.array([pose.pose.position.x, pose.pose.position.y, pose.pose.position.z]) + model_platform_m(model) @ R.T
        for i in range(6):
            assert np.abs(robot.get_transform(f"leg{i + 1}_end", "base_link")[:3, 3] - B[i]).max() < TOL
    assert len(got_joints[0].velocity) == 0 and len(got_joints[1].velocity) == 36   # a twist needs two poses
