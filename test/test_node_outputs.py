"""The node's outputs besides the pose, without a transport, and their wire form.

* TF = the pose (to 1e-12; in fact the same numbers), same stamp, frame_id -> child_frame_id;
* every extra output switches off by its parameter (at runtime too);
* markers: decoded from the bytes the DDS node writes, leg endpoints = base joints and the
  inverse kinematics' platform joints, leg lengths = the input's;
* the struct-based encoders (glpma_ros.node.dds.cdr) give the bytes of Cyclone DDS's own
  serializer, and the decoders read what it writes;
* the RIHS01 type hashes of the new types are the ones a Jazzy build reports.
"""
import math

import numpy as np
import pytest

from conftest import HEX_YAML, RPR_YAML
from glpma_ros.node import params as P
from glpma_ros.node.outputs import LINE_LIST, LINE_STRIP, SPHERE_LIST
from glpma_ros.node.service import FkService, JointStateInput

SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]
SEED_LEGS_M = [0.100, 0.120, 0.150]
#: read from a ROS 2 Jazzy build (rosidl_generator_type_description on the Jazzy .msg files,
#: and `ros2 topic info -v` against the node)
JAZZY_HASHES = {
    "tf2_msgs/msg/TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "visualization_msgs/msg/MarkerArray": "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf",
    "geometry_msgs/msg/PoseWithCovarianceStamped":
        "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e",
    "geometry_msgs/msg/TwistStamped": "RIHS01_5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64",
}


@pytest.fixture
def service():
    # a generous budget: these tests are about the outputs, not timing
    return FkService({"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X, "frame_id": "robot_base",
                      "publish_markers": True, "time_budget_ms": 1000.0})


def hexapod_service(**params):
    hexapod_x0 = [-68.194, 917.281, 821.484, -374.945, 430.433, 609.062, -306.53, 321.95, 561.634]
    return FkService({"manipulator_config": str(HEX_YAML), "initial_pose": hexapod_x0, "publish_markers": True,
                      "time_budget_ms": 1000.0, **params})


def test_new_type_hashes_are_jazzys():
    pytest.importorskip("cyclonedds")
    from glpma_ros.node.dds.messages import TYPE_HASHES
    for name, expected in JAZZY_HASHES.items():
        assert TYPE_HASHES[name] == expected, name


def test_new_parameters_are_declared():
    for name, default in (("child_frame_id", "platform"), ("publish_tf", True), ("publish_covariance", True),
                          ("leg_noise_std", 1e-5), ("publish_twist", True), ("publish_markers", False),
                          ("markers_period_s", 0.1)):
        assert P.SPECS[name].default == default and P.SPECS[name].description
    with pytest.raises(Exception, match="must not be empty"):
        P.coerce("child_frame_id", " ")
    with pytest.raises(Exception, match="leg_noise_std"):
        P.coerce("leg_noise_std", 0.0)


def test_tf_is_the_pose(service):
    out = service.handle(SEED_LEGS_M, 1_234_567_890_123)
    extras = service.extras(out)
    assert extras.stamp_ns == out.pose.stamp_ns == 1_234_567_890_123
    assert (extras.frame_id, extras.child_frame_id) == ("robot_base", "platform")
    np.testing.assert_allclose(extras.position, out.pose.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(extras.orientation, out.pose.orientation, rtol=0, atol=1e-12)
    cov = np.array(extras.covariance).reshape(6, 6)
    np.testing.assert_array_equal(cov, cov.T)
    assert extras.twist is None          # the first pose: nothing to difference yet


def test_frames_must_differ(service):
    ok, reason = service.set_parameters({"child_frame_id": "robot_base"})
    assert not ok and "must differ" in reason
    with pytest.raises(Exception, match="must differ"):
        FkService({"manipulator_config": str(RPR_YAML), "frame_id": "a", "child_frame_id": "a"})


def test_each_extra_output_switches_off_at_runtime(service):
    service.handle(SEED_LEGS_M, 1)
    ok, _ = service.set_parameters({"publish_tf": False, "publish_covariance": False, "publish_twist": False,
                                    "publish_markers": False})
    assert ok
    assert service.extras(service.handle([0.1, 0.12, 0.1501], 2)) is None
    assert service.diagnostics().as_dict()["outputs"] == "pose_estimate"
    for k, name in enumerate(("publish_tf", "publish_covariance", "publish_twist", "publish_markers")):
        service.set_parameters({"publish_tf": False, "publish_covariance": False, "publish_twist": False,
                                "publish_markers": False, name: True})
        service.set_parameters({"markers_period_s": 0.0})
        extras = service.extras(service.handle([0.1, 0.12, 0.15 + 1e-6 * k], 1_000_000 * (k + 3)))
        present = {"publish_tf": extras.child_frame_id is not None, "publish_covariance": extras.covariance is not None,
                   "publish_twist": extras.twist is not None, "publish_markers": extras.markers is not None}
        assert [k for k, v in present.items() if v] == [name]


def test_markers_follow_markers_period_s(service):
    service.set_parameters({"markers_period_s": 0.1})
    published = []
    for k in range(25):                            # 1 kHz... of stamps, 10 ms apart
        out = service.handle([0.1, 0.12, 0.15 + 1e-5 * k], 10_000_000 * k + 1)
        published.append(service.extras(out).markers is not None)
    assert [k for k, v in enumerate(published) if v] == [0, 10, 20]


def decode_markers(extras):
    """The MarkerArray the DDS node writes for ``extras``, read back by Cyclone DDS's own
    deserializer."""
    pytest.importorskip("cyclonedds")
    from glpma_ros.node.dds.cdr import Encoder
    from glpma_ros.node.dds.messages import MarkerArray
    return MarkerArray.deserialize(Encoder().marker_array(extras.stamp_ns, extras.frame_id, extras.markers))


@pytest.mark.parametrize("manipulator", ["planar_3rpr", "hexapod_66"])
def test_markers_put_the_legs_where_the_inverse_kinematics_does(service, manipulator):
    svc = service if manipulator == "planar_3rpr" else hexapod_service()
    model, mpu = svc.model, svc.metres_per_unit
    legs_m = SEED_LEGS_M if manipulator == "planar_3rpr" else [1.25] * 6
    out = svc.handle(legs_m, 42)
    assert out.pose is not None, out.reason
    msg = decode_markers(svc.extras(out))
    by_ns = {m.ns: m for m in msg.markers}
    assert set(by_ns) == {"base_joints", "platform_joints", "legs", "base", "platform"}
    for m in msg.markers:
        assert m.header.frame_id == svc.frame_id and m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == 42
        assert m.action == 0 and m.pose.orientation.w == 1.0
    legs = by_ns["legs"]
    assert legs.type == LINE_LIST and len(legs.points) == 2 * model.n_legs == len(legs.colors)
    joints = model.joints(out.estimate.x) * mpu                              # inverse kinematics: B_i
    base = model.base * mpu
    if joints.shape[1] == 2:
        joints, base = (np.hstack((a, np.zeros((3, 1)))) for a in (joints, base))
    a = np.array([[p.x, p.y, p.z] for p in legs.points[0::2]])
    b = np.array([[p.x, p.y, p.z] for p in legs.points[1::2]])
    np.testing.assert_allclose(a, base, atol=1e-12)
    np.testing.assert_allclose(b, joints, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(b - a, axis=1), legs_m, atol=1e-12)
    assert by_ns["base_joints"].type == by_ns["platform_joints"].type == SPHERE_LIST
    np.testing.assert_allclose([[p.x, p.y, p.z] for p in by_ns["platform_joints"].points], joints, atol=1e-12)
    polygon = by_ns["platform"]
    assert polygon.type == LINE_STRIP and len(polygon.points) == model.n_legs + 1
    assert polygon.points[0] == polygon.points[-1]
    np.testing.assert_allclose(sorted(map(tuple, np.array([[p.x, p.y, p.z] for p in polygon.points[:-1]]))),
                               sorted(map(tuple, joints)), atol=1e-12)


def test_legs_are_coloured_by_length_over_the_limits(tmp_path):
    import yaml
    doc = yaml.safe_load(RPR_YAML.read_text())
    doc["leg_limits"] = [50.0, 250.0]
    path = tmp_path / "limits.yaml"
    path.write_text(yaml.safe_dump(doc))
    svc = FkService({"manipulator_config": str(path), "initial_pose": SEED_X, "publish_markers": True,
                     "time_budget_ms": 1000.0})
    extras = svc.extras(svc.handle(SEED_LEGS_M, 1))
    colours = {m.ns: m for m in extras.markers}["legs"].colors[0::2]
    blue_to_red = [(c[0] - 0.1) / 0.9 for c in colours]          # r goes 0.1 -> 1.0 over the range
    np.testing.assert_allclose(blue_to_red, [(l_mm - 50) / 200 for l_mm in (100, 120, 150)], atol=1e-12)


# -- wire form ---------------------------------------------------------------------------------------------

def padded(raw: bytes) -> bytes:
    return raw.ljust((len(raw) + 3) & ~3, b"\0")


def test_encoders_write_what_cyclone_dds_writes():
    pytest.importorskip("cyclonedds")
    from glpma_ros.node.dds import cdr
    from glpma_ros.node.dds import messages as M
    from glpma_ros.node.outputs import MarkerOutput
    rng = np.random.default_rng(3)
    enc = cdr.Encoder()
    from glpma_ros.node.diagnostics import DiagnosticReport
    for n_values in (0, 1, 3, 25):
        values = [("k" * (k % 5), "value " * (k % 3)) for k in range(n_values)]
        report = DiagnosticReport(n_values % 4, "glpma_fk: forward kinematics", "tracking", "planar_3rpr:seed.yaml",
                                  values)
        stamp = int(rng.integers(0, 2**31 * 10**9))
        status = M.DiagnosticStatus(level=report.level, name=report.name, message=report.message,
                                    hardware_id=report.hardware_id, values=[M.KeyValue(a, b) for a, b in values])
        msg = M.DiagnosticArray(header=M.Header(stamp=M.Time.from_ns(stamp)), status=[status])
        assert cdr.diagnostic_array(stamp, report) == padded(msg.serialize())
    for frame in ("", "b", "base", "robot_base_link"):
        for child in ("", "platform", "pl"):
            stamp = int(rng.integers(0, 2**31 * 10**9))
            pos, q, cov = (tuple(float(v) for v in rng.normal(size=n)) for n in (3, 4, 36))
            header = M.Header(stamp=M.Time.from_ns(stamp), frame_id=frame)
            pose = M.Pose(M.Point(*pos), M.Quaternion(*q))
            assert enc.pose_stamped(stamp, frame, pos, q) == padded(M.PoseStamped(header, pose).serialize())
            tf = M.TFMessage([M.TransformStamped(header, child, M.Transform(M.Vector3(*pos), M.Quaternion(*q)))])
            assert enc.tf_message(stamp, frame, child, pos, q) == padded(tf.serialize())
            pwc = M.PoseWithCovarianceStamped(header, M.PoseWithCovariance(pose, list(cov)))
            assert enc.pose_with_covariance_stamped(stamp, frame, pos, q, cov) == padded(pwc.serialize())
            twist = M.TwistStamped(header, M.Twist(M.Vector3(*pos), M.Vector3(*q[:3])))
            assert enc.twist_stamped(stamp, frame, pos, q[:3]) == padded(twist.serialize())
            outs, msgs = [], []
            for k, (n_points, n_colours) in enumerate(((0, 0), (3, 0), (6, 6), (1, 1))):
                points = tuple(tuple(float(v) for v in rng.normal(size=3)) for _ in range(n_points))
                colours = tuple(tuple(float(np.float32(v)) for v in rng.random(4)) for _ in range(n_colours))
                scale, colour = tuple(rng.random(3)), tuple(float(np.float32(v)) for v in rng.random(4))
                outs.append(MarkerOutput(child * k, k, 5, scale, colour, points, colours))
                msgs.append(M.Marker(header=header, ns=child * k, id=k, type=5, scale=M.Vector3(*scale),
                                     color=M.ColorRGBA(*colour), points=[M.Point(*p) for p in points],
                                     colors=[M.ColorRGBA(*c) for c in colours]))
            assert enc.marker_array(stamp, frame, outs) == padded(M.MarkerArray(msgs).serialize())


def test_decoders_read_what_cyclone_dds_writes():
    pytest.importorskip("cyclonedds")
    from glpma_ros.node.dds import cdr
    from glpma_ros.node.dds import messages as M
    rng = np.random.default_rng(4)
    for dims in ([], [M.MultiArrayDimension("legs", 3, 3)],
                 [M.MultiArrayDimension("a", 1, 1), M.MultiArrayDimension("xyz", 2, 2)]):
        for n in (0, 1, 3, 6):
            data = [float(v) for v in rng.normal(size=n)]
            raw = M.Float64MultiArray(M.MultiArrayLayout(dims, 7), data).serialize()
            assert cdr.float64_multi_array_data(raw) == tuple(data)
            if not dims:        # what a controller sends: the encoder writes it as the binding does
                plain = M.Float64MultiArray(M.MultiArrayLayout([], 0), data).serialize()
                assert cdr.Encoder().float64_multi_array(data) == padded(plain)
    for names in ([], ["leg_1"], ["a", "bb", "ccc", "leg_4"]):
        n = len(names)
        positions = [float(v) for v in rng.normal(size=n)]
        velocities = [float(v) for v in rng.normal(size=n)] if n % 2 else []
        raw = M.JointState(M.Header(M.Time.from_ns(123_456_789_123), "frame"), names, positions, velocities,
                           [1.0] * n).serialize()
        assert cdr.joint_state_fields(raw) == (123_456_789_123, tuple(names), tuple(positions), tuple(velocities))


def test_joint_state_velocities_reach_the_twist():
    svc = FkService({"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X, "input_type": "joint_state",
                     "time_budget_ms": 1000.0})
    names = ("other", "leg_3", "leg_1", "leg_2")
    out = svc.handle(JointStateInput(names, (9.0, 0.15, 0.1, 0.12), (5.0, 0.0, 0.0, 0.0)), 7)
    assert svc.extras(out).twist == ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))     # legs at rest, another joint moving
    # velocities that are absent, partial or not finite: the finite difference instead
    for velocities in ((), (1.0, 0.0), (0.0, float("nan"), 0.0, 0.0)):
        out = svc.handle(JointStateInput(names, (9.0, 0.15, 0.1, 0.12), velocities), 8)
        assert out.leg_rates_m is None


def test_extras_thread_publishes_in_order_only_what_is_subscribed(service):
    """The solving thread hands each pose over; the extras thread builds and publishes them in
    order, and builds only the outputs that have a subscriber (none: nothing at all)."""
    from glpma_ros.node.loops import SolveLoop
    poses, extras, subscribed = [], [], [{"tf", "twist"}]
    loop = SolveLoop(service, poses.append, publish_extras=extras.append, subscribed=lambda: subscribed[0],
                     stats=service.stats, modes=service.modes)
    for k in range(20):
        loop.offer((0.1, 0.12, 0.15 + 1e-5 * k), 1_000_000 * (k + 1))
    assert loop.extras.flush(30.0)
    assert [e.stamp_ns for e in extras] == [p.stamp_ns for p in poses] and len(poses) == 20
    assert all(e.child_frame_id == "platform" and e.covariance is None and e.markers is None for e in extras)
    assert all(e.twist is not None for e in extras[1:])          # differences of consecutive poses
    subscribed[0] = set()
    loop.offer((0.1, 0.12, 0.1503), 30_000_000)
    assert loop.extras.flush(30.0)
    assert len(poses) == 21 and len(extras) == 20                # no subscriber: not even built
    st = service.stats
    assert len(st.extras_handoff_s) == 21 and len(st.extras_s) == 21 and st.extras_dropped == 0
    loop.stop()


def test_extras_without_a_thread_are_written_after_each_pose_by_the_solving_thread(service):
    """``extras_thread=False`` (the rclpy adapter): no extras thread; the thread that solved the pose
    builds and writes its extra outputs right after it, before it returns."""
    import threading

    from glpma_ros.node.loops import SolveLoop
    order, writers = [], set()

    def publish_extras(e):
        writers.add(threading.get_ident())
        order.append(("extras", e.stamp_ns))
    loop = SolveLoop(service, lambda p: order.append(("pose", p.stamp_ns)), publish_extras=publish_extras,
                     subscribed=lambda: {"tf"}, stats=service.stats, modes=service.modes, extras_thread=False)
    for k in range(5):
        loop.offer((0.1, 0.12, 0.15 + 1e-5 * k), 1_000_000 * (k + 1))
        assert order[-2:] == [("pose", 1_000_000 * (k + 1)), ("extras", 1_000_000 * (k + 1))]   # before offer returns
    assert writers == {threading.get_ident()} and loop.extras.flush(0.0)
    assert len(service.stats.extras_s) == 5
    loop.stop()


def test_extras_backlog_drops_the_oldest_and_counts_them(service):
    """A stalled extras thread never holds up the poses: beyond EXTRAS_BACKLOG the oldest
    waiting extras are dropped and counted on /diagnostics."""
    import threading

    from glpma_ros.node.loops import EXTRAS_BACKLOG, SolveLoop
    release, poses, extras = threading.Event(), [], []

    def slow_publish(e):
        release.wait(60.0)
        extras.append(e)
    loop = SolveLoop(service, poses.append, publish_extras=slow_publish, stats=service.stats, modes=service.modes)
    n = EXTRAS_BACKLOG + 30
    for k in range(n):
        loop.offer((0.1, 0.12, 0.15 + 1e-6 * k), 1_000_000 * (k + 1))
    assert len(poses) == n                                       # every pose went out at once
    release.set()
    assert loop.extras.flush(60.0)
    st = service.stats
    assert st.extras_dropped + len(extras) == n and st.extras_dropped >= n - EXTRAS_BACKLOG - 1
    assert extras[-1].stamp_ns == poses[-1].stamp_ns             # the newest are kept
    assert dict(service.diagnostics().values)["extra outputs dropped (backlog)"] == str(st.extras_dropped)
    loop.stop()
