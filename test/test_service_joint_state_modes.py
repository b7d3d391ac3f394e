"""The node without a transport: JointState input, every assembly mode on request (in this
process and through the worker process), the new parameters, the type hashes and topic names."""
import math
import threading
import time

import numpy as np
import pytest
import yaml

from conftest import GENEROUS_BUDGET_MS, HEX_YAML, RPR_YAML
from glpma_ros.errors import InputError
from glpma_ros.node import params as P
from glpma_ros.node.loops import AssemblyModesLoop, SolveLoop
from glpma_ros.node.ros_args import node_values
from glpma_ros.node.service import FkService, JointStateInput
from glpma_ros.solvers import SOLVERS

SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]
SEED_LEGS_M = [0.100, 0.120, 0.150]
NAMES = ["j_a", "j_b", "j_c"]
#: seconds a test waits for a worker (a bound for a hang, not a timing figure)
WAIT_S = 60.0


@pytest.fixture(scope="module", autouse=True)
def compiled():
    FkService({"manipulator_config": str(RPR_YAML)}).warm_up(solvers=("glpma",))


@pytest.fixture
def service():
    return FkService({"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X, "input_type": "joint_state",
                      "joint_names": NAMES, "time_budget_ms": GENEROUS_BUDGET_MS})


def rpr_solutions_m():
    doc = yaml.safe_load(RPR_YAML.read_text())
    return sorted((s["x"] / 1000, s["y"] / 1000) for s in doc["real_solutions"])


# -- parameters -------------------------------------------------------------------------------------

def test_solver_choices_are_the_registry():
    assert P.SOLVER_CHOICES == tuple(SOLVERS)
    assert {"sa", "gasa", "de"} <= set(P.SPECS["solver"].choices)
    assert P.coerce("solver", "gasa") == "gasa"


def test_new_parameters_are_declared_with_descriptions():
    for name in ("input_type", "joint_names", "assembly_modes_runs"):
        assert P.SPECS[name].description
    assert P.SPECS["input_type"].choices == ("float64_multi_array", "joint_state")
    assert P.SPECS["input_type"].read_only
    assert P.defaults()["input_type"] == "float64_multi_array" and P.defaults()["joint_names"] == []


@pytest.mark.parametrize("value, message", [
    ("leg_1", "list of strings"), ([1, 2, 3], "list of strings"), (["a", ""], "empty"),
    (["a", "b", "a"], "twice")])
def test_joint_names_values_are_checked(value, message):
    with pytest.raises(InputError, match=message):
        P.coerce("joint_names", value)


def test_joint_names_from_ros_args_and_params_file(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("glpma_fk:\n  ros__parameters:\n    input_type: joint_state\n    joint_names: [x1, '2', x3]\n")
    values, _ = node_values(["--ros-args", "--params-file", str(f)])[:2]
    assert values["input_type"] == "joint_state" and values["joint_names"] == ["x1", "2", "x3"]
    values, _ = node_values(["--ros-args", "-p", "joint_names:=[a, b, c]"])[:2]
    assert values["joint_names"] == ["a", "b", "c"]


def test_joint_names_must_name_every_leg_and_input_type_is_read_only(service):
    with pytest.raises(InputError, match="name the 3 legs"):
        FkService({"manipulator_config": str(RPR_YAML), "joint_names": ["a", "b"]})
    ok, reason = service.set_parameters({"joint_names": ["a", "b", "c", "d"]})
    assert not ok and "name the 3 legs" in reason
    ok, reason = service.set_parameters({"input_type": "float64_multi_array"})
    assert not ok and "read-only" in reason
    assert service.set_parameters({"joint_names": []}) == (True, "")
    assert service.joint_names == ["leg_1", "leg_2", "leg_3"]


# -- JointState input ---------------------------------------------------------------------------------

def test_joint_names_changed_at_runtime_pick_the_legs_from_then_on(service):
    renamed = ["p_a", "p_b", "p_c"]
    assert service.handle_joint_state(NAMES, SEED_LEGS_M, 1).pose is not None
    assert service.set_parameters({"joint_names": renamed}) == (True, "")
    assert service.joint_names == renamed
    assert service.handle_joint_state(NAMES, SEED_LEGS_M, 2).reason == "joint_states has no joint 'p_a'"
    assert service.handle_joint_state(renamed[::-1], SEED_LEGS_M[::-1], 3).pose is not None
    assert service.diagnostics().as_dict()["input"] == "joint_states (p_a, p_b, p_c)"
    # a refused change leaves the names as they were
    assert not service.set_parameters({"joint_names": ["q_a", "q_b"]})[0]
    assert service.handle_joint_state(renamed, SEED_LEGS_M, 4).pose is not None


def test_legs_are_picked_by_name_in_any_order_among_other_joints(service):
    names = ["wrist", "j_c", "gripper", "j_a", "j_b"]
    positions = [3.0, 0.15, -1.0, 0.1, 0.12]
    assert service.legs_from_joint_state(names, positions) == [0.1, 0.12, 0.15]


@pytest.mark.parametrize("names, positions, reason", [
    (["j_a", "j_c", "wrist"], [0.1, 0.15, 0.0], "joint_states has no joint 'j_b'"),
    (["j_a", "j_b", "j_c"], [0.1, 0.12], "joint_states has 3 names but 2 positions"),
    (["j_a", "j_b", "j_c", "j_b"], [0.1, 0.12, 0.15, 0.12], "joint_states names joint 'j_b' 2 times"),
    ([], [], "joint_states has no joint 'j_a'"),
])
def test_bad_joint_states_are_rejected_with_the_reason(service, names, positions, reason):
    out = service.handle_joint_state(names, positions, 5)
    assert out.pose is None and out.reason == reason
    values = service.diagnostics().as_dict()
    assert values[f"rejected: {reason}"] == "1" and values["last rejection"] == reason
    assert values["input"] == "joint_states (j_a, j_b, j_c)"


def test_joint_state_gives_the_array_pose_with_its_own_stamp(service):
    reference = FkService({"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X,
                           "time_budget_ms": GENEROUS_BUDGET_MS})
    for k, third in enumerate((0.150, 0.1502, 0.1504)):
        legs = [0.100, 0.120, third]
        out = service.handle_joint_state(["other", "j_c", "j_b", "j_a"], [9.9, legs[2], legs[1], legs[0]],
                                         1_000_000_000 + k)
        ref = reference.handle(legs, 0)
        assert out.pose is not None, out.reason
        assert out.pose.stamp_ns == 1_000_000_000 + k
        np.testing.assert_allclose(out.pose.position, ref.pose.position, atol=1e-9)
        np.testing.assert_allclose(out.pose.orientation, ref.pose.orientation, atol=1e-9)
    # a bad length inside a good JointState goes the array input's way
    out = service.handle_joint_state(NAMES, [0.1, float("nan"), 0.15], 0)
    assert out.reason == "leg lengths must be finite (got NaN or inf)"


def test_solve_loop_takes_joint_states(service):
    published = []
    loop = SolveLoop(service, published.append, stats=service.stats, modes=service.modes).start()
    try:
        loop.submit(JointStateInput(("j_b", "j_a", "x", "j_c"), (0.12, 0.1, 0.0, 0.15), ()), 77)
        deadline = time.monotonic() + WAIT_S
        while not published and time.monotonic() < deadline:
            time.sleep(0.001)
    finally:
        loop.stop()
    assert [p.stamp_ns for p in published] == [77]
    assert service.diagnostics().message == "tracking"


def test_waiting_message_names_the_input_topic(service):
    assert service.diagnostics().message == "waiting for joint_states"


# -- every assembly mode ------------------------------------------------------------------------------

def test_assembly_modes_of_the_last_input_in_metres(service):
    with pytest.raises(InputError, match="no input received yet on joint_states"):
        service.modes.compute(1)
    service.modes.note_input(JointStateInput(("j_c", "j_a", "j_b", "x"), (0.15, 0.1, 0.12, 4.0)), 33)
    result = service.modes.compute(1234)
    assert result.stamp_ns == 1234 and result.input_stamp_ns == 33 and result.frame_id == "base"
    assert len(result.poses) == 2
    np.testing.assert_allclose(sorted(p[:2] for p, _ in result.poses), rpr_solutions_m(), atol=1e-9)
    for position, q in result.poses:
        assert position[2] == 0.0 and abs(np.linalg.norm(q) - 1.0) < 1e-12
    service.modes.note_input(JointStateInput(("j_a",), (0.1,)), 34)
    with pytest.raises(InputError, match="the last input is invalid: joint_states has no joint 'j_b'"):
        service.modes.compute(1)


def test_assembly_modes_of_the_hexapod_example_are_sixteen():
    svc = FkService({"manipulator_config": str(HEX_YAML)})
    svc.modes.note_input([1.25] * 6, 0)
    result = svc.modes.compute(0)
    assert len(result.poses) == 16
    assert all(abs(p[2]) < 3.0 for p, _ in result.poses)          # metres


def test_assembly_modes_loop_with_the_worker_process(service):
    published = []
    loop = AssemblyModesLoop(service.modes, published.append, log=service.log)
    worker = loop.solve
    loop.start()
    try:
        assert worker.pid is not None
        loop.request(10)                                   # nothing received yet
        deadline = time.monotonic() + WAIT_S
        while service.modes.failed == 0 and time.monotonic() < deadline:
            time.sleep(0.001)
        service.modes.note_input(JointStateInput(tuple(NAMES), tuple(SEED_LEGS_M)), 20)
        loop.request(11)
        deadline = time.monotonic() + WAIT_S
        while not published and time.monotonic() < deadline:
            time.sleep(0.01)
        assert len(published) == 1
        assert published[0].stamp_ns == 11 and published[0].input_stamp_ns == 20
        np.testing.assert_allclose(sorted(p[:2] for p, _ in published[0].poses), rpr_solutions_m(), atol=1e-9)
        values = service.diagnostics().as_dict()
        assert values["assembly modes requests"] == "2" and values["assembly modes failed"] == "1"
        assert values["assembly modes last failure"] == "no input received yet on joint_states"
        assert values["assembly modes last"].startswith("2 modes in ")
        # the worker's result is the in-process one
        ours = service.modes.compute(0, (list(SEED_LEGS_M), 0))
        # the same work in two processes: the same modes to round-off (the polish stops at the floating-point
        # grid, where an operation fused or ordered otherwise by another compilation moves the last bit)
        assert len(ours.poses) == len(published[0].poses)
        for (p, q), (pw, qw) in zip(ours.poses, published[0].poses):
            np.testing.assert_allclose(p, pw, rtol=0, atol=1e-12)
            np.testing.assert_allclose(q, qw, rtol=0, atol=1e-12)
    finally:
        loop.stop()
    assert worker.pid is None                             # the child was stopped


def test_assembly_modes_requests_are_coalesced_while_one_waits(service):
    release, calls = threading.Event(), []

    def slow(legs, runs, seed, leg_noise_std):
        calls.append(list(legs))
        release.wait(WAIT_S)
        return []

    published = []
    loop = AssemblyModesLoop(service.modes, published.append, solve=slow, log=service.log).start()
    try:
        service.modes.note_input(list(SEED_LEGS_M), 1)
        loop.request(1)
        deadline = time.monotonic() + WAIT_S
        while not calls and time.monotonic() < deadline:
            time.sleep(0.001)
        service.modes.note_input([0.1, 0.12, 0.1501], 2)
        loop.request(2)
        loop.request(3)                                    # replaces 2
        release.set()
        while len(published) < 2 and time.monotonic() < deadline:
            time.sleep(0.001)
    finally:
        loop.stop()
    assert [p.stamp_ns for p in published] == [1, 3]
    assert [p.input_stamp_ns for p in published] == [1, 2]
    assert service.diagnostics().as_dict()["assembly modes coalesced"] == "1"


def test_switching_to_a_baseline_solver_warms_it_up_first():
    svc = FkService({"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X,
                     "time_budget_ms": GENEROUS_BUDGET_MS})
    assert svc.set_parameters({"solver": "de"}) == (True, "")
    assert "de" in svc.warmed_up
    out = svc.handle([0.1, 0.12, 0.1501], 0)
    assert out.pose is not None and out.estimate.solver == "de" and out.estimate.start == "warm"


# -- DDS names and type hashes ------------------------------------------------------------------------

CONTRACT_HASHES = {
    "std_msgs/msg/Float64MultiArray": "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f",
    "geometry_msgs/msg/PoseStamped": "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    "diagnostic_msgs/msg/DiagnosticArray": "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e",
    "sensor_msgs/msg/JointState": "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    "geometry_msgs/msg/PoseArray": "RIHS01_af0cc36d190e104d546d168d6b39df04fa4b4ccecf59cb4c9ed328d3d5004aa0",
}


def test_the_type_hash_table_is_jazzys():
    """The node's fixed table of RIHS01 hashes against an independent implementation (rosbags'
    Jazzy type store, from the Jazzy .msg definitions) and the contract's."""
    pytest.importorskip("cyclonedds")
    typesys = pytest.importorskip("rosbags.typesys")
    from glpma_ros.node.dds import messages
    jazzy = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    for name, expected in messages.TYPE_HASHES.items():
        assert jazzy.hash_rihs01(name) == expected, name
    for name, expected in CONTRACT_HASHES.items():
        assert messages.TYPE_HASHES[name] == expected, name
    assert set(messages.ROS_TYPE_NAMES.values()) <= set(messages.TYPE_HASHES)
    for msg_type, ros_name in messages.ROS_TYPE_NAMES.items():
        assert messages.type_hash(msg_type) == messages.TYPE_HASHES[ros_name], ros_name
    assert messages.Empty.__idl_typename__ == "std_msgs::msg::dds_::Empty_"


def test_private_topic_names():
    pytest.importorskip("cyclonedds")
    from glpma_ros.node.dds.endpoints import dds_topic_name, expand_topic_name
    assert dds_topic_name("~/assembly_modes") == "rt/glpma_fk/assembly_modes"
    assert dds_topic_name("~/request_assembly_modes") == "rt/glpma_fk/request_assembly_modes"
    assert dds_topic_name("/diagnostics") == "rt/diagnostics" and dds_topic_name("joint_states") == "rt/joint_states"
    assert expand_topic_name("~/assembly_modes", "fk2") == "fk2/assembly_modes"
