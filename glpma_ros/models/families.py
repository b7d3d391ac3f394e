"""The actuated families' YAML (``manipulator: delta`` ...) -> model, with the validation errors users see.

Schema (see ``config/delta_*.yaml``, ``config/rus6_*.yaml`` and the README's "Your robot")::

    manipulator: delta | rus_6 | planar_3rrr | linear_delta | pus_6 | planar_3prr   # the family (FAMILIES)
    unit: mm | cm | m                  # every length in the file; prismatic actuators move in it too
    platform_motion: translation       # optional; the family's (delta, linear_delta: translation; rus_6,
                                       # pus_6: full; planar_3rrr, planar_3prr: planar, 2-D points)
    legs:                              # leg order = actuator order
      - actuator: revolute             # revolute: q in radians | prismatic: q in the config unit
        origin: [x, y, z]              # the actuated joint (prismatic: the rail's zero), base frame
        axis: [ax, ay, az]             # revolute: rotation axis (q > 0 turns right-handed about it; none
                                       # in the plane: +z) | prismatic: the rail's direction (q > 0 along it)
        crank: [cx, cy, cz]            # revolute only: the crank's tip at q = 0, relative to origin
        rod: 800.0                     # the distal link's length, crank tip to platform joint
        platform: [bx, by, bz]         # the distal joint on the platform, platform frame
    actuator_limits: [[lo, hi], ...]   # optional, per leg (rad / config unit): readings outside are rejected
    actuator_offsets: [...]            # optional, per leg: added to every reading (zero offsets)
    example_actuator_positions: [...]  # optional: a reading with known solutions
    known_solutions: [[...], ...]      # optional: the solver variables of every real mode at that reading
    name: ..., description: ...        # optional, free text
"""
from __future__ import annotations

import difflib
import math

import numpy as np

from ..errors import ConfigError
from ..units import UNIT_TO_METRES
from .actuated import ActuatedPlanar, ActuatedSpatial, DeltaTranslation
from .legs import ACTUATOR_KINDS, REVOLUTE

#: the shipped families: model class, legs, the actuator every leg has, the platform's motion
FAMILIES = {
    "delta": (DeltaTranslation, 3, "revolute", "translation"),
    "rus_6": (ActuatedSpatial, 6, "revolute", "full"),
    "planar_3rrr": (ActuatedPlanar, 3, "revolute", "planar"),
    # the rail-driven ones: the proximal point is a carriage, P_i(q) = origin_i + q axis_i
    "linear_delta": (DeltaTranslation, 3, "prismatic", "translation"),
    "pus_6": (ActuatedSpatial, 6, "prismatic", "full"),
    "planar_3prr": (ActuatedPlanar, 3, "prismatic", "planar"),
}
#: a planar family's legs: 2-D points, the cranks turn about +z (no axis; a planar rail has its 2-D axis)
PLANAR_MOTION = "planar"
REQUIRED_KEYS = ("manipulator", "unit", "legs")
OPTIONAL_KEYS = ("platform_motion", "actuator_limits", "actuator_offsets", "example_actuator_positions",
                 "known_solutions", "name", "description")
LEG_KEYS = ("actuator", "origin", "axis", "crank", "rod", "platform")
#: an actuator offset larger than this share of a turn (revolute) or of the scale (prismatic) is no zero error
MAX_OFFSET_SHARE = 0.1
#: an axis shorter than this (it is normalised) or a crank along its axis (sine of the angle) is degenerate
DEGENERATE = 1e-9


def is_family(doc) -> bool:
    return isinstance(doc, dict) and doc.get("manipulator") in FAMILIES


def _vector(value, dim, what, problems) -> np.ndarray | None:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (dim,) or not np.all(np.isfinite(arr)):
        problems.append(f"{what} must be {dim} finite numbers")
        return None
    return arr


def _leg_keys(dim, actuator) -> tuple:
    """The keys of a leg: a planar crank (``dim`` 2) has no axis (it turns about +z); a rail has no crank."""
    if actuator == "prismatic":
        return tuple(k for k in LEG_KEYS if k != "crank")
    return LEG_KEYS if dim == 3 else tuple(k for k in LEG_KEYS if k != "axis")


def _leg(i, leg, dim, actuator, problems):
    """One leg's (kind, origin, axis, crank, rod, platform), problems noted (:func:`_leg_keys`; a rail's crank
    is zero)."""
    where = f"legs[{i + 1}]"
    keys = _leg_keys(dim, actuator)
    if not isinstance(leg, dict):
        problems.append(f"{where} must be a mapping with keys {', '.join(keys)}")
        return None
    for key in leg:
        if key not in keys:
            close = difflib.get_close_matches(str(key), keys, n=1)
            why = " (a planar crank turns about +z)" if key == "axis" else \
                " (a rail has no crank)" if key == "crank" else \
                (f" (did you mean '{close[0]}'?)" if close else "")
            problems.append(f"{where}: unknown key {str(key)!r}{why}")
    missing = [k for k in keys if k not in leg]
    if missing:
        problems.append(f"{where}: missing {', '.join(missing)}")
        return None
    if leg["actuator"] != actuator:
        problems.append(f"{where}: actuator must be {actuator!r} in this family, got {leg['actuator']!r}")
        return None
    axis_value = leg.get("axis", [1.0, 0.0])       # unused by a planar crank
    crank_value = leg.get("crank", [0.0] * dim)     # unused by a rail
    origin, axis, crank, platform = (_vector(v, dim, f"{where}.{k}", problems) for k, v in
                                     (("origin", leg["origin"]), ("axis", axis_value), ("crank", crank_value),
                                      ("platform", leg["platform"])))
    try:
        rod = float(leg["rod"])
    except (TypeError, ValueError):
        rod = math.nan
    if not (math.isfinite(rod) and rod > 0.0):
        problems.append(f"{where}.rod must be a positive length")
    if any(v is None for v in (origin, axis, crank, platform)) or not rod > 0.0:
        return None
    norm = float(np.linalg.norm(axis))
    if norm < DEGENERATE:
        problems.append(f"{where}.axis must not be zero")
        return None
    kind = ACTUATOR_KINDS[actuator]
    if dim == 2 and kind == REVOLUTE and float(np.linalg.norm(crank)) < DEGENERATE * max(1.0, rod):
        problems.append(f"{where}.crank must not be zero (it would not move)")
        return None
    along_axis = dim == 3 and float(np.linalg.norm(np.cross(axis / norm, crank))) < DEGENERATE * max(1.0, rod)
    if kind == REVOLUTE and along_axis:
        problems.append(f"{where}.crank must not be along the axis (it would not move)")
        return None
    return kind, origin, axis, crank, rod, platform


def _per_leg(doc, key, n, problems, pairs=False):
    if doc.get(key) is None:
        return None
    shape = (n, 2) if pairs else (n,)
    try:
        arr = np.array(doc[key], dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != shape or not np.all(np.isfinite(arr)):
        problems.append(f"'{key}' must be {n} " + ("[min, max] pairs" if pairs else "numbers") + " (one per leg)")
        return None
    if pairs and np.any(arr[:, 0] >= arr[:, 1]):
        problems.append(f"'{key}' must have min < max for every leg")
        return None
    return arr


def model_from_family(doc: dict, path: str):
    """The model of an actuated family's YAML; every problem found is named, in one line."""
    family = doc["manipulator"]
    cls, n, actuator, motion = FAMILIES[family]
    problems = []
    for key in doc:
        if key not in REQUIRED_KEYS + OPTIONAL_KEYS:
            close = difflib.get_close_matches(str(key), REQUIRED_KEYS + OPTIONAL_KEYS, n=1)
            problems.append(f"unknown key {str(key)!r}" + (f" (did you mean '{close[0]}'?)" if close else ""))
    unit = doc.get("unit")
    if unit not in UNIT_TO_METRES:
        problems.append(f"'unit' must be one of {', '.join(UNIT_TO_METRES)}, got {unit!r}")
    given_motion = doc.get("platform_motion", motion)
    if given_motion != motion:
        problems.append(f"'platform_motion' of {family} is {motion!r}, got {given_motion!r}")
    legs = doc.get("legs")
    parsed = []
    if not isinstance(legs, list) or len(legs) != n:
        problems.append(f"'legs' must list the {n} legs of {family}")
    else:
        dim = 2 if motion == PLANAR_MOTION else 3
        parsed = [_leg(i, leg, dim, actuator, problems) for i, leg in enumerate(legs)]
    limits = _per_leg(doc, "actuator_limits", n, problems, pairs=True)
    offsets = _per_leg(doc, "actuator_offsets", n, problems)
    revolute = ACTUATOR_KINDS[actuator] == REVOLUTE
    if offsets is not None and revolute and np.abs(offsets).max() > MAX_OFFSET_SHARE * math.pi:
        problems.append(f"'actuator_offsets' must be small zero errors (at most {MAX_OFFSET_SHARE * math.pi:.3g} rad)")
    if problems or any(p is None for p in parsed):
        raise ConfigError(f"{path}: {problems[0]}" if len(problems) == 1
                          else f"{path}: {len(problems)} problems: " + "; ".join(problems))
    kinds, origin, axis, crank, rods, platform = (np.array(col) for col in zip(*parsed))
    try:
        model = cls(family, kinds, origin, axis, crank, rods, platform, unit=unit, actuator_limits=limits)
    except ValueError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    if offsets is not None and not revolute and np.abs(offsets).max() > MAX_OFFSET_SHARE * model.scale:
        raise ConfigError(f"{path}: 'actuator_offsets' must be small zero errors beside the geometry")
    model.actuator_offsets = offsets
    model.leg_offsets = None
    model.source = path
    model.metres_per_unit = UNIT_TO_METRES[unit]
    model.example_leg_lengths = None
    model.example_actuator_positions = None
    example = doc.get("example_actuator_positions")
    if example is not None:
        try:
            model.example_actuator_positions = model.check_actuators(example)
            model.example_leg_lengths = model.legs_from_sensors(example)
        except Exception as exc:  # noqa: BLE001 - reported as a config error
            raise ConfigError(f"{path}: 'example_actuator_positions': {exc}") from None
    known = doc.get("known_solutions")
    model.known_solutions = None
    if known is not None:
        try:
            arr = np.array(known, dtype=float)
        except (TypeError, ValueError):
            arr = None
        if arr is None or arr.ndim != 2 or arr.shape[1] != model.n_vars or example is None:
            raise ConfigError(f"{path}: 'known_solutions' must be rows of the {model.n_vars} solver variables "
                              f"({' '.join(model.variable_names)}) at 'example_actuator_positions'")
        model.known_solutions = arr
    return model
