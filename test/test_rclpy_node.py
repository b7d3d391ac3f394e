"""The rclpy transport (``ros2 run glpma_ros fk_node``): runs only where ROS 2 Jazzy is sourced."""
import contextlib
import math
import signal
import subprocess
import sys
import time
import types

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
def ros(dds_env):
    """rclpy in the test's own ROS domain (conftest: claimed, loopback discovery)."""
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


@contextlib.contextmanager
def _client(name, *spun, topic="leg_lengths", depth=10):
    """A client node writing Float64MultiArray on ``topic`` (``c.publish(data)``) and keeping every
    ``pose_estimate`` (``c.poses``), spun with the nodes ``spun`` by ``c.executor``; destroyed on exit (the nodes
    ``spun`` are not)."""
    node = rclpy.create_node(name)
    poses = []
    pub = node.create_publisher(Float64MultiArray, topic, 10)
    node.create_subscription(PoseStamped, "pose_estimate", poses.append, depth)
    executor = SingleThreadedExecutor()
    for spun_node in (*spun, node):
        executor.add_node(spun_node)
    try:
        yield types.SimpleNamespace(node=node, poses=poses, executor=executor,
                                    publish=lambda data: pub.publish(Float64MultiArray(data=list(data))))
    finally:
        executor.shutdown()
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
    with _client("glpma_fk_test_client", fk_node) as c:
        assert _spin_until(c.executor, lambda: bool(c.poses), timeout_s=120.0,   # a bound for a hang
                           publish=lambda: c.publish([0.100, 0.120, 0.150])), "no pose_estimate received"
        msg = c.poses[0]
        assert msg.header.frame_id == "robot_base"
        assert msg.pose.position.x == pytest.approx(SEED_X[0] / 1000, abs=1e-9)
        assert msg.pose.position.y == pytest.approx(SEED_X[1] / 1000, abs=1e-9)
        assert msg.pose.orientation.z == pytest.approx(math.sin(SEED_X[2] / 2), abs=1e-9)


def test_the_input_is_taken_by_its_own_thread_not_the_executor(fk_node):
    """The node's input is waited on and taken by its input thread (rcl_take): with no executor spinning the
    node, legs published still get their pose, and the subscription is in the graph as any other (remapping,
    ``ros2 node info``); the executor never waits on it."""
    from glpma_ros.node.rcl_take import NotByExecutor
    with _client("glpma_fk_test_input_thread") as c:      # the client only: nothing spins fk_node
        assert isinstance(fk_node.endpoints.input_sub.callback_group, NotByExecutor)
        assert not c.executor.can_execute(fk_node.endpoints.input_sub)
        assert _spin_until(c.executor, lambda: bool(c.poses), timeout_s=120.0,   # a bound for a hang
                           publish=lambda: c.publish([0.100, 0.120, 0.150]))
        assert c.poses[0].pose.position.x == pytest.approx(SEED_X[0] / 1000, abs=1e-9)   # metres, to round-off
        names = fk_node.get_subscriber_names_and_types_by_node("glpma_fk", "/")
        assert ("/leg_lengths", ["std_msgs/msg/Float64MultiArray"]) in names
        fk_node.endpoints.input_thread.stop()
        assert not fk_node.endpoints.input_thread.running


@pytest.mark.parametrize("config", ["delta_irb360", "linear_delta_kossel_mini"])
def test_actuator_positions_in_pose_out(ros, config):
    """An actuated family on a real rclpy: the config's example reading in SI on actuator_positions (the Delta's
    arm angles in radians, the linear Delta's carriage heights in metres) -> its working mode's pose (metres)."""
    from conftest import CONFIG
    from glpma_ros.config import load_manipulator
    from glpma_ros.node.ros_node import FkNode
    path = CONFIG / f"{config}.yaml"
    model = load_manipulator(path)
    node = FkNode(parameter_overrides=[Parameter("manipulator_config", value=str(path)),
                                       Parameter("time_budget_ms", value=GENEROUS_BUDGET_MS)])
    reading = [float(v) for v in model.readings_to_si(model.example_actuator_positions)]
    try:
        with _client("glpma_fk_actuated_client", node, topic="actuator_positions") as c:
            assert _spin_until(c.executor, lambda: bool(c.poses), timeout_s=120.0,   # a bound for a hang
                               publish=lambda: c.publish(reading))
            p = c.poses[0].pose.position
            expected = model.known_solutions[0] * model.metres_per_unit
            # metres; the known solution is written to 1e-9 mm
            assert [p.x, p.y, p.z] == pytest.approx(list(expected), abs=1e-9)
    finally:
        node.destroy_node()


# -- the further outputs ---------------------------------------------------------------------------------

def _spin_until(executor, done, timeout_s=20.0, publish=None):
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        if publish is not None:
            publish()
        executor.spin_once(timeout_sec=0.05)
    return done()


def test_tf_covariance_twist_and_markers(ros):
    from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    from glpma_ros.node.ros_node import FkNode
    node = FkNode(parameter_overrides=[Parameter("manipulator_config", value=str(RPR_YAML)),
                                       Parameter("initial_pose", value=SEED_X),
                                       Parameter("time_budget_ms", value=50.0),
                                       Parameter("publish_markers", value=True),
                                       Parameter("markers_period_s", value=0.0)])
    # the extra outputs go through rcl's C call with the interpreter lock released (rcl_publish), here too
    assert all(w.direct for w in node.endpoints.extra_writers.values())
    try:
        with _client("glpma_fk_outputs_client", node, depth=100) as c:
            got = {"pose": c.poses, "tf": [], "cov": [], "twist": [], "markers": []}
            for key, msg_type, topic in (("tf", TFMessage, "/tf"),
                                         ("cov", PoseWithCovarianceStamped, "pose_estimate_cov"),
                                         ("twist", TwistStamped, "twist_estimate"),
                                         ("markers", MarkerArray, "/glpma_fk/markers")):
                c.node.create_subscription(msg_type, topic, got[key].append, 100)
            third = iter(0.150 + 1e-5 * k for k in range(10**6))
            assert _spin_until(c.executor, lambda: len(got["twist"]) >= 2 and len(got["markers"]) >= 2,
                               publish=lambda: c.publish([0.100, 0.120, next(third)]))
            # the extra outputs follow each pose, written after it by the thread taking the input: wait for those of the
            # first poses (a pose without its TF and covariance fails below)
            poses = list(got["pose"][:5])       # more may arrive while waiting (inputs still in flight)
            first = {(p.header.stamp.sec, p.header.stamp.nanosec) for p in poses}

            def stamps(key):
                msgs = [t for m in got[key] for t in m.transforms] if key == "tf" else got[key]
                return {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in msgs}
            _spin_until(c.executor, lambda: first <= set(stamps("tf")) and first <= set(stamps("cov")), timeout_s=10.0)
            tf_by_stamp, cov_by_stamp = stamps("tf"), stamps("cov")
            for pose in poses:
                key = (pose.header.stamp.sec, pose.header.stamp.nanosec)
                t = tf_by_stamp[key]
                assert (t.header.frame_id, t.child_frame_id) == ("base", "platform")
                p, q = pose.pose.position, pose.pose.orientation
                tr, rot = t.transform.translation, t.transform.rotation
                assert max(abs(a - b) for a, b in zip((tr.x, tr.y, tr.z, rot.x, rot.y, rot.z, rot.w),
                                                      (p.x, p.y, p.z, q.x, q.y, q.z, q.w))) <= 1e-12
                cov = cov_by_stamp[key]
                assert cov.pose.pose == pose.pose
                cv = list(cov.pose.covariance)
                assert cv[14] == cv[21] == cv[28] == 1e6 and all(math.isfinite(v) for v in cv)
                assert all(cv[6 * i + j] == cv[6 * j + i] for i in range(6) for j in range(6))
            assert got["twist"][0].header.frame_id == "base"
            legs = next(m for m in got["markers"][0].markers if m.ns == "legs")
            assert len(legs.points) == 6
    finally:
        node.destroy_node()


def test_mechanism_joint_states(ros):
    """publish_joint_states: every joint of the URDF beside each pose, same stamp, on ~/mechanism_joint_states."""
    from sensor_msgs.msg import JointState

    from glpma_ros.config import load_manipulator
    from glpma_ros.description.mechanism import Mechanism
    from glpma_ros.node.ros_node import FkNode
    node = FkNode(parameter_overrides=[Parameter("manipulator_config", value=str(RPR_YAML)),
                                       Parameter("initial_pose", value=SEED_X),
                                       Parameter("time_budget_ms", value=50.0),
                                       Parameter("publish_joint_states", value=True)])
    try:
        with _client("glpma_fk_joint_states_client", node, depth=100) as c:
            poses, joints = c.poses, []
            c.node.create_subscription(JointState, "/glpma_fk/mechanism_joint_states", joints.append, 100)
            mech = Mechanism(load_manipulator(RPR_YAML))
            assert _spin_until(c.executor, lambda: len(joints) >= 2,
                               publish=lambda: c.publish([0.100, 0.120, 0.150]))
            by_stamp = {(p.header.stamp.sec, p.header.stamp.nanosec): p for p in poses}
            for js in joints[:2]:
                pose = by_stamp[(js.header.stamp.sec, js.header.stamp.nanosec)]
                p, o = pose.pose.position, pose.pose.orientation
                assert list(js.name) == list(mech.joint_names)
                # the node computed them from this pose's doubles the same way: only round-off could differ
                expected = mech.positions((p.x, p.y, p.z), (o.x, o.y, o.z, o.w))
                assert max(abs(a - b) for a, b in zip(js.position, expected)) <= 1e-12
    finally:
        node.destroy_node()


def test_ctrl_c_stops_cleanly(tmp_path, dds_env):
    """SIGINT: the summary is logged (also to /rosout, while the context is valid), exit 0, and no
    'publisher's context is invalid' or abort."""
    from conftest import CONFIG, ROOT
    out = tmp_path / "node.log"
    env = dds_env
    with open(out, "w") as f:
        proc = subprocess.Popen([sys.executable, "-c", "import sys; from glpma_ros.node.ros_node import main; "
                                 "sys.exit(main(sys.argv[1:]))", "--ros-args", "--params-file",
                                 str(CONFIG / "params_3rpr.yaml")], stdout=f, stderr=subprocess.STDOUT, env=env,
                                cwd=ROOT, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while "ready" not in out.read_text() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        assert "ready" in out.read_text(), out.read_text()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 0, out.read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
    log = out.read_text()
    assert "stopped: received" in log
    for bad in ("context is invalid", "Failed to publish", "terminate called", "Traceback"):
        assert bad not in log, log


# -- the managed node, QoS overrides, the mock publisher -----------------------------------------------

def test_lifecycle_node_walk_in_process(ros):
    """configure builds the service and the endpoints (with the QoS override), activate lets inputs
    through, deactivate counts them as dropped, cleanup releases everything."""
    from lifecycle_msgs.msg import State
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.qos import ReliabilityPolicy

    from glpma_ros.node.ros_node import FkLifecycleNode
    node = FkLifecycleNode(parameter_overrides=[
        Parameter("manipulator_config", value=str(RPR_YAML)), Parameter("initial_pose", value=SEED_X),
        Parameter("time_budget_ms", value=GENEROUS_BUDGET_MS),
        Parameter("qos_overrides./leg_lengths.subscription.reliability", value="best_effort"),
        Parameter("qos_overrides./leg_lengths.subscription.depth", value=4)])
    try:
        with _client("glpma_fk_lifecycle_client", node) as c:
            poses = c.poses

            def mine():     # the node's own subscription as the ROS graph (discovery, asynchronous) shows it
                return [i for i in node.get_subscriptions_info_by_topic("/leg_lengths") if i.node_name == "glpma_fk"]
            assert node.service is None and not mine()
            assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
            assert node.service is not None
            assert node.get_parameter("qos_overrides./leg_lengths.subscription.depth").value == 4

            assert _spin_until(c.executor, lambda: mine())
            assert mine()[0].qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
            legs = [0.100, 0.120, 0.150]
            # inactive: inputs are taken and counted as dropped, no pose
            assert _spin_until(c.executor, lambda: node.service.stats.dropped >= 3, publish=lambda: c.publish(legs))
            assert poses == []
            assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
            assert _spin_until(c.executor, lambda: poses, publish=lambda: c.publish(legs))
            assert poses[0].pose.position.x == pytest.approx(SEED_X[0] / 1000, abs=1e-9)
            assert node.trigger_deactivate() == TransitionCallbackReturn.SUCCESS
            assert node.trigger_cleanup() == TransitionCallbackReturn.SUCCESS
            assert node.service is None and _spin_until(c.executor, lambda: not mine())
            assert node.trigger_shutdown() == TransitionCallbackReturn.SUCCESS
            # rclpy (Jazzy) has no public accessor of the current state
            assert node._state_machine.current_state[0] == State.PRIMARY_STATE_FINALIZED  # noqa: SLF001
    finally:
        node.destroy_node()


def test_a_bad_qos_override_is_one_line(dds_env):
    r = subprocess.run([sys.executable, "-c", "import sys; from glpma_ros.node.ros_node import main; "
                        "sys.exit(main(sys.argv[1:]))", "--ros-args", "-p",
                        "qos_overrides./leg_lengths.subscription.reliability:=fast"],
                       capture_output=True, text=True, env=dds_env, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "qos_overrides./leg_lengths.subscription.reliability" in r.stderr


def test_mock_publisher_with_every_parameter(ros, dds_env):
    """ros2 run glpma_ros mock_publisher with a valid value of each parameter: JointState legs under the
    given names, the true pose in the given frame, the same stamp on both, exit 0 after duration_s."""
    from sensor_msgs.msg import JointState
    client = rclpy.create_node("glpma_mock_client")
    states, truths = [], []
    client.create_subscription(JointState, "joint_states", states.append, 100)
    client.create_subscription(PoseStamped, "/glpma_mock_publisher/true_pose", truths.append, 100)
    executor = SingleThreadedExecutor()
    executor.add_node(client)
    proc = subprocess.Popen([sys.executable, "-c", "import sys; from glpma_tools.mock_publisher import main; "
                             "sys.exit(main())", "--ros-args", "-p", "config:=planar_3rpr_seed",
                             "-p", "input_type:=joint_state", "-p", "joint_names:=[a, b, c]", "-p", "rate_hz:=50.0",
                             "-p", "duration_s:=2.0", "-p", "solution:=1", "-p", "amplitude:=0.5",
                             "-p", "frame_id:=world", "-p", "wait_for_subscriber:=true",
                             "-p", "wait_for_monitor:=true"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=dds_env)
    try:
        assert _spin_until(executor, lambda: proc.poll() is not None and len(truths) >= 100, timeout_s=120)
        assert proc.wait(30) == 0, proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
        executor.shutdown()
        client.destroy_node()
    assert len(states) == len(truths) == 100            # 2 s at 50 Hz, started when we subscribed
    assert states[0].name == ["a", "b", "c"] and truths[0].header.frame_id == "world"
    assert [s.header.stamp for s in states] == [t.header.stamp for t in truths]


def test_mock_publisher_bad_parameter_is_one_line(dds_env):
    r = subprocess.run([sys.executable, "-c", "import sys; from glpma_tools.mock_publisher import main; "
                        "sys.exit(main())", "--ros-args", "-p", "config:=no_such_config"],
                       capture_output=True, text=True, env=dds_env, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr


def test_the_encoders_bytes_are_the_messages_rclpy_reads():
    """The rclpy node publishes cdr.Encoder's bytes and reads its inputs with cdr: rclpy's own
    (de)serializer agrees with them, field for field (the same numbers: no arithmetic on the way)."""
    from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    from glpma_ros.node.dds import cdr
    from glpma_ros.node.outputs import ExtraOutputs, MarkerOutput
    enc = cdr.Encoder()
    stamp_ns, p, q = 1_795_000_000_123_456_789, (0.1, -0.2, 0.3), (0.0, 0.6, 0.0, 0.8)
    pose = deserialize_message(enc.pose_stamped(stamp_ns, "robot_base", p, q), PoseStamped)
    assert (pose.header.stamp.sec, pose.header.stamp.nanosec, pose.header.frame_id) == (1_795_000_000, 123_456_789,
                                                                                          "robot_base")
    assert (pose.pose.position.x, pose.pose.position.y, pose.pose.position.z) == p
    assert (pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z, pose.pose.orientation.w) == q
    cov = [float(k) for k in range(36)]
    marker = MarkerOutput(ns="legs", id=1, type=5, action=0, scale=(0.01, 0.0, 0.0), color=(1.0, 0.0, 0.0, 1.0),
                          points=((0.0, 0.0, 0.0), (1.0, 2.0, 3.0)), colors=((0.5, 0.5, 0.5, 1.0),) * 2)
    ex = ExtraOutputs(stamp_ns=stamp_ns, frame_id="base", child_frame_id="platform", position=p, orientation=q,
                      covariance=cov, twist=((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)), markers=[marker])
    out = {name: data for name, data in enc.extras(ex)}
    tf = deserialize_message(out["tf"], TFMessage).transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id, tf.transform.translation.y, tf.transform.rotation.w) == \
        ("base", "platform", -0.2, 0.8)
    assert list(deserialize_message(out["covariance"], PoseWithCovarianceStamped).pose.covariance) == cov
    tw = deserialize_message(out["twist"], TwistStamped).twist
    assert (tw.linear.x, tw.angular.z) == (1.0, 6.0)
    m = deserialize_message(out["markers"], MarkerArray).markers[0]
    assert (m.ns, m.id, m.type, m.header.frame_id, len(m.points), m.points[1].z, m.colors[1].r) == \
        ("legs", 1, 5, "base", 2, 3.0, 0.5)
    legs = Float64MultiArray(data=[0.1, 0.12, 0.15])
    assert cdr.float64_multi_array_data(serialize_message(legs)) == (0.1, 0.12, 0.15)
    ex = ExtraOutputs(stamp_ns=stamp_ns, frame_id="base", position=p, orientation=q,
                      joint_names=("leg1_u1", "leg1_actuator"), joint_positions=(0.25, 1.5),
                      joint_velocities=(-1.0, 2.0))
    (name, data), = enc.extras(ex)
    mjs = deserialize_message(data, JointState)
    assert (name, mjs.header.frame_id, list(mjs.name), list(mjs.position), list(mjs.velocity), list(mjs.effort)) == \
        ("joint_states", "base", ["leg1_u1", "leg1_actuator"], [0.25, 1.5], [-1.0, 2.0], [])
    js = JointState(name=["a", "leg_1"], position=[0.5, 0.1], velocity=[0.0, -0.01])
    js.header.stamp.sec, js.header.stamp.nanosec = 7, 8
    assert cdr.joint_state_fields(serialize_message(js)) == (7_000_000_008, ("a", "leg_1"), (0.5, 0.1), (0.0, -0.01))


@pytest.mark.parametrize("variant", ["echo", "shipped"])
def test_bench_part_4_pairs_every_pose_with_the_input_it_answers(dds_env, dds_domain, variant):
    """The bench's part 4 for 1 s: the client process writes the legs as bytes and takes every pose by its own
    thread; each pose it received pairs with an input sent (by the legs an echo carries, by the true pose
    the node's lies on), none is wrong, and the counts add up (no share asserted: that is the bench's figure)."""
    from glpma_tools.bench import rclpy_client
    from glpma_tools.bench.scenarios import load
    from glpma_tools.bench.transport import params_of
    sc = load("3rpr")
    row = rclpy_client.run_variant(sc, 1.0, dds_domain, variant, rclpy_client.LISTENER, False,
                                   {**params_of(sc.model.kind), "manipulator_config": sc.path})
    assert row["sent"] == 1000 and row["wrong"] == 0
    assert 0 < row["poses"] <= row["received"] <= row["sent"]
    assert row["received"] - row["dropped"] >= row["poses"]          # a pose per input solved, at most
    assert 0 <= row["client_late"] <= row["sent"] and row["p50"] <= row["p99"]
    assert row["steal_ms"] is None or row["steal_ms"] >= 0          # the hypervisor's, where Linux reports it


def test_the_pose_is_stamped_by_the_ros_clock_simulated_or_not(ros):
    """A pose's stamp is its input's arrival on the node's ROS clock: the /clock time with ``use_sim_time``
    (at start and when switched on at runtime), the system time without."""
    from rosgraph_msgs.msg import Clock

    from glpma_ros.node.ros_node import FkNode
    node = FkNode(parameter_overrides=[Parameter("manipulator_config", value=str(RPR_YAML)),
                                       Parameter("initial_pose", value=SEED_X),
                                       Parameter("time_budget_ms", value=GENEROUS_BUDGET_MS),
                                       Parameter("use_sim_time", value=True)])
    try:
        with _client("glpma_fk_test_sim_time", node) as c:
            clock_pub = c.node.create_publisher(Clock, "/clock", 10)
            sim = Clock()
            sim.clock.sec, sim.clock.nanosec = 1234, 500_000_000

            def publish():
                clock_pub.publish(sim)
                c.publish([0.100, 0.120, 0.150])
            # the node takes /clock in its executor: poses stamped 0 until the first one arrives
            assert _spin_until(c.executor, lambda: any(p.header.stamp.sec == 1234 for p in c.poses),
                               timeout_s=120.0, publish=publish), [p.header.stamp for p in c.poses]
            assert any(p.header.stamp.nanosec == 500_000_000 for p in c.poses if p.header.stamp.sec == 1234)
            assert node.set_parameters([Parameter("use_sim_time", value=False)])[0].successful
            c.poses.clear()
            before = time.time()
            assert _spin_until(c.executor, lambda: bool(c.poses), timeout_s=120.0,
                               publish=lambda: c.publish([0.100, 0.120, 0.150]))
            stamp = c.poses[-1].header.stamp.sec + c.poses[-1].header.stamp.nanosec * 1e-9
            # the system clock: at or after the first input was published (a bound, not a latency)
            assert before - 1.0 <= stamp <= time.time() + 1.0, (before, stamp)
            assert node.set_parameters([Parameter("use_sim_time", value=True)])[0].successful
            c.poses.clear()
            assert _spin_until(c.executor, lambda: any(p.header.stamp.sec == 1234 for p in c.poses),
                               timeout_s=120.0, publish=publish)
    finally:
        node.destroy_node()
