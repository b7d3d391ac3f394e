"""An actuated family through the node: the DDS twin (real processes, the test's claimed domain) answers a
Delta's actuator angles on ``actuator_positions`` with the right poses, driven by the mock controller."""
import json
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from conftest import CONFIG, ROOT
from glpma_ros.config import load_manipulator
from glpma_ros.node.dds import endpoints
from glpma_ros.node.dds.messages import Float64MultiArray, PoseStamped
from test_dds_integration import check_tracking, run_mock, start_node  # noqa: F401 - start_node: a fixture

DELTA = CONFIG / "delta_irb360.yaml"
#: (config, label, started warm at its working mode): the Delta starts cold (its closed form), the others at
#: ``initial_pose`` = their first known solution
TRACKED = [("delta_irb360.yaml", "delta", False), ("rus6_simulator.yaml", "6-RUS", True),
           ("planar_3rrr_symmetric.yaml", "3-RRR", True)]


@pytest.mark.timing
@pytest.mark.parametrize("config, label, warm", TRACKED, ids=[label for _, label, _ in TRACKED])
def test_family_node_tracks_the_mock_controller(start_node, dds_env, capsys, config, label, warm):  # noqa: F811
    """The node (at 100 Hz from the mock controller) answers every input of the family with the right pose."""
    path = CONFIG / config
    warm_start = []
    if warm:
        x0 = load_manipulator(path).known_solutions[0]
        warm_start = ["-p", "initial_pose:=[" + ", ".join(repr(float(v)) for v in x0) + "]"]
    node = start_node("-p", f"manipulator_config:={path}", "-p", "diagnostics_period_s:=0.2", *warm_start)
    summary = run_mock(dds_env, str(path), 100, 3)
    check_tracking(summary, capsys, f"{label} 100 Hz")
    assert node.proc.poll() is None


def test_delta_node_answers_three_angles(start_node):  # noqa: F811 - the fixture
    """Three angles (radians) on actuator_positions -> the pose of the config's known solution (metres)."""
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
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "demo", "--duration", "2", "--out", str(tmp_path),
                        "--manipulator", "delta", "--domain-id", str(dds_domain)],
                       cwd=ROOT, env=dds_env, capture_output=True, text=True, timeout=400)
    assert p.returncode == 0, p.stdout + p.stderr
    s = json.loads((tmp_path / "demo_delta.json").read_text())
    assert s["ok"] and s["poses_wrong"] == 0 and s["poses_received"] >= 1
    assert s["tracking_error"]["position_m"]["max"] <= 1e-6
