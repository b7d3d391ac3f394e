"""``ros2 run glpma_ros mock_publisher``: a simulated controller on rclpy, for launch tests of a bringup.

It moves the platform along the loop of :mod:`glpma_tools.sim.trajectories` around one of the
config's known solutions (the loop the DDS mock controller, the demo and the benchmark use) and,
every ``1 / rate_hz`` seconds, publishes

* the legs of that pose in metres: ``leg_lengths`` (``std_msgs/msg/Float64MultiArray``, leg order;
  an actuated family's actuator positions, radians or metres for rails, on ``actuator_positions``) or, with
  ``input_type:=joint_state``, ``joint_states`` (``sensor_msgs/msg/JointState``: the legs
  under ``joint_names``, ``header.stamp`` = the time of publishing);
* beside them the true pose, ``~/true_pose`` (``geometry_msgs/msg/PoseStamped``, metres, unit
  quaternion, ``frame_id``, stamped with the same time as the JointState).

Sample k is the trajectory at ``k / rate_hz`` (the motion does not depend on timer jitter).  With
``wait_for_subscriber`` (default) it starts once something subscribes to the legs (the estimator
node subscribes after its warm-up), with ``wait_for_monitor`` also once something subscribes to
``~/true_pose`` (a test's :class:`glpma_ros.testing.TrackingMonitor`, which then misses no true pose); with
``duration_s`` > 0 it ends after that many seconds of
trajectory with status 0, else at SIGINT.  :mod:`glpma_ros.testing` pairs the node's poses with
these true poses.  Parameters are declared with descriptions and ranges (``ros2 param describe``);
a bad value is one line on stderr and status 2.
"""
from __future__ import annotations

import sys

from glpma_ros.errors import GlpmaError

NODE_NAME = "glpma_mock_publisher"
#: the trajectory's default solution (index of the config's known solutions): -1 = the tools' default
DEFAULT_SOLUTION = -1


def _parameters():
    """(name, default, description, (min, max) or None) of the declared parameters."""
    from glpma_ros.node.params import INPUT_FLOAT64_MULTI_ARRAY, INPUT_TYPES
    return (
        ("config", "planar_3rpr_seed", "Manipulator YAML (a path or a shipped name) whose legs are published", None),
        ("input_type", INPUT_FLOAT64_MULTI_ARRAY,
         f"What to publish: {' or '.join(INPUT_TYPES)} (leg_lengths or joint_states)", None),
        ("joint_names", [], "joint_state: the legs' joint names in leg order (empty = leg_1 .. leg_n)", None),
        ("rate_hz", 50.0, "Inputs per second", (0.1, 10000.0)),
        ("duration_s", 0.0, "Seconds of trajectory to publish, then exit 0; 0 = until stopped", (0.0, 1e6)),
        ("solution", DEFAULT_SOLUTION, "Known solution of the config to move around (-1 = the tools' default)",
         (-1, 1000)),
        ("amplitude", 1.0, "Size of the motion (1 = the tools' loop)", (0.0, 10.0)),
        ("frame_id", "base", "header.frame_id of ~/true_pose", None),
        ("wait_for_subscriber", True, "Start once something subscribes to the legs (e.g. after the node's warm-up)",
         None),
        ("wait_for_monitor", False, "Also wait until something subscribes to ~/true_pose (a test's monitor: then "
                                    "it has the true pose of every input)", None),
    )


def main(args=None) -> int:
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.exceptions import ParameterException, ParameterUninitializedException
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension

    from glpma_ros.node.input_topic import input_topic, model_is_actuated, readings_in_si
    from glpma_ros.node.params import INPUT_JOINT_STATE, INPUT_TYPES
    from glpma_ros.node.service import default_joint_names
    from glpma_tools.sim.trajectories import Plan

    class MockPublisher(Node):
        def __init__(self):
            super().__init__(NODE_NAME)
            for name, default, description, bounds in _parameters():
                d = ParameterDescriptor(description=description)
                if bounds and isinstance(default, float):
                    d.floating_point_range = [FloatingPointRange(from_value=bounds[0], to_value=bounds[1])]
                elif bounds:
                    d.integer_range = [IntegerRange(from_value=bounds[0], to_value=bounds[1], step=1)]
                # an empty list has no inferable type: declared by type
                self.declare_parameter(name, Parameter.Type.STRING_ARRAY if default == [] else default, d)
            p = {name: self._value(name, default) for name, default, *_ in _parameters()}
            if p["input_type"] not in INPUT_TYPES:
                raise GlpmaError(f"input_type must be one of {', '.join(INPUT_TYPES)}, got {p['input_type']!r}")
            self.plan = Plan(p["config"], None if p["solution"] == DEFAULT_SOLUTION else p["solution"],
                             p["amplitude"])
            n_legs = self.plan.model.n_legs
            names = [n for n in p["joint_names"] if n] or default_joint_names(n_legs)
            if len(names) != n_legs:
                raise GlpmaError(f"joint_names must name the {n_legs} legs, got {len(names)} names")
            self.names, self.frame_id = names, p["frame_id"]
            self.joint_state = p["input_type"] == INPUT_JOINT_STATE
            self.rate, self.wait, self.wait_monitor = p["rate_hz"], p["wait_for_subscriber"], p["wait_for_monitor"]
            self.total = round(p["duration_s"] * self.rate) if p["duration_s"] > 0 else None
            # leg_lengths, or actuator_positions for an actuated family (the node's input topic)
            topic = input_topic(p["input_type"], model_is_actuated(self.plan.model))
            self.legs_pub = (self.create_publisher(JointState, topic, 10) if self.joint_state
                             else self.create_publisher(Float64MultiArray, topic, 10))
            self.true_pub = self.create_publisher(PoseStamped, "~/true_pose", 10)
            self.layout_dim = MultiArrayDimension(label="legs", size=n_legs, stride=n_legs)
            self.k = 0
            self.done = False
            self.timer = self.create_timer(1.0 / self.rate, self._tick)
            self.get_logger().info(f"{self.plan.model.kind} {self.plan.path.name}, solution {self.plan.solution}, "
                                   f"{self.rate:g} Hz on {self.legs_pub.topic_name}"
                                   + (" once the node subscribes" if self.wait else ""))

        def _value(self, name, default):
            try:
                value = self.get_parameter(name).value
            except ParameterUninitializedException:
                return default
            return list(value) if isinstance(value, (list, tuple)) else value

        def _waiting(self) -> bool:
            """Before the first input: is a subscriber it waits for still missing?"""
            return self.k == 0 and ((self.wait and self.legs_pub.get_subscription_count() == 0)
                                    or (self.wait_monitor and self.true_pub.get_subscription_count() == 0))

        def _tick(self):
            if self.done or self._waiting():
                return
            legs, position_m, q = self.plan.sample(self.k / self.rate)
            legs_m = readings_in_si(self.plan.model, legs)     # metres; an actuated family's radians (rails: metres)
            stamp = self.get_clock().now().to_msg()
            if self.joint_state:
                msg = JointState(name=list(self.names), position=legs_m)
                msg.header.stamp = stamp
            else:
                msg = Float64MultiArray(data=legs_m)
                msg.layout.dim = [self.layout_dim]
            truth = PoseStamped()
            truth.header.stamp, truth.header.frame_id = stamp, self.frame_id
            truth.pose.position.x, truth.pose.position.y, truth.pose.position.z = (float(v) for v in position_m)
            o = truth.pose.orientation
            o.x, o.y, o.z, o.w = (float(v) for v in q)
            self.true_pub.publish(truth)        # the truth first: a listener has it before the pose
            self.legs_pub.publish(msg)
            self.k += 1
            if self.total is not None and self.k >= self.total:
                self.done = True
                self.get_logger().info(f"done: {self.k} inputs published")

    rclpy.init(args=args)
    node = None
    try:
        node = MockPublisher()
        while rclpy.ok() and not node.done:
            rclpy.spin_once(node, timeout_sec=0.1)
    except (GlpmaError, ParameterException) as exc:
        print(f"{NODE_NAME}: error: {exc}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
