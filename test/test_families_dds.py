"""The actuated families through the node: the DDS twin (real processes, the test's claimed domain) answers each
family's actuator positions on ``actuator_positions`` (radians; metres for rails) with the right poses, driven by
the mock controller and the demo."""
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from test_families_outputs import FAMILY_CONFIGS, LEG_NOISE_M, actuators_si, numeric_jacobian

from conftest import CONFIG
from glpma_ros.config import load_manipulator
from glpma_ros.node.params import DEFAULT_ANGLE_NOISE_RAD
from test_dds_integration import check_tracking, run_mock, start_node  # noqa: F401 - start_node: a fixture

DELTA = CONFIG / "delta_irb360.yaml"
#: each family's shipped config and whether the node starts cold (a translating family: the closed form's working
#: mode) or warm at the config's working mode (``initial_pose``: which mode a cold full-pose start takes is open)
FAMILIES = {"delta": ("delta_irb360", False), "linear_delta": ("linear_delta_kossel_mini", False),
            "rus_6": ("rus6_simulator", True), "pus_6": ("pus6_rail_hexapod", True),
            "planar_3rrr": ("planar_3rrr_symmetric", True), "planar_3prr": ("planar_3prr_triangle", True)}


def _node_args(family):
    path = CONFIG / f"{FAMILIES[family][0]}.yaml"
    args = ["-p", f"manipulator_config:={path}"]
    if FAMILIES[family][1]:
        x0 = load_manipulator(path).known_solutions[0]
        args += ["-p", "initial_pose:=[" + ", ".join(repr(float(v)) for v in x0) + "]"]
    return path, args


@pytest.mark.timing
@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_node_tracks_the_mock_controller(family, start_node, dds_env, capsys):  # noqa: F811 - the fixture
    path, args = _node_args(family)
    node = start_node(*args, "-p", "diagnostics_period_s:=0.2")
    summary = run_mock(dds_env, str(path), 100, 3)
    check_tracking(summary, capsys, f"{family} 100 Hz")
    assert node.proc.poll() is None


@pytest.mark.parametrize("family", ["delta", "linear_delta", "pus_6", "planar_3prr"])
def test_node_answers_actuator_positions(family, start_node):  # noqa: F811 - the fixture
    """The config's example reading in SI (radians; a rail's carriages in metres) on actuator_positions -> the
    pose of the config's known working mode (metres)."""
    from glpma_ros.node.dds import endpoints
    from glpma_ros.node.dds.messages import Float64MultiArray, PoseStamped
    path, args = _node_args(family)
    model = load_manipulator(path)
    start_node(*args)
    participant = endpoints.Participant()
    writer = participant.writer("actuator_positions", Float64MultiArray)
    poses = participant.reader("pose_estimate", PoseStamped, depth=10)
    assert endpoints.wait_for_match([writer, poses], 30), "no node found"
    time.sleep(0.3)
    writer.write(Float64MultiArray(data=[float(v) for v in model.readings_to_si(model.example_actuator_positions)]))
    got, deadline = [], time.monotonic() + 60
    while not got and time.monotonic() < deadline:
        got = [s for s in poses.take(10) if hasattr(s, "pose")]
        time.sleep(0.02)
    assert got, "no pose came back"
    p = got[0].pose.position
    # metres; the known solution is written to 1e-9 mm (its platform origin: the pose of the solver variables)
    expected = model.pose(model.known_solutions[0]).position * model.metres_per_unit
    assert np.max(np.abs(np.array([p.x, p.y, p.z]) - expected)) < 1e-9


@pytest.mark.timing
@pytest.mark.parametrize("family, label", [("delta", "delta"), ("linear_delta", "linear_delta_kossel_mini"),
                                           ("pus_6", "pus6_rail_hexapod"), ("planar_3prr", "planar_3prr_triangle")])
def test_demo_drives_the_family(family, label, tmp_path, dds_env, dds_domain):
    import json
    import subprocess
    import sys

    from conftest import ROOT
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "demo", "--duration", "2", "--out", str(tmp_path),
                        "--manipulator", family, "--domain-id", str(dds_domain)],
                       cwd=ROOT, env=dds_env, capture_output=True, text=True, timeout=400)
    assert p.returncode == 0, p.stdout + p.stderr
    s = json.loads((tmp_path / f"demo_{label}.json").read_text())
    assert s["ok"] and s["poses_wrong"] == 0 and s["poses_received"] >= 1
    assert s["tracking_error"]["position_m"]["max"] <= 1e-6


@pytest.mark.parametrize("config", FAMILY_CONFIGS)
def test_covariance_and_twist_topics_of_every_family(start_node, config):  # noqa: F811 - the fixture
    """A JointState of the actuators' positions (rad) and velocities (rad/s) -> pose_estimate_cov with the covariance
    of the actuators' noise and twist_estimate from the joint velocities, the in-process model's at the pose."""
    from glpma_ros.estimation.covariance import PoseJacobian
    from glpma_ros.node.dds import endpoints
    from glpma_ros.node.dds.messages import JointState, PoseWithCovarianceStamped, TwistStamped
    path = CONFIG / config
    model = load_manipulator(path)
    x = np.array(model.known_solutions[0])
    names = [f"act_{i + 1}" for i in range(model.n_legs)]
    start_node("-p", f"manipulator_config:={path}", "-p", "input_type:=joint_state",
               "-p", "joint_names:=[" + ", ".join(names) + "]", "-p", f"leg_noise_std:={LEG_NOISE_M!r}",
               "-p", f"actuator_noise_std:={DEFAULT_ANGLE_NOISE_RAD!r}",
               "-p", "initial_pose:=[" + ", ".join(repr(float(v)) for v in x) + "]")
    jac = PoseJacobian(model)
    J = numeric_jacobian(model, x, jac.columns)
    true_twist = np.zeros(6)
    true_twist[jac.columns] = np.random.default_rng(7).normal(scale=0.05, size=jac.columns.size)
    participant = endpoints.Participant()
    writer = participant.writer("joint_states", JointState)
    covs = participant.reader("pose_estimate_cov", PoseWithCovarianceStamped, depth=10)
    twists = participant.reader("twist_estimate", TwistStamped, depth=10)
    assert endpoints.wait_for_match([writer, covs, twists], 30), "no node found"
    time.sleep(0.3)
    writer.write(JointState(name=names, position=actuators_si(model, x).tolist(), velocity=(J @ true_twist).tolist()))
    got = {"cov": [], "twist": []}
    deadline = time.monotonic() + 60
    while not (got["cov"] and got["twist"]) and time.monotonic() < deadline:
        got["cov"] += [s for s in covs.take(10) if hasattr(s, "pose")]
        got["twist"] += [s for s in twists.take(10) if hasattr(s, "twist")]
        time.sleep(0.02)
    assert got["cov"] and got["twist"], f"no covariance / twist came back: {got}"
    pose = model.pose(x)
    jac.solve(np.asarray(pose.position), np.asarray(pose.orientation), LEG_NOISE_M, None, model.metres_per_unit,
              model.inverse_kinematics(x), DEFAULT_ANGLE_NOISE_RAD)
    cov = np.array(got["cov"][0].pose.covariance).reshape(6, 6)
    # the published pose is the solve's (round-off) and the covariance is smooth in it
    assert np.allclose(cov, jac.covariance, rtol=1e-6,
                       atol=1e-6 * np.abs(jac.covariance[np.ix_(jac.columns, jac.columns)]).max())
    t = got["twist"][0].twist
    twist = np.array([t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z])
    assert np.allclose(twist, true_twist, rtol=0, atol=1e-5 * np.abs(true_twist).max())   # FD Jacobian error
