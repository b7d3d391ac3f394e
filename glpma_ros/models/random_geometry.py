"""Random manipulators with leg lengths that have at least one real assembly mode: the test
and benchmark cases of every-assembly-mode search (``solve_all``).

Each generator takes a seeded ``numpy.random.Generator`` and returns ``(model, legs, pose)``:
a general geometry (no symmetry, no coplanarity beyond what the manipulator has by
construction) and the leg lengths of a random pose ``pose`` (solver variables), which is
therefore one of the real modes.  Units: millimetres.
"""
from __future__ import annotations

import math

import numpy as np

from .hexapod_66 import Hexapod66
from .planar_3rpr import Planar3RPR

#: 3-RPR: base joints uniform in [-B, B]^2, platform joints in [-P, P]^2 (mm)
PLANAR_BASE_HALF_WIDTH = 200.0
PLANAR_PLATFORM_HALF_WIDTH = 120.0
#: 3-RPR: the random pose's platform origin uniform in [-C, C]^2 (mm), angle uniform
PLANAR_POSITION_HALF_WIDTH = 100.0
#: a triangle whose smallest angle is below this is rejected (a nearly degenerate geometry)
MIN_TRIANGLE_ANGLE_RAD = math.radians(15.0)

#: 6-6 (the random cases of the assembly-mode tests): base joints x, y uniform in [-600, 600] mm, platform
#: joints x, y in [-300, 300] mm, both with z offsets uniform in [-Z, Z]; the pose at height ~800 mm
HEXAPOD_BASE_HALF_WIDTH = 600.0
HEXAPOD_PLATFORM_HALF_WIDTH = 300.0
HEXAPOD_Z_OFFSET = 30.0
HEXAPOD_HEIGHT = 800.0
#: the pose: horizontal offset uniform in [-X, X]^2, height HEIGHT +- dZ (mm), rotation vector
#: with components uniform in [-A, A] (rad)
HEXAPOD_POSE_OFFSET = 100.0
HEXAPOD_POSE_HEIGHT_SPREAD = 100.0
HEXAPOD_POSE_ANGLE = math.radians(20.0)
#: joints of base or platform closer than this (mm) are redrawn
HEXAPOD_MIN_JOINT_SPACING = 50.0


def _smallest_angle(tri: np.ndarray) -> float:
    angles = []
    for k in range(3):
        u, v = tri[(k + 1) % 3] - tri[k], tri[(k + 2) % 3] - tri[k]
        c = float(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)))
        angles.append(math.acos(max(-1.0, min(1.0, c))))
    return min(angles)


def _triangle(rng, half_width) -> np.ndarray:
    while True:
        tri = rng.uniform(-half_width, half_width, size=(3, 2))
        if _smallest_angle(tri) >= MIN_TRIANGLE_ANGLE_RAD:
            return tri


def random_planar_3rpr(rng: np.random.Generator):
    """A random 3-RPR (platform frame origin at joint B1) and the legs of a random pose."""
    base = _triangle(rng, PLANAR_BASE_HALF_WIDTH)
    platform = _triangle(rng, PLANAR_PLATFORM_HALF_WIDTH)
    platform = platform - platform[0]
    model = Planar3RPR(base, platform)
    pose = np.array([*rng.uniform(-PLANAR_POSITION_HALF_WIDTH, PLANAR_POSITION_HALF_WIDTH, 2),
                     rng.uniform(-math.pi, math.pi)])
    return model, model.inverse_kinematics(pose), pose


def _joints(rng, half_width) -> np.ndarray:
    while True:
        pts = np.column_stack((rng.uniform(-half_width, half_width, size=(6, 2)),
                               rng.uniform(-HEXAPOD_Z_OFFSET, HEXAPOD_Z_OFFSET, size=6)))
        d = np.linalg.norm(pts[:, None] - pts[None], axis=2) + np.eye(6) * 1e9
        if d.min() >= HEXAPOD_MIN_JOINT_SPACING:
            return pts


def random_hexapod(rng: np.random.Generator):
    """A random general 6-6 hexapod and the legs of a random pose above its base."""
    return _posed(rng, Hexapod66(_joints(rng, HEXAPOD_BASE_HALF_WIDTH), _joints(rng, HEXAPOD_PLATFORM_HALF_WIDTH)))


#: which of three joints each leg of a 3-3 (octahedral) hexapod joins on the base and on the platform:
#: every joint is shared by two legs, the legs are the lateral edges of an octahedron
OCTAHEDRAL_BASE = (0, 1, 1, 2, 2, 0)
OCTAHEDRAL_PLATFORM = (0, 0, 1, 1, 2, 2)
#: a 6-3: legs 1-2, 3-4, 5-6 share a platform joint
STEWART_PLATFORM = (0, 0, 1, 1, 2, 2)


def random_hexapod_33(rng: np.random.Generator):
    """A random 3-3 hexapod (three base and three platform joints, each shared by two legs, paired as an
    octahedron) and the legs of a random pose above its base."""
    base = _joints(rng, HEXAPOD_BASE_HALF_WIDTH)[:3]
    platform = _joints(rng, HEXAPOD_PLATFORM_HALF_WIDTH)[:3]
    return _posed(rng, Hexapod66(base[list(OCTAHEDRAL_BASE)], platform[list(OCTAHEDRAL_PLATFORM)]))


def random_hexapod_63(rng: np.random.Generator):
    """A random 6-3 hexapod (six base joints, three platform joints shared by two legs each) and the legs
    of a random pose above its base."""
    base = _joints(rng, HEXAPOD_BASE_HALF_WIDTH)
    platform = _joints(rng, HEXAPOD_PLATFORM_HALF_WIDTH)[:3]
    return _posed(rng, Hexapod66(base, platform[list(STEWART_PLATFORM)]))


def _posed(rng, model):
    """``(model, legs, pose)`` for a random pose above the base."""
    w = rng.uniform(-HEXAPOD_POSE_ANGLE, HEXAPOD_POSE_ANGLE, 3)
    angle = float(np.linalg.norm(w))
    axis = w / angle if angle > 0 else np.array([0.0, 0.0, 1.0])
    q = np.array([*(math.sin(angle / 2) * axis), math.cos(angle / 2)])
    position = np.array([*rng.uniform(-HEXAPOD_POSE_OFFSET, HEXAPOD_POSE_OFFSET, 2),
                         HEXAPOD_HEIGHT + rng.uniform(-HEXAPOD_POSE_HEIGHT_SPREAD, HEXAPOD_POSE_HEIGHT_SPREAD)])
    pose = model.variables_from_pose(position, q)
    return model, model.inverse_kinematics(pose), pose


GENERATORS = {"planar_3rpr": random_planar_3rpr, "hexapod_66": random_hexapod}
