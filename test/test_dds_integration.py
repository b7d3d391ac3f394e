"""The node over real Cyclone DDS on loopback: real processes, a private ROS_DOMAIN_ID per test.

* node + mock controller: 3-RPR at 200 Hz for 5 s, hexapod at 100 Hz for 3 s;
* a sequence of bad inputs: the node keeps running, poses resume, rejections on /diagnostics;
  then a runtime solver switch through a params-file reload (SIGHUP);
* a minimal DDS participant written only against doc/interface.md sees the poses.
"""
import json
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float64, int32, sequence, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from conftest import CONFIG, GENEROUS_BUDGET_MS, ROOT, RPR_YAML, interrupt

READY_TIMEOUT_S = 600.0        # a first run compiles the solvers (Numba): minutes on a busy machine
SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]


@dataclass
class NodeProcess:
    proc: subprocess.Popen
    stdout: Path
    stderr: Path

    def output(self) -> str:
        return f"stdout:\n{self.stdout.read_text()}\nstderr:\n{self.stderr.read_text()}"

    def wait_ready(self, timeout=READY_TIMEOUT_S):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if "ready" in self.stdout.read_text():
                return
            if self.proc.poll() is not None:
                pytest.fail(f"node exited with {self.proc.returncode} before it was ready\n{self.output()}")
            time.sleep(0.05)
        pytest.fail(f"node not ready within {timeout} s\n{self.output()}")

    def stop(self):
        if self.proc.poll() is None:
            interrupt(self.proc, timeout=10)


@pytest.fixture
def start_node(dds_env, tmp_path):
    nodes = []

    def start(*ros_args):
        n = len(nodes)
        out, err = tmp_path / f"node{n}.out", tmp_path / f"node{n}.err"
        with open(out, "w") as fo, open(err, "w") as fe:
            proc = subprocess.Popen([sys.executable, "-m", "glpma_ros.node.dds.node", "--ros-args", *ros_args],
                                    stdout=fo, stderr=fe, env=dds_env, cwd=ROOT)
        node = NodeProcess(proc, out, err)
        nodes.append(node)
        node.wait_ready()
        return node

    try:
        yield start
    finally:
        for node in nodes:
            node.stop()


#: seconds a subprocess of a test may take before it counts as hung (a cold Numba cache on a busy
#: machine takes minutes; this bounds a hang, it is not a timing figure)
SUBPROCESS_TIMEOUT_S = 600


def run_mock(env, config, rate, duration):
    result = subprocess.run([sys.executable, "-m", "glpma_tools.mock_controller", "--config", config,
                             "--rate", str(rate), "--duration", str(duration), "--json", "--timeout", "60"],
                            env=env, cwd=ROOT, capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT_S)
    assert result.returncode == 0, result.stdout + result.stderr
    return json.loads(result.stdout)


def check_tracking(summary, capsys, label):
    """What holds on any machine: every pose that came back is right (paired with the input it
    answers), the node's counters add up; the share answered and the latency are printed only
    (a busy machine answers fewer inputs: the node drops old ones rather than queueing them)."""
    lat, err = summary["latency_ms"], summary["tracking_error"]
    with capsys.disabled():
        print(f"\n[{label}] {summary['inputs_sent']} inputs, {summary['poses_matched']} poses "
              f"({100 * summary['pose_ratio']:.1f} %), latency p50 {lat['p50']} ms, p99 {lat['p99']} ms, "
              f"max {lat['max']} ms; error max {err['position_m']['max']} m, {err['orientation_rad']['max']} rad; "
              f"node {summary['node_counters']}; load average {summary['load_average']}")
    assert summary["poses_received"] >= 1, "no pose came back"
    assert summary["poses_wrong"] == 0 and summary["poses_received"] == summary["poses_matched"]
    assert err["position_m"]["max"] <= 1e-6
    assert err["orientation_rad"]["max"] <= 1e-6
    assert summary["frame_ids"] == ["base"]
    counts = summary["node_counters"]
    assert counts is not None, "the node's /diagnostics never reported it idle after the last input"
    # nothing lost inside the node: every input it received was solved, rejected or dropped (replaced
    # by a newer one), a pose went out per solved input (DDS may overwrite some on the way back)
    assert counts["received"] == counts["solved"] + counts["rejected"] + counts["dropped"], counts
    assert counts["received"] <= summary["inputs_sent"] and summary["poses_received"] <= counts["solved"], counts


@pytest.mark.timing
def test_3rpr_at_200hz_with_mock_controller(start_node, dds_env, capsys):
    node = start_node("--params-file", str(CONFIG / "params_3rpr.yaml"), "-p", "diagnostics_period_s:=0.2")
    summary = run_mock(dds_env, "planar_3rpr_seed", 200, 5)
    assert summary["inputs_sent"] == 1000
    check_tracking(summary, capsys, "3-RPR 200 Hz")
    assert node.proc.poll() is None


@pytest.mark.timing
def test_hexapod_at_100hz_with_mock_controller(start_node, dds_env, capsys):
    node = start_node("--params-file", str(CONFIG / "params_hexapod.yaml"), "-p", "diagnostics_period_s:=0.2",
                      "--log-level", "info")
    summary = run_mock(dds_env, "hexapod_66_rolland", 100, 3)
    check_tracking(summary, capsys, "hexapod 100 Hz")
    assert node.proc.poll() is None


# -- bad inputs and runtime changes (uses the project's DDS types) ------------------------------------

class DiagnosticsWatcher:
    """For a test client with a ``/diagnostics`` reader ``self.diag`` and a
    ``self.last_diagnostics`` dict."""

    def diagnostics_until(self, predicate, timeout=60.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for sample in self.diag.take(100):
                if getattr(sample, "status", None):
                    self.last_diagnostics = {kv.key: kv.value for kv in sample.status[0].values}
            if self.last_diagnostics and predicate(self.last_diagnostics):
                return self.last_diagnostics
            time.sleep(0.05)
        pytest.fail(f"diagnostics never satisfied the check; last: {self.last_diagnostics}")


class Client(DiagnosticsWatcher):
    """Publishes leg lengths, collects poses and diagnostics."""

    def __init__(self):
        from glpma_ros.node.dds import endpoints
        from glpma_ros.node.dds.messages import DiagnosticArray, Float64MultiArray, PoseStamped
        self.Float64MultiArray = Float64MultiArray
        self.participant = endpoints.Participant()
        self.writer = self.participant.writer("leg_lengths", Float64MultiArray)
        self.poses = self.participant.reader("pose_estimate", PoseStamped, depth=100)
        self.diag = self.participant.reader("/diagnostics", DiagnosticArray, depth=100)
        assert endpoints.wait_for_match([self.writer, self.poses, self.diag], 30), "no node found"
        time.sleep(0.3)
        self.last_diagnostics = {}
        self.sent = 0

    def send(self, legs):
        """Send one input and wait until the node has taken it (its /diagnostics count it): the next
        input cannot replace it in the node's one-slot mailbox, however busy the machine."""
        self.sent += 1
        self.writer.write(self.Float64MultiArray(data=[float(v) for v in legs]))
        self.diagnostics_until(lambda d: int(d["inputs received"]) >= self.sent)

    def take_poses(self, expected, timeout=60.0):
        """Poses until ``expected`` of them arrived (or the timeout)."""
        poses, deadline = [], time.monotonic() + timeout
        while len(poses) < expected and time.monotonic() < deadline:
            poses += [s for s in self.poses.take(100) if hasattr(s, "pose")]
            time.sleep(0.01)
        time.sleep(0.1)
        return poses + [s for s in self.poses.take(100) if hasattr(s, "pose")]



def test_bad_inputs_are_rejected_and_the_node_keeps_tracking(start_node, tmp_path):
    doc = yaml.safe_load(RPR_YAML.read_text())
    doc["leg_limits"] = [50.0, 250.0]
    config = tmp_path / "rpr_limits.yaml"
    config.write_text(yaml.safe_dump(doc))
    params = tmp_path / "params.yaml"

    def write_params(solver):
        params.write_text(yaml.safe_dump({"glpma_fk": {"ros__parameters": {
            "manipulator_config": str(config), "initial_pose": SEED_X, "solver": solver,
            "time_budget_ms": GENEROUS_BUDGET_MS,   # robustness, not timing: the same on a busy machine
            "diagnostics_period_s": 0.05}}}))

    write_params("glpma")
    node = start_node("--params-file", str(params))
    client = Client()
    trajectory = [[0.1, 0.12, 0.15 + k * 2e-5] for k in range(40)]

    for legs in trajectory[:5]:
        client.send(legs)
    bad = [[0.1, 0.12], [0.1, 0.12, 0.15, 0.2], [0.1, float("nan"), 0.15], [float("inf"), 0.12, 0.15],
           [0.1, -0.12, 0.15], [0.1, 0.0, 0.15], [0.1, 0.12, 0.30], [0.06, 0.06, 0.06], []]
    for legs in bad:
        client.send(legs)
    for legs in trajectory[5:10]:
        client.send(legs)

    diag = client.diagnostics_until(lambda d: d["inputs received"] == "19" and d["inputs solved"] == "10")
    assert node.proc.poll() is None, node.output()
    poses = client.take_poses(10)
    assert len(poses) == 10, f"{len(poses)} poses"
    assert diag["inputs rejected"] == str(len(bad)) and diag["inputs dropped"] == "0"
    reasons = {k[len("rejected: "):]: int(v) for k, v in diag.items() if k.startswith("rejected: ")}
    assert reasons["no_solution"] == 1
    assert reasons["leg lengths must be finite (got NaN or inf)"] == 2
    assert reasons["leg lengths must be positive"] == 2
    assert any("limits" in r for r in reasons)
    assert sum(n for r, n in reasons.items() if r.startswith("expected 3 leg lengths")) == 3
    last = poses[-1].pose.position
    assert abs(last.x - SEED_X[0] / 1000) < 1e-3 and abs(last.y - SEED_X[1] / 1000) < 1e-3
    assert "input rejected" in node.stderr.read_text()

    # switch the solver at runtime: edit the params file, SIGHUP; tracking goes on warm
    write_params("g3pcx")
    node.proc.send_signal(signal.SIGHUP)
    client.diagnostics_until(lambda d: d["solver"] == "g3pcx")
    for legs in trajectory[10:20]:
        client.send(legs)
    diag = client.diagnostics_until(lambda d: d["inputs solved"] == "20")
    assert diag["last start"] == "warm"
    assert len(client.take_poses(10)) == 10
    # an invalid value in the file is rejected and the old value kept
    params.write_text(params.read_text().replace("solver: g3pcx", "solver: simplex"))
    node.proc.send_signal(signal.SIGHUP)
    client.diagnostics_until(lambda d: "parameter reload failed" in node.stderr.read_text())
    client.send(trajectory[20])
    diag = client.diagnostics_until(lambda d: d["inputs solved"] == "21")
    assert diag["solver"] == "g3pcx"
    assert "parameter reload failed" in node.stderr.read_text()
    assert node.proc.poll() is None


# -- an independent participant, written only against doc/interface.md ------------------------------
# The ROS 2 Jazzy types as rmw_cyclonedds_cpp names them, defined here without any glpma_ros import.

@dataclass
class MultiArrayDimension(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayDimension_"):
    label: str = ""
    size: uint32 = 0
    stride: uint32 = 0


@dataclass
class MultiArrayLayout(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayLayout_"):
    dim: sequence[MultiArrayDimension] = field(default_factory=list)
    data_offset: uint32 = 0


@dataclass
class Float64MultiArray(IdlStruct, typename="std_msgs::msg::dds_::Float64MultiArray_"):
    layout: MultiArrayLayout = field(default_factory=MultiArrayLayout)
    data: sequence[float64] = field(default_factory=list)


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


def test_independent_contract_participant_sees_the_poses(start_node):
    """No glpma_ros import: the types, topic names, QoS and USER_DATA come from the contract."""
    # a generous budget: this test is about the interface, not timing
    start_node("--params-file", str(CONFIG / "params_3rpr.yaml"), "-p", "frame_id:=robot_base",
               "-p", f"time_budget_ms:={GENEROUS_BUDGET_MS}")
    dp = DomainParticipant(int(os.environ["ROS_DOMAIN_ID"]))

    def qos(type_hash):
        return Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10),
                   Policy.Durability.Volatile, Policy.Userdata(f"typehash={type_hash};".encode()))

    writer = DataWriter(dp, Topic(dp, "rt/leg_lengths", Float64MultiArray), qos(
        "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f"))
    reader = DataReader(dp, Topic(dp, "rt/pose_estimate", PoseStamped), qos(
        "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"))
    deadline = time.monotonic() + 60
    while not (writer.get_matched_subscriptions() and reader.get_matched_publications()):
        assert time.monotonic() < deadline, "the node's endpoints were not discovered"
        time.sleep(0.05)
    time.sleep(0.3)
    # the node's endpoints carry the same USER_DATA
    peer = reader.get_matched_publication_data(reader.get_matched_publications()[0])
    assert peer.qos[Policy.Userdata].data == \
        b"typehash=RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8;"

    t_send = time.time()
    writer.write(Float64MultiArray(data=[0.100, 0.120, 0.150]))   # metres
    samples, deadline = [], time.monotonic() + 60
    while not samples and time.monotonic() < deadline:
        samples = reader.take(10)
        time.sleep(0.01)
    assert len(samples) == 1
    msg = samples[0]
    assert msg.header.frame_id == "robot_base"
    stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    assert t_send - 1 < stamp < time.time() + 1
    p, q = msg.pose.position, msg.pose.orientation
    np.testing.assert_allclose([p.x, p.y, p.z], [SEED_X[0] / 1000, SEED_X[1] / 1000, 0.0], atol=1e-9)
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], [0, 0, math.sin(SEED_X[2] / 2), math.cos(SEED_X[2] / 2)],
                               atol=1e-9)
