"""Manipulator YAML -> model, with the validation errors users see.

Schema (see ``config/*.yaml``)::

    manipulator: planar_3rpr | hexapod_66
    unit: mm | cm | m            # unit of every length in the file and on the CLI
    base: [[...], ...]           # base joints A_i in the base frame
    platform: [[...], ...]       # platform joints B_i in the platform frame
    leg_limits: [min, max]       # optional, config unit
    example_leg_lengths: [...]   # optional
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import yaml

from .errors import ConfigError
from .models import MODELS, Manipulator

UNIT_TO_METRES = {"m": 1.0, "cm": 0.01, "mm": 0.001}
JOINT_DIMENSION = {"planar_3rpr": (3, 2), "hexapod_66": (6, 3)}


def _matrix(doc: dict, key: str, shape: tuple[int, int], path: str) -> np.ndarray:
    if key not in doc:
        raise ConfigError(f"{path}: missing key '{key}'")
    try:
        arr = np.array(doc[key], dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{path}: '{key}' must be a list of {shape[0]} points of {shape[1]} numbers") from None
    if arr.shape != shape:
        raise ConfigError(f"{path}: '{key}' must have {shape[0]} points of {shape[1]} coordinates, got shape "
                          f"{'x'.join(str(s) for s in arr.shape) or 'scalar'}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{path}: '{key}' has a non-finite coordinate")
    return arr


def _check_joints(arr: np.ndarray, key: str, path: str, need_triangle: bool) -> None:
    """Coincident joints, and (for the platform) collinear first three joints."""
    size = float(np.ptp(arr, axis=0).max())
    if size <= 0.0:
        raise ConfigError(f"{path}: all '{key}' joints coincide")
    tol = 1e-9 * size
    for i in range(len(arr)):
        for j in range(i + 1, len(arr)):
            if np.linalg.norm(arr[i] - arr[j]) <= tol:
                raise ConfigError(f"{path}: '{key}' joints {i + 1} and {j + 1} coincide")
    if need_triangle:
        e1, e2 = arr[1] - arr[0], arr[2] - arr[0]
        if arr.shape[1] == 2:
            area = abs(e1[0] * e2[1] - e1[1] * e2[0])
        else:
            area = float(np.linalg.norm(np.cross(e1, e2)))
        if area <= 1e-9 * size * size:
            raise ConfigError(f"{path}: '{key}' joints 1, 2 and 3 are collinear")


def model_from_dict(doc, path: str = "config") -> Manipulator:
    """Build and validate a model from a parsed YAML mapping."""
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: expected a YAML mapping with keys manipulator, unit, base, platform")
    kind = doc.get("manipulator")
    if kind not in MODELS:
        raise ConfigError(f"{path}: 'manipulator' must be one of {', '.join(MODELS)}, got {kind!r}")
    unit = doc.get("unit", "mm")
    if unit not in UNIT_TO_METRES:
        raise ConfigError(f"{path}: 'unit' must be one of {', '.join(UNIT_TO_METRES)}, got {unit!r}")
    shape = JOINT_DIMENSION[kind]
    base = _matrix(doc, "base", shape, path)
    platform = _matrix(doc, "platform", shape, path)
    _check_joints(base, "base", path, need_triangle=False)
    _check_joints(platform, "platform", path, need_triangle=True)
    limits = doc.get("leg_limits")
    if limits is not None:
        try:
            lo, hi = (float(v) for v in limits)
        except (TypeError, ValueError):
            raise ConfigError(f"{path}: 'leg_limits' must be [min, max]") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo < hi):
            raise ConfigError(f"{path}: 'leg_limits' must satisfy 0 <= min < max, got [{lo}, {hi}]")
        limits = (lo, hi)
    model = MODELS[kind](base, platform, unit=unit, leg_limits=limits)
    model.source = path
    model.metres_per_unit = UNIT_TO_METRES[unit]
    example = doc.get("example_leg_lengths")
    model.example_leg_lengths = None
    if example is not None:
        try:
            model.example_leg_lengths = model.check_legs(example)
        except Exception as exc:  # noqa: BLE001 - reported as a config error
            raise ConfigError(f"{path}: 'example_leg_lengths': {exc}") from None
    return model


def load_document(path) -> dict:
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read manipulator config ({exc.strerror or exc})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"{path}: invalid YAML{where}") from None


def load_manipulator(path) -> Manipulator:
    """Read a manipulator YAML and return its validated model."""
    return model_from_dict(load_document(path), str(path))


def config_dir() -> Path:
    """Directory of the shipped configs (installed share dir or source tree)."""
    here = Path(__file__).resolve().parent
    for candidate in (here.parent / "config", Path(sys.prefix) / "share" / "glpma_ros" / "config"):
        if candidate.is_dir():
            return candidate
    try:  # a sourced ROS 2 workspace
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory("glpma_ros")) / "config"
    except Exception:  # noqa: BLE001 - not a ROS environment
        return here.parent / "config"


def resolve_config(name: str) -> Path:
    """A path as given, or the name of a shipped config (``planar_3rpr_seed``)."""
    p = Path(name)
    if p.exists():
        return p
    for cand in (config_dir() / name, config_dir() / f"{name}.yaml"):
        if cand.exists():
            return cand
    return p
