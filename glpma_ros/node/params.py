"""Parameters of the ``glpma_fk`` node: one declaration per parameter (name, ROS type,
default, description, range).  Both transports read them from here: the rclpy node turns
them into ``ParameterDescriptor``s, the DDS node and the offline tools parse ``--ros-args``
with :mod:`.ros_args` and resolve the values with :func:`resolve`.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from ..errors import InputError
from ..estimation.redundancy import DEFAULT_LEG_NOISE_M
from ..solvers import SOLVERS
from .qos import PREFIX as QOS_PREFIX
from .realtime import MAX_PRIORITY

NODE_NAME = "glpma_fk"
#: a revolute actuator's reading noise (rad): a 16-bit absolute encoder's quantisation step 2 pi / 2^16
#: over sqrt(12), rounded up (3e-5 rad), the order of the joint encoders of the servo-driven robots shipped
DEFAULT_ANGLE_NOISE_RAD = 3e-5
#: every registered solver: the papers' G3-PCX, RCGA, GLPMA and the baselines SA, GA-SA, DE
SOLVER_CHOICES = tuple(SOLVERS)
#: what the node subscribes to: ``leg_lengths`` (std_msgs/Float64MultiArray) or
#: ``joint_states`` (sensor_msgs/JointState, legs picked by ``joint_names``)
INPUT_FLOAT64_MULTI_ARRAY, INPUT_JOINT_STATE = "float64_multi_array", "joint_state"
INPUT_TYPES = (INPUT_FLOAT64_MULTI_ARRAY, INPUT_JOINT_STATE)

STRING, DOUBLE, INTEGER, BOOL, DOUBLE_ARRAY, STRING_ARRAY, INTEGER_ARRAY = (
    "string", "double", "integer", "bool", "double_array", "string_array", "integer_array")
ARRAY_TYPES = (DOUBLE_ARRAY, STRING_ARRAY, INTEGER_ARRAY)
#: the largest core number cpu_affinity accepts (Linux's default CPU set size, CONFIG_NR_CPUS)
MAX_CPU = 8191
#: a URDF prefix (``glpma-fk urdf --prefix``) goes before joint and TF names
URDF_PREFIX = re.compile(r"[A-Za-z0-9_/]*")


@dataclass(frozen=True)
class ParamSpec:
    name: str
    type: str                      # one of STRING, DOUBLE, INTEGER, BOOL, DOUBLE_ARRAY, STRING_ARRAY, INTEGER_ARRAY
    default: Any
    description: str
    range: tuple | None = None     # inclusive (min, max) for numbers (INTEGER_ARRAY: for each element)
    min_exclusive: bool = False    # the minimum itself is not allowed
    choices: tuple | None = None   # allowed strings
    read_only: bool = False        # fixed once the node runs

    @property
    def constraints(self) -> str:
        """The constraints in words (ParameterDescriptor.additional_constraints)."""
        parts = []
        if self.choices:
            parts.append("one of " + ", ".join(self.choices))
        if self.range:
            lo, hi = self.range
            parts.append(f"{'>' if self.min_exclusive else '>='} {lo:g} and <= {hi:g}")
        if self.read_only:
            parts.append("read-only at runtime")
        return "; ".join(parts)


PARAMETERS = (
    ParamSpec("manipulator_config", STRING, "planar_3rpr_seed",
              "Manipulator YAML: a path, or the name of a shipped config (planar_3rpr_seed, hexapod_66_rolland)",
              read_only=True),
    ParamSpec("solver", STRING, "glpma",
              "Evolutionary solver: glpma, g3pcx, rcga (the papers'), or the baselines sa, gasa, de",
              choices=SOLVER_CHOICES),
    ParamSpec("input_type", STRING, INPUT_FLOAT64_MULTI_ARRAY,
              "Input topic and type: float64_multi_array = leg_lengths (std_msgs/Float64MultiArray, legs in "
              "config order); joint_state = joint_states (sensor_msgs/JointState, legs picked by joint_names, "
              "pose stamped with the message's header.stamp)", choices=INPUT_TYPES, read_only=True),
    ParamSpec("joint_names", STRING_ARRAY, [],
              "input_type joint_state: names of the legs' prismatic joints in the config's leg order "
              "(empty = leg_1 .. leg_n); other joints in the message are ignored"),
    ParamSpec("assembly_modes_runs", INTEGER, 20000,
              "Cap on the local solves (starts) of one ~/request_assembly_modes (solve_all's multistart stops "
              "earlier, once many starts in a row found nothing new)",
              range=(1, 100000)),
    ParamSpec("time_budget_ms", DOUBLE, 2.0, "Hard time budget of one solve (ms)", range=(0.0, 60000.0),
              min_exclusive=True),
    ParamSpec("tolerance", DOUBLE, 1e-20,
              "Fitness (the papers' sum of squared residuals, config unit squared) at which the evolutionary "
              "search hands over to the refinement; with polish a pose is converged when its leg residuals are at "
              "round-off relative to the geometry's size (without polish: fitness below this)",
              range=(0.0, 1.0), min_exclusive=True),
    ParamSpec("frame_id", STRING, "base",
              "header.frame_id of pose_estimate and of every other output (the manipulator's base frame)"),
    ParamSpec("child_frame_id", STRING, "platform",
              "The platform frame: child_frame_id of the transform frame_id -> child_frame_id broadcast on /tf"),
    ParamSpec("publish_tf", BOOL, True,
              "Broadcast every published pose on /tf (tf2_msgs/TFMessage, frame_id -> child_frame_id, same stamp)"),
    ParamSpec("publish_covariance", BOOL, True,
              "Publish pose_estimate_cov (geometry_msgs/PoseWithCovarianceStamped): the pose with the first-order "
              "covariance sigma^2 (J^T J)^-1 of leg-length noise leg_noise_std (an actuated family: of each "
              "actuator's noise, leg_noise_std or actuator_noise_std)"),
    ParamSpec("leg_noise_std", DOUBLE, DEFAULT_LEG_NOISE_M,
              "Standard deviation of the leg-length measurements (metres) behind pose_estimate_cov and, with "
              "redundant legs, the chi-square consistency test (inconsistent_legs); an actuated family: of each "
              "prismatic actuator's reading (metres)",
              range=(0.0, 1.0), min_exclusive=True),
    ParamSpec("actuator_noise_std", DOUBLE, DEFAULT_ANGLE_NOISE_RAD,
              "An actuated family (delta, rus_6, planar_3rrr, ...): standard deviation of each revolute actuator's "
              "reading (radians) behind pose_estimate_cov (prismatic actuators: leg_noise_std)",
              range=(0.0, 1.0), min_exclusive=True),
    ParamSpec("exclude_faulty_leg", BOOL, True,
              "Redundant legs: when the legs are inconsistent (inconsistent_legs) and the others determine the "
              "pose consistently, publish the pose without the leg most likely at fault (false: publish nothing)"),
    ParamSpec("publish_twist", BOOL, True,
              "Publish twist_estimate (geometry_msgs/TwistStamped, base frame): from the joint_states velocities "
              "(forward velocity kinematics) when present, else the finite difference of consecutive poses"),
    ParamSpec("publish_markers", BOOL, False,
              "Publish ~/markers (visualization_msgs/MarkerArray): base and platform joints, legs coloured by length, "
              "the platform polygon"),
    ParamSpec("publish_joint_states", BOOL, False,
              "Publish ~/mechanism_joint_states (sensor_msgs/JointState, stamped as the pose): every joint of the "
              "manipulator's URDF (glpma-fk urdf) at the pose -- universal, actuator and spherical joints of every "
              "leg -- with their rates when the twist is computed; remap it to /joint_states for "
              "robot_state_publisher"),
    ParamSpec("urdf_prefix", STRING, "",
              "The prefix of the URDF's joint names (glpma-fk urdf --prefix) in ~/mechanism_joint_states",
              read_only=True),
    ParamSpec("markers_period_s", DOUBLE, 0.1,
              "Least time between two ~/markers messages (by the poses' stamps); 0 = with every pose",
              range=(0.0, 3600.0)),
    ParamSpec("initial_pose", DOUBLE_ARRAY, [],
              "Solver variables (config unit, radians) that select the assembly mode to start from; "
              "3-RPR: x y theta, hexapod: x1 y1 z1 x2 y2 z2 x3 y3 z3 (with coincident joints: of the first three "
              "distinct platform joints off one line, e.g. x1 y1 z1 x3 y3 z3 x5 y5 z5 for a 6-3); empty = cold "
              "start. "
              "Setting it at runtime restarts tracking from it"),
    ParamSpec("population", INTEGER, 0, "Population size (RCGA/G3-PCX; GLPMA master); 0 = the papers' setting",
              range=(0, 100000)),
    ParamSpec("local_population", INTEGER, 0, "GLPMA local population size; 0 = the papers' setting",
              range=(0, 100000)),
    ParamSpec("ls_interval", INTEGER, 0, "GLPMA: master generations between local searches; 0 = the papers' setting",
              range=(0, 100000)),
    ParamSpec("ls_intensity", INTEGER, 0, "GLPMA: G3-PCX generations per local search; 0 = the papers' setting",
              range=(0, 100000)),
    ParamSpec("polish", BOOL, True, "Refine the evolutionary result with Levenberg-Marquardt"),
    ParamSpec("seed", INTEGER, 0, "Seed of the solver's random generator", range=(0, 2**31 - 1)),
    ParamSpec("deadline_ms", DOUBLE, 0.0,
              "An input whose result comes later than this after its arrival is a deadline miss; "
              "0 = time_budget_ms", range=(0.0, 60000.0)),
    ParamSpec("qos_depth", INTEGER, 10, "History depth (keep-last) of the topics", range=(1, 10000),
              read_only=True),
    ParamSpec("diagnostics_period_s", DOUBLE, 1.0, "Period of /diagnostics (s)", range=(0.05, 3600.0),
              read_only=True),
    ParamSpec("thread_priority", INTEGER, 0,
              "SCHED_FIFO priority of the solving thread (as ros2_control's thread_priority); 0 = normal "
              "scheduling. Needs CAP_SYS_NICE or an rtprio limit of at least this value (ulimit -r); when refused, "
              "one warning and the node runs on", range=(0, MAX_PRIORITY), read_only=True),
    ParamSpec("cpu_affinity", INTEGER_ARRAY, [],
              "Cores the solving thread may run on (as ros2_control's cpu_affinity); empty = unchanged. "
              "Cores this process may not use: one warning and the node runs on",
              range=(0, MAX_CPU), read_only=True),
)
SPECS = {spec.name: spec for spec in PARAMETERS}

#: a population smaller than this cannot form the G3-PCX family (mu = 3 parents)
MIN_POPULATION = 4


def defaults() -> dict:
    return {spec.name: (list(spec.default) if spec.type in ARRAY_TYPES else spec.default)
            for spec in PARAMETERS}


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def coerce(name: str, value):
    """The value of parameter ``name`` in its declared type, or :class:`InputError` with the reason."""
    spec = SPECS.get(name)
    if spec is None:
        raise InputError(f"unknown parameter '{name}'")
    t = spec.type
    if t == STRING:
        if not isinstance(value, str):
            raise InputError(f"parameter '{name}' must be a string, got {value!r}")
        if spec.choices and value not in spec.choices:
            raise InputError(f"parameter '{name}' must be one of {', '.join(spec.choices)}, got {value!r}")
        if name in ("frame_id", "child_frame_id", "manipulator_config") and not value.strip():
            raise InputError(f"parameter '{name}' must not be empty")
        if name == "urdf_prefix" and not URDF_PREFIX.fullmatch(value):
            raise InputError(f"parameter '{name}' must be letters, digits, '_' and '/' only, got {value!r}")
        return value
    if t == BOOL:
        if not isinstance(value, bool):
            raise InputError(f"parameter '{name}' must be true or false, got {value!r}")
        return value
    if t == STRING_ARRAY:
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise InputError(f"parameter '{name}' must be a list of strings, got {value!r}")
        out = list(value)
        if any(not v.strip() for v in out):
            raise InputError(f"parameter '{name}' must not contain empty names")
        if len(set(out)) != len(out):
            raise InputError(f"parameter '{name}' must not contain a name twice")
        return out
    if t == DOUBLE_ARRAY:
        if not isinstance(value, (list, tuple)) or not all(_is_number(v) for v in value):
            raise InputError(f"parameter '{name}' must be a list of numbers, got {value!r}")
        out = [float(v) for v in value]
        if not all(math.isfinite(v) for v in out):
            raise InputError(f"parameter '{name}' must contain finite numbers only")
        return out
    if t == INTEGER_ARRAY:
        if not isinstance(value, (list, tuple)) or not all(_is_number(v) and float(v).is_integer() for v in value):
            raise InputError(f"parameter '{name}' must be a list of integers, got {value!r}")
        out = [int(v) for v in value]
        lo, hi = spec.range
        if any(v < lo or v > hi for v in out):
            raise InputError(f"parameter '{name}' must hold integers {spec.constraints}, got {value!r}")
        if len(set(out)) != len(out):
            raise InputError(f"parameter '{name}' must not contain a value twice")
        return out
    if t == INTEGER:
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not _is_number(value) or not isinstance(value, int):
            raise InputError(f"parameter '{name}' must be an integer, got {value!r}")
    elif t == DOUBLE:
        if not _is_number(value):
            raise InputError(f"parameter '{name}' must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise InputError(f"parameter '{name}' must be finite, got {value!r}")
    if spec.range:
        lo, hi = spec.range
        if value < lo or value > hi or (spec.min_exclusive and value == lo):
            raise InputError(f"parameter '{name}' must be {spec.constraints}, got {value!r}")
    if name in ("population", "local_population") and 0 < value < MIN_POPULATION:
        raise InputError(f"parameter '{name}' must be 0 (the papers' setting) or at least {MIN_POPULATION}, "
                         f"got {value}")
    return value


def resolve(overrides: dict) -> tuple[dict, list[str]]:
    """Defaults updated with the overrides, each coerced to its declared type.

    Returns ``(params, warnings)``; an override of an unknown parameter is a
    warning (ROS ignores overrides of undeclared parameters), a bad value an
    :class:`InputError`.  The QoS overrides (``qos_overrides.*``) are not among them: they are
    read by :func:`glpma_ros.node.qos.resolve`.
    """
    params = defaults()
    warnings = []
    for name, value in overrides.items():
        if name.startswith(QOS_PREFIX):
            continue
        if name not in SPECS:
            warnings.append(f"ignoring unknown parameter '{name}'")
            continue
        params[name] = coerce(name, value)
    return params, warnings
