"""glpma-fk bag: a bag written here with rosbags from a known trajectory goes through the
node's service; the output bag holds the input unchanged plus poses that match the truth."""
import hashlib
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from conftest import CONFIG, ROOT
from glpma_ros.node.dds import cdr
from glpma_tools import bag as B
from glpma_tools import bag_run as C
from glpma_tools.sim.trajectories import variables_along

TS = get_typestore(Stores.ROS2_JAZZY)
PARAMS = CONFIG / "params_3rpr.yaml"     # initial_pose = the published real_solutions[0]
T0 = 1_700_000_000_123_456_789
PERIOD_NS = 1_000_000                    # 1 kHz
STEPS = 150
CORRUPT = b"\x00\x01\x00\x00\x07\x00"    # a Float64MultiArray cut short
#: QoS of the recorded input topic, to be copied as is
SENSOR_QOS = Qos(QosHistory.KEEP_LAST, 5, QosReliability.BEST_EFFORT, QosDurability.VOLATILE, QosTime(0, 0),
                 QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False)


def _float64_multi_array(values) -> bytes:
    T = TS.types
    msg = T[C.FLOAT64_MULTI_ARRAY](layout=T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
                                   data=np.asarray(values, dtype=float))
    return bytes(TS.serialize_cdr(msg, C.FLOAT64_MULTI_ARRAY))


def _string(text) -> bytes:
    return bytes(TS.serialize_cdr(TS.types["std_msgs/msg/String"](data=text), "std_msgs/msg/String"))


def _joint_state(stamp_ns, names, positions) -> bytes:
    T = TS.types
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                      frame_id="")
    msg = T[C.JOINT_STATE](header=header, name=list(names), position=np.asarray(positions, dtype=float),
                           velocity=np.zeros(0), effort=np.zeros(0))
    return bytes(TS.serialize_cdr(msg, C.JOINT_STATE))


@pytest.fixture(scope="module")
def truth(rpr, rpr_solutions):
    """Solver variables along a loop from the published solution, and its legs in metres."""
    xs = variables_along(rpr, rpr_solutions[0], STEPS)
    legs_m = np.array([rpr.inverse_kinematics(x) for x in xs]) * rpr.metres_per_unit
    return xs, legs_m


def write_legs_bag(path: Path, storage: str, legs_m, corrupt_at=None, legs_topic="/leg_lengths") -> None:
    """``legs_topic`` at 1 kHz (a corrupt message between inputs ``corrupt_at - 1`` and
    ``corrupt_at``), and /chatter (std_msgs/String) every 10 ms."""
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        legs = w.add_connection(legs_topic, C.FLOAT64_MULTI_ARRAY, typestore=TS, offered_qos_profiles=[SENSOR_QOS])
        chatter = w.add_connection("/chatter", "std_msgs/msg/String", typestore=TS)
        for i, row in enumerate(legs_m):
            t = T0 + i * PERIOD_NS
            if i == corrupt_at:
                w.write(legs, t - PERIOD_NS // 2, CORRUPT)
            w.write(legs, t, _float64_multi_array(row))
            if i % 10 == 0:
                w.write(chatter, t + 1, _string(f"tick {i}"))


def read_bag(path: Path) -> dict:
    """topic -> [(log time, raw bytes)] in the bag's order, and the connections."""
    out = {}
    with Reader(path) as r:
        conns = {c.topic: c for c in r.connections}
        for c, t, raw in r.messages():
            out.setdefault(c.topic, []).append((t, bytes(raw)))
    return out, conns


def tree_digest(path: Path) -> str:
    h = hashlib.sha256()
    for f in sorted(path.rglob("*")):
        if f.is_file():
            h.update(f.name.encode() + f.read_bytes() + str(f.stat().st_mtime_ns).encode())
    return h.hexdigest()


def run_bag(*args):
    return B.main([str(a) for a in args])


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_bag_poses_match_the_truth(tmp_path, truth, rpr, storage, capsys):
    xs, legs_m = truth
    src, dst = tmp_path / "in", tmp_path / "out"
    write_legs_bag(src, storage, legs_m, corrupt_at=STEPS // 2)
    before = tree_digest(src)
    assert run_bag(src, dst, "--no-progress", "--json", "--ros-args", "--params-file", PARAMS) == 0
    summary = json.loads(capsys.readouterr().out)
    assert tree_digest(src) == before                      # the input bag is untouched

    assert summary["storage"] == storage and summary["inputs"] == STEPS + 1
    assert summary["converged"] == STEPS and summary["rejected"] == 1
    (reason, n), = summary["rejected_by_reason"].items()
    assert n == 1 and "cannot decode" in reason
    assert summary["assembly_mode_changes"] == 0

    inp, _ = read_bag(src)
    out, conns = read_bag(dst)
    for topic, messages in inp.items():                     # every input message, byte for byte
        assert out[topic] == messages
    assert conns["/leg_lengths"].ext.offered_qos_profiles == [SENSOR_QOS]
    assert conns["/pose_estimate"].msgtype == C.POSE_STAMPED
    assert conns["/tf"].msgtype == C.TF_MESSAGE
    assert conns["/glpma_fk/status"].msgtype == C.DIAGNOSTIC_STATUS

    stamps = [t for t, raw in inp["/leg_lengths"] if raw != CORRUPT]
    poses = [(t, TS.deserialize_cdr(raw, C.POSE_STAMPED)) for t, raw in out["/pose_estimate"]]
    assert [t for t, _ in poses] == stamps
    for (t, msg), x in zip(poses, xs):
        assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == t   # the receive time
        assert msg.header.frame_id == "base"
        p, q = msg.pose.position, msg.pose.orientation
        truth_m = x[:2] * rpr.metres_per_unit
        assert abs(p.x - truth_m[0]) < 1e-9 and abs(p.y - truth_m[1]) < 1e-9 and p.z == 0.0
        assert abs(q.z - math.sin(x[2] / 2)) < 1e-9 and abs(q.w - math.cos(x[2] / 2)) < 1e-9
    transforms = [TS.deserialize_cdr(raw, C.TF_MESSAGE).transforms[0] for _, raw in out["/tf"]]
    assert len(transforms) == STEPS
    assert transforms[7].child_frame_id == "platform" and transforms[7].header.frame_id == "base"
    assert transforms[7].transform.translation.x == poses[7][1].pose.position.x

    statuses = [(t, TS.deserialize_cdr(raw, C.DIAGNOSTIC_STATUS)) for t, raw in out["/glpma_fk/status"]]
    assert [t for t, _ in statuses] == [t for t, _ in inp["/leg_lengths"]]
    bad = [s for t, s in statuses if dict((kv.key, kv.value) for kv in s.values)["status"] != "converged"]
    assert len(bad) == 1 and bad[0].level == 2 and "cannot decode" in bad[0].message
    assert dict((kv.key, kv.value) for kv in bad[0].values)["status"] == "undecodable"

    if storage == "mcap":                                   # readable by the mcap library too
        from mcap.reader import make_reader
        mcap_file, = dst.glob("*.mcap")
        with open(mcap_file, "rb") as f:
            reader = make_reader(f)
            schemas = {c.topic: s.name for s, c, _ in reader.iter_messages()}
            f.seek(0)
            count = sum(1 for _ in make_reader(f).iter_messages())
        assert schemas["/pose_estimate"] == C.POSE_STAMPED and schemas["/tf"] == C.TF_MESSAGE
        assert count == sum(len(v) for v in out.values())
    else:
        assert list(dst.glob("*.db3"))


def test_bag_joint_states_keep_their_stamps(tmp_path, truth, rpr, capsys):
    """JointState input: legs picked by name among other joints, the pose keeps header.stamp;
    a message without one of the legs is rejected with the reason; --storage converts."""
    xs, legs_m = truth
    src, dst = tmp_path / "in", tmp_path / "out"
    names = ["wrist", "leg_c", "leg_a", "leg_b"]
    stamps = [T0 - 5_000_000 + i * PERIOD_NS for i in range(40)]     # stamped 5 ms before reception
    with Writer(src, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        js = w.add_connection("/robot/joint_states", C.JOINT_STATE, typestore=TS)
        for i, stamp in enumerate(stamps):
            a, b, c = legs_m[i]
            w.write(js, T0 + i * PERIOD_NS, _joint_state(stamp, names, [0.3, c, a, b]))
        w.write(js, T0 + 40 * PERIOD_NS, _joint_state(T0, ["leg_a", "leg_b"], [0.1, 0.1]))
    assert run_bag(src, dst, "--no-progress", "--json", "--storage", "sqlite3", "--input-type", "joint_state",
                   "--joint-states-topic", "/robot/joint_states", "--joint-names", "leg_a", "leg_b", "leg_c",
                   "--no-tf", "--ros-args", "--params-file", PARAMS, "--log-level", "warn") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["converged"] == 40 and summary["rejected_by_reason"] == {"joint_states has no joint 'leg_c'": 1}
    out, _ = read_bag(dst)
    assert list(dst.glob("*.db3"))
    assert "/tf" not in out                                 # --no-tf
    poses = [TS.deserialize_cdr(raw, C.POSE_STAMPED) for _, raw in out["/pose_estimate"]]
    for msg, stamp, x in zip(poses, stamps, xs):
        assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == stamp
        assert abs(msg.pose.position.x - x[0] * rpr.metres_per_unit) < 1e-9


def test_existing_output_refused_unless_overwrite(tmp_path, truth, capsys):
    src, dst = tmp_path / "in", tmp_path / "out"
    write_legs_bag(src, "mcap", truth[1][:5])
    dst.mkdir()
    (dst / "keep").write_text("x")
    assert run_bag(src, dst, "--no-progress") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists" in err and (dst / "keep").exists()
    assert run_bag(src, dst, "--no-progress", "--overwrite", "--ros-args", "--params-file", PARAMS) == 0
    assert not (dst / "keep").exists() and len(read_bag(dst)[0]["/pose_estimate"]) == 5
    assert run_bag(src, src / "sub", "--no-progress", "--overwrite") == 2      # never inside the input


def test_codecs_agree_with_rosbags():
    """The node's codec (what the bag's poses and transforms are written with) gives rosbags'
    bytes, and reads rosbags' inputs."""
    rng = np.random.default_rng(5)
    T, encode = TS.types, cdr.Encoder()
    for _ in range(50):
        stamp = int(rng.integers(0, 2**31 * 1_000_000_000))  # builtin_interfaces/Time: int32 seconds
        sec, nanosec = divmod(stamp, 1_000_000_000)
        p, q = rng.normal(size=3), rng.normal(size=4)
        header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                          frame_id="world_frame")
        pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](*p),
                                           orientation=T["geometry_msgs/msg/Quaternion"](*q))
        ours = encode.pose_stamped(stamp, "world_frame", tuple(p), tuple(q))
        assert ours == bytes(TS.serialize_cdr(T[C.POSE_STAMPED](header=header, pose=pose), C.POSE_STAMPED))
        transform = T["geometry_msgs/msg/TransformStamped"](
            header=header, child_frame_id="platform_1",
            transform=T["geometry_msgs/msg/Transform"](translation=T["geometry_msgs/msg/Vector3"](*p),
                                                       rotation=T["geometry_msgs/msg/Quaternion"](*q)))
        ours = encode.tf_message(stamp, "world_frame", "platform_1", tuple(p), tuple(q))
        assert ours == bytes(TS.serialize_cdr(T[C.TF_MESSAGE](transforms=[transform]), C.TF_MESSAGE))
        data = rng.normal(size=int(rng.integers(0, 8)))
        assert np.array_equal(C.decode_float64_multi_array(_float64_multi_array(data), TS), data)
    dims = [T["std_msgs/msg/MultiArrayDimension"](label="legs", size=3, stride=3)]
    msg = T[C.FLOAT64_MULTI_ARRAY](layout=T["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0),
                                   data=np.array([1.0, 2.0, 3.0]))
    raw = bytes(TS.serialize_cdr(msg, C.FLOAT64_MULTI_ARRAY))
    assert list(C.decode_float64_multi_array(raw, TS)) == [1.0, 2.0, 3.0]


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory, truth):
    path = tmp_path_factory.mktemp("bags") / "in"
    write_legs_bag(path, "mcap", truth[1][:3])
    return path


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "glpma_ros", "bag", *map(str, args)], capture_output=True,
                          text=True, cwd=ROOT, timeout=300)


@pytest.mark.parametrize("args, words", [
    (["{tmp}/missing", "{tmp}/out"], "does not exist"),
    (["{tmp}", "{tmp}/../out2"], "cannot read bag"),
    (["{bag}", "{tmp}/out", "--legs-topic", "/nope"], "has no topic /nope"),
    (["{bag}", "{tmp}/out", "--legs-topic", "chatter"], "has type std_msgs/msg/String"),
    (["{bag}", "{tmp}/out", "--ros-args", "-p", "solver:=newton"], "must be one of"),
    (["{bag}", "{tmp}/out", "--ros-args", "-p", "manipulator_config:=missing.yaml"], "cannot read"),
    (["{bag}", "{tmp}/out", "--pose-topic", "/chatter"], "already has a topic /chatter"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, small_bag, args, words):
    p = _cli(*[a.format(tmp=tmp_path, bag=small_bag) for a in args])
    assert p.returncode == 2, p.stderr
    assert p.stderr.count("\n") == 1 and p.stderr.startswith("error: glpma-fk bag:") and words in p.stderr, p.stderr
    assert not (tmp_path / "out").exists()


def test_missing_extra_names_the_pip_command(monkeypatch, capsys):
    import importlib.util
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "rosbags" else real(name, *a))
    assert B.main(["in", "out"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install" in err and "[bag]" in err


def test_help_describes_every_option():
    p = _cli("--help")
    assert p.returncode == 0
    for option in ("--out-dir", "--workers", "--scheduler", "--storage", "--overwrite", "--budget-ms",
                   "--legs-topic", "--joint-states-topic", "--joint-names", "--pose-topic", "--tf-topic",
                   "--status-topic", "--child-frame-id", "--ros-args", "time_budget_ms", "exit status"):
        assert option in p.stdout


def test_topic_and_frame_names_are_chosen(tmp_path, truth, capsys):
    """Every topic name and the child frame can be chosen; the poses are the same."""
    xs, legs_m = truth
    src, dst = tmp_path / "in", tmp_path / "out"
    write_legs_bag(src, "mcap", legs_m[:10], legs_topic="/robot/legs")
    assert run_bag(src, dst, "--no-progress", "--json", "--legs-topic", "/robot/legs", "--pose-topic", "/fk/pose",
                   "--tf-topic", "/fk/tf", "--status-topic", "/fk/status", "--child-frame-id", "tool",
                   "--ros-args", "--params-file", PARAMS) == 0
    assert json.loads(capsys.readouterr().out)["converged"] == 10
    out, conns = read_bag(dst)
    assert {"/fk/pose", "/fk/tf", "/fk/status"} <= set(out) and "/pose_estimate" not in out
    assert TS.deserialize_cdr(out["/fk/tf"][0][1], C.TF_MESSAGE).transforms[0].child_frame_id == "tool"
    for (_, raw), x in zip(out["/fk/pose"], xs):
        assert abs(TS.deserialize_cdr(raw, C.POSE_STAMPED).pose.position.x - x[0] * 1e-3) < 1e-9
# -- exit statuses, the budget's wording ---------------------------------------------------------------

#: equal legs this short have no real assembly of the seed 3-RPR (README: `solve ... --legs 60 60 60`)
NO_ASSEMBLY_M = 0.060


def test_exit_1_when_no_input_converged(tmp_path, capsys):
    src = tmp_path / "in"
    write_legs_bag(src, "mcap", np.full((3, 3), NO_ASSEMBLY_M))
    assert run_bag(src, tmp_path / "out", "--no-progress", "--budget-ms", 5000, "--ros-args", "--params-file",
                   PARAMS) == 1
    captured = capsys.readouterr()
    assert "0 converged, 3 rejected" in captured.out and "budget 5000 ms per input (--budget-ms)" in captured.out
    line = captured.err.strip().splitlines()[-1]      # after the service's log line of the first rejection
    assert line.startswith("error: glpma-fk bag: no input of") and "3 no_solution" in line


def test_default_budget_is_the_parameters_maximum_and_says_so(tmp_path, truth, capsys):
    src = tmp_path / "in"
    write_legs_bag(src, "mcap", truth[1][:3])
    assert run_bag(src, tmp_path / "out", "--no-progress", "--ros-args", "--params-file", PARAMS) == 0
    out = capsys.readouterr().out
    assert f"budget {B.OFFLINE_BUDGET_MS:g} ms per input, the parameter's maximum: statuses from the work done" in out


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# -- a fleet's recordings ---------------------------------------------------------------------------------

#: poses of the same bag computed by two engines: the same arithmetic, equal to round-off of a leg
#: length in metres (about 1e-16 m); this bound leaves room for a different summation order
SAME_POSE_M = 1e-12


@pytest.fixture(scope="module")
def fleet(tmp_path_factory, truth):
    """Three recordings: two bag directories in a folder, one single MCAP file beside it."""
    root = tmp_path_factory.mktemp("fleet")
    legs_m = truth[1]
    write_legs_bag(root / "runs" / "run_a", "mcap", legs_m[:40])
    write_legs_bag(root / "runs" / "run_b", "sqlite3", legs_m[40:70], corrupt_at=10)
    write_legs_bag(root / "run_c_dir", "mcap", legs_m[70:90])
    mcap, = (root / "run_c_dir").glob("*.mcap")
    single = root / "run_c.mcap"
    single.write_bytes(mcap.read_bytes())
    return root, [root / "runs", single]


def _decoded(dst: Path) -> dict:
    out, _ = read_bag(dst)
    poses = [TS.deserialize_cdr(raw, C.POSE_STAMPED) for _, raw in out["/pose_estimate"]]
    return {"stamps": [t for t, _ in out["/pose_estimate"]],
            "poses": np.array([[m.pose.position.x, m.pose.position.y, m.pose.orientation.z, m.pose.orientation.w]
                               for m in poses]),
            "status": out["/glpma_fk/status"], "legs": out["/leg_lengths"]}


def test_fleet_writes_one_bag_per_input_the_same_on_every_engine(tmp_path, fleet, capsys):
    distributed = pytest.importorskip("distributed")
    root, inputs = fleet
    names = ["run_a", "run_b", "run_c"]
    runs = {"serial": ["--workers", 1], "processes": ["--workers", 2]}
    for engine, options in runs.items():
        assert run_bag(*inputs, "--out-dir", tmp_path / engine, *options, "--no-progress", "--ros-args",
                       "--params-file", PARAMS) == 0
        text = capsys.readouterr().out
        for name in names:
            assert str(tmp_path / engine / name) in text
        assert "total (3 bags)" in text and " 90 " in text.replace(",", "")        # 40 + 30 + 20 converged
        assert sorted(p.name for p in (tmp_path / engine).iterdir()) == names
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        assert run_bag(*inputs, "--out-dir", tmp_path / "dask", "--scheduler", c.scheduler_address, "--json",
                       "--no-progress", "--ros-args", "--params-file", PARAMS) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["engine"].startswith("Dask") and [Path(b["output"]).name for b in summary["bags"]] == names
    assert [b["converged"] for b in summary["bags"]] == [40, 30, 20] and summary["total"]["rejected"] == 1
    assert summary["bags"][1]["storage"] == "sqlite3"
    for name in names:
        reference = _decoded(tmp_path / "serial" / name)
        for engine in ("processes", "dask"):
            other = _decoded(tmp_path / engine / name)
            assert other["stamps"] == reference["stamps"] and other["legs"] == reference["legs"]
            assert other["status"] == reference["status"]          # statuses are words: the same bytes
            assert np.allclose(other["poses"], reference["poses"], rtol=0.0, atol=SAME_POSE_M)


def test_fleet_refuses_ambiguous_or_missing_inputs(tmp_path, fleet, small_bag):
    root, _ = fleet
    cases = [
        ([small_bag, tmp_path / "o1", tmp_path / "o2"], "expected INPUT OUTPUT"),
        ([small_bag, tmp_path / "o", "--workers", 2], "--out-dir"),
        ([tmp_path / "empty", "--out-dir", tmp_path / "o"], "neither a bag nor a directory holding bags"),
        ([root / "runs", root / "runs" / "run_a", "--out-dir", tmp_path / "o"], "would both write"),
        ([root / "runs", "--out-dir", tmp_path / "o", "--workers", 0], "--workers"),
    ]
    (tmp_path / "empty").mkdir()
    for args, words in cases:
        p = _cli(*args)
        assert p.returncode == 2, (args, p.stderr)
        assert one_line(p.stderr).startswith("error: glpma-fk bag:") and words in p.stderr, p.stderr
    assert not (tmp_path / "o").exists()


def test_bag_of_an_actuated_family_reads_its_actuator_positions(tmp_path, capsys):
    """A Delta's bag: its arm angles recorded on /actuator_positions (radians), the topic the node reads for an
    actuated family and the command's default for its config; the poses are the trajectory's (closed form)."""
    from glpma_ros.config import load_manipulator
    delta = load_manipulator(CONFIG / "delta_irb360.yaml")
    xs = variables_along(delta, delta.known_solutions[0], STEPS)
    angles = np.array([delta.readings_to_si(delta.actuator_positions(x)) for x in xs])
    src, dst = tmp_path / "in", tmp_path / "out"
    write_legs_bag(src, "mcap", angles, legs_topic="/actuator_positions")
    assert run_bag(src, dst, "--no-progress", "--json", "--ros-args", "--params-file",
                   CONFIG / "params_delta.yaml") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["inputs"] == len(xs) and summary["converged"] == len(xs)
    out, _ = read_bag(dst)
    poses = [TS.deserialize_cdr(raw, C.POSE_STAMPED).pose.position for _, raw in out["/pose_estimate"]]
    assert len(poses) == len(xs)
    for p, x in zip(poses, xs):
        truth_m = x * delta.metres_per_unit
        # metres; the warm solve converges to round-off of the 1.2 m robot
        assert np.allclose([p.x, p.y, p.z], truth_m, atol=1e-9)
