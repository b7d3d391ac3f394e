"""The manipulators, their published solutions and the tracking trajectories."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import yaml

from ..config import config_dir, load_manipulator
from ..models.hexapod_66 import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector

#: short name -> shipped config
CONFIGS = {"3rpr": "planar_3rpr_seed.yaml", "hexapod": "hexapod_66_rolland.yaml"}
LABEL = {"3rpr": "3-RPR", "hexapod": "6-6 hexapod"}
#: solve-only tracking latency targets (p99, ms)
LATENCY_TARGET_MS = {"3rpr": 0.06, "hexapod": 0.12}


@dataclass
class Scenario:
    key: str
    label: str
    path: str
    model: object
    legs: np.ndarray
    published: list            # published solutions as solver variables


def load(key: str) -> Scenario:
    path = config_dir() / CONFIGS[key]
    model = load_manipulator(path)
    doc = yaml.safe_load(path.read_text())
    if key == "3rpr":
        published = [np.array([s["x"], s["y"], math.radians(s["theta_deg"])]) for s in doc.get("real_solutions", [])]
    else:
        published = [np.array(s, dtype=float) for s in doc.get("published_solutions", [])]
    return Scenario(key, LABEL[key], str(path), model, np.asarray(model.example_leg_lengths, dtype=float),
                    published)


def trajectory(sc: Scenario, steps: int) -> np.ndarray:
    """``steps + 1`` solver-variable vectors of a smooth motion on one assembly mode.

    3-RPR: a closed loop (circle of radius 10 mm, angle +/- 5 deg) around the first
    published solution.  Hexapod: a helix (radius 30 mm, two turns, 100 mm rise)
    with the platform rotating (yaw +/- 10 deg, roll and pitch +/- 3 deg) around the
    published solution nearest the home pose (platform above the base, level)."""
    s = np.linspace(0.0, 1.0, steps + 1)
    model = sc.model
    if sc.key == "3rpr":
        x0 = sc.published[0]
        return np.column_stack((x0[0] + 10.0 * (np.cos(2 * np.pi * s) - 1.0),
                                x0[1] + 10.0 * np.sin(2 * np.pi * s),
                                x0[2] + math.radians(5.0) * np.sin(4 * np.pi * s)))
    # home-like solution: the published one with the platform highest and most level
    def tilt(x):
        p = model.pose(x)
        R = matrix_from_quaternion(p.orientation)
        return -p.position[2] + 1e3 * (1.0 - R[2, 2])
    home = min(sc.published, key=tilt)
    from ..solvers import refine
    x0, _, _ = refine.polish(model, home, sc.legs, np.random.default_rng(0))
    p0 = model.pose(x0)
    R0 = matrix_from_quaternion(p0.orientation)
    out = []
    for t in s:
        pos = p0.position + np.array([30.0 * (math.cos(4 * np.pi * t) - 1.0), 30.0 * math.sin(4 * np.pi * t),
                                      100.0 * t])
        w = np.radians([3.0 * math.sin(2 * np.pi * t), 3.0 * math.sin(4 * np.pi * t), 10.0 * math.sin(2 * np.pi * t)])
        out.append(model.variables_from_pose(pos, quaternion_from_matrix(rotation_from_vector(w) @ R0)))
    return np.array(out)
