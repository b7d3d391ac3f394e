"""Manipulator YAML -> model, with the validation errors users see.

Schema (see ``config/*.yaml`` and ``doc/interface.md``)::

    manipulator: planar_3rpr | hexapod_66
    unit: mm | cm | m            # required: unit of every length in the file and on the CLI
    base: [[...], ...]           # base joints A_i in the base frame
    platform: [[...], ...]       # platform joints B_i in the platform frame
    leg_limits: [min, max]       # optional, config unit: leg lengths outside are rejected
    example_leg_lengths: [...]   # optional
    real_solutions: [...]        # optional (3-RPR): {x, y, theta_deg} of known assembly modes
    published_solutions: [...]   # optional (hexapod): [x1 y1 z1 x2 y2 z2 x3 y3 z3] of known modes
    name: ..., description: ...  # optional, free text

Any other key is an error that names it (a typo such as ``basee`` is not silently ignored).

Leg lengths that are off by a unit factor (metres given to a millimetre config, millimetres
on a topic in metres) are recognised by :func:`unit_mistake`.
"""
from __future__ import annotations

import difflib
import math
import sys
from pathlib import Path

import numpy as np
import yaml

from .errors import ConfigError, InputError
from .models import MODELS, Manipulator

UNIT_TO_METRES = {"m": 1.0, "cm": 0.01, "mm": 0.001}
UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}
JOINT_DIMENSION = {"planar_3rpr": (3, 2), "hexapod_66": (6, 3)}
#: keys a manipulator YAML may have (the first four are required)
REQUIRED_KEYS = ("manipulator", "unit", "base", "platform")
OPTIONAL_KEYS = ("leg_limits", "example_leg_lengths", "real_solutions", "published_solutions", "name",
                 "description")
#: without ``leg_limits``, leg lengths are plausible between the geometry's scale (largest extent of
#: the base or platform joints) divided and multiplied by this factor; all legs outside that band and
#: inside it once read in another unit are taken for a unit mistake
PLAUSIBLE_SCALE_FACTOR = 100.0


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


def _check_keys(doc: dict, path: str) -> None:
    """Unknown keys are an error naming the key (and the known key it most resembles)."""
    known = REQUIRED_KEYS + OPTIONAL_KEYS
    for key in doc:
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else f"; known keys: {', '.join(known)}"
            raise ConfigError(f"{path}: unknown key {str(key)!r}{hint}")


def model_from_dict(doc, path: str = "config") -> Manipulator:
    """Build and validate a model from a parsed YAML mapping."""
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: expected a YAML mapping with keys {', '.join(REQUIRED_KEYS)}")
    _check_keys(doc, path)
    kind = doc.get("manipulator")
    if kind not in MODELS:
        raise ConfigError(f"{path}: 'manipulator' must be one of {', '.join(MODELS)}, got {kind!r}")
    if "unit" not in doc:
        raise ConfigError(f"{path}: missing key 'unit' (the unit of every length in the file: "
                          f"{', '.join(UNIT_TO_METRES)})")
    unit = doc["unit"]
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


def plausible_band(model) -> tuple[float, float]:
    """Leg lengths (config unit) a set of legs should lie in: ``leg_limits``, or else the
    geometry's scale divided and multiplied by :data:`PLAUSIBLE_SCALE_FACTOR`."""
    if model.leg_limits is not None:
        return model.leg_limits
    return model.scale / PLAUSIBLE_SCALE_FACTOR, model.scale * PLAUSIBLE_SCALE_FACTOR


def unit_mistake(model, legs, given_unit: str | None = None) -> str | None:
    """The unit that finite, positive leg lengths ``legs`` (config unit, converted from
    ``given_unit``; default: the config's unit) look like they were really written in, or None.

    Rule: the legs lie outside the plausible band (``leg_limits`` when the config has them,
    otherwise [scale / 100, 100 x scale] with the geometry's scale), and read in another unit
    they all lie inside it.  When several units fit, the one putting the legs nearest the
    geometry's scale (in ratio) wins.  A factor of 10 to 1000 between the units makes this
    reliable for the usual mistakes (metres <-> millimetres); any other input is left to the
    solver, which reports ``no_solution`` when the legs have no real assembly."""
    given_unit = given_unit or model.unit
    arr = np.asarray(legs, dtype=float).reshape(-1)
    if arr.size == 0:
        return None
    shortest, longest = float(arr.min()), float(arr.max())      # NaN in, NaN out: no hint
    if not (math.isfinite(shortest) and math.isfinite(longest)) or shortest <= 0.0:
        return None
    lo, hi = plausible_band(model)
    if lo <= shortest and longest <= hi:
        return None
    best, best_distance = None, math.inf
    for unit, metres in UNIT_TO_METRES.items():
        if unit == given_unit:
            continue
        factor = metres / UNIT_TO_METRES[given_unit]   # the numbers were written in `unit`
        if lo <= shortest * factor and longest * factor <= hi:
            distance = abs(math.log(float(np.median(arr)) * factor / model.scale))
            if distance < best_distance:
                best, best_distance = unit, distance
    return best


def check_units(model, legs, given_unit: str | None = None, where: str | None = None) -> None:
    """:class:`~glpma_ros.errors.InputError` with a one-line hint when :func:`unit_mistake`
    finds the legs written in another unit.  ``where`` says which unit the input should be in
    (default: "this config is in <unit>")."""
    unit = unit_mistake(model, legs, given_unit)
    if unit is not None:
        where = where or f"this config is in {model.unit}"
        raise InputError(f"leg lengths look like {UNIT_NAMES[unit]}; {where}")


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
