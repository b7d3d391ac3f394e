"""The node's input conversion: a ``std_msgs/Float64MultiArray`` of leg lengths or a
``sensor_msgs/JointState`` (decoded by the transport into :class:`JointStateInput`) as the leg
lengths the estimator solves for -- the legs picked by name from a JointState, metres (REP 103)
turned into the config's unit, the config's ``leg_offsets`` added -- with a one-line
:class:`~glpma_ros.errors.InputError` naming what is wrong with a bad input."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import check_units, plausible_band
from ..errors import InputError
from ..models.base import lengths_from_readings
from .dds import cdr
from .input_topic import model_is_actuated


def default_joint_names(n_legs: int) -> list:
    """``leg_1`` .. ``leg_n``: the joint names when parameter ``joint_names`` is empty."""
    return [f"leg_{i + 1}" for i in range(n_legs)]


@dataclass(frozen=True)
class JointStateInput:
    """A ``sensor_msgs/JointState`` as far as the node reads it: joint names, positions (metres)
    and velocities (m/s; empty when the message has none)."""

    names: tuple
    positions: tuple
    velocities: tuple = ()


class InputConverter:
    """An input (leg lengths in metres, or a :class:`JointStateInput`) as leg lengths in the config's
    unit, for one manipulator ``model``; ``joint_names``: the legs' joint names in leg order (empty:
    :func:`default_joint_names`), set again when the parameter changes."""

    def __init__(self, model, joint_names=()):
        self.model = model
        self.metres_per_unit = float(model.metres_per_unit)
        self._band = plausible_band(model)          # config unit
        self._actuated = model_is_actuated(model)
        #: how a leg-length reading becomes a leg length (:func:`~glpma_ros.models.base.lengths_from_readings`:
        #: metres per config unit, the plausible band's ends, the config's ``leg_offsets``); None for an
        #: actuated family, whose readings the model converts (:meth:`to_config_unit`)
        self.readings = None if self._actuated else (
            self.metres_per_unit, float(self._band[0]), float(self._band[1]),
            np.zeros(model.n_legs) if model.leg_offsets is None else np.array(model.leg_offsets, dtype=float))
        self.joint_names = joint_names

    @property
    def joint_names(self) -> list:
        """The legs' joint names in leg order (``joint_names``, or ``leg_1`` .. ``leg_n``)."""
        return list(self._joint_names)

    @joint_names.setter
    def joint_names(self, names) -> None:
        self._joint_names = tuple(names) or tuple(default_joint_names(self.model.n_legs))

    def _leg_indices(self, names, positions) -> list:
        """Where each leg of :attr:`joint_names` is in a JointState's ``names``."""
        names = list(names)
        if len(names) != len(positions):
            raise InputError(f"joint_states has {len(names)} names but {len(positions)} positions")
        index: dict = {}
        for i, name in enumerate(names):
            index.setdefault(name, []).append(i)
        found_at = []
        for leg in self._joint_names:
            found = index.get(leg)
            if not found:
                raise InputError(f"joint_states has no joint '{leg}'")
            if len(found) > 1:
                raise InputError(f"joint_states names joint '{leg}' {len(found)} times")
            found_at.append(found[0])
        return found_at

    def legs_from_joint_state(self, names, positions) -> list:
        """The leg lengths (metres, leg order) in a JointState's ``names`` / ``positions``: each
        leg by its name in :attr:`joint_names`, in any order; other joints are ignored.
        :class:`InputError` with the reason when a leg is missing or named twice, or when there
        are not as many positions as names."""
        positions = list(positions)
        return [positions[i] for i in self._leg_indices(names, positions)]

    def leg_rates_from_joint_state(self, js: JointStateInput):
        """The legs' rates (m/s, leg order) from a JointState's velocities, or None when it has
        none (``velocity`` empty, as the message allows) or they are not finite."""
        if not js.velocities or len(js.velocities) != len(js.names):
            return None
        try:
            rates = np.array([js.velocities[i] for i in self._leg_indices(js.names, js.positions)], dtype=float)
        except (InputError, TypeError, ValueError):
            return None
        return rates if np.all(np.isfinite(rates)) else None

    def legs_m(self, raw):
        """An input (leg lengths in metres, a :class:`JointStateInput`, or a ``Float64MultiArray`` message's
        CDR_LE bytes: what the one-call way keeps of its input) as leg lengths in metres."""
        if isinstance(raw, JointStateInput):
            return self.legs_from_joint_state(raw.names, raw.positions)
        if type(raw) is bytes:
            return cdr.float64_multi_array_data(raw)
        return raw

    def to_config_unit(self, raw) -> np.ndarray:
        """An input's leg lengths (metres, or a :class:`JointStateInput`) in the config's unit, with the
        config's ``leg_offsets`` added: the lengths |B_i - A_i| the estimator solves for; an actuated
        family's actuator positions (radians, or metres for prismatic ones) as its leg vector."""
        model = self.model
        if self._actuated:
            return model.legs_from_si(self.legs_m(raw))
        if type(raw) is tuple and len(raw) == model.n_legs:
            # the usual input (a message's floats), every leg within the plausible band (finite, no unit
            # mistake possible): converted in one compiled pass; otherwise the checks below name the problem
            try:
                values = np.array(raw, dtype=float)
            except (TypeError, ValueError):
                values = None
            if values is not None:
                legs = np.empty(model.n_legs)
                if lengths_from_readings(values, *self.readings, legs):
                    return legs
        try:
            legs_m = np.asarray(self.legs_m(raw), dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError("leg lengths are not numbers") from None
        with np.errstate(over="ignore", invalid="ignore"):
            legs = legs_m / self.metres_per_unit
        if legs.size == model.n_legs and np.all(np.isfinite(legs_m)) and not np.all(np.isfinite(legs)):
            raise InputError(f"leg lengths too large to express in {model.unit}")
        if legs.size == model.n_legs:   # e.g. millimetres sent on the topic: a reason naming units
            check_units(model, legs, "m", "topics are in metres (REP 103)")
        return model.legs_from_sensors(legs)      # the config's leg_offsets added
