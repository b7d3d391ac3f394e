"""The passive joints' limits a config may give (``passive_joint_limits``), and the check of a pose against them.

A universal or spherical joint bends up to a cone angle: the largest angle between the leg and the
joint's mounting axis -- the base's z axis at a hexapod's universal joint, the platform's z axis at its
spherical joint (a joint with the leg along that axis is straight).  A planar RPR leg's revolute joints
turn over a range: the base joint is the leg's angle from the base's x axis, the platform joint the
platform's angle minus the leg's.  Config (degrees; each value one number / pair for every leg, or a
list with one per leg)::

    passive_joint_limits:
      universal_cone_deg: 35          # hexapod
      spherical_cone_deg: 40          # hexapod
      base_revolute_deg: [-10, 120]   # planar
      platform_revolute_deg: [-90, 90]

A pose beyond a limit is still a pose of the mechanism (the forward kinematics does not know the
joints' hardware): the node publishes it and names the joint on ``/diagnostics`` (``joint limit``:
``leg 3 spherical 42.0 deg > 35.0 deg``).  No ROS import here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

KEY = "passive_joint_limits"
#: cone keys (hexapod) -> the joint they bound, and the URDF joints whose box holds the cone
CONES = {"universal_cone_deg": ("universal", ("u1", "u2")), "spherical_cone_deg": ("spherical", ("s1", "s2"))}
#: range keys (planar) -> the joint they bound (its URDF role)
RANGES = {"base_revolute_deg": ("base revolute", "base"), "platform_revolute_deg": ("platform revolute", "platform")}
KINDS = {"hexapod_66": CONES, "planar_3rpr": RANGES}
#: a cone angle is within (0, 180) degrees: 0 would forbid any bend, 180 bounds nothing
MAX_CONE_DEG = 180.0


def wrap(angle):
    """Angles in (-pi, pi]."""
    return math.pi - np.remainder(math.pi - np.asarray(angle, dtype=float), 2.0 * math.pi)


@dataclass(frozen=True)
class Violation:
    """One passive joint beyond its limit at a pose (angles in degrees)."""

    leg: int          # 0-based
    joint: str        # universal, spherical, base revolute, platform revolute
    angle_deg: float
    limit_deg: float

    def __str__(self) -> str:
        sign = ">" if self.angle_deg > self.limit_deg else "<"
        return f"leg {self.leg + 1} {self.joint} {self.angle_deg:.1f} deg {sign} {self.limit_deg:.1f} deg"


def _per_leg(value, n: int, pair: bool, name: str, path: str) -> np.ndarray:
    """``value`` (a number / pair for every leg, or one per leg) as an (n,) or (n, 2) array of degrees."""
    shape = "[min, max]" if pair else "a number"
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{path}: '{KEY}.{name}' must be {shape} or a list of {n} (one per leg)") from None
    single = arr.shape == ((2,) if pair else ())
    if not single and arr.shape != ((n, 2) if pair else (n,)):
        raise ConfigError(f"{path}: '{KEY}.{name}' must be {shape} or a list of {n} (one per leg), got shape "
                          f"{'x'.join(str(s) for s in arr.shape) or 'scalar'}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{path}: '{KEY}.{name}' has a non-finite value")
    out = np.broadcast_to(arr, (n, 2) if pair else (n,)).copy()
    if pair:
        if np.any(out[:, 0] >= out[:, 1]) or np.any(out < -180.0) or np.any(out > 180.0):
            raise ConfigError(f"{path}: '{KEY}.{name}' must be [min, max] with -180 <= min < max <= 180 (degrees)")
    elif np.any(out <= 0.0) or np.any(out >= MAX_CONE_DEG):
        raise ConfigError(f"{path}: '{KEY}.{name}' must be a cone angle between 0 and {MAX_CONE_DEG:g} degrees")
    return out


class PassiveLimits:
    """The limits of one config: ``cones`` (name -> (n,) degrees) and ``ranges`` (name -> (n, 2) degrees)."""

    def __init__(self, kind: str, cones: dict, ranges: dict):
        self.kind, self.cones, self.ranges = kind, cones, ranges

    @classmethod
    def from_config(cls, value, kind: str, n_legs: int, path: str = "config") -> "PassiveLimits":
        keys = KINDS.get(kind, {})
        if not isinstance(value, dict) or not value:
            raise ConfigError(f"{path}: '{KEY}' must be a mapping with {' or '.join(keys) or 'no keys'}")
        unknown = [k for k in value if k not in keys]
        if unknown:
            raise ConfigError(f"{path}: '{KEY}' has no key {unknown[0]!r} for a {kind} (known: {', '.join(keys)})")
        cones = {k: _per_leg(v, n_legs, False, k, path) for k, v in value.items() if k in CONES}
        ranges = {k: _per_leg(v, n_legs, True, k, path) for k, v in value.items() if k in RANGES}
        return cls(kind, cones, ranges)

    def joint_range(self, leg: int, role: str):
        """The range (radians) of URDF joint ``role`` of leg ``leg`` the limits imply, or None: a cone of
        angle c lies inside the box [-c, c] of the universal (spherical) joint's first two angles."""
        for key, (_, roles) in CONES.items():
            if key in self.cones and role in roles:
                c = math.radians(float(self.cones[key][leg]))
                return (-c, c)
        for key, (_, r) in RANGES.items():
            if key in self.ranges and role == r:
                lo, hi = self.ranges[key][leg]
                return (math.radians(float(lo)), math.radians(float(hi)))
        return None

    def violations(self, mech, position_m, orientation) -> list:
        """The passive joints of a :class:`~glpma_ros.description.mechanism.Mechanism` ``mech`` beyond
        their limits with the platform at ``position_m`` / ``orientation``, as :class:`Violation`."""
        R, _, d, L = mech.legs_at(position_m, orientation)
        u = d / L[:, None]
        out = []
        if self.kind == "hexapod_66":
            angles = {"universal_cone_deg": u[:, 2], "spherical_cone_deg": u @ R[:, 2]}
            for key, cos in angles.items():
                if key not in self.cones:
                    continue
                deg = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
                for i in np.flatnonzero(deg > self.cones[key]):
                    out.append(Violation(int(i), CONES[key][0], float(deg[i]), float(self.cones[key][i])))
            return out
        phi = np.arctan2(d[:, 1], d[:, 0])
        theta = math.atan2(R[1, 0], R[0, 0])
        angles = {"base_revolute_deg": np.degrees(phi),
                  "platform_revolute_deg": np.degrees(wrap(theta - phi))}
        for key, deg in angles.items():
            if key not in self.ranges:
                continue
            lo, hi = self.ranges[key][:, 0], self.ranges[key][:, 1]
            for i in np.flatnonzero((deg < lo) | (deg > hi)):
                limit = lo[i] if deg[i] < lo[i] else hi[i]
                out.append(Violation(int(i), RANGES[key][0], float(deg[i]), float(limit)))
        return out
