"""Parameters of the ``glpma_fk`` node and the ``--ros-args`` command-line syntax.

One declaration per parameter (name, ROS type, default, description, range);
both transports read them from here: the rclpy node turns them into
``ParameterDescriptor``s, the DDS node parses ``--ros-args`` itself with
:func:`parse_ros_args`.  Supported ``--ros-args`` syntax (as in ROS 2 Jazzy)::

    --ros-args -p NAME:=VALUE            (VALUE parsed as YAML, e.g. [1.0, 2.0])
               -p NODE:NAME:=VALUE       (only if NODE is this node)
               --params-file FILE        (``glpma_fk: ros__parameters: {...}`` or ``/**:``)
               -r __node:=NAME  -r FROM:=TO (topic remapping)
               --log-level LEVEL | --log-level NODE:=LEVEL
               --                        (ends the ROS arguments)

Later sources override earlier ones, in command-line order.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

import yaml

from .errors import InputError
from .solvers import SOLVERS

NODE_NAME = "glpma_fk"
#: every registered solver: the papers' G3-PCX, RCGA, GLPMA and the baselines SA, GA-SA, DE
SOLVER_CHOICES = tuple(SOLVERS)
#: what the node subscribes to: ``leg_lengths`` (std_msgs/Float64MultiArray) or
#: ``joint_states`` (sensor_msgs/JointState, legs picked by ``joint_names``)
INPUT_FLOAT64_MULTI_ARRAY, INPUT_JOINT_STATE = "float64_multi_array", "joint_state"
INPUT_TYPES = (INPUT_FLOAT64_MULTI_ARRAY, INPUT_JOINT_STATE)

STRING, DOUBLE, INTEGER, BOOL, DOUBLE_ARRAY, STRING_ARRAY = (
    "string", "double", "integer", "bool", "double_array", "string_array")
ARRAY_TYPES = (DOUBLE_ARRAY, STRING_ARRAY)


@dataclass(frozen=True)
class ParamSpec:
    name: str
    type: str                      # one of STRING, DOUBLE, INTEGER, BOOL, DOUBLE_ARRAY, STRING_ARRAY
    default: Any
    description: str
    range: tuple | None = None     # inclusive (min, max) for numbers
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
              "Convergence threshold on the fitness (sum of squared leg residuals, config unit squared)",
              range=(0.0, 1.0), min_exclusive=True),
    ParamSpec("frame_id", STRING, "base", "header.frame_id of pose_estimate (the manipulator's base frame)"),
    ParamSpec("initial_pose", DOUBLE_ARRAY, [],
              "Solver variables (config unit, radians) that select the assembly mode to start from; "
              "3-RPR: x y theta, hexapod: x1 y1 z1 x2 y2 z2 x3 y3 z3; empty = cold start. "
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
        if name in ("frame_id", "manipulator_config") and not value.strip():
            raise InputError(f"parameter '{name}' must not be empty")
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


# -- --ros-args -------------------------------------------------------------------------------

@dataclass
class RosArgs:
    """What ``--ros-args`` asked for."""

    node_name: str = NODE_NAME
    overrides: dict = field(default_factory=dict)   # parameter name -> raw value, in command-line order
    remaps: dict = field(default_factory=dict)      # topic name -> topic name
    log_level: str | None = None
    params_files: list = field(default_factory=list)
    warnings: list = field(default_factory=list)    # ignored parameters and options
    other: list = field(default_factory=list)       # arguments outside --ros-args


def _split_assignment(text: str, option: str) -> tuple[str, str]:
    if ":=" not in text:
        raise InputError(f"{option} expects NAME:=VALUE, got {text!r}")
    name, value = text.split(":=", 1)
    if not name:
        raise InputError(f"{option} expects NAME:=VALUE, got {text!r}")
    return name, value


def _node_matches(key: str, node_name: str) -> bool:
    """Does a params-file key (``/**``, ``glpma_fk``, ``/**/glpma_fk``, ``/glpma_*``) select this node?"""
    pattern = key.strip().lstrip("/")
    regex = "".join(".*" if tok == "**" else "[^/]*" if tok == "*" else re.escape(tok)
                    for tok in re.split(r"(\*\*|\*)", pattern))
    regex = regex.replace(".*/", "(?:.*/)?")  # '/**/name' also matches a node without namespace
    return re.fullmatch(regex, node_name) is not None


def _flatten(prefix: str, value, out: dict) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else str(k), v, out)
    else:
        out[prefix] = value


def load_params_file(path: str, node_name: str = NODE_NAME) -> dict:
    """Parameters for ``node_name`` from a ROS 2 params file (raw YAML values)."""
    try:
        with open(path) as f:
            doc = yaml.safe_load(f)
    except OSError as exc:
        raise InputError(f"cannot read params file {path}: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise InputError(f"params file {path}: invalid YAML{where}") from None
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise InputError(f"params file {path}: expected 'NODE: ros__parameters: {{...}}' mappings")
    params: dict = {}
    for key, section in doc.items():
        if not _node_matches(str(key), node_name):
            continue
        if not isinstance(section, dict) or "ros__parameters" not in section:
            raise InputError(f"params file {path}: '{key}' has no 'ros__parameters' mapping")
        values = section["ros__parameters"] or {}
        if not isinstance(values, dict):
            raise InputError(f"params file {path}: '{key}: ros__parameters' must be a mapping")
        _flatten("", values, params)
    return {name: _typed_value(name, value) for name, value in params.items()}


_FLOAT_RE = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|[-+]?(inf|nan)", re.IGNORECASE)


def _fix_yaml_number(value):
    """PyYAML (YAML 1.1) reads ``1e-20`` as a string; ROS' parser reads it as a double."""
    if isinstance(value, str) and _FLOAT_RE.fullmatch(value.strip()):
        return float(value)
    if isinstance(value, list):
        return [_fix_yaml_number(v) for v in value]
    return value


def _typed_value(name: str, value, text: str | None = None):
    """A raw YAML value for parameter ``name``: a string parameter keeps the text as
    written (``-p frame_id:=123``), any other gets numbers written as strings fixed."""
    spec = SPECS.get(name)
    if spec is not None and spec.type == STRING:
        if not isinstance(value, str) and text is not None:
            return text
        return value
    if spec is not None and spec.type == STRING_ARRAY:
        return value
    return _fix_yaml_number(value)


def _parse_value(name: str, text: str):
    """A ``-p`` value, parsed as YAML like ROS does."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        value = text
    return _typed_value(name, value, text)


def parse_ros_args(argv) -> RosArgs:
    """Parse a command line containing ``--ros-args ... [--]`` sections; :class:`InputError` on bad syntax."""
    args = RosArgs()
    pending: list[tuple[str, str, str]] = []   # ('p', name, text) or ('f', path, '') in order
    i, in_ros = 0, False
    argv = list(argv)
    while i < len(argv):
        tok = argv[i]
        if tok == "--ros-args":
            in_ros = True
        elif not in_ros:
            args.other.append(tok)
        elif tok == "--":
            in_ros = False
        else:
            if tok in ("-p", "--param", "--params-file", "-r", "--remap", "--log-level"):
                if i + 1 >= len(argv):
                    raise InputError(f"{tok} expects an argument")
                arg = argv[i + 1]
                i += 1
                if tok in ("-p", "--param"):
                    name, text = _split_assignment(arg, tok)
                    pending.append(("p", name, text))
                elif tok == "--params-file":
                    pending.append(("f", arg, ""))
                elif tok in ("-r", "--remap"):
                    src, dst = _split_assignment(arg, tok)
                    if src.endswith("__node") or src.endswith("__name"):
                        args.node_name = dst
                    elif src.endswith("__ns"):
                        args.warnings.append(f"ignoring namespace remapping {arg!r} (the node has no namespace)")
                    else:
                        args.remaps[src.split(":", 1)[-1] if ":" in src else src] = dst
                else:
                    level = arg.split(":=", 1)[-1]
                    args.log_level = level.lower()
            elif tok in ("--enclave", "-e"):
                args.warnings.append(f"ignoring {tok} {argv[i + 1] if i + 1 < len(argv) else ''}".strip())
                i += 1
            elif tok.startswith("--"):
                args.warnings.append(f"ignoring ROS argument {tok}")
            else:
                raise InputError(f"unexpected ROS argument {tok!r} (expected -p NAME:=VALUE, --params-file FILE, "
                                 f"-r FROM:=TO, --log-level LEVEL)")
        i += 1
    # apply in order, now that the node name is known
    for kind, a, b in pending:
        if kind == "f":
            args.params_files.append(a)
            args.overrides.update(load_params_file(a, args.node_name))
        else:
            name = a
            if ":" in name:                       # NODE:NAME:=VALUE
                node, name = name.split(":", 1)
                if not _node_matches(node, args.node_name):
                    continue
            args.overrides[name] = _parse_value(name, b)
    return args


def resolve(overrides: dict) -> tuple[dict, list[str]]:
    """Defaults updated with the overrides, each coerced to its declared type.

    Returns ``(params, warnings)``; an override of an unknown parameter is a
    warning (ROS ignores overrides of undeclared parameters), a bad value an
    :class:`InputError`.
    """
    params = defaults()
    warnings = []
    for name, value in overrides.items():
        if name not in SPECS:
            warnings.append(f"ignoring unknown parameter '{name}'")
            continue
        params[name] = coerce(name, value)
    return params, warnings


TRANSPORTS = ("auto", "rclpy", "dds")


def split_transport(argv, default: str = "auto") -> tuple[str, list]:
    """``--transport X`` (or ``--transport=X``) before ``--ros-args``, and the other arguments."""
    rest, transport, i = [], default, 0
    argv = list(argv)
    while i < len(argv):
        tok = argv[i]
        if tok == "--ros-args":
            rest.extend(argv[i:])
            break
        if tok == "--transport" and i + 1 < len(argv):
            transport = argv[i + 1]
            i += 2
            continue
        if tok.startswith("--transport="):
            transport = tok.split("=", 1)[1]
        else:
            rest.append(tok)
        i += 1
    return transport, rest
