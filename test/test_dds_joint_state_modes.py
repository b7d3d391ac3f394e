"""JointState input and the assembly-modes request, over real Cyclone DDS with real node processes.

* 3-RPR node with ``input_type:=joint_state`` and its own joint names: shuffled joint order and
  extra joints give the poses the array input gives, stamped with the JointState's own stamp;
  a missing joint and a name/position length mismatch are rejected with their reason on
  /diagnostics; ``~/request_assembly_modes`` answers on ``~/assembly_modes`` with the 2 real modes
  of the example legs; the mock controller streams JointState at 200 Hz.
* hexapod node: a 100 Hz JointState stream of the 1250 mm legs, with the end-to-end pose latency
  (JointState stamp -> pose received) measured before and while the 16 assembly modes are
  computed, request after request; a late subscriber gets the latched answer.
"""
import math
import time

import numpy as np
import pytest
import yaml

from glpma_ros.config import load_manipulator

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from conftest import CONFIG, GENEROUS_BUDGET_MS, HEX_YAML, RPR_YAML
from test_dds_integration import SEED_X, DiagnosticsWatcher, check_tracking, start_node  # noqa: F401 - fixture

RPR_NAMES = ["rpr_a1", "rpr_a2", "rpr_a3"]
OTHER_JOINTS = [("gripper", 0.03), ("camera_tilt", -0.4), ("conveyor", 12.5)]


class Client(DiagnosticsWatcher):
    """JointState in; poses, diagnostics and assembly modes out; requests."""

    def __init__(self, node_name="glpma_fk"):
        from glpma_ros.node.dds import endpoints
        from glpma_ros.node.dds.messages import DiagnosticArray, Empty, JointState, PoseArray, PoseStamped
        self.types = {"JointState": JointState, "Empty": Empty, "PoseArray": PoseArray}
        self.endpoints = endpoints
        self.participant = endpoints.Participant()
        self.writer = self.participant.writer("joint_states", JointState)
        self.request_writer = self.participant.writer(f"{node_name}/request_assembly_modes", Empty)
        self.poses = self.participant.reader("pose_estimate", PoseStamped, depth=1000)
        self.diag = self.participant.reader("/diagnostics", DiagnosticArray, depth=100)
        self.modes = self.participant.reader(f"{node_name}/assembly_modes", PoseArray, depth=1, transient_local=True)
        assert endpoints.wait_for_match([self.writer, self.request_writer, self.poses, self.diag, self.modes], 30), \
            "the node's endpoints were not discovered"
        time.sleep(0.3)
        self.last_diagnostics = {}
        self.sent = 0

    def send(self, names, positions, stamp_ns, wait=True):
        """Send one JointState; with ``wait``, until the node has taken it (its /diagnostics count
        it): the next input cannot replace it in the node's one-slot mailbox, however busy the machine."""
        from glpma_ros.node.dds.messages import Header, Time
        self.sent += 1
        self.writer.write(self.types["JointState"](header=Header(stamp=Time.from_ns(stamp_ns)), name=list(names),
                                                   position=[float(v) for v in positions]))
        if wait:
            self.diagnostics_until(lambda d: int(d["inputs received"]) >= self.sent)

    def request_modes(self):
        self.request_writer.write(self.types["Empty"]())

    def take_poses(self, expected, timeout=60.0):
        poses, deadline = [], time.monotonic() + timeout
        while len(poses) < expected and time.monotonic() < deadline:
            poses += [s for s in self.poses.take(100) if hasattr(s, "pose")]
            time.sleep(0.01)
        return poses

    def take_modes(self, timeout=120.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            got = [s for s in self.modes.take(10) if hasattr(s, "poses")]
            if got:
                return got[-1]
            time.sleep(0.005)
        pytest.fail("no PoseArray on ~/assembly_modes")


def shuffled(names, legs_m, rng):
    """The legs among other joints, in a random order."""
    joints = list(zip(names, legs_m)) + OTHER_JOINTS
    order = rng.permutation(len(joints))
    return [joints[k][0] for k in order], [joints[k][1] for k in order]


def pose_tuple(msg):
    p, q = msg.pose.position, msg.pose.orientation
    return np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])


def test_3rpr_joint_state_input_rejections_and_assembly_modes(start_node, dds_env, tmp_path, capsys):
    from glpma_ros.node.service import FkService
    from glpma_tools.mock_controller import run
    params = {"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X, "input_type": "joint_state",
              "joint_names": RPR_NAMES, "time_budget_ms": GENEROUS_BUDGET_MS, "diagnostics_period_s": 0.05}
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump({"glpma_fk": {"ros__parameters": params}}))
    node = start_node("--params-file", str(path))
    client = Client()

    # a request before any input fails with its reason
    client.request_modes()
    client.diagnostics_until(lambda d: d["assembly modes failed"] == "1")
    assert client.last_diagnostics["assembly modes last failure"] == "no input received yet on joint_states"
    assert client.last_diagnostics["input"] == "joint_states (rpr_a1, rpr_a2, rpr_a3)"

    # shuffled order + extra joints: the poses the array input gives (same service, same start)
    reference = FkService(dict(params, input_type="float64_multi_array"))
    reference.warm_up(solvers=("glpma",))
    rng = np.random.default_rng(7)
    trajectory = [[0.100, 0.120, 0.150 + k * 2e-5] for k in range(6)]
    stamps = [1_700_000_000_000_000_000 + 1_000_000 * k for k in range(len(trajectory))]   # not the clock
    for legs, stamp in zip(trajectory, stamps):
        client.send(*shuffled(RPR_NAMES, legs, rng), stamp)
    poses = client.take_poses(len(trajectory))
    assert [p.header.stamp.to_ns() for p in poses] == stamps          # the JointState's own stamp
    for legs, msg in zip(trajectory, poses):
        expected = reference.handle(legs, 0).pose
        position, quaternion = pose_tuple(msg)
        np.testing.assert_allclose(position, expected.position, atol=1e-9)
        np.testing.assert_allclose(quaternion, expected.orientation, atol=1e-9)
        assert msg.header.frame_id == "base"

    # a missing leg, a name/position mismatch: rejected, the reason on /diagnostics, tracking goes on
    client.send(["rpr_a1", "gripper", "rpr_a3"], [0.1, 0.03, 0.15], stamps[-1] + 10)
    client.send(["rpr_a3", "rpr_a2", "rpr_a1", "gripper"], [0.15, 0.12, 0.1], stamps[-1] + 20)
    client.send(*shuffled(RPR_NAMES, [0.100, 0.120, 0.150], rng), stamps[-1] + 30)
    diag = client.diagnostics_until(lambda d: d["inputs received"] == str(len(trajectory) + 3))
    assert diag["rejected: joint_states has no joint 'rpr_a2'"] == "1"
    assert diag["rejected: joint_states has 4 names but 3 positions"] == "1"
    assert diag["inputs rejected"] == "2"
    last = client.take_poses(1)
    assert len(last) == 1 and last[0].header.stamp.to_ns() == stamps[-1] + 30
    assert node.proc.poll() is None, node.output()

    # every real assembly mode of the last input (100, 120, 150 mm): the 2 of 001 Table 1, in metres
    t_request = time.time_ns()
    client.request_modes()
    modes = client.take_modes()
    assert len(modes.poses) == 2
    assert modes.header.frame_id == "base"
    assert t_request - 1e9 < modes.header.stamp.to_ns() < time.time_ns()
    doc = yaml.safe_load(RPR_YAML.read_text())
    got = sorted((p.position.x, p.position.y) for p in modes.poses)
    want = sorted((s["x"] / 1000, s["y"] / 1000) for s in doc["real_solutions"])
    np.testing.assert_allclose(got, want, atol=1e-9)
    for p in modes.poses:
        q = p.orientation
        assert p.position.z == 0.0 and abs(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w - 1) < 1e-12
    client.diagnostics_until(lambda d: d["assembly modes published"] == "1")

    # the mock controller's JointState stream (shuffled, extra joints) is tracked
    summary = run("planar_3rpr_seed", 200, 1.5, input_type="joint_state", joint_names=RPR_NAMES,
                  connect_timeout_s=60)
    check_tracking(summary, capsys, "3-RPR JointState 200 Hz")
    assert node.proc.poll() is None, node.output()


def _latency_stats(ms):
    if not ms:
        return math.nan, math.nan, math.nan
    arr = np.asarray(ms, dtype=float)
    return float(np.percentile(arr, 50)), float(np.percentile(arr, 99)), float(arr.max())


@pytest.mark.timing
def test_hexapod_assembly_modes_while_streaming(start_node, dds_env, capsys):
    import threading

    from glpma_tools.sim.controller import PoseListener
    node = start_node("--params-file", str(CONFIG / "params_hexapod.yaml"), "-p", "input_type:=joint_state",
                      "-p", "diagnostics_period_s:=0.2", "-p", f"time_budget_ms:={GENEROUS_BUDGET_MS}")
    client = Client()
    listener = PoseListener(client.participant, 1000)   # a second reader of pose_estimate, on its own thread
    names = [f"leg_{i + 1}" for i in range(6)]
    legs_m = [1.25] * 6                                  # 1250 mm, the 16-mode example of 002
    rng = np.random.default_rng(3)
    stop = threading.Event()
    sent = []

    def stream(rate_hz=100.0):
        t0, k = time.perf_counter(), 0
        while not stop.is_set():
            delay = t0 + k / rate_hz - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            stamp = time.time_ns()
            client.send(*shuffled(names, legs_m, rng), stamp, wait=False)
            sent.append(stamp)
            k += 1

    streamer = threading.Thread(target=stream, daemon=True)
    streamer.start()
    try:
        time.sleep(2.0)                                  # before: the stream alone
        t_before = time.time_ns()
        windows = []
        # during: requests one after the other, until 1.5 s of computing (at most 10 requests)
        while len(windows) < 10 and sum(b - a for a, b in windows) < 1.5e9:
            t_req = time.time_ns()
            client.request_modes()
            modes = client.take_modes()
            windows.append((t_req, time.time_ns()))
            assert len(modes.poses) == 16
            assert modes.header.frame_id == "base"
        time.sleep(0.3)
    finally:
        stop.set()
        streamer.join(2)
    time.sleep(0.3)
    listener.close()

    # every pose is right: it reproduces the 1250 mm legs (a pose per JointState stamp, none invented)
    model = load_manipulator(HEX_YAML)
    for _, _, _, position, quaternion in listener.poses:
        x = model.variables_from_pose(position / model.metres_per_unit, quaternion)
        np.testing.assert_allclose(model.inverse_kinematics(x) * model.metres_per_unit, legs_m, atol=1e-6)
    assert {stamp for _, stamp, *_ in listener.poses} <= set(sent)
    latency = {stamp: (recv - stamp) * 1e-6 for recv, stamp, *_ in listener.poses}
    before = [ms for stamp, ms in latency.items() if stamp < t_before and stamp > sent[0] + 0.5e9]
    during = [ms for stamp, ms in latency.items() if any(a <= stamp <= b for a, b in windows)]
    # the node is idle once the stream stopped: its counters add up, nothing lost inside it
    diag = client.diagnostics_until(lambda d: int(d["inputs received"]) >= len(latency) and int(d["inputs received"])
                                    == sum(int(d[k]) for k in ("inputs solved", "inputs rejected", "inputs dropped")))
    assert len(latency) <= int(diag["inputs solved"]) and int(diag["inputs received"]) <= len(sent), diag
    b50, b99, bmax = _latency_stats(before)
    d50, d99, dmax = _latency_stats(during)
    ratio = len(latency) / len(sent)
    with capsys.disabled():
        print(f"\n[hexapod 100 Hz JointState] pose latency before a request: p50 {b50:.3f} ms, p99 {b99:.3f} ms, "
              f"max {bmax:.3f} ms ({len(before)} poses); while 16 assembly modes are computed "
              f"({', '.join(f'{(b - a) * 1e-9:.2f} s' for a, b in windows)}): p50 {d50:.3f} ms, p99 {d99:.3f} ms, "
              f"max {dmax:.3f} ms ({len(during)} poses); {len(latency)}/{len(sent)} poses ({100 * ratio:.1f} %); node: "
              + ", ".join(f"{k} {diag[k]}" for k in ("inputs received", "inputs rejected", "inputs dropped",
                                                      "deadline misses")))
    # the node answers while the modes are computed in its worker process; how fast it answers (the
    # latency figures above) and how many inputs a busy machine lets it answer are the benchmark's
    assert len(during) >= 1 and len(before) >= 1, (len(before), len(during))

    # the answer is latched (transient-local, keep-last 1): a late subscriber gets it
    late = client.endpoints.Participant()
    reader = late.reader("glpma_fk/assembly_modes", client.types["PoseArray"], depth=1, transient_local=True)
    deadline, got = time.monotonic() + 60, []
    while not got and time.monotonic() < deadline:
        got = [s for s in reader.take(10) if hasattr(s, "poses")]
        time.sleep(0.02)
    assert len(got) == 1 and len(got[0].poses) == 16
    z = sorted(p.position.z for p in got[0].poses)
    assert all(abs(v) < 3.0 for v in z)                  # metres, not millimetres
    diag = client.diagnostics_until(lambda d: d["assembly modes published"] == str(len(windows)))
    assert diag["assembly modes last"].startswith("16 modes")
    assert node.proc.poll() is None, node.output()
