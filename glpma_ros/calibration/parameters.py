"""The data of a kinematic calibration (:mod:`glpma_ros.calibration.identify`): the geometry and the
measurements it is identified from, and what the identification reports -- each parameter with its standard
error, the directions of parameter space the data see badly, named in words with the kind of pose that would
separate them (:func:`describe_direction`), the campaign's observability.  Plain Python + NumPy."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: components of a direction (a unit vector) at least this large in magnitude are named in its
#: description (1/sqrt(k) of a k-parameter direction spread evenly is 0.38 for k = 7)
NAMED_COMPONENT = 0.3


@dataclass
class Geometry:
    """Base joints A (n, d), platform joints B (n, d) and sensor offsets (n,), config unit."""

    base: np.ndarray
    platform: np.ndarray
    offsets: np.ndarray

    @property
    def n_legs(self) -> int:
        return self.base.shape[0]

    @property
    def dim(self) -> int:
        return self.base.shape[1]

    def copy(self) -> "Geometry":
        return Geometry(self.base.copy(), self.platform.copy(), self.offsets.copy())


@dataclass
class Measurements:
    """``legs`` (m, n): the sensors' readings; ``position`` (m, d) and ``rotation`` (m, d, d): the
    measured platform poses in the base frame (platform -> base); config unit."""

    legs: np.ndarray
    position: np.ndarray
    rotation: np.ndarray

    def __len__(self) -> int:
        return self.legs.shape[0]

    def subset(self, index) -> "Measurements":
        return Measurements(self.legs[index], self.position[index], self.rotation[index])


@dataclass
class Parameter:
    legs: tuple               # the legs it belongs to, 1-based (several for a joint they share)
    group: str                # base | platform | offsets
    axis: str                 # x | y | z, "" for an offset
    nominal: float
    value: float
    se: float
    #: the parameter's share in the directions left at nominal, sum_k v_kj^2 over them: 0 = fully
    #: identified (``se`` is its whole standard error), 1 = fully at nominal
    fixed_share: float = 0.0

    @property
    def leg(self) -> int:
        return self.legs[0]

    @property
    def name(self) -> str:
        if self.group == "offsets":
            return f"leg {self.leg} offset"
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
        if g == "offsets":
            words.append(f"the offset of leg {legs[0]}")
        elif one_leg and said:
            words.append(f"the {a} of its {g} joint")
        elif len(legs) == 1:
            words.append(f"the {a} of leg {legs[0]}'s {g} joint")
            said = True
        else:
            words.append(f"the {a} of the {g} joint of {legs_phrase(legs)}")
    involved = {g for _, g, _ in big}
    alone = f"{words[0]} is {'not seen' if rank_deficient else 'seen badly'}"
    what = alone if len(words) == 1 else ", ".join(words[:-1]) + f" and {words[-1]} move together"
    legs_text = legs_phrase(tuple(sorted({leg for legs, _, _ in big for leg in legs})))
    if {"base", "platform"} <= involved and "offsets" not in involved:
        advice = "add poses that rotate the platform"
    elif "offsets" in involved:
        advice = (f"add poses that tilt the platform and move it sideways ({legs_text} must change direction)"
                  if dim == 3 else f"add poses that move and rotate the platform so that {legs_text} changes "
                                   f"direction")
    else:
        advice = "add poses spread wider over the workspace"
    return Direction(all_legs, comps, sigma, se, f"{what}: {advice}", rank_deficient)
