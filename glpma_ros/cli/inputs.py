"""What the built-in commands read from their arguments: the manipulator config, the leg lengths as the
sensors give them, and numbers as JSON has them."""
from __future__ import annotations

import math

import numpy as np

from ..config import check_units, load_manipulator, resolve_config


def load(config):
    """The manipulator of ``config`` (a YAML path or the name of a shipped config)."""
    return load_manipulator(resolve_config(config))


def pose_json(model, x):
    """The pose of solver variables ``x`` as JSON has it (position, orientation)."""
    return model.pose(x).as_dict()


def sensor_legs(model, legs):
    """Validated leg lengths (config unit) from the sensors' readings ``legs`` (the config's
    ``leg_offsets`` added); legs off by a unit factor get a one-line hint."""
    if np.asarray(legs).size == model.n_legs:
        check_units(model, legs)
    return model.check_legs(model.legs_from_sensors(legs))


def finite(value):
    """JSON has no inf or NaN: those become null."""
    return float(value) if value is not None and math.isfinite(value) else None
