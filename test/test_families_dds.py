"""An actuated family through the node: the DDS twin (real processes, the test's claimed domain) answers a
Delta's actuator angles on ``actuator_positions`` with the right poses, driven by the mock controller."""
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from conftest import CONFIG
from glpma_ros.config import load_manipulator
from test_dds_integration import check_tracking, run_mock, start_node  # noqa: F401 - start_node: a fixture

DELTA = CONFIG / "delta_irb360.yaml"


@pytest.mark.timing
def test_delta_node_tracks_the_mock_controller(start_node, dds_env, capsys):  # noqa: F811 - the fixture
    node = start_node("-p", f"manipulator_config:={DELTA}", "-p", "diagnostics_period_s:=0.2")
    summary = run_mock(dds_env, str(DELTA), 100, 3)
    check_tracking(summary, capsys, "delta 100 Hz")
    assert node.proc.poll() is None


def test_delta_node_answers_three_angles(start_node):  # noqa: F811 - the fixture
    """Three angles (radians) on actuator_positions -> the pose of the config's known solution (metres)."""
    from glpma_ros.node.dds import endpoints
    from glpma_ros.node.dds.messages import Float64MultiArray, PoseStamped
    model = load_manipulator(DELTA)
    start_node("-p", f"manipulator_config:={DELTA}")
    participant = endpoints.Participant()
    writer = participant.writer("actuator_positions", Float64MultiArray)
    poses = participant.reader("pose_estimate", PoseStamped, depth=10)
    assert endpoints.wait_for_match([writer, poses], 30), "no node found"
    time.sleep(0.3)
    writer.write(Float64MultiArray(data=[float(v) for v in model.example_actuator_positions]))
    got, deadline = [], time.monotonic() + 60
    while not got and time.monotonic() < deadline:
        got = [s for s in poses.take(10) if hasattr(s, "pose")]
        time.sleep(0.02)
    assert got, "no pose came back"
    p = got[0].pose.position
    # metres; the known solution is written to 1e-9 mm
    assert np.max(np.abs(np.array([p.x, p.y, p.z]) - model.known_solutions[0] * 1e-3)) < 1e-9


@pytest.mark.timing
def test_demo_drives_the_delta(tmp_path, dds_env, dds_domain):
    import json
    import subprocess
    import sys

    from conftest import ROOT
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "demo", "--duration", "2", "--out", str(tmp_path),
                        "--manipulator", "delta", "--domain-id", str(dds_domain)],
                       cwd=ROOT, env=dds_env, capture_output=True, text=True, timeout=400)
    assert p.returncode == 0, p.stdout + p.stderr
    s = json.loads((tmp_path / "demo_delta.json").read_text())
    assert s["ok"] and s["poses_wrong"] == 0 and s["poses_received"] >= 1
    assert s["tracking_error"]["position_m"]["max"] <= 1e-6


@pytest.mark.timing
def test_rus6_node_tracks_the_mock_controller(start_node, dds_env, capsys):  # noqa: F811 - the fixture
    """A 6-RUS started warm at its working mode (``initial_pose``) tracks the controller's cranks."""
    rus = CONFIG / "rus6_simulator.yaml"
    x0 = load_manipulator(rus).known_solutions[0]
    node = start_node("-p", f"manipulator_config:={rus}", "-p", "diagnostics_period_s:=0.2",
                      "-p", "initial_pose:=[" + ", ".join(repr(float(v)) for v in x0) + "]")
    summary = run_mock(dds_env, str(rus), 100, 3)
    check_tracking(summary, capsys, "6-RUS 100 Hz")
    assert node.proc.poll() is None


@pytest.mark.timing
def test_3rrr_node_tracks_the_mock_controller(start_node, dds_env, capsys):  # noqa: F811 - the fixture
    rrr = CONFIG / "planar_3rrr_symmetric.yaml"
    x0 = load_manipulator(rrr).known_solutions[0]
    node = start_node("-p", f"manipulator_config:={rrr}", "-p", "diagnostics_period_s:=0.2",
                      "-p", "initial_pose:=[" + ", ".join(repr(float(v)) for v in x0) + "]")
    summary = run_mock(dds_env, str(rrr), 100, 3)
    check_tracking(summary, capsys, "3-RRR 100 Hz")
    assert node.proc.poll() is None
