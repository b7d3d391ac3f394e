"""The ``--ros-args`` command line of ROS 2, for the DDS transport and the offline tools
(rclpy parses its own).  Supported ``--ros-args`` syntax (as in ROS 2 Jazzy)::

    --ros-args -p NAME:=VALUE            (VALUE parsed as YAML, e.g. [1.0, 2.0])
               -p NODE:NAME:=VALUE       (only if NODE is this node)
               --params-file FILE        (``glpma_fk: ros__parameters: {...}`` or ``/**:``)
               -r __node:=NAME  -r FROM:=TO (topic remapping)
               --log-level LEVEL | --log-level NODE:=LEVEL
               --                        (ends the ROS arguments)

Later sources override earlier ones, in command-line order.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import yaml

from ..errors import InputError
from .params import NODE_NAME, SPECS, STRING, STRING_ARRAY, resolve


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
    if "manipulator" in doc and not any("ros__parameters" in (v or {}) for v in doc.values() if isinstance(v, dict)):
        raise InputError(f"{path} is a manipulator config, not a ROS 2 params file: pass it as "
                         f"-p manipulator_config:={path}")
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


def check_params_files(argv, node_name: str = NODE_NAME) -> None:
    """Read every ``--params-file`` after ``--ros-args`` as :func:`load_params_file` does, so that a
    mistake (a manipulator YAML, invalid YAML) is one line (:class:`InputError`) on any transport."""
    argv, in_ros = list(argv), False
    for i, tok in enumerate(argv):
        if tok == "--ros-args":
            in_ros = True
        elif tok == "--":
            in_ros = False
        elif in_ros and tok == "--params-file" and i + 1 < len(argv):
            load_params_file(argv[i + 1], node_name)


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


def remapped(ros_name: str, remaps: dict) -> str:
    """``ros_name`` after the ``-r FROM:=TO`` remappings (FROM with or without its leading slash)."""
    return remaps.get(ros_name, remaps.get(ros_name.lstrip("/"), remaps.get("/" + ros_name.lstrip("/"), ros_name)))


def node_values(argv) -> tuple[dict, list[str], RosArgs]:
    """Every parameter of the node for a command line with ``--ros-args``: ``(values, warnings, args)``."""
    args = parse_ros_args(argv)
    values, warnings = resolve(args.overrides)
    return values, args.warnings + warnings, args


#: the ``--ros-args`` lines of a ``--help`` (``glpma-fk node``, ``glpma-fk bag``)
ROS_ARGS_HELP = (
    "  --ros-args            the rest is ROS 2 arguments, as for ros2 run glpma_ros fk_node:",
    "  -p NAME:=VALUE        set a parameter (VALUE read as YAML)",
    "  --params-file FILE    a ROS 2 params file (glpma_fk: ros__parameters: ...), not a manipulator YAML",
    "  -r FROM:=TO           remap a topic (-r __node:=NAME renames the node)",
    "  --log-level LEVEL     debug, info, warn, error",
)


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
