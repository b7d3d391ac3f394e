"""Manipulator YAML -> model, with the validation errors users see.

Schema (see ``config/*.yaml`` and ``doc/interface.md``)::

    manipulator: planar_3rpr | hexapod_66  (the actuated families, delta | rus_6 | ...: :mod:`.models.families`)
    unit: mm | cm | m            # required: unit of every length in the file and on the CLI
    base: [[...], ...]           # base joints A_i in the base frame, one per leg (3-RPR: 3 to 12
                                 # legs, hexapod: 6 to 12; more than 3 / 6 are redundant legs)
    platform: [[...], ...]       # platform joints B_i in the platform frame (hexapod: joints may
                                 # coincide, two legs sharing one: 6-3, 3-6, 3-3)
    leg_limits: [min, max]       # optional, config unit: leg lengths outside are rejected
    leg_offsets: [...]           # optional, config unit, one per leg: added to every measured length
    passive_joint_limits: {...}  # optional, degrees: universal_cone_deg, spherical_cone_deg (hexapod),
                                 # base_revolute_deg, platform_revolute_deg (3-RPR); see description/limits.py
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

from .description.limits import PassiveLimits
from .errors import ConfigError, InputError
from .models import MODELS, Manipulator
from .models.families import FAMILIES, is_family, model_from_family
from .models.hexapod_66 import COINCIDENT_RELATIVE, frame_joints
from .units import UNIT_NAMES, UNIT_TO_METRES

#: coordinates of a joint, per kind
JOINT_DIMENSION = {"planar_3rpr": 2, "hexapod_66": 3}
#: legs a config may list, per kind: the degrees of freedom up to redundant legs (more squared
#: residuals; beyond a dozen a sensor is better fused elsewhere)
LEG_COUNT = {"planar_3rpr": (3, 12), "hexapod_66": (6, 12)}
#: keys a manipulator YAML may have (the first four are required)
REQUIRED_KEYS = ("manipulator", "unit", "base", "platform")
OPTIONAL_KEYS = ("leg_limits", "leg_offsets", "example_leg_lengths", "real_solutions", "published_solutions", "name",
                 "description", "passive_joint_limits")
#: without ``leg_limits``, leg lengths are plausible between the geometry's scale (largest extent of
#: the base or platform joints) divided and multiplied by this factor; all legs outside that band and
#: inside it once read in another unit are taken for a unit mistake
PLAUSIBLE_SCALE_FACTOR = 100.0
#: a leg offset (a sensor's zero error) larger than this share of the geometry's scale is refused:
#: it is no zero error but a wrong unit or a misplaced joint (calibrated offsets are a fraction of a mm)
MAX_OFFSET_SHARE = 0.1


def _matrix(doc: dict, key: str, kind: str, path: str, count: int | None = None) -> np.ndarray:
    """``doc[key]`` as an (n, dim) array: ``count`` points (default: the kind's range of leg counts)."""
    dim = JOINT_DIMENSION[kind]
    lo, hi = LEG_COUNT[kind]
    points = f"{count}" if count is not None else (f"{lo}" if lo == hi else f"{lo} to {hi}")
    if key not in doc:
        raise ConfigError(f"{path}: missing key '{key}'")
    try:
        arr = np.array(doc[key], dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{path}: '{key}' must be a list of {points} points of {dim} numbers") from None
    n = arr.shape[0] if arr.ndim == 2 else -1
    if arr.ndim != 2 or arr.shape[1] != dim or not (n == count if count is not None else lo <= n <= hi):
        raise ConfigError(f"{path}: '{key}' must have {points} points of {dim} coordinates, got shape "
                          f"{'x'.join(str(s) for s in arr.shape) or 'scalar'}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{path}: '{key}' has a non-finite coordinate")
    return arr


def _check_shared_joints(base: np.ndarray, platform: np.ndarray, path: str) -> None:
    """A hexapod's joints may coincide (two legs sharing a joint: the 6-3, 3-6 and 3-3 designs),
    as long as the pose stays determined: three distinct joints off one line on either side (the
    platform's give the solver variables, :func:`~glpma_ros.models.hexapod_66.frame_joints`), and
    at least six distinct legs (two legs joining the same two joints measure the same length)."""
    for key, arr in (("base", base), ("platform", platform)):
        if float(np.ptp(arr, axis=0).max()) <= 0.0:
            raise ConfigError(f"{path}: all '{key}' joints coincide")
        if frame_joints(arr) is None:
            raise ConfigError(f"{path}: the '{key}' joints leave the pose undetermined (fewer than three "
                              f"distinct joints, or all on one line)")
    size = max(float(np.ptp(base, axis=0).max()), float(np.ptp(platform, axis=0).max()))
    distinct = []
    for i in range(len(base)):
        same = next((j for j in distinct if np.linalg.norm(base[i] - base[j]) <= COINCIDENT_RELATIVE * size
                     and np.linalg.norm(platform[i] - platform[j]) <= COINCIDENT_RELATIVE * size), None)
        if same is None:
            distinct.append(i)
        elif len(base) == LEG_COUNT["hexapod_66"][0]:
            raise ConfigError(f"{path}: legs {same + 1} and {i + 1} join the same two joints (the pose is "
                              f"undetermined with six legs)")


def _check_joints(arr: np.ndarray, key: str, path: str, need_triangle: bool) -> None:
    """Coincident joints, and (for the platform) collinear first three joints."""
    size = float(np.ptp(arr, axis=0).max())
    if size <= 0.0:
        raise ConfigError(f"{path}: all '{key}' joints coincide")
    tol = COINCIDENT_RELATIVE * size
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
        if area <= COINCIDENT_RELATIVE * size * size:
            raise ConfigError(f"{path}: '{key}' joints 1, 2 and 3 are collinear")


def _unknown_keys(doc: dict) -> list:
    """Every unknown key, each named (with the known key it most resembles)."""
    known = REQUIRED_KEYS + OPTIONAL_KEYS
    problems = []
    for key in doc:
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else f"; known keys: {', '.join(known)}"
            problems.append(f"unknown key {str(key)!r}{hint}")
    return problems


class _Problems:
    """Collects the problems of one config, so that a file with several mistakes names them all."""

    def __init__(self, path: str):
        self.path, self.found = path, []

    def check(self, fn, *args):
        """``fn(*args)``, or None with its :class:`ConfigError` noted."""
        try:
            return fn(*args)
        except ConfigError as exc:
            self.found.append(str(exc).removeprefix(f"{self.path}: "))
            return None

    def raise_if_any(self) -> None:
        if len(self.found) == 1:
            raise ConfigError(f"{self.path}: {self.found[0]}")
        if self.found:
            raise ConfigError(f"{self.path}: {len(self.found)} problems: " + "; ".join(self.found))


def _leg_limits(doc: dict, path: str):
    limits = doc.get("leg_limits")
    if limits is None:
        return None
    try:
        lo, hi = (float(v) for v in limits)
    except (TypeError, ValueError):
        raise ConfigError(f"{path}: 'leg_limits' must be [min, max]") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo < hi):
        raise ConfigError(f"{path}: 'leg_limits' must satisfy 0 <= min < max, got [{lo}, {hi}]")
    return (lo, hi)


def model_from_dict(doc, path: str = "config") -> Manipulator:
    """Build and validate a model from a parsed YAML mapping.  Every problem found is named, in one
    line (``N problems: a; b``); checks that need a valid ``manipulator`` or joints run once those are."""
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: expected a YAML mapping with keys {', '.join(REQUIRED_KEYS)}")
    if is_family(doc):              # an actuated family (delta, rus_6): legs of the one leg model
        return model_from_family(doc, path)
    problems = _Problems(path)
    problems.found += _unknown_keys(doc)
    kind = doc.get("manipulator")
    if kind not in MODELS:
        problems.found.append(f"'manipulator' must be one of {', '.join([*MODELS, *FAMILIES])}, got {kind!r}")
    unit = doc.get("unit")
    if "unit" not in doc:
        problems.found.append(f"missing key 'unit' (the unit of every length in the file: "
                              f"{', '.join(UNIT_TO_METRES)})")
    elif unit not in UNIT_TO_METRES:
        problems.found.append(f"'unit' must be one of {', '.join(UNIT_TO_METRES)}, got {unit!r}")
    base = platform = None
    if kind in MODELS:
        base = problems.check(_matrix, doc, "base", kind, path)
        count = None if base is None else base.shape[0]
        platform = problems.check(_matrix, doc, "platform", kind, path, count)
        if kind == "hexapod_66":
            if base is not None and platform is not None:
                problems.check(_check_shared_joints, base, platform, path)
        else:
            if base is not None:
                problems.check(_check_joints, base, "base", path, False)
            if platform is not None:
                problems.check(_check_joints, platform, "platform", path, True)
    limits = problems.check(_leg_limits, doc, path)
    problems.raise_if_any()
    model = MODELS[kind](base, platform, unit=unit, leg_limits=limits)
    model.leg_offsets = _leg_offsets(doc, model, path)
    model.passive_limits = (None if doc.get("passive_joint_limits") is None else
                            PassiveLimits.from_config(doc["passive_joint_limits"], kind, model.n_legs, path))
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


def _leg_offsets(doc: dict, model, path: str):
    """``leg_offsets``: one finite number per leg (config unit), or None when the key is absent.
    An offset is a sensor's zero error, so it must be small beside the geometry: at most
    :data:`MAX_OFFSET_SHARE` of the scale."""
    if doc.get("leg_offsets") is None:
        return None
    n = model.n_legs
    try:
        arr = np.array(doc["leg_offsets"], dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{path}: 'leg_offsets' must be a list of {n} numbers (config unit)") from None
    if arr.shape != (n,):
        raise ConfigError(f"{path}: 'leg_offsets' must have one number per leg ({n}), got shape "
                          f"{'x'.join(str(s) for s in arr.shape) or 'scalar'}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{path}: 'leg_offsets' has a non-finite value")
    largest = float(np.abs(arr).max())
    if largest > MAX_OFFSET_SHARE * model.scale:
        raise ConfigError(f"{path}: 'leg_offsets' has an offset of {largest:g} {model.unit}, more than "
                          f"{MAX_OFFSET_SHARE:.0%} of the geometry's size ({model.scale:g} {model.unit}); "
                          f"offsets are in the config's unit")
    return arr


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


def shipped_configs() -> list:
    """Names of the shipped manipulator configs (the YAMLs beside the params files)."""
    return sorted(p.stem for p in config_dir().glob("*.yaml") if not p.name.startswith("params_"))


def yaml_error_text(exc: yaml.YAMLError) -> str:
    """The YAML parser's own message in one line, each part with its line and column (1-based)."""
    def at(mark):
        return f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    context, problem = getattr(exc, "context", None), getattr(exc, "problem", None)
    if problem is None:
        return " ".join(str(exc).split())
    parts = [f"{context}{at(exc.context_mark)}"] if context else []
    parts.append(f"{problem}{at(exc.problem_mark)}")
    return ": ".join(parts)


def load_document(path) -> dict:
    p = Path(path)
    try:
        text = p.read_text()
    except FileNotFoundError:
        raise ConfigError(f"{path}: cannot read manipulator config: no such file (give a YAML file, or the name "
                          f"of a shipped one: {', '.join(shipped_configs())})") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read manipulator config ({exc.strerror or exc})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: invalid YAML: {yaml_error_text(exc)}") from None


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
