"""Helpers for launch tests of a bringup that uses the ``glpma_fk`` node (``launch_testing`` or
``launch_pytest``, run by ``colcon test``).

* :func:`fk_with_mock` -- the launch actions of ``fk.launch.py`` (the node, managed or not) and of
  ``ros2 run glpma_ros mock_publisher`` (a simulated controller along a known trajectory that
  publishes the true pose beside the legs);
* :class:`TrackingMonitor` -- an rclpy helper that collects the node's ``pose_estimate`` and the
  mock's ``~/true_pose``, pairs every pose with the input it answers
  (:mod:`glpma_ros.testing.matching`: by stamp for ``joint_states``, by the legs it reproduces for
  ``leg_lengths``) and asserts the tracking error.

README, "Testing your integration", has a complete test to copy.  rclpy and launch are imported
only by the functions that need them; :mod:`.matching` needs neither.
"""
from __future__ import annotations

import time

#: the mock publisher's node name and its true-pose topic
MOCK_NODE_NAME = "glpma_mock_publisher"
TRUE_POSE_TOPIC = f"/{MOCK_NODE_NAME}/true_pose"
#: the shipped manipulator config of each ``manipulator:=`` of fk.launch.py
MANIPULATOR_CONFIGS = {"3rpr": "planar_3rpr_seed", "hexapod": "hexapod_66_rolland", "delta": "delta_irb360"}
#: a pose on its input's true pose to this distance is right: a converged pose is at round-off
#: (leg residuals ~1e-13 of the geometry's size), six orders of magnitude below
POSITION_TOL_M = 1e-9
ORIENTATION_TOL_RAD = 1e-9
#: history kept by the monitor's subscriptions (about 20 s at 50 Hz): nothing is lost while a test spins
MONITOR_DEPTH = 1000


def fk_with_mock(manipulator: str = "3rpr", *, managed: bool = False, autostart: bool = False,
                 input_type: str = "float64_multi_array",
                 rate_hz: float = 50.0, duration_s: float = 0.0, params_file: str | None = None,
                 mock_parameters: dict | None = None, keystore: str | None = None,
                 mock_enclave: str = "/controller", launch_arguments: dict | None = None) -> list:
    """Launch actions: ``fk.launch.py`` with ``manipulator``, ``managed``, ``autostart``, ``input_type`` (and
    ``params_file`` if given) and the mock publisher driving the same manipulator's shipped config
    at ``rate_hz`` for ``duration_s`` (0: until shutdown).  With ``keystore`` (an SROS2 keystore
    with enclaves ``/glpma_fk`` and ``mock_enclave``) both run secured (``secure:=true``; README,
    "Running secured").  ``launch_arguments``: more arguments of ``fk.launch.py`` (e.g.
    ``{"robot_description": "true"}``).  Add ``launch_testing.actions.ReadyToTest()`` (or launch_pytest's)
    after them."""
    from launch.actions import IncludeLaunchDescription
    from launch.launch_description_sources import PythonLaunchDescriptionSource
    from launch.substitutions import PathJoinSubstitution
    from launch_ros.actions import Node
    from launch_ros.substitutions import FindPackageShare

    args = {"manipulator": manipulator, "managed": str(bool(managed)).lower(),
            "autostart": str(bool(autostart)).lower(), "input_type": input_type}
    if params_file is not None:
        args["params_file"] = str(params_file)
    args.update({str(k): str(v) for k, v in (launch_arguments or {}).items()})
    secured = {}
    if keystore is not None:
        args.update(secure="true", keystore=str(keystore))
        secured = dict(ros_arguments=["--enclave", mock_enclave],
                       additional_env={"ROS_SECURITY_KEYSTORE": str(keystore), "ROS_SECURITY_ENABLE": "true",
                                       "ROS_SECURITY_STRATEGY": "Enforce"})
    fk = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(PathJoinSubstitution([FindPackageShare("glpma_ros"), "launch", "fk.launch.py"])),
        launch_arguments=args.items())
    mock = Node(package="glpma_ros", executable="mock_publisher", name=MOCK_NODE_NAME, output="screen",
                parameters=[{"config": MANIPULATOR_CONFIGS.get(manipulator, manipulator), "input_type": input_type,
                             "rate_hz": float(rate_hz), "duration_s": float(duration_s),
                             # the first input once the node and the test's TrackingMonitor listen
                             "wait_for_subscriber": True, "wait_for_monitor": True, **(mock_parameters or {})}],
                **secured)
    return [fk, mock]


class TrackingMonitor:
    """Collects ``pose_estimate`` and the mock's ``~/true_pose`` on an rclpy node of the test and
    judges the tracking (:meth:`assert_tracking`).  ``config``: the manipulator config the mock
    drives (a shipped name or a path); ``input_type``: what the mock publishes."""

    def __init__(self, node, config: str = "planar_3rpr_seed", input_type: str = "float64_multi_array",
                 pose_topic: str = "pose_estimate", true_pose_topic: str = TRUE_POSE_TOPIC):
        from geometry_msgs.msg import PoseStamped

        from ..config import load_manipulator, resolve_config
        self.node = node
        self.model = load_manipulator(resolve_config(MANIPULATOR_CONFIGS.get(config, config)))
        self.by_stamp = input_type == "joint_state"
        self.poses: list = []           # (receive ns, stamp ns, frame_id, position m (3,), quaternion (4,))
        self.truths: list = []          # matching's inputs: send ns (= stamp), legs, position m, quaternion
        node.create_subscription(PoseStamped, pose_topic, self._on_pose, MONITOR_DEPTH)
        node.create_subscription(PoseStamped, true_pose_topic, self._on_truth, MONITOR_DEPTH)

    @staticmethod
    def _fields(msg):
        import numpy as np
        p, q = msg.pose.position, msg.pose.orientation
        return (msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, msg.header.frame_id,
                np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]))

    def _on_pose(self, msg) -> None:
        self.poses.append((self.node.get_clock().now().nanoseconds, *self._fields(msg)))

    def _on_truth(self, msg) -> None:
        from .matching import legs_for
        stamp_ns, _, position_m, q = self._fields(msg)
        legs = legs_for(self.model, position_m / self.model.metres_per_unit, q)
        self.truths.append(_Truth(stamp_ns, legs, position_m, q))

    def judged(self) -> list:
        """The poses that can be judged: stamped no later than the newest true pose received (a
        later one may answer an input whose true pose is still on its way; it is judged once a
        later true pose has come, which the mock's stream guarantees while it runs)."""
        newest = max((t.send_ns for t in self.truths), default=None)
        return [] if newest is None else [p for p in self.poses if p[1] <= newest]

    def spin_until(self, executor, poses: int, timeout_s: float) -> bool:
        """Spin ``executor`` (holding the monitor's node) until ``poses`` poses can be judged, or
        ``timeout_s`` passed (a bound for a hang, not a timing figure); True when they can."""
        deadline = time.monotonic() + timeout_s
        while len(self.judged()) < poses and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        return len(self.judged()) >= poses

    def comparison(self):
        """:class:`~glpma_ros.testing.matching.Comparison` of the judged poses with their inputs."""
        from .matching import compare
        return compare(self.model, list(self.truths), self.judged(), self.by_stamp)

    def assert_tracking(self, min_poses: int = 1, position_tol_m: float = POSITION_TOL_M,
                        orientation_tol_rad: float = ORIENTATION_TOL_RAD):
        """Every pose answers an input of the mock and lies on that input's true pose within the
        tolerances; at least ``min_poses`` of them.  Returns the comparison."""
        c = self.comparison()
        total = len(c.unpaired) + len(c.index)
        assert not c.unpaired, f"{len(c.unpaired)} of {total} poses answer no input of the mock"
        assert len(c.index) >= min_poses, f"{len(c.index)} poses paired with an input, expected >= {min_poses}"
        worst_p, worst_a = float(c.position_error_m.max()), float(c.orientation_error_rad.max())
        assert worst_p <= position_tol_m, f"position error {worst_p:.3g} m > {position_tol_m:g} m"
        assert worst_a <= orientation_tol_rad, f"orientation error {worst_a:.3g} rad > {orientation_tol_rad:g} rad"
        return c


class _Truth:
    """One input of the mock as :mod:`.matching` takes it."""

    __slots__ = ("send_ns", "legs", "position_m", "quaternion")

    def __init__(self, send_ns, legs, position_m, quaternion):
        self.send_ns, self.legs, self.position_m, self.quaternion = send_ns, legs, position_m, quaternion
