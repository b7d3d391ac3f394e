"""The manipulators the benchmark runs on: the shipped configs, their published solutions and
the start of the tracking loop (:mod:`glpma_tools.sim.trajectories`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glpma_ros.config import config_dir, load_document, model_from_dict
from glpma_ros.models.rotations import quaternion_from_matrix
from glpma_tools.sim.trajectories import start_pose, variables_along

#: short name -> shipped config
CONFIGS = {"3rpr": "planar_3rpr_seed.yaml", "hexapod": "hexapod_66_rolland.yaml"}
LABEL = {"3rpr": "3-RPR", "hexapod": "6-6 hexapod"}
#: solve-only tracking latency targets (p99, ms)
LATENCY_TARGET_MS = {"3rpr": 0.06, "hexapod": 0.12}
#: legs written -> pose read over DDS at 1 kHz: (p50, p99) targets in ms (None: no target)
END_TO_END_TARGET_MS = {"3rpr": (0.25, 0.5), "hexapod": (None, 0.7)}


@dataclass
class Scenario:
    key: str
    label: str
    path: str
    model: object
    legs: np.ndarray
    published: list            # published solutions as solver variables
    start: np.ndarray          # solver variables where the tracking loop starts

    def along(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` solver-variable vectors evenly along one loop of the simulated motion from :attr:`start`,
        and their leg lengths (config unit)."""
        xs = variables_along(self.model, self.start, n)
        return xs, np.array([self.model.inverse_kinematics(x) for x in xs])


def load(key: str) -> Scenario:
    """The manipulator ``key`` of :data:`CONFIGS`, ready to benchmark."""
    path = config_dir() / CONFIGS[key]
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    if key == "3rpr":
        published = [np.array([s["x"], s["y"], math.radians(s["theta_deg"])]) for s in doc.get("real_solutions", [])]
    else:
        published = [np.array(s, dtype=float) for s in doc.get("published_solutions", [])]
    p0, R0 = start_pose(model, doc)
    return Scenario(key, LABEL[key], str(path), model, np.asarray(model.example_leg_lengths, dtype=float),
                    published, model.variables_from_pose(p0, quaternion_from_matrix(R0)))
