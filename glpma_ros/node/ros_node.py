"""The ``glpma_fk`` node on rclpy (``ros2 run glpma_ros fk_node``).

A thin adapter: parameters are declared from :mod:`glpma_ros.node.params` (with
descriptions and ranges), changes are validated and applied by
:class:`~glpma_ros.node.service.FkService`, inputs go through the shared
:class:`~glpma_ros.node.loops.SolveLoop` (newest input only), assembly-modes requests
through :class:`~glpma_ros.node.loops.AssemblyModesLoop`, and messages are
converted here.  Importable only where rclpy is.

Threads: the input is waited on and taken by a thread of its own
(:class:`~glpma_ros.node.rcl_take.InputThread`: a wait set of the input subscription alone, the interpreter
lock released while it waits), which takes the newest input waiting (the ones it passes over count as dropped:
the node's newest-input rule) and solves it right there (:meth:`SolveLoop.offer
<glpma_ros.node.loops.SolveLoop.offer>`), then publishes the pose and, after it, TF, covariance, twist and
markers on the topics that have subscribers (:class:`~glpma_ros.node.loops.ExtrasLoop` without a thread of its
own: their writes release the interpreter lock, see below, and a second Python thread building them would take
that lock from this one when the next input arrives). A ``SingleThreadedExecutor`` spinning in a thread of its
own runs the rest (parameters, services, the assembly-modes request, lifecycle transitions) and never waits on
the input: rclpy's executors rebuild their wait set from every entity of the node on each wake-up, several
hundred microseconds of Python per input on a small machine. Solving in the thread that takes the input saves
the thread switch per input that a solver thread would cost (BENCHMARKS.md, "Extra outputs and the transport
path", measures the set-ups). Messages: the input is taken as bytes (``raw=True``) and read with ``struct``,
the pose and its extra outputs are written as bytes (through ``rcl``, :mod:`~glpma_ros.node.rcl_publish`; a
real-time node's pose by ``Publisher.publish(bytes)``) from the DDS twin's
:class:`~glpma_ros.node.dds.cdr.Encoder` -- no rclpy message object is built per input (test_rclpy_node checks
that rclpy reads those bytes as the same messages); diagnostics and assembly modes are rclpy messages.
Signals: rclpy's own handler is not installed (``SignalHandlerOptions.NO``); SIGINT / SIGTERM stop the node,
which logs its summary while the context is still valid and then shuts down -- no "publisher's context is
invalid" at Ctrl-C.
"""
from __future__ import annotations

import array
import math
import signal
import sys
import threading
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, PoseWithCovarianceStamped, TwistStamped
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSPolicyKind, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import InvalidQosOverridesError, QoSOverridingOptions
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from rclpy.time_source import USE_SIM_TIME_NAME as USE_SIM_TIME
from sensor_msgs.msg import JointState
from std_msgs.msg import Empty, Float64MultiArray
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from ..errors import GlpmaError
from . import input_topic as inputs
from . import params as P
from . import qos
from .dds import cdr
from .loops import node_loops
from .rcl_publish import RawPublisher
from .rcl_take import subscribe_taken_by_thread
from .ros_args import check_params_files, node_values, remapped
from .service import FkService, JointStateInput

#: every publisher and subscription declares qos_overrides.<topic>.<entity>.<policy> for these
#: policies (glpma_ros.node.qos.POLICIES; the DDS transport reads the same keys)
QOS_OVERRIDING = QoSOverridingOptions([QoSPolicyKind[name.upper()] for name in qos.POLICIES])
#: seconds main() waits at exit for the executor's thread to leave rclpy (it wakes at once on
#: executor.shutdown(); the cap only guards against a wedged middleware)
SPINNER_JOIN_TIMEOUT_S = 10.0
#: seconds the extra outputs' subscriber counts are reused: a count is a call into rcl that
#: holds the interpreter lock (5 outputs, about 4 us each, per pose); a new subscriber waits this much
#: longer for its first message, well within the discovery's own delay
SUBSCRIBED_REFRESH_S = 0.1
ROS_TYPES = {P.STRING: ParameterType.PARAMETER_STRING, P.DOUBLE: ParameterType.PARAMETER_DOUBLE,
             P.INTEGER: ParameterType.PARAMETER_INTEGER, P.BOOL: ParameterType.PARAMETER_BOOL,
             P.DOUBLE_ARRAY: ParameterType.PARAMETER_DOUBLE_ARRAY,
             P.STRING_ARRAY: ParameterType.PARAMETER_STRING_ARRAY,
             P.INTEGER_ARRAY: ParameterType.PARAMETER_INTEGER_ARRAY}
#: how an array parameter without default is declared (an empty list has no inferable type)
ARRAY_PARAMETER_TYPES = {P.DOUBLE_ARRAY: Parameter.Type.DOUBLE_ARRAY, P.STRING_ARRAY: Parameter.Type.STRING_ARRAY,
                         P.INTEGER_ARRAY: Parameter.Type.INTEGER_ARRAY}


def descriptor(spec: P.ParamSpec) -> ParameterDescriptor:
    d = ParameterDescriptor(name=spec.name, type=ROS_TYPES[spec.type], description=spec.description,
                            additional_constraints=spec.constraints, read_only=spec.read_only)
    if spec.range and spec.type == P.DOUBLE:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.range[0]),
                                                     to_value=float(spec.range[1]), step=0.0)]
    elif spec.range and spec.type == P.INTEGER:
        d.integer_range = [IntegerRange(from_value=int(spec.range[0]), to_value=int(spec.range[1]), step=1)]
    return d


def qos_profile(spec: qos.QosSpec) -> QoSProfile:
    """:class:`~glpma_ros.node.qos.QosSpec` -> rclpy's ``QoSProfile``."""
    return QoSProfile(depth=spec.depth, history=HistoryPolicy[spec.history.upper()],
                      reliability=ReliabilityPolicy[spec.reliability.upper()],
                      durability=DurabilityPolicy[spec.durability.upper()])


def _plain(value):
    """rclpy parameter value -> the plain Python value the service expects."""
    if isinstance(value, (array.array, tuple)):
        return list(value)
    return value


def declare_parameters(node, on_set_parameters) -> None:
    """Declare every parameter of :mod:`glpma_ros.node.params` on ``node`` (with its descriptor) and
    route their changes to ``on_set_parameters``."""
    for spec in P.PARAMETERS:
        # an empty array has no inferable type: declare the type without a default
        default = ARRAY_PARAMETER_TYPES[spec.type] if spec.type in P.ARRAY_TYPES and not spec.default \
            else spec.default
        node.declare_parameter(spec.name, default, descriptor(spec))
    node.add_on_set_parameters_callback(on_set_parameters)


def parameter_values(node) -> dict:
    """name -> current value of every parameter declared by :func:`declare_parameters`."""
    values = {}
    for spec in P.PARAMETERS:
        try:
            value = node.get_parameter(spec.name).value
        except ParameterUninitializedException:     # declared by type only, and not overridden
            value = None
        values[spec.name] = spec.default if value is None else _plain(value)
    return values


def _use_sim_time(node) -> bool:
    """The node's ``use_sim_time`` (declared by rclpy for every node; False when not a bool, as rclpy's
    TimeSource reads it)."""
    parameter = node.get_parameter(USE_SIM_TIME)
    return parameter.type_ == Parameter.Type.BOOL and bool(parameter.value)


class FkEndpoints:
    """What both rclpy nodes hold as a member (:class:`FkNode`, :class:`FkLifecycleNode`), handed the
    node it serves and how that node creates and destroys its publishers (a lifecycle node's are
    managed): :meth:`open` / :meth:`close` of the service, the publishers and subscriptions (with
    QoS overrides), the loops and the diagnostics thread, the message conversions, and the
    parameter changes (:meth:`on_set_parameters`)."""

    def __init__(self, node, create_publisher, destroy_publisher, active: bool = True):
        """``active``: inputs are solved and outputs published (a lifecycle node: only while active)."""
        self.node = node
        self._create_publisher = create_publisher
        self._destroy_publisher = destroy_publisher
        self.active = active
        self.service = None
        self._stopped = True
        self._clock = node.get_clock()
        # whether the ROS clock runs on simulated time (use_sim_time, which rclpy's TimeSource follows):
        # kept here from the parameter, read on every input at no cost (the clock's own flag is a call
        # into rcl, a tenth of the input path when the caches are cold between inputs)
        self._sim_time = _use_sim_time(node)
        node.add_post_set_parameters_callback(self._note_use_sim_time)

    def open(self, values: dict) -> None:
        """Build the service (reads the config), warm up the solvers, create every endpoint and
        start the loops."""
        node = self.node
        service = FkService(values, logger=node.get_logger(), node_name=node.get_name())
        node.get_logger().info(f"{service.describe()}; warming up the solvers")
        node.get_logger().info(f"warm-up done in {service.warm_up():.2f} s")
        self.service, self._stopped = service, False
        input_topic = service.input_topic
        profiles = qos.node_endpoints(values["qos_depth"], input_topic)

        def pub(msg_type, topic):
            return self._create_publisher(msg_type, topic, qos_profile(profiles[(topic, qos.PUBLISHER)]),
                                          qos_overriding_options=QOS_OVERRIDING)

        def sub_qos(topic):
            return qos_profile(profiles[(topic, qos.SUBSCRIPTION)])

        # every output has its publisher from the start: the publish_* parameters switch them at runtime;
        # the pose and the extra outputs go out as bytes from cdr.Encoder (rcl_publish.RawPublisher)
        self._encode = cdr.Encoder()
        self.pose_pub = pub(PoseStamped, "pose_estimate")
        self.tf_pub = pub(TFMessage, "/tf")
        self.cov_pub = pub(PoseWithCovarianceStamped, "pose_estimate_cov")
        self.twist_pub = pub(TwistStamped, "twist_estimate")
        self.markers_pub = pub(MarkerArray, "~/markers")
        self.joint_states_pub = pub(JointState, "~/mechanism_joint_states")
        self.diag_pub = pub(DiagnosticArray, "/diagnostics")
        self.modes_pub = pub(PoseArray, "~/assembly_modes")        # latched by default
        self._publishers_opened = [self.pose_pub, self.tf_pub, self.cov_pub, self.twist_pub, self.markers_pub,
                                   self.joint_states_pub, self.diag_pub, self.modes_pub]
        # inputs are solved in the executor's thread (SolveLoop.offer): its own thread is not started
        self._extra_pubs = {"tf": self.tf_pub, "covariance": self.cov_pub, "twist": self.twist_pub,
                            "markers": self.markers_pub, "joint_states": self.joint_states_pub}
        # the extra outputs are written with the interpreter lock released (rcl_publish.RawPublisher)
        self.extra_writers = {name: RawPublisher(p) for name, p in self._extra_pubs.items()}
        # ... and the pose too, unless the input thread is real-time (thread_priority): a thread of normal
        # priority taking the lock meanwhile could hold it, preempted, from the real-time one (BENCHMARKS.md, part 4)
        realtime = values["thread_priority"] > 0
        self.pose_writer = self.pose_pub if realtime else RawPublisher(self.pose_pub)
        self._subscribed_cache, self._subscribed_at = set(), -math.inf
        self.loop, self.modes, self.reports = node_loops(
            service, publish_pose=self._publish_pose, publish_extras=self._publish_extras,
            subscribed=self._subscribed, publish_modes=self._publish_modes, publish_report=self._publish_diagnostics,
            # built and written after the pose by the thread that took the input; a real-time node keeps a thread
            # of their own, real-time too: their writes release the interpreter lock (as above)
            extras_thread=realtime)
        self.modes.start()
        # the input is taken as bytes and read with struct (cdr): no message object per input; by a thread of
        # its own waiting on it alone (rcl_take.InputThread), not by the executor
        if values["input_type"] == P.INPUT_JOINT_STATE:     # read-only: fixed for the node's life
            input_type, input_name, on_input = JointState, "joint_states", self._on_joint_state
        else:
            input_type, input_name, on_input = Float64MultiArray, input_topic, self._on_legs
        self.input_sub, self.input_thread = subscribe_taken_by_thread(
            node.create_subscription, input_type, input_name, sub_qos(input_name), node.context, on_input,
            qos_overriding_options=QOS_OVERRIDING)
        self.request_sub = node.create_subscription(Empty, "~/request_assembly_modes", self._on_request_modes,
                                                    sub_qos("~/request_assembly_modes"),
                                                    qos_overriding_options=QOS_OVERRIDING)
        # /diagnostics from a thread of its own, off the executor's (ReportLoop)
        self.reports.start()

    def close(self) -> None:
        """Stop the loops (logging the summary) and destroy what :meth:`open` created."""
        if self.service is None:
            return
        self.stop()
        for subscription in (self.input_sub, self.request_sub):
            self.node.destroy_subscription(subscription)
        for publisher in self._publishers_opened:
            self._destroy_publisher(publisher)
        self._publishers_opened, self._extra_pubs, self.extra_writers, self.pose_writer = [], {}, {}, None
        self.service = None

    def _taking(self, passed_over: int) -> bool:
        """True when inputs are solved (the ``passed_over`` older ones taken with it count as dropped);
        otherwise (an inactive lifecycle node) the input and those count as received and dropped."""
        if passed_over:
            self.service.note_dropped(passed_over)
        if self.active:
            return True
        self.service.note_dropped(1)
        return False

    def _on_legs(self, data: bytes, passed_over: int) -> None:
        """The newest input taken (:class:`~.rcl_take.InputThread`), ``passed_over``: the older ones taken with it."""
        if not self._taking(passed_over):
            return
        stamp_ns = self._now_ns()       # the pose's stamp: the arrival of its input
        if self.loop.offer_message(data, stamp_ns):     # solved and published in one compiled call
            return
        try:
            legs = (cdr.float64_multi_array_data(data) if cdr.little_endian_cdr(data)
                    else tuple(deserialize_message(data, Float64MultiArray).data))
        except Exception as exc:  # noqa: BLE001 - a sample that does not deserialize
            self.service.log.warning(f"could not read leg_lengths: {exc}")
            return
        self.loop.offer(legs, stamp_ns)

    def _now_ns(self) -> int:
        """The node's ROS clock now (ns): the system clock read directly unless simulated time is active --
        what the ROS clock reads then, at a tenth of the cost of ``Clock.now()`` and its ``Time`` object."""
        return self._clock.now().nanoseconds if self._sim_time else time.time_ns()

    def _note_use_sim_time(self, parameters) -> None:
        for parameter in parameters:
            if parameter.name == USE_SIM_TIME and parameter.type_ == Parameter.Type.BOOL:
                self._sim_time = parameter.value

    def _on_joint_state(self, data: bytes, passed_over: int) -> None:
        if not self._taking(passed_over):
            return
        try:
            if cdr.little_endian_cdr(data):
                stamp_ns, names, positions, velocities = cdr.joint_state_fields(data)
            else:
                msg = deserialize_message(data, JointState)
                stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
                names, positions, velocities = tuple(msg.name), tuple(msg.position), tuple(msg.velocity)
        except Exception as exc:  # noqa: BLE001
            self.service.log.warning(f"could not read joint_states: {exc}")
            return
        self.loop.offer(JointStateInput(names, positions, velocities), stamp_ns)

    def _on_request_modes(self, _msg: Empty) -> None:
        if self.active:
            self.modes.request(self._now_ns())

    def _publish_modes(self, modes) -> None:
        msg = PoseArray()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(modes.stamp_ns, 1_000_000_000)
        msg.header.frame_id = modes.frame_id
        for position, orientation in modes.poses:
            pose = Pose()
            pose.position.x, pose.position.y, pose.position.z = position
            pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = orientation
            msg.poses.append(pose)
        self.modes_pub.publish(msg)

    def _publish_pose(self, pose) -> None:
        self.pose_writer.publish(self._encode.pose(pose))

    def _subscribed(self) -> set:
        """The extra outputs some subscription is matched with (the others are not built), counted
        again at most every :data:`SUBSCRIBED_REFRESH_S` (called by the thread taking the input only)."""
        now = time.monotonic()
        if now - self._subscribed_at >= SUBSCRIBED_REFRESH_S:
            self._subscribed_cache = {name for name, pub in self._extra_pubs.items() if pub.get_subscription_count()}
            self._subscribed_at = now
        return self._subscribed_cache

    def _publish_extras(self, ex) -> None:
        """/tf, pose_estimate_cov, twist_estimate, ~/markers, ~/mechanism_joint_states of
        :class:`~glpma_ros.node.outputs.ExtraOutputs`, each written with the interpreter lock released."""
        for name, data in self._encode.extras(ex):
            self.extra_writers[name].publish(data)

    def _publish_diagnostics(self, report) -> None:
        if not self.active:
            return
        msg = DiagnosticArray()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.status = [DiagnosticStatus(level=bytes([report.level]), name=report.name, message=report.message,
                                       hardware_id=report.hardware_id,
                                       values=[KeyValue(key=k, value=v) for k, v in report.values])]
        self.diag_pub.publish(msg)

    def on_set_parameters(self, parameters) -> SetParametersResult:
        """The node's parameters callback: checked and applied by the service (before configure:
        checked only, applied at configure)."""
        # the service's own; rclpy's (use_sim_time, which its TimeSource applies; the QoS overrides, read-only)
        # are left to it
        mine = [p for p in parameters if p.name in P.SPECS]
        if not mine:
            return SetParametersResult(successful=True)
        if self.service is None:        # not configured yet (lifecycle): checked now, applied at configure
            try:
                for p in mine:
                    P.coerce(p.name, _plain(p.value))
            except GlpmaError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            return SetParametersResult(successful=True)
        ok, reason = self.service.set_parameters({p.name: _plain(p.value) for p in mine})
        return SetParametersResult(successful=ok, reason=reason)

    def stop(self) -> None:
        """Stop the solver and assembly-modes threads and log the summary (the context must
        still be valid: the log goes to /rosout too).  Idempotent."""
        if self._stopped:
            return
        self._stopped = True
        self.input_thread.stop()
        self.reports.stop()
        self.loop.stop()
        self.modes.stop()
        self.node.get_logger().info(f"stopped: {self.service.summary()}")

    def destroy(self) -> None:
        """Before the node is destroyed: stop the threads (with the summary while the context is valid)."""
        if self.service is None:
            return
        if rclpy.ok(context=self.node.context):
            self.stop()
        elif not self._stopped:     # the context is gone: no logging through rosout any more
            self._stopped = True
            self.input_thread.stop()
            self.reports.stop()
            self.loop.stop()
            self.modes.stop()


class FkNode(Node):
    """``ros2 run glpma_ros fk_node``: configured and publishing from the start."""

    def __init__(self, **node_kwargs):
        super().__init__(P.NODE_NAME, **node_kwargs)
        self.endpoints = FkEndpoints(self, self.create_publisher, self.destroy_publisher)
        declare_parameters(self, self.endpoints.on_set_parameters)
        self.endpoints.open(parameter_values(self))
        self.get_logger().info("ready")

    @property
    def service(self):
        """The node's :class:`~glpma_ros.node.service.FkService`."""
        return self.endpoints.service

    def stop(self) -> None:
        """Stop the node's threads and log the summary (:meth:`FkEndpoints.stop`)."""
        self.endpoints.stop()

    def destroy_node(self):
        self.endpoints.destroy()
        return super().destroy_node()


class FkLifecycleNode(LifecycleNode):
    """``ros2 run glpma_ros fk_lifecycle_node``: the same node, managed (ROS 2 design, *Managed nodes*).

    * unconfigured: parameters declared (and checked when set), nothing else;
    * ``configure``: reads the config, builds the estimator, loads the compiled solvers (the
      warm-up), creates the publishers (managed: silent until active) and subscriptions;
    * ``activate``: inputs are solved and every output published;
    * ``deactivate``: nothing is published; inputs that arrive are counted (received, dropped)
      and not solved; the warm-start state is kept;
    * ``cleanup`` / ``shutdown``: the loops stop (the summary is logged) and every endpoint is
      destroyed; ``configure`` starts again from the parameters' values.
    A failed configure (a bad config) logs the reason and leaves the node unconfigured."""

    def __init__(self, **node_kwargs):
        super().__init__(P.NODE_NAME, **node_kwargs)
        self.endpoints = FkEndpoints(self, self.create_lifecycle_publisher, self.destroy_lifecycle_publisher,
                                     active=False)
        declare_parameters(self, self.endpoints.on_set_parameters)
        self.get_logger().info("unconfigured: waiting for configure (ros2 lifecycle set /glpma_fk configure)")

    @property
    def service(self):
        """The node's :class:`~glpma_ros.node.service.FkService` (None while unconfigured)."""
        return self.endpoints.service

    def stop(self) -> None:
        """Stop the node's threads and log the summary (:meth:`FkEndpoints.stop`)."""
        self.endpoints.stop()

    def destroy_node(self):
        self.endpoints.destroy()
        return super().destroy_node()

    def on_configure(self, state) -> TransitionCallbackReturn:
        try:
            self.endpoints.open(parameter_values(self))
        except GlpmaError as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info("configured (inactive)")
        return super().on_configure(state)

    def on_activate(self, state) -> TransitionCallbackReturn:
        result = super().on_activate(state)        # enables the managed publishers
        self.endpoints.active = True
        self.get_logger().info("active")
        return result

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        self.endpoints.active = False
        self.get_logger().info("inactive: inputs are counted and dropped")
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        self.endpoints.active = False
        self.endpoints.close()
        return super().on_cleanup(state)

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        self.endpoints.active = False
        self.endpoints.close()
        return super().on_shutdown(state)


def check_arguments(argv) -> None:
    """The mistakes in ``--ros-args`` that rclpy would report with a traceback, as one
    :class:`GlpmaError` line: a params file that is not one (e.g. a manipulator YAML) and a bad QoS
    override.  What our parser cannot read is left to rclpy."""
    check_params_files(argv)
    try:
        values, _, ros = node_values(argv)
    except GlpmaError:
        return
    input_topic = inputs.input_topic(values["input_type"], inputs.config_is_actuated(values["manipulator_config"]))
    qos.resolve(ros.overrides, values["qos_depth"], input_topic, ros.node_name,
                topic_of=lambda name: remapped(name, ros.remaps))


def main(args=None, node_class=None) -> int:
    """Entry point of ``fk_node`` (``node_class`` :class:`FkNode`) and ``fk_lifecycle_node``
    (:class:`FkLifecycleNode`); ``args`` are the arguments after the program name.
    SIGINT / SIGTERM end it with status 0 after logging the summary."""
    node_class = node_class or FkNode
    try:   # a params-file mistake (e.g. a manipulator YAML) in one line, before rcl's parser sees it
        check_arguments(sys.argv[1:] if args is None else args)
    except GlpmaError as exc:
        print(f"glpma_fk: error: {exc}", file=sys.stderr)
        return 2
    rclpy.init(args=None if args is None else [sys.argv[0], *args],
               signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    node = executor = spinner = None
    try:
        node = node_class()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spinner = threading.Thread(target=_spin, args=(executor, stop), name="glpma_fk-executor", daemon=True)
        spinner.start()
        stop.wait()                 # returns on a signal (the handler runs in this thread)
        if node.service is not None:
            node.stop()
    except (GlpmaError, ParameterException, InvalidQosOverridesError) as exc:
        print(f"glpma_fk: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if executor is not None:
            executor.shutdown()
        if spinner is not None:
            # joined, not left to die at exit: a thread still inside rclpy's C++ code when the
            # interpreter finalizes aborts the process ("terminate called without an active exception")
            spinner.join(SPINNER_JOIN_TIMEOUT_S)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0


def lifecycle_main(args=None) -> int:
    """Entry point of ``fk_lifecycle_node``: the managed node, driven by ``ros2 lifecycle set``."""
    return main(args, FkLifecycleNode)


def _spin(executor, stop: threading.Event) -> None:
    """The executor's thread: spin until shut down; an external shutdown stops the node too."""
    try:
        executor.spin()
    except ExternalShutdownException:
        pass
    finally:
        stop.set()


if __name__ == "__main__":
    sys.exit(main())
