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
"""
from __future__ import annotations

import csv
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from glpma_ros.calibration.data import pose_columns, pose_values, rotation_2d
from glpma_ros.calibration.identify import Geometry, Measurements
from glpma_ros.cli.api import OneLineParser
from glpma_ros.config import load_document, model_from_dict, resolve_config
from glpma_ros.errors import GlpmaError
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
    if model.base.shape[1] == 2:
        return PLANAR_POSITION_SHARE * model.scale, PLANAR_ANGLE_RAD
    return SPATIAL_POSITION_SHARE * model.scale, SPATIAL_ANGLE_RAD


def simulate(model, center, rng: np.random.Generator, poses: int = POSES, joint_error_m: float = JOINT_ERROR_M,
             offset_error_m: float = OFFSET_ERROR_M, noise_m: float = NOISE_M, spread=None) -> Simulated:
    """Calibration data for ``model`` (the nominal geometry, config unit) around ``center`` =
    (position (3,), rotation (3, 3)), e.g. :func:`glpma_tools.sim.trajectories.start_pose`;
    ``spread`` = (position half-range, config unit; angle half-range, radians), default
    :func:`default_spread`."""
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


def write_csv(path, meas: Measurements) -> None:
    """A calibration CSV (header row, then one measurement per row) of ``meas``."""
    n, d = meas.legs.shape[1], meas.position.shape[1]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([f"leg_{i + 1}" for i in range(n)] + list(pose_columns(d)))
        for legs, pose in zip(meas.legs, pose_values(meas.position, meas.rotation)):
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
                                  f"{JOINT_ERROR_M * 1e3:g} mm and sensor offsets up to {OFFSET_ERROR_M * 1e3:g} mm, "
                                  f"{NOISE_M * 1e3:g} mm noise on the legs and the poses.")
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
                        f"hexapod)")
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
        write_csv(Path(args.out), sim.measured)
    except (GlpmaError, OSError) as exc:
        print(f"error: {p.prog}: {exc}", file=sys.stderr)
        return 2
    print(f"true offsets ({model.unit}): {np.round(sim.truth.offsets, 4).tolist()}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
