"""Simulated calibration data: a shipped geometry with every joint moved and every leg sensor
offset, poses spread over the workspace around one of the config's known solutions, and the
measurements an external instrument and the leg sensors would give, with noise on both.

The protocol (in metres, converted to the config's unit): every joint moved by up to
:data:`JOINT_ERROR_M` in a random direction, offsets uniform within :data:`OFFSET_ERROR_M`, Gaussian
noise :data:`NOISE_M` on each leg reading and on each coordinate of the measured position; the
measured orientation is off by a rotation whose components have the standard deviation that moves
the platform joints by :data:`NOISE_M` (noise over the platform's radius, in radians).

The poses spread over the workspace by default (a calibration run that moves and tilts the platform
widely); ``spread`` = (position, angle) narrows or widens them to a campaign's range: positions
uniform within +- position (config unit) of the centre on each axis, and the angle (3-RPR) or each
rotation-vector component (hexapod) uniform within +- angle (radians) -- e.g. a tracker campaign in a
robot's working range, 20 mm and 8 degrees around home, where some directions of the geometry are only
weakly identifiable.

An actuated family (Delta, linear Delta, 6-RUS, 6-PUS, 3-RRR, 3-PRR) has its legs moved likewise: every
origin, platform joint and crank tip moved by up to :data:`JOINT_ERROR_M`, every rod's length off by up to
as much, every rail tilted by up to :data:`RAIL_TILT_RAD`, the actuators' zero offsets uniform within
:data:`OFFSET_ERROR_RAD` (revolute) or :data:`OFFSET_ERROR_M` (prismatic); a revolute actuator's axis is
not moved (the calibration does not identify it).  The readings are the true geometry's inverse kinematics
(:func:`glpma_ros.models.legs.actuator_roots`, the branch the model takes: :func:`~glpma_ros.models.legs.choose_root`)
less the true offsets, with noise :data:`NOISE_M` on a prismatic reading and, on a revolute one, the angle
that moves its crank tip by :data:`NOISE_M`; poses a leg cannot reach within its limits are drawn again.  A
platform that only translates (Delta) is measured in position only (its orientation is the base's).
"""
from __future__ import annotations

import csv
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from glpma_ros.calibration.data import geometry_of, pose_columns, pose_values, rotation_2d
from glpma_ros.calibration.identify import Geometry, Measurements
from glpma_ros.cli.api import OneLineParser
from glpma_ros.config import load_document, model_from_dict, resolve_config
from glpma_ros.errors import GlpmaError
from glpma_ros.models.legs import REVOLUTE, actuator_roots, choose_root
from glpma_ros.models.rotations import rotation_from_vector
from glpma_tools.sim.trajectories import start_pose

#: joints moved by up to this much (m), each in a random direction
JOINT_ERROR_M = 1e-3
#: sensor offsets uniform in [-OFFSET, OFFSET] (m)
OFFSET_ERROR_M = 0.5e-3
#: standard deviation of the leg readings and of each coordinate of the measured position (m)
NOISE_M = 1e-5
#: measurements of a simulated campaign (BENCHMARKS.md, "Calibration", times 200 of them)
POSES = 200
#: 3-RPR poses: position uniform within this share of the scale around the known solution, angle
#: uniform within +- PLANAR_ANGLE_RAD (a calibration run moves the platform over its workspace)
PLANAR_POSITION_SHARE = 0.2
PLANAR_ANGLE_RAD = 0.5
#: hexapod poses: position uniform within this share of the scale around the known solution in x, y
#: and z, rotation vector components uniform within +- SPATIAL_ANGLE_RAD (about 11 degrees of tilt
#: and twist)
SPATIAL_POSITION_SHARE = 0.1
SPATIAL_ANGLE_RAD = 0.2
#: an actuated family's rails tilted by up to this (rad): a rail mounted within a milliradian (0.1 mm over
#: 100 mm of travel)
RAIL_TILT_RAD = 1e-3
#: revolute actuators' zero offsets uniform in [-OFFSET, OFFSET] (rad): 0.1 degree, an encoder's zero set
#: by eye
OFFSET_ERROR_RAD = 2e-3
#: a platform that only translates (Delta): positions uniform within this share of the scale around the
#: known solution (its workspace is wide beside its base -- an IRB 360's reaches about its base's size
#: around home -- and a calibration run covers much of it)
TRANSLATION_POSITION_SHARE = 1.0
#: poses drawn at most this many times the poses wanted before giving up (most poses around a known
#: solution are reachable; a spread far beyond the workspace is an error)
MAX_DRAWS_PER_POSE = 50


@dataclass
class Simulated:
    nominal: Geometry          # the config's geometry (what the user believes)
    truth: Geometry            # the manipulator's real geometry
    measured: Measurements     # noisy leg readings and noisy measured poses
    true_poses: Measurements   # the true poses and their noise-free readings


def _rotations_3d(vectors) -> np.ndarray:
    return np.array([rotation_from_vector(w) for w in vectors])


def true_readings(truth: Geometry, position, rotation) -> np.ndarray:
    """What the sensors of geometry ``truth`` read at the poses: |p + R B - A| - offset, (m, n)."""
    w = np.einsum("mde,ne->mnd", rotation, truth.platform)
    e = position[:, None, :] + w - truth.base[None]
    return np.sqrt((e * e).sum(axis=2)) - truth.offsets


def default_spread(model) -> tuple[float, float]:
    """(position half-range in the config unit, angle half-range in radians) of the default poses."""
    if geometry_of(model).translation:
        return TRANSLATION_POSITION_SHARE * model.scale, 0.0
    if model.base.shape[1] == 2:
        return PLANAR_POSITION_SHARE * model.scale, PLANAR_ANGLE_RAD
    return SPATIAL_POSITION_SHARE * model.scale, SPATIAL_ANGLE_RAD


def simulate(model, center, rng: np.random.Generator, poses: int = POSES, joint_error_m: float = JOINT_ERROR_M,
             offset_error_m: float = OFFSET_ERROR_M, noise_m: float = NOISE_M, spread=None) -> Simulated:
    """Calibration data for ``model`` (the nominal geometry, config unit) around ``center`` =
    (position (3,), rotation (3, 3)), e.g. :func:`glpma_tools.sim.trajectories.start_pose`;
    ``spread`` = (position half-range, config unit; angle half-range, radians), default
    :func:`default_spread`."""
    if getattr(model, "actuated", False):
        return _simulate_actuated(model, center, rng, poses, joint_error_m, offset_error_m, noise_m, spread)
    mpu = float(model.metres_per_unit)
    d = model.base.shape[1]
    n = model.base.shape[0]
    nominal = Geometry(model.base.copy(), model.platform.copy(),
                       np.zeros(n) if model.leg_offsets is None else model.leg_offsets.copy())

    def moved(joints):
        direction = rng.normal(size=joints.shape)
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        return joints + direction * rng.uniform(0.0, joint_error_m / mpu, size=(len(joints), 1))
    truth = Geometry(moved(nominal.base), moved(nominal.platform),
                     nominal.offsets + rng.uniform(-offset_error_m / mpu, offset_error_m / mpu, size=n))
    p0, R0 = (np.asarray(c, dtype=float) for c in center)
    noise = noise_m / mpu
    radius = float(np.linalg.norm(model.platform, axis=1).max())
    angle_noise = noise / radius
    reach, angle = default_spread(model) if spread is None else (float(spread[0]), float(spread[1]))
    if d == 2:
        theta0 = math.atan2(R0[1, 0], R0[0, 0])
        position = p0[:2] + rng.uniform(-reach, reach, size=(poses, 2))
        theta = theta0 + rng.uniform(-angle, angle, size=poses)
        rotation = rotation_2d(theta)
        m_position = position + rng.normal(0.0, noise, size=position.shape)
        m_rotation = rotation_2d(theta + rng.normal(0.0, angle_noise, size=poses))
    else:
        position = p0 + rng.uniform(-reach, reach, size=(poses, 3))
        rotation = _rotations_3d(rng.uniform(-angle, angle, size=(poses, 3))) @ R0
        m_position = position + rng.normal(0.0, noise, size=position.shape)
        m_rotation = _rotations_3d(rng.normal(0.0, angle_noise, size=(poses, 3))) @ rotation
    readings = true_readings(truth, position, rotation)
    measured = Measurements(readings + rng.normal(0.0, noise, size=readings.shape), m_position, m_rotation)
    return Simulated(nominal, truth, measured, Measurements(readings, position, rotation))


def _moved(points, error, rng) -> np.ndarray:
    """``points`` (n, d) each moved by up to ``error`` in a random direction."""
    direction = rng.normal(size=points.shape)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return points + direction * rng.uniform(0.0, error, size=(len(points), 1))


def _tilted(axes, angle, rng) -> np.ndarray:
    """Unit vectors ``axes`` (n, d) each tilted by up to ``angle`` (rad) in a random direction."""
    out = axes + _moved(np.zeros_like(axes), 1.0, rng) * angle
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def true_actuator_readings(truth: Geometry, position, rotation, limits) -> np.ndarray:
    """What the actuators of geometry ``truth`` read at the poses (m, n): each leg's inverse kinematics, the
    root inside ``limits`` (n, 2 readings, or None) that the model takes, less the offset; NaN where a leg
    cannot reach."""
    distal = position[:, None, :] + np.einsum("mde,ne->mnd", rotation, truth.platform)
    out = np.full(distal.shape[:2], np.nan)
    for j, points in enumerate(distal):
        for i, point in enumerate(points):
            o = float(truth.offsets[i])
            crank = None if truth.crank is None else truth.crank[i]
            roots = actuator_roots(truth.kind, truth.base[i], truth.axis[i], crank, float(truth.rods[i]), point)
            root = choose_root(roots, None if limits is None else (limits[i][0] + o, limits[i][1] + o))
            if root is not None:
                out[j, i] = root - o
    return out


def _simulate_actuated(model, center, rng, poses, joint_error_m, offset_error_m, noise_m, spread) -> Simulated:
    """:func:`simulate` of an actuated family (the module's docstring)."""
    mpu = float(model.metres_per_unit)
    nominal = geometry_of(model)
    n, d = nominal.base.shape
    error, noise = joint_error_m / mpu, noise_m / mpu
    revolute = nominal.kind == REVOLUTE
    truth = nominal.copy()
    truth.base = _moved(nominal.base, error, rng)
    truth.platform = _moved(nominal.platform, error, rng)
    truth.rods = nominal.rods + rng.uniform(-error, error, size=n)
    if revolute:
        truth.crank = _moved(nominal.crank, error, rng)
        truth.offsets = nominal.offsets + rng.uniform(-OFFSET_ERROR_RAD, OFFSET_ERROR_RAD, size=n)
        radius = np.linalg.norm(nominal.crank, axis=1)
        reading_noise = noise / radius               # the angle that moves the crank tip by the noise
    else:
        truth.axis = _tilted(nominal.axis, RAIL_TILT_RAD, rng)
        truth.offsets = nominal.offsets + rng.uniform(-offset_error_m / mpu, offset_error_m / mpu, size=n)
        reading_noise = np.full(n, noise)
    p0, R0 = (np.asarray(c, dtype=float) for c in center)
    reach, angle = default_spread(model) if spread is None else (float(spread[0]), float(spread[1]))
    position, rotation, readings = np.empty((0, d)), np.empty((0, d, d)), np.empty((0, n))
    for _ in range(MAX_DRAWS_PER_POSE):
        if d == 2:
            pos = p0[:2] + rng.uniform(-reach, reach, size=(poses, 2))
            rot = rotation_2d(math.atan2(R0[1, 0], R0[0, 0]) + rng.uniform(-angle, angle, size=poses))
        elif nominal.translation:
            pos = p0 + rng.uniform(-reach, reach, size=(poses, 3))
            rot = np.broadcast_to(np.eye(3), (poses, 3, 3))
        else:
            pos = p0 + rng.uniform(-reach, reach, size=(poses, 3))
            rot = _rotations_3d(rng.uniform(-angle, angle, size=(poses, 3))) @ R0
        q = true_actuator_readings(truth, pos, rot, model.actuator_limits)
        ok = np.all(np.isfinite(q), axis=1)
        position, rotation, readings = (np.concatenate((a, b[ok])) for a, b in
                                        ((position, pos), (rotation, rot), (readings, q)))
        if len(readings) >= poses:
            break
    else:
        raise GlpmaError(f"the poses within +- {reach:g} {model.unit} of the known pose are mostly out of reach: "
                         f"fewer than {poses} reachable in {MAX_DRAWS_PER_POSE * poses} drawn; narrow --spread")
    position, rotation, readings = position[:poses], rotation[:poses], readings[:poses]
    m_position = position + rng.normal(0.0, noise, size=position.shape)
    if nominal.translation:
        m_rotation = rotation.copy()                  # the orientation is the base's: not measured
    elif d == 2:
        angle_noise = noise / float(np.linalg.norm(model.platform, axis=1).max())
        m_rotation = rotation_2d(np.arctan2(rotation[:, 1, 0], rotation[:, 0, 0])
                                 + rng.normal(0.0, angle_noise, size=poses))
    else:
        angle_noise = noise / float(np.linalg.norm(model.platform, axis=1).max())
        m_rotation = _rotations_3d(rng.normal(0.0, angle_noise, size=(poses, 3))) @ rotation
    measured = Measurements(readings + rng.normal(0.0, 1.0, size=readings.shape) * reading_noise, m_position,
                            m_rotation)
    return Simulated(nominal, truth, measured, Measurements(readings, position, rotation))


def write_csv(path, meas: Measurements, translation: bool = False) -> None:
    """A calibration CSV (header row, then one measurement per row) of ``meas`` (``translation``: a platform
    that only translates, its position only)."""
    n, d = meas.legs.shape[1], meas.position.shape[1]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([f"leg_{i + 1}" for i in range(n)] + list(pose_columns(d, translation)))
        for legs, pose in zip(meas.legs, pose_values(meas.position, meas.rotation, translation)):
            w.writerow([repr(float(v)) for v in (*legs, *pose)])


def main(argv=None) -> int:
    """``python -m glpma_tools.sim.calibration_data CONFIG OUT.csv [POSES] [SEED] [--spread POSITION
    DEGREES]``: simulated data for the README's example (the true geometry printed on stderr)."""

    class Parser(OneLineParser):
        def error(self, message):            # one line, with the usage
            print(f"error: {self.prog}: {message}; {' '.join(self.format_usage().split())}", file=sys.stderr)
            raise SystemExit(2)

    p = Parser(prog="python -m glpma_tools.sim.calibration_data",
                      description="Simulated calibration data: CONFIG's geometry with every joint moved by up to "
                                  f"{JOINT_ERROR_M * 1e3:g} mm and sensor offsets up to {OFFSET_ERROR_M * 1e3:g} mm "
                                  f"({OFFSET_ERROR_RAD:g} rad for revolute actuators), {NOISE_M * 1e3:g} mm noise on "
                                  f"the legs and the poses; an actuated family's readings by the true geometry's "
                                  f"inverse kinematics.")
    p.add_argument("config", metavar="CONFIG", help="manipulator YAML (or the name of a shipped one)")
    p.add_argument("out", metavar="OUT.csv", help="the calibration CSV to write")
    p.add_argument("poses", metavar="POSES", type=int, nargs="?", default=POSES,
                   help=f"measurements (default {POSES})")
    p.add_argument("seed", metavar="SEED", type=int, nargs="?", default=0, help="random seed (default 0)")
    p.add_argument("--spread", nargs=2, type=float, metavar=("POSITION", "DEGREES"), default=None,
                   help="the campaign's range around the config's known pose: positions within +- POSITION (config "
                        "unit) on each axis, the angle (3-RPR) or each rotation-vector component (hexapod) within "
                        f"+- DEGREES (default: {PLANAR_POSITION_SHARE * 100:.0f} %% of the size and "
                        f"{math.degrees(PLANAR_ANGLE_RAD):.1f} degrees for a 3-RPR, "
                        f"{SPATIAL_POSITION_SHARE * 100:.0f} %% and {math.degrees(SPATIAL_ANGLE_RAD):.1f} for a "
                        f"hexapod, a 6-RUS or a 6-PUS, as a 3-RPR for a 3-RRR or a 3-PRR, "
                        f"{TRANSLATION_POSITION_SHARE * 100:.0f} %% and no rotation for a Delta)")
    try:
        args = p.parse_args(list(sys.argv[1:] if argv is None else argv))
    except SystemExit as exc:               # --help (0) or a usage error (2, already printed)
        return exc.code if isinstance(exc.code, int) else 0
    try:
        if args.poses < 1:
            raise GlpmaError(f"POSES must be at least 1, got {args.poses}")
        spread = None
        if args.spread is not None:
            reach, degrees = args.spread
            if not (math.isfinite(reach) and reach >= 0.0 and math.isfinite(degrees) and 0.0 <= degrees <= 180.0):
                raise GlpmaError(f"--spread needs a position >= 0 and 0 <= DEGREES <= 180, got {reach:g} {degrees:g}")
            spread = (reach, math.radians(degrees))
        path = resolve_config(args.config)
        doc = load_document(path)
        model = model_from_dict(doc, str(path))
        sim = simulate(model, start_pose(model, doc), np.random.default_rng(args.seed), args.poses, spread=spread)
        write_csv(Path(args.out), sim.measured, sim.nominal.translation)
    except (GlpmaError, OSError) as exc:
        print(f"error: {p.prog}: {exc}", file=sys.stderr)
        return 2
    unit = "rad" if sim.nominal.kind == REVOLUTE else model.unit
    print(f"true offsets ({unit}): {np.round(sim.truth.offsets, 4 if unit != 'rad' else 6).tolist()}",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
