"""The data of a kinematic calibration (:mod:`glpma_ros.calibration.identify`): the geometry and the
measurements it is identified from, and what the identification reports -- each parameter with its standard
error, the directions of parameter space the data see badly, named in words with the kind of pose that would
separate them (:func:`describe_direction`), the gauge directions no data can separate, the campaign's
observability.  Plain Python + NumPy."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..models.legs import LENGTH, PRISMATIC, REVOLUTE

#: components of a direction (a unit vector) at least this large in magnitude are named in its
#: description (1/sqrt(k) of a k-parameter direction spread evenly is 0.38 for k = 7)
NAMED_COMPONENT = 0.3


@dataclass
class Geometry:
    """The legs as the calibration sees them (the one leg model of :mod:`glpma_ros.models.legs`), config unit.

    Leg i is a rod between its proximal point ``P_i(q_i + o_i)`` and its platform joint ``B_i`` (``platform``,
    platform frame), ``q_i`` the sensor's reading and ``o_i`` its zero offset (``offsets``).  ``kind`` (one
    for every leg): ``LENGTH`` -- ``P_i = A_i`` (``base``) and the rod's length is ``q_i + o_i``; ``REVOLUTE``
    -- ``P_i = origin_i + Rot(axis_i, q_i + o_i) crank_i`` (``base`` holds the origins; radians; planar cranks
    turn about +z); ``PRISMATIC`` -- ``P_i = origin_i + (q_i + o_i) axis_i`` (``axis`` a unit vector); the
    actuated legs' rods have the lengths ``rods``.  ``translation``: the platform only translates (Delta),
    its orientation is the base's."""

    base: np.ndarray
    platform: np.ndarray
    offsets: np.ndarray
    kind: int = LENGTH
    crank: np.ndarray | None = None
    axis: np.ndarray | None = None
    rods: np.ndarray | None = None
    translation: bool = False

    @property
    def n_legs(self) -> int:
        return self.base.shape[0]

    @property
    def dim(self) -> int:
        return self.base.shape[1]

    @property
    def actuated(self) -> bool:
        return self.kind != LENGTH

    def copy(self) -> "Geometry":
        def c(a):
            return None if a is None else a.copy()
        return Geometry(self.base.copy(), self.platform.copy(), self.offsets.copy(), self.kind, c(self.crank),
                        c(self.axis), c(self.rods), self.translation)


@dataclass
class Measurements:
    """``legs`` (m, n): the sensors' readings (leg lengths; an actuated family's actuator positions: radians
    for revolute, config unit for prismatic actuators); ``position`` (m, d) and ``rotation`` (m, d, d): the
    measured platform poses in the base frame (platform -> base); config unit."""

    legs: np.ndarray
    position: np.ndarray
    rotation: np.ndarray

    def __len__(self) -> int:
        return self.legs.shape[0]

    def subset(self, index) -> "Measurements":
        return Measurements(self.legs[index], self.position[index], self.rotation[index])


#: what each parameter group is, in words (a leg's ...)
PART = {"base": "base joint", "origin": "origin", "crank": "crank", "axis": "rail direction", "rod": "rod",
        "platform": "platform joint", "offsets": "offset"}


@dataclass
class Parameter:
    legs: tuple               # the legs it belongs to, 1-based (several for a joint they share)
    group: str                # base | origin | crank | axis | rod | platform | offsets (identify.GROUPS)
    axis: str                 # x | y | z, "" for a rod or an offset
    nominal: float
    value: float
    se: float
    #: the parameter's share in the directions left at nominal, sum_k v_kj^2 over them (gauge directions
    #: included): 0 = fully identified (``se`` is its whole standard error), 1 = fully at nominal
    fixed_share: float = 0.0
    #: what it measures: "length" (config unit), "angle" (radians: a revolute actuator's offset) or
    #: "direction" (a component of a unit vector: a rail's direction)
    quantity: str = "length"

    @property
    def leg(self) -> int:
        return self.legs[0]

    @property
    def name(self) -> str:
        if self.group in ("offsets", "rod"):
            return f"leg {self.leg} {PART[self.group]}"
        return f"{legs_phrase(self.legs)} {self.group} {self.axis}"


@dataclass
class Direction:
    """A direction of parameter space the data see badly: the legs it concerns, its unit vector over
    their identified parameters (names -> component), its singular value per pose (``sigma_k /
    sqrt(m)``), the standard error along it (inf when ``rank_deficient``: sigma at round-off), in words."""

    legs: tuple
    components: dict
    singular_value: float
    se: float
    text: str
    rank_deficient: bool = False
    #: a gauge direction's name (a key of GAUGE_TEXT; "" for a direction the data see badly): a change of
    #: the parameters that changes no leg residual at any pose (the model's own redundancy, e.g. a crank
    #: turned about its axis against the actuator's zero offset)
    gauge: str = ""
    axis: str = ""            # the coordinate a gauge direction moves, where it is one (a Delta's x, y, z)

    @property
    def leg(self) -> int:
        return self.legs[0]


@dataclass
class Observability:
    """How well the campaign sees the parameters: the singular values of the identification Jacobian
    per pose (``sigma_k / sqrt(m)``, ascending), O1 (Borm & Menq), O3 (the smallest), the condition
    number (O2)."""

    singular_values: np.ndarray
    o1: float
    o3: float
    condition_number: float


@dataclass
class Identification:
    geometry: Geometry                   # identified (the groups not identified as given)
    parameters: list                     # Parameter, in GROUPS order, joints in leg order
    residual_std: np.ndarray             # s_i per leg (config unit)
    condition_number: float
    unidentifiable: list = field(default_factory=list)   # Direction left at nominal (rank-deficient or se > limit)
    weak: list = field(default_factory=list)             # Direction estimated, se above WEAK_SE_SHARE
    iterations: int = 0
    converged: bool = False
    observability: Observability | None = None
    se_limit: float = math.inf           # standard error above which a direction is left at nominal
    gauges: list = field(default_factory=list)           # Direction of the leg model's gauge, left at nominal


def legs_phrase(legs) -> str:
    return f"leg {legs[0]}" if len(legs) == 1 else "legs " + ", ".join(map(str, legs[:-1])) + f" and {legs[-1]}"


def describe_direction(v, labels, sigma, se, dim, rank_deficient=False) -> Direction:
    """Name direction ``v`` (unit vector over the distinct parameters ``labels``: (legs, group, axis))
    in words, with the kind of pose that would separate what moves together."""
    v = v if v[int(np.argmax(np.abs(v)))] > 0 else -v
    comps = {Parameter(legs, g, a, 0.0, 0.0, 0.0).name: float(x) for (legs, g, a), x in zip(labels, v)}
    big = [(legs, g, a) for (legs, g, a), x in zip(labels, v) if abs(x) >= NAMED_COMPONENT]
    all_legs = tuple(sorted({leg for legs, _, _ in labels for leg in legs}))
    one_leg = len({legs for legs, _, _ in big}) == 1 and len(big[0][0]) == 1
    words, said = [], False
    for legs, g, a in big:
        if g in ("offsets", "rod"):
            words.append(f"the {PART[g]} of leg {legs[0]}")
        elif one_leg and said:
            words.append(f"the {a} of its {PART[g]}")
        elif len(legs) == 1:
            words.append(f"the {a} of leg {legs[0]}'s {PART[g]}")
            said = True
        else:
            words.append(f"the {a} of the {PART[g]} of {legs_phrase(legs)}")
    involved = {g for _, g, _ in big}
    alone = f"{words[0]} is {'not seen' if rank_deficient else 'seen badly'}"
    what = alone if len(words) == 1 else ", ".join(words[:-1]) + f" and {words[-1]} move together"
    legs_text = legs_phrase(tuple(sorted({leg for legs, _, _ in big for leg in legs})))
    if {"base", "platform"} <= involved and "offsets" not in involved:
        advice = "add poses that rotate the platform"
    elif involved & set(ACTUATED_GROUPS):
        advice = f"add poses that move the actuators of {legs_text} over more of their range"
    elif "offsets" in involved:
        advice = (f"add poses that tilt the platform and move it sideways ({legs_text} must change direction)"
                  if dim == 3 else f"add poses that move and rotate the platform so that {legs_text} changes "
                                   f"direction")
    else:
        advice = "add poses spread wider over the workspace"
    return Direction(all_legs, comps, sigma, se, f"{what}: {advice}", rank_deficient)


#: the parameter groups only an actuated leg has
ACTUATED_GROUPS = ("origin", "crank", "axis", "rod")
#: each gauge of the leg model in words ({legs}: "leg 1" or "legs 1, 2 and 3"; {axes}: "x" or "x, y and z"),
#: by name (identify.gauge_vectors)
GAUGE_TEXT = {
    "crank_turn": "{legs}: the crank turned about its axis and the actuator's offset changed by the opposite "
                  "angle move no joint -- one parameter, the crank's angle at reading 0",
    "crank_along_axis": "{legs}: the origin and the crank moved oppositely along the axis move no joint -- only "
                        "the crank tip's position along the axis is a parameter",
    "rail_origin": "{legs}: the origin moved along the rail and the offset changed by the opposite length move no "
                   "joint -- one parameter, the carriage's position at reading 0",
    "translation": "{legs}: the origin and the platform joint moved together ({axes}) change no leg -- a platform "
                   "that only translates sees only their difference",
}


def gauge_text(name: str, legs, axes=("",)) -> str:
    """A gauge direction in words, for one or several legs (and coordinates)."""
    axes = [a for a in axes if a]
    axes_text = axes[0] if len(axes) == 1 else ", ".join(axes[:-1]) + f" and {axes[-1]}" if axes else ""
    return GAUGE_TEXT[name].format(legs=legs_phrase(tuple(legs)).capitalize(), axes=axes_text)


def gauge_direction(name: str, leg: int, axis: str, components: dict) -> Direction:
    """A gauge direction of leg ``leg`` (1-based) in words: nothing any pose measures separates it, so it
    stays at nominal whatever the data (no singular value, no standard error)."""
    return Direction((leg,), components, 0.0, math.inf, gauge_text(name, (leg,), (axis,)), rank_deficient=True,
                     gauge=name, axis=axis)


def kind_groups(kind: int) -> tuple:
    """The parameter groups of a leg of ``kind``, the identification Jacobian's column order."""
    if kind == REVOLUTE:
        return ("origin", "crank", "rod", "platform", "offsets")
    if kind == PRISMATIC:
        return ("origin", "axis", "rod", "platform", "offsets")
    return ("base", "platform", "offsets")
