"""The motion the tools simulate: a closed loop of the platform around one of the config's
known solutions, the same for the mock controller, the demo, the stress test, the benchmark's
tracking runs and the tests.

* 3-RPR: the platform origin goes round a circle through the start (radius
  :data:`PLANAR_RADIUS` of the geometry's scale) while the platform turns back and forth
  (:data:`PLANAR_SWING_RAD`) twice per loop.
* hexapod: the platform origin goes round a circle in x-y (:data:`SPATIAL_RADIUS`), rising and
  falling twice per loop (:data:`SPATIAL_RISE`), while the platform turns about the vertical
  (:data:`SPATIAL_TWIST_RAD`) and tilts (:data:`SPATIAL_TILT` of the twist).

The position on the circle tells the time within a loop, so the pose (and, this close to one
assembly mode, the legs) repeats only a whole period later: :mod:`glpma_ros.testing.matching` relies on it to pair
a pose with the input it answers.  Sizes scale with ``amplitude``.
"""
from __future__ import annotations

import math

import numpy as np

from glpma_ros.config import load_document, model_from_dict, resolve_config
from glpma_ros.errors import GlpmaError
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector
from glpma_ros.testing.matching import legs_for

#: known solution of each manipulator to move around (index in the config's list)
DEFAULT_SOLUTION = {"planar_3rpr": 0,      # real_solutions[0], the one of 001 Table 1
                    "hexapod_66": 10}      # platform above the base, centred, well conditioned
#: seconds per loop
PERIOD_S = 4.0
#: 3-RPR: radius of the circle (share of the scale) and swing of the platform angle (rad)
PLANAR_RADIUS = 0.05
PLANAR_SWING_RAD = 0.1
#: hexapod: radius of the circle and rise (shares of the scale), twist about the vertical (rad),
#: tilt about x (share of the twist)
SPATIAL_RADIUS = 0.02
SPATIAL_RISE = 0.03
SPATIAL_TWIST_RAD = 0.1
SPATIAL_TILT = 0.3


def _rot_z(angle: float) -> np.ndarray:
    return rotation_from_vector(np.array([0.0, 0.0, angle]))


def known_solutions(doc: dict) -> list:
    """The config's known solutions (``real_solutions`` of a 3-RPR, ``published_solutions`` of a hexapod)."""
    return list(doc.get("real_solutions") or doc.get("published_solutions") or [])


def default_solution(model, doc: dict) -> int:
    """:data:`DEFAULT_SOLUTION` of the kind, or 0 for a config listing fewer known solutions (the
    papers' configs list many modes and the default picks one; a config of one's own, one)."""
    index = DEFAULT_SOLUTION[model.kind]
    return index if index < len(known_solutions(doc)) else 0


def start_pose(model, doc: dict, solution: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(position, rotation matrix) of a known solution of the config (config unit)."""
    sols = known_solutions(doc)
    if solution is None and not sols:
        return _solved_start_pose(model)
    index = default_solution(model, doc) if solution is None else int(solution)
    if not 0 <= index < len(sols):
        key = "real_solutions" if model.kind == "planar_3rpr" else "published_solutions"
        raise GlpmaError(f"the config has {len(sols)} {key}; cannot use solution {index}")
    s = sols[index]
    if model.kind == "planar_3rpr":
        return np.array([s["x"], s["y"], 0.0], dtype=float), _rot_z(math.radians(s["theta_deg"]))
    R, p = model.pose_state(np.asarray(s, dtype=float))   # rigid fit of the published joints
    return np.asarray(p, dtype=float), np.asarray(R, dtype=float)


def _solved_start_pose(model) -> tuple[np.ndarray, np.ndarray]:
    """A user's own config without known solutions: start where its ``example_leg_lengths`` put
    the platform (one cold solve, no time limit)."""
    if model.example_leg_lengths is None:
        raise GlpmaError("the config has no known solutions and no example_leg_lengths to start from; "
                         "add example_leg_lengths (a pose's leg lengths)")
    e = Estimator(model, time_budget_s=60.0).estimate(model.example_leg_lengths)
    if not e.converged:
        raise GlpmaError(f"cannot start from the config's example_leg_lengths: {e.message}")
    return np.asarray(e.pose.position, dtype=float), matrix_from_quaternion(e.pose.orientation)


def trajectory(model, p0: np.ndarray, R0: np.ndarray, amplitude: float = 1.0, period_s: float = PERIOD_S):
    """``t -> (position, rotation matrix)``, at ``(p0, R0)`` when ``t`` is a multiple of ``period_s``."""
    w = 2.0 * math.pi / period_s
    s = model.scale * amplitude
    if model.kind == "planar_3rpr":
        def pose_at(t):
            r = PLANAR_RADIUS * s
            p = p0 + np.array([r * (math.cos(w * t) - 1.0), r * math.sin(w * t), 0.0])
            return p, _rot_z(PLANAR_SWING_RAD * amplitude * math.sin(2 * w * t)) @ R0
    else:
        def pose_at(t):
            r, rise, twist = SPATIAL_RADIUS * s, SPATIAL_RISE * s, SPATIAL_TWIST_RAD * amplitude
            p = p0 + np.array([r * (math.cos(w * t) - 1.0), r * math.sin(w * t), rise * math.sin(2 * w * t)])
            tilt = rotation_from_vector(np.array([SPATIAL_TILT * twist * math.sin(2 * w * t), 0.0, 0.0]))
            return p, _rot_z(twist * math.sin(w * t)) @ tilt @ R0
    return pose_at


def variables_along(model, x0, n: int, amplitude: float = 1.0) -> np.ndarray:
    """``n`` solver-variable vectors evenly along one loop that starts at solver variables ``x0``."""
    pose = model.pose(np.asarray(x0, dtype=float))
    pose_at = trajectory(model, pose.position, matrix_from_quaternion(pose.orientation), amplitude)
    out = []
    for k in range(n):
        p, R = pose_at(k * PERIOD_S / n)
        out.append(model.variables_from_pose(p, quaternion_from_matrix(R)))
    return np.array(out)


class Plan:
    """The loop around one known solution of a config, sampled at trajectory times.  ``fault``: ``(leg,
    step_m, t_start)`` -- from trajectory time ``t_start`` on, leg ``leg`` (from 0) is *measured*
    ``step_m`` metres too long (a faulty sensor, :meth:`measured`); the true legs stay the truth."""

    def __init__(self, config, solution: int | None = None, amplitude: float = 1.0, fault=None):
        self.path = resolve_config(config)
        self.doc = load_document(self.path)
        self.model = model_from_dict(self.doc, str(self.path))
        self.mpu = float(self.model.metres_per_unit)
        self.solution = default_solution(self.model, self.doc) if solution is None else int(solution)
        self.amplitude = amplitude
        self.start = start_pose(self.model, self.doc, self.solution)
        self.pose_at = trajectory(self.model, *self.start, amplitude)
        self.fault = fault
        if fault is not None and not 0 <= int(fault[0]) < self.model.n_legs:
            raise GlpmaError(f"the faulty leg must be 1 to {self.model.n_legs}, got {int(fault[0]) + 1}")

    def other_solution(self) -> int:
        """The index of another known solution (another assembly mode) of the config."""
        return (self.solution + 1) % max(len(known_solutions(self.doc)), 1)

    def start_variables(self) -> np.ndarray:
        """Solver variables of the loop's start (the known solution)."""
        position, R = self.start
        return self.model.variables_from_pose(position, quaternion_from_matrix(R))

    def sample(self, t: float):
        """(legs in the config's unit, position in metres, quaternion [x, y, z, w]) at time ``t``."""
        position, R = self.pose_at(t)
        q = quaternion_from_matrix(R)
        return legs_for(self.model, position, q), position * self.mpu, q

    def measured(self, legs, t: float):
        """The legs a controller sends at time ``t``: the true ``legs``, with the fault's step from its start."""
        if self.fault is None or t < self.fault[2]:
            return legs
        out = np.array(legs, dtype=float)
        out[int(self.fault[0])] += float(self.fault[1]) / self.mpu
        return out
