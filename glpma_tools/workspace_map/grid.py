"""The grid of ``glpma-fk map`` and what is computed at its points.

:class:`MapSpec` is the grid over two pose coordinates (the others fixed) and how each point is solved;
:func:`solve_point` gives the number of real assembly modes (:func:`glpma_ros.modes.multistart.solve_all`: by
default its parameter homotopy, certified by the root count, where the family has a start system, else its
multistart, counted without polishing the modes; with ``method="g3pcx"`` the papers' ``runs`` polished G3-PCX
searches; seeded from the point's index by :func:`point_seed`), whether the homotopy's certificate holds, how
many of those modes are double (a leg Jacobian singular at the solver's tolerance,
:data:`glpma_ros.modes.solutions.DOUBLE_CONDITIONING`: the point is on a singularity and its count is decided
by round-off), the conditioning and the sign of det J of one point; :func:`solve_chunk` a range of points, as
a worker process or a Dask worker runs it.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass

import numpy as np
import yaml

from glpma_ros.config import model_from_dict
from glpma_ros.errors import InputError
from glpma_ros.modes.multistart import default_method as solve_all_default
from glpma_ros.modes.multistart import homotopy_modes, solve_all
from glpma_ros.modes.solutions import DOUBLE_CONDITIONING

#: pose coordinates per manipulator kind; angles are in degrees on the command line and in the files
COORDINATES = {"planar_3rpr": ("x", "y", "theta"), "hexapod_66": ("x", "y", "z", "roll", "pitch", "yaw")}
#: an actuated family's pose coordinates by its platform's motion (:func:`coordinates_of`)
TRANSLATION_COORDINATES = ("x", "y", "z")
ANGLES = ("theta", "roll", "pitch", "yaw")
#: how the modes of a point are counted: solve_all's parameter homotopy (certified by the root count; the default
#: where the family has a start system), its multistart (the default elsewhere), the papers' G3-PCX runs or a
#: model's closed form
METHODS = ("homotopy", "multistart", "g3pcx", "closed_form")
DEFAULT_METHOD = "homotopy"
#: the homotopy's path-tracking threads per point: one, since a map runs its points in parallel instead (``--workers``
#: processes, default every core), without a thread hand-over per point
POINT_THREADS = 1
#: a model with a closed-form forward kinematics (the three-leg Delta) is counted by it unless told otherwise
CLOSED_FORM = "closed_form"
#: independent G3-PCX searches per grid point with method g3pcx (the papers' method)
DEFAULT_RUNS = 50
#: count of a grid point without valid legs (a leg of length 0, or outside the configured leg limits)
OUTSIDE = -1
#: ``certified`` of a point whose method has no certificate (multistart, g3pcx) or that has no valid legs
NOT_CERTIFIABLE = -1


@dataclass(frozen=True)
class MapSpec:
    """A grid over two pose coordinates, the other coordinates fixed, and how each point is solved."""

    kind: str
    axes: tuple            # (name along the columns, name along the rows)
    limits: tuple          # ((low, high), (low, high)), config unit or degrees
    shape: tuple           # (columns, rows)
    fixed: tuple           # ((name, value), ...) every coordinate not on the grid
    runs: int              # method g3pcx: searches per point; multistart: cap on the starts (0 = solve_all's)
    seed: int
    method: str = DEFAULT_METHOD

    @property
    def n_points(self) -> int:
        return self.shape[0] * self.shape[1]

    def axis_values(self, k: int) -> np.ndarray:
        return np.linspace(*self.limits[k], self.shape[k])

    def coordinates(self, index: int) -> dict:
        """All pose coordinates of grid point ``index`` (row-major: ``row * columns + column``)."""
        row, col = divmod(int(index), self.shape[0])
        coords = dict(self.fixed)
        coords[self.axes[0]] = float(self.axis_values(0)[col])
        coords[self.axes[1]] = float(self.axis_values(1)[row])
        return coords

    def describe_method(self) -> str:
        """How the modes of a point are counted, in words (summary, figure title)."""
        if self.method == "g3pcx":
            return f"{self.runs} polished G3-PCX runs per point"
        if self.method == "homotopy":
            return "the parameter homotopy"
        if self.method == CLOSED_FORM:
            return "the closed form"
        return "the multistart" + (f" (at most {self.runs} starts per point)" if self.runs else "")

    def key(self, config_text: str) -> str:
        """Identifies the chunks of this map of this configuration."""
        blob = json.dumps({"spec": asdict(self), "config": config_text}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


def coordinates_of(model) -> tuple:
    """The pose coordinates of ``model``: its kind's (:data:`COORDINATES`); an actuated family's by its platform's
    motion: a translating platform (the Delta) x y z, a planar one (3-RRR) x y theta, a full pose (6-RUS) the
    hexapod's six."""
    if model.kind in COORDINATES:
        return COORDINATES[model.kind]
    if int(getattr(model, "dim", 3)) == 2:
        return COORDINATES["planar_3rpr"]
    return TRANSLATION_COORDINATES if model.n_vars == len(TRANSLATION_COORDINATES) else COORDINATES["hexapod_66"]


def default_method(model) -> str:
    """How the modes of a point are counted when ``--method`` is not given, as ``solve_all``'s default: the closed
    form where the model has one (the Delta's two mirror modes), the homotopy (:data:`DEFAULT_METHOD`) where its
    family has a start system, else the multistart."""
    return solve_all_default(model)


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Unit quaternion [qx, qy, qz, qw] of R = Rz(yaw) Ry(pitch) Rx(roll) (radians), as in REP 103."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])


def pose_variables(model, coords: dict) -> np.ndarray:
    """Solver variables of the pose with these coordinates (config unit, angles in degrees)."""
    if "theta" in coords:
        position = (coords["x"], coords["y"], 0.0)
        orientation = quaternion_from_rpy(0.0, 0.0, math.radians(coords["theta"]))
    elif "roll" not in coords:                      # a translating platform: orientation fixed
        position = (coords["x"], coords["y"], coords["z"])
        orientation = np.array([0.0, 0.0, 0.0, 1.0])
    else:
        position = (coords["x"], coords["y"], coords["z"])
        orientation = quaternion_from_rpy(*(math.radians(coords[a]) for a in ("roll", "pitch", "yaw")))
    return model.variables_from_pose(np.array(position, dtype=float), orientation)


def point_seed(seed: int, index: int) -> int:
    """solve_all's seed at grid point ``index``: independent of the engine and of the chunking."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def double_modes(model, found, legs) -> int:
    """How many modes of ``found`` (an ``AllSolutions``) are double at the solver's tolerance: their leg
    Jacobian's reciprocal condition number is below :data:`~glpma_ros.modes.solutions.DOUBLE_CONDITIONING`
    (the multistart reports it; the G3-PCX runs' modes are measured here).  Such a mode stands for two
    real modes met at a singularity (a double root), for two closer than the tolerance, or for the real
    shadow of a complex pair: the count of distinct modes there is decided by round-off."""
    if found.conditioning:
        return found.double_modes
    return sum(model.conditioning(s.x, legs) < DOUBLE_CONDITIONING for s in found.solutions)


def solve_point(model, spec: MapSpec, index: int) -> tuple[int, float, int, int, int]:
    """(real assembly modes, conditioning, sign of det J, double modes among them, certified) at grid point
    ``index``; the sign is 0 with redundant legs (a non-square J: the singularities are where the
    conditioning vanishes); certified: 1 when the homotopy's root count certifies the count, 0 when it
    does not (paths failed or met at a double root: the count is of the modes found), -1 for the methods
    without a certificate (multistart, g3pcx).  The homotopy does not fall back on msolve here: a map's counts
    do not depend on the extras installed."""
    x = pose_variables(model, spec.coordinates(index))
    try:
        legs = model.check_legs(model.inverse_kinematics(x))
    except (InputError, ValueError):          # a leg of length 0 or outside the leg limits (an actuated
        return OUTSIDE, math.nan, 0, 0, NOT_CERTIFIABLE   # family: a leg that cannot reach the pose): no such pose
    seed = point_seed(spec.seed, index)
    certified = NOT_CERTIFIABLE
    if spec.method == CLOSED_FORM:
        modes = solve_all(model, legs, method=CLOSED_FORM, seed=seed)
    elif spec.method == "g3pcx":
        modes = solve_all(model, legs, method="g3pcx", runs=spec.runs, seed=seed)
    elif spec.method == "homotopy":
        modes = homotopy_modes(model, legs, seed=seed, fallback=False, threads=POINT_THREADS)
        certified = int(bool(modes.complete))
    else:
        modes = solve_all(model, legs, method="multistart", seed=seed, max_starts=spec.runs or None, polish=False)
    _, J = model.pose_residuals_jacobian(model.pose_state(x), legs)
    sign = int(np.sign(np.linalg.det(J * model.pose_column_scale))) if J.shape[0] == J.shape[1] else 0
    return (len(modes.solutions), float(model.conditioning(x, legs)), sign, double_modes(model, modes, legs),
            certified)


_MODELS: dict = {}     # per process: configuration text -> model


def solve_chunk(config_text: str, source: str, spec: MapSpec, start: int, stop: int) -> dict:
    """Grid points ``start`` .. ``stop - 1``: what a worker (process or Dask) runs."""
    model = _MODELS.get(config_text)
    if model is None:
        model = _MODELS[config_text] = model_from_dict(yaml.safe_load(config_text), source)
    n = stop - start
    counts, cond, sign, double = np.empty(n, np.int16), np.empty(n), np.empty(n, np.int8), np.empty(n, np.int8)
    certified = np.empty(n, np.int8)
    for k in range(n):
        counts[k], cond[k], sign[k], double[k], certified[k] = solve_point(model, spec, start + k)
    return {"start": start, "stop": stop, "counts": counts, "conditioning": cond, "jacobian_sign": sign,
            "double_modes": double, "certified": certified}
