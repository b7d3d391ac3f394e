"""glpma-fk calibrate on simulated data (the protocol of glpma_tools/sim/calibration_data.py: a shipped geometry
with every joint moved by up to 1 mm, leg offsets up to 0.5 mm, 200 poses over the workspace, 0.01 mm noise on legs
and poses): parameters within 3 standard errors of the truth, honest standard errors over many
seeds, forward kinematics with NEW.yaml within 0.05 mm of the true poses, a rosbag2 calibrating as
the CSV does, every option, bad input; and the config key ``leg_offsets`` where measured legs enter.
Campaigns in a working range (poses near home: some directions only weakly identifiable) and
rank-deficient ones (the platform never turns): what the data identify is fitted, the rest stays at
nominal with a warning, ``--strict`` refuses."""
import hashlib
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import CONFIG, GENEROUS_BUDGET_MS, GENEROUS_BUDGET_S, HEX_YAML, ROOT, RPR_YAML
from glpma_ros.calibration import data as D
from glpma_ros.calibration import identify as I
from glpma_ros.calibration.data import nearest_pairs
from glpma_ros.cli.main import main
from glpma_ros.config import load_document, load_manipulator, model_from_dict
from glpma_ros.errors import ConfigError
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector
from glpma_tools.sim import calibration_data as S
from glpma_tools.sim.trajectories import legs_for, start_pose

CONFIGS = {"3rpr": RPR_YAML, "hexapod": HEX_YAML, "hexapod_8legs": CONFIG / "hexapod_8legs.yaml"}
#: the issue's bound on the forward kinematics with NEW.yaml (mm), and what "off by millimetres"
#: means for the nominal config here: its poses are off by more than this (mm)
FK_BOUND_MM = 0.05
NOMINAL_OFF_MM = 0.5
#: parameters allowed beyond 3 standard errors in one calibration (see the test)
ALLOWED_BEYOND_3 = 1
#: fresh poses the forward kinematics is checked at
FK_POSES = 5
#: seeds of the standard errors' check, and the spread the z-scores (error / standard error) must
#: have: about 1000 z-scores per manipulator, whose sample standard deviation has a spread of ~0.02
#: around 1; the bounds are seven of those away
HONEST_SEEDS = 25
Z_STD_BOUNDS = (0.85, 1.15)
#: share of |z| > 3 allowed (0.27 % for a normal distribution)
Z_BEYOND_3_SHARE = 0.01
#: two runs on the same measurements (CSV in mm, bag in metres: read back as mm) agree to round-off:
#: the conversion loses ~1e-16 relative, the identification amplifies it by its condition number
#: (~1e3), so 1e-9 of the geometry's size is far above round-off and far below any standard error
SAME_RTOL = 1e-9
TIMEOUT_S = 600
#: a tracker campaign in a robot's working range (the issue's): 200 poses within +- 20 mm and +- 8
#: degrees of home on the hexapods, +- 10 mm and +- 0.2 rad on the 3-RPR (position config unit, angle rad)
WORKING_RANGE = {"3rpr": (10.0, 0.2), "hexapod": (20.0, math.radians(8.0)), "hexapod_8legs": (20.0, math.radians(8.0))}
#: seeds of each working-range campaign
WORKING_RANGE_SEEDS = (0, 1, 2)
#: the rotation the calibrated forward kinematics must reach (rad), the issue's bound for a hexapod: it
#: moves the platform joints (radius 464 mm) by the position bound.  The 3-RPR's platform is 57 mm in
#: radius: there 1e-4 rad is 0.006 mm at the joints, below the rotation error one reading's own 0.01 mm
#: noise gives with the true geometry (2.3e-4 rad RMS at these poses); its bound is the rotation that
#: moves its joints by the position bound, FK_BOUND_MM / radius (8.8e-4 rad)
ROTATION_BOUND_RAD = 1e-4
#: evaluation cap of each forward-kinematics solve in these tests (the status comes from work done)
MAX_EVALS = 20_000
#: a direction left at nominal moves no parameter: its component of the estimate's change is round-off
#: of the few Gauss-Newton steps (1e-9 of the geometry's size: far above round-off, far below any error)
NOMINAL_RTOL = 1e-9


def load(key):
    doc = load_document(CONFIGS[key])
    return model_from_dict(doc, str(CONFIGS[key])), doc


def simulated(key, seed, poses=S.POSES):
    model, doc = load(key)
    return model, S.simulate(model, start_pose(model, doc), np.random.default_rng(seed), poses)


def truth_of(truth, p):
    """The true value (in geometry ``truth``) of a reported parameter (a JSON entry or an identify.Parameter)."""
    group, leg, axis = (p["group"], p["leg"], p["axis"]) if isinstance(p, dict) else (p.group, p.leg, p.axis)
    group = "offsets" if group == "leg_offsets" else group
    value = getattr(truth, group)[leg - 1]
    return float(value if group == "offsets" else value["xyz".index(axis)])


def rotation_bound(model) -> float:
    """ROTATION_BOUND_RAD for a hexapod; for a 3-RPR the rotation that moves its platform joints by
    FK_BOUND_MM (see ROTATION_BOUND_RAD)."""
    if model.base.shape[1] == 3:
        return ROTATION_BOUND_RAD
    radius_mm = float(np.linalg.norm(model.platform, axis=1).max()) * model.metres_per_unit * 1e3
    return FK_BOUND_MM / radius_mm


def calibrate(*args, capsys):
    """``glpma-fk calibrate ... --json`` in this process: (exit status, JSON or None, stderr)."""
    code = main(["calibrate", *map(str, args), "--json"])
    captured = capsys.readouterr()
    return code, (json.loads(captured.out) if code == 0 else None), captured.err


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def platform_error_mm(model, pose, position, rotation, points) -> float:
    """Largest distance between where platform ``points`` are at the solved ``pose`` (CLI JSON) and
    at the true pose (position, rotation): the pose error as the platform feels it."""
    d = position.shape[0]
    p_hat = np.asarray(pose["position"][:d])
    R_hat = matrix_from_quaternion(pose["orientation"])[:d, :d]
    error = (p_hat + points @ R_hat.T) - (position + points @ rotation.T)
    return float(np.linalg.norm(error, axis=1).max()) * model.metres_per_unit * 1e3


def quaternion_of(rotation) -> np.ndarray:
    """Unit quaternion of a 2-D (about z) or 3-D rotation matrix."""
    R3 = np.eye(3)
    R3[:len(rotation), :len(rotation)] = rotation
    return quaternion_from_matrix(R3)


def solve_pose(config, legs, near, capsys):
    assert main(["solve", str(config), "--legs", *map(str, legs), "--near", *map(str, near), "--json",
                 "--budget-ms", str(GENEROUS_BUDGET_MS)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == "converged"
    return out["pose"]


# -- the protocol ------------------------------------------------------------------------

@pytest.mark.parametrize("key", ["3rpr", "hexapod"])
def test_identified_within_three_standard_errors_and_forward_kinematics_within_bound(key, tmp_path, capsys):
    model, sim = simulated(key, seed=0)
    data, new = tmp_path / "data.csv", tmp_path / "new.yaml"
    S.write_csv(data, sim.measured)
    config_digest, data_digest = digest(CONFIGS[key]), digest(data)
    code, out, err = calibrate(CONFIGS[key], data, "--out", new, capsys=capsys)
    assert code == 0, err
    assert digest(CONFIGS[key]) == config_digest and digest(data) == data_digest   # inputs never modified
    assert out["measurements"] == 200 and out["fitted"] == 160 and out["held_out"] == 40
    n, d = model.base.shape
    assert len(out["parameters"]) == n * (2 * d + 1) and out["unidentifiable"] == []
    z = np.array([(p["value"] - truth_of(sim.truth, p)) / p["se"] for p in out["parameters"]])
    beyond = {p["name"]: float(v) for p, v in zip(out["parameters"], z) if abs(v) > 3.0}
    # within 3 standard errors; of 42 honest estimates 0.11 are expected beyond 3 (0.27 % each), so one
    # is allowed, and none beyond 4 (6e-5 each): a test of the estimates, not of one draw of the noise
    assert len(beyond) <= ALLOWED_BEYOND_3 and np.all(np.abs(z) <= 4.0), beyond
    # the fit explains the legs to their noise, on the held-out measurements too
    noise = S.NOISE_M / model.metres_per_unit
    assert out["rms_after"] < 3 * noise < out["rms_before"] and out["holdout_rms_after"] < 3 * noise
    assert math.isfinite(out["condition_number"]) and out["condition_number"] >= 1.0

    # NEW.yaml: CONFIG's other keys kept; the forward kinematics with it finds the true poses
    doc, new_doc = yaml.safe_load(CONFIGS[key].read_text()), yaml.safe_load(new.read_text())
    assert {k: v for k, v in new_doc.items() if k not in ("base", "platform", "leg_offsets")} == \
        {k: v for k, v in doc.items() if k not in ("base", "platform")}
    new_model = load_manipulator(new)
    assert new_model.leg_offsets is not None and len(new_model.leg_offsets) == n
    rng = np.random.default_rng(1)
    fresh = S.simulate(model, start_pose(model, load(key)[1]), rng, FK_POSES)
    readings = S.true_readings(sim.truth, fresh.true_poses.position, fresh.true_poses.rotation)
    points = sim.truth.platform
    for legs, position, rotation in zip(readings, fresh.true_poses.position, fresh.true_poses.rotation):
        pos3 = np.append(position, 0.0) if d == 2 else position
        q = quaternion_of(rotation)
        calibrated = solve_pose(new, legs, new_model.variables_from_pose(pos3, q), capsys)
        nominal = solve_pose(CONFIGS[key], legs, model.variables_from_pose(pos3, q), capsys)
        assert platform_error_mm(model, calibrated, position, rotation, points) <= FK_BOUND_MM
        assert platform_error_mm(model, nominal, position, rotation, points) > NOMINAL_OFF_MM


def fk_errors(model, readings, position, rotation, leg_noise_std=None) -> tuple[float, float, float]:
    """Position (mm) and rotation (rad) error of the forward kinematics of ``model`` (the project's
    Estimator, from the true pose, evaluation-capped) for sensor ``readings`` against the true pose, and
    the largest displacement of the platform joints between the two poses (mm); ``leg_noise_std`` (config
    unit) what redundant legs are tested against (default: the Estimator's)."""
    d = position.shape[0]
    pos3, R3 = np.zeros(3), np.eye(3)
    pos3[:d], R3[:d, :d] = position, rotation
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, leg_noise_std=leg_noise_std,
                    initial_pose=model.variables_from_pose(pos3, quaternion_from_matrix(R3)))
    e = est.estimate(model.legs_from_sensors(readings))
    assert e.converged, e.message
    cos = (np.trace(matrix_from_quaternion(e.pose.orientation) @ R3.T) - 1.0) / 2.0
    mm = model.metres_per_unit * 1e3
    solved = {"position": e.pose.position, "orientation": e.pose.orientation}
    return (float(np.linalg.norm(np.asarray(e.pose.position)[:d] - position)) * mm,
            math.acos(min(1.0, max(-1.0, cos))), platform_error_mm(model, solved, position, rotation, model.platform))


@pytest.mark.parametrize("key", ["3rpr", "hexapod", "hexapod_8legs"])
def test_a_campaign_in_the_working_range_fits_what_it_identifies(key, tmp_path, capsys):
    """The issue's campaign: 200 poses near home.  Some directions (a leg's offset with its base joint's
    coordinate along it) have standard errors of millimetres: they stay at nominal with a warning and
    the command exits 0.  In the identified directions every parameter is within 3 standard errors of
    the truth; the forward kinematics with NEW.yaml is within FK_BOUND_MM (and the rotation bound) of
    the true pose at fresh poses in the range, where the nominal config is off by about a millimetre;
    --strict refuses the same data."""
    model, doc = load(key)
    spread = WORKING_RANGE[key]
    for seed in WORKING_RANGE_SEEDS:
        rng = np.random.default_rng(seed)
        sim = S.simulate(model, start_pose(model, doc), rng, spread=spread)
        data, new = tmp_path / f"data{seed}.csv", tmp_path / f"new{seed}.yaml"
        S.write_csv(data, sim.measured)
        code, out, err = calibrate(CONFIGS[key], data, "--out", new, capsys=capsys)
        assert code == 0, err
        assert out["unidentifiable"] and not any(u["rank_deficient"] for u in out["unidentifiable"])
        assert all(u["se"] > out["se_limit"] for u in out["unidentifiable"])
        assert all("left at nominal" in w and "add poses" in w for w in out["warnings"])
        # the parameters in the identified directions: P (estimate - truth) / standard error, with P the
        # projection off the directions left at nominal; of ~50 honest estimates ~0.13 are expected beyond
        # 3 (0.27 % each), so one is allowed, and none beyond 4 (6e-5 each), as in the wide campaign's test
        V = _left_at_nominal(out)
        P = np.eye(len(V)) - V @ V.T
        error = np.array([p["value"] - truth_of(sim.truth, p) for p in out["parameters"]])
        z = (P @ error) / np.array([p["se"] for p in out["parameters"]])
        beyond = {p["name"]: float(v) for p, v in zip(out["parameters"], z) if abs(v) > 3.0}
        assert len(beyond) <= ALLOWED_BEYOND_3 and np.all(np.abs(z) <= 4.0), (seed, beyond)
        # the report: observability and the held-out forward kinematics
        obs = out["observability"]
        assert 0.0 < obs["o3"] <= obs["o1"] and obs["singular_values"][0] == obs["o3"]
        pose = out["holdout_pose"]
        assert pose["before"]["solved"] == pose["after"]["solved"] == out["held_out"] == 40
        assert pose["after"]["position_rms"] < pose["before"]["position_rms"]
        assert pose["after"]["rotation_rms_deg"] < pose["before"]["rotation_rms_deg"]
        # forward kinematics at fresh poses in the range, from noise-free readings of the true geometry
        new_model = load_manipulator(new)
        fresh = S.simulate(model, start_pose(model, doc), rng, FK_POSES, spread=spread).true_poses
        readings = S.true_readings(sim.truth, fresh.position, fresh.rotation)
        nominal_off = 0.0
        for legs, position, rotation in zip(readings, fresh.position, fresh.rotation):
            position_mm, angle, _ = fk_errors(new_model, legs, position, rotation)
            assert position_mm <= FK_BOUND_MM and angle <= rotation_bound(model), (seed, position_mm, angle)
            # the nominal geometry explains redundant legs only to its own errors: judged against those;
            # its pose is off by about a millimetre where the platform's joints are
            nominal_off = max(nominal_off, fk_errors(model, legs, position, rotation,
                                                     S.JOINT_ERROR_M / model.metres_per_unit)[2])
        assert nominal_off > NOMINAL_OFF_MM, seed
        code, _, err = calibrate(CONFIGS[key], data, "--out", tmp_path / "strict.yaml", "--strict", capsys=capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1 and "--strict" in err
        assert not (tmp_path / "strict.yaml").exists()


@pytest.mark.parametrize("key", ["3rpr", "hexapod"])
def test_standard_errors_are_honest_over_many_seeds(key):
    """z = (estimate - truth) / standard error over many simulated calibrations: spread ~1 (not
    smaller: standard errors too large; not larger: too small) and few beyond 3."""
    z = []
    for seed in range(HONEST_SEEDS):
        model, sim = simulated(key, seed=100 + seed)
        res = I.identify(sim.nominal, sim.measured, scale=model.scale)
        assert res.converged and not res.unidentifiable
        z += [(p.value - truth_of(sim.truth, p)) / p.se for p in res.parameters]
    z = np.array(z)
    assert Z_STD_BOUNDS[0] <= z.std() <= Z_STD_BOUNDS[1], z.std()
    assert np.mean(np.abs(z) > 3.0) <= Z_BEYOND_3_SHARE


def test_identification_separates_by_leg_and_matches_a_generic_solver():
    """The per-leg Gauss-Newton reaches the least-squares optimum that scipy's least_squares finds
    on the whole problem at once (its own finite-difference Jacobian), on data that identify every
    direction (80 poses: with 60, one direction's standard error is above the limit and stays at nominal)."""
    scipy_optimize = pytest.importorskip("scipy.optimize")
    model, sim = simulated("3rpr", seed=3, poses=80)
    res = I.identify(sim.nominal, sim.measured, scale=model.scale)
    assert res.converged and not res.unidentifiable
    n, d = model.base.shape

    def residuals(theta):
        t = theta.reshape(n, 2 * d + 1)
        g = I.Geometry(t[:, :d], t[:, d:2 * d], t[:, 2 * d])
        return I.leg_residuals(g, sim.measured).ravel()
    start = np.column_stack((sim.nominal.base, sim.nominal.platform, sim.nominal.offsets)).ravel()
    ref = scipy_optimize.least_squares(residuals, start, xtol=1e-15, ftol=1e-15, gtol=1e-15).x.reshape(n, -1)
    ours = np.array([[p.value for p in res.parameters if p.leg == i + 1] for i in range(n)])
    se = np.array([[p.se for p in res.parameters if p.leg == i + 1] for i in range(n)])
    # the same optimum: far closer than the standard errors (1e-3 of them)
    assert np.all(np.abs(ours - ref) <= 1e-3 * se)


@pytest.mark.parametrize("legs, dim", [(4, 2), (8, 3)])
def test_any_number_of_legs(legs, dim):
    """The identification knows legs, not manipulators: a redundant planar (4 legs) and a spatial
    8-leg design are identified like the shipped ones (truth within 4 standard errors, residuals at
    the noise)."""
    rng = np.random.default_rng(legs)
    scale = 500.0
    base = rng.uniform(-scale, scale, (legs, dim)) * (np.array([1, 1, 0.05])[:dim] if dim == 3 else 1)
    platform = rng.uniform(-scale / 3, scale / 3, (legs, dim))
    nominal = I.Geometry(base, platform, np.zeros(legs))
    truth = I.Geometry(base + rng.normal(0, 0.5, base.shape), platform + rng.normal(0, 0.5, platform.shape),
                       rng.uniform(-0.5, 0.5, legs))
    m = 300
    if dim == 2:
        position = rng.uniform(-100, 100, (m, 2))
        rotation = S.rotation_2d(rng.uniform(-0.5, 0.5, m))
    else:
        position = rng.uniform(-100, 100, (m, 3)) + [0, 0, 800]
        rotation = np.array([rotation_from_vector(w) for w in rng.uniform(-0.3, 0.3, (m, 3))])
    noise = 0.01
    legs_read = S.true_readings(truth, position, rotation) + rng.normal(0, noise, (m, legs))
    res = I.identify(nominal, I.Measurements(legs_read, position, rotation), scale=2 * scale)
    assert res.converged and not res.unidentifiable and len(res.parameters) == legs * (2 * dim + 1)
    z = np.array([(p.value - truth_of(truth, p)) / p.se for p in res.parameters])
    assert np.all(np.abs(z) <= 4.0)
    assert np.all(np.abs(res.residual_std - noise) <= 0.2 * noise)      # the noise, to its sampling spread


def test_joints_legs_share_are_identified_once():
    """A 6-3 hexapod (platform joints coinciding in pairs): each shared joint is one physical joint,
    identified once from both legs' residuals, and stays shared; the truth within 4 standard errors."""
    model, sim = simulated("hexapod", seed=11)
    pairs = np.repeat(sim.nominal.platform[[0, 2, 4]], 2, axis=0)          # B1 = B2, B3 = B4, B5 = B6
    moved = np.repeat(sim.truth.platform[[0, 2, 4]], 2, axis=0)
    nominal = I.Geometry(sim.nominal.base, pairs, sim.nominal.offsets)
    truth = I.Geometry(sim.truth.base, moved, sim.truth.offsets)
    m = sim.measured
    legs = S.true_readings(truth, sim.true_poses.position, sim.true_poses.rotation) + \
        np.random.default_rng(12).normal(0.0, S.NOISE_M / model.metres_per_unit, m.legs.shape)
    res = I.identify(nominal, I.Measurements(legs, m.position, m.rotation), scale=model.scale)
    assert res.converged and not res.unidentifiable
    shared = [p for p in res.parameters if p.group == "platform"]
    assert len(shared) == 9 and {p.legs for p in shared} == {(1, 2), (3, 4), (5, 6)}
    assert shared[0].name == "legs 1 and 2 platform x"
    assert len(res.parameters) == 6 * 3 + 9 + 6
    for a, b in ((0, 1), (2, 3), (4, 5)):
        # one parameter written to both legs: still one joint (far below round-off of the geometry's scale)
        assert np.all(np.abs(res.geometry.platform[a] - res.geometry.platform[b]) <= 1e-12 * model.scale)
    z = np.array([(p.value - truth_of(truth, p)) / p.se for p in res.parameters])
    assert np.all(np.abs(z) <= 4.0), z


# -- identifiability ------------------------------------------------------------------------------

def _left_at_nominal(out) -> np.ndarray:
    """The directions left at nominal (JSON ``unidentifiable``) as columns over the report's parameters."""
    names = [p["name"] for p in out["parameters"]]
    V = np.zeros((len(names), len(out["unidentifiable"])))
    for c, d in enumerate(out["unidentifiable"]):
        for name, x in d["components"].items():
            V[names.index(name), c] = x
    return V


@pytest.mark.parametrize("key", ["3rpr", "hexapod"])
def test_poses_without_rotation_are_rank_deficient_left_at_nominal_and_named(key, tmp_path, capsys):
    """The platform never turns: each leg's platform joint cannot be told from its base joint (moving
    A_i by delta and B_i by R^T delta changes no leg): d directions per leg the data do not see at all.
    They stay at nominal, named with the poses that would identify them; the rest is fitted (exit 0);
    --strict refuses the same data in one line and writes nothing."""
    model, sim = simulated(key, seed=4)
    n, d = model.base.shape
    R0 = sim.true_poses.rotation[0]
    rotation = np.repeat(R0[None], S.POSES, axis=0)
    legs = S.true_readings(sim.truth, sim.true_poses.position, rotation) + \
        np.random.default_rng(5).normal(0.0, S.NOISE_M / model.metres_per_unit, (S.POSES, n))
    data = tmp_path / "translations.csv"
    S.write_csv(data, I.Measurements(legs, sim.true_poses.position, rotation))
    new = tmp_path / "new.yaml"
    code, out, err = calibrate(CONFIGS[key], data, "--out", new, capsys=capsys)
    assert code == 0, err
    unseen = [u for u in out["unidentifiable"] if u["rank_deficient"]]
    assert len(unseen) == n * d and all(u["se"] is None for u in unseen)
    for u in unseen:
        assert "add poses that rotate the platform" in u["text"]
        assert "base joint" in u["text"] and "platform joint" in u["text"]
    assert len(out["warnings"]) == len(out["unidentifiable"])
    assert sum("not seen by the data at all" in w for w in out["warnings"]) == n * d
    # left at nominal: the estimate did not move along them
    V = _left_at_nominal(out)[:, [c for c, u in enumerate(out["unidentifiable"]) if u["rank_deficient"]]]
    change = np.array([p["value"] - p["nominal"] for p in out["parameters"]])
    assert np.all(np.abs(V.T @ change) <= NOMINAL_RTOL * model.scale)
    # what the data see is fitted: the legs to their noise (leg and position noise: 3 sigma bounds both)
    assert out["rms_after"] < 3 * S.NOISE_M / model.metres_per_unit < out["rms_before"]
    assert new.exists() and load_manipulator(new).leg_offsets is not None
    new.unlink()
    code, _, err = calibrate(CONFIGS[key], data, "--out", new, "--strict", capsys=capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert "rank-deficient" in lines[0] and "add poses that rotate the platform" in lines[0]
    assert not new.exists()


def test_a_leg_that_never_changes_direction_names_its_offset_and_base_joint():
    """Offsets only moved along with the base joints' coordinate along a leg that keeps its
    direction: the offset and that coordinate move together (the issue's example)."""
    # a 3-D "leg" along z whose platform only translates along z: u = (0, 0, 1) always
    m = 50
    position = np.column_stack((np.zeros(m), np.zeros(m), np.linspace(500.0, 700.0, m)))
    rotation = np.repeat(np.eye(3)[None], m, axis=0)
    truth = I.Geometry(np.zeros((1, 3)), np.zeros((1, 3)), np.array([0.3]))
    legs = S.true_readings(truth, position, rotation)
    res = I.identify(I.Geometry(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1)),
                     I.Measurements(legs, position, rotation), groups=("base", "offsets"), scale=1000.0)
    texts = [d.text for d in res.unidentifiable]
    assert any("the z of leg 1's base joint and the offset of leg 1 move together" in t for t in texts), texts
    assert all("tilt the platform" in t for t in texts if "offset" in t)


# -- rosbag2 --------------------------------------------------------------------------------------

def _write_calibration_bag(path, sim, model, storage, joint_state, to_si=None):
    """Leg readings at 100 Hz (five per held pose, each a fresh noisy reading; the one nearest the
    reference pose is the CSV's), the reference PoseStamped at 20 Hz, stamped 1 ms after that reading.
    ``to_si``: the readings (config units) as the topic carries them (default: lengths in metres)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    mpu = model.metres_per_unit
    to_si = to_si or (lambda values: np.asarray(values) * mpu)
    t0, hold, period = 1_700_000_000_000_000_000, 50_000_000, 10_000_000
    rng = np.random.default_rng(9)
    names = [f"leg_{i + 1}" for i in range(model.n_legs)]

    def stamp(t):
        return T["builtin_interfaces/msg/Time"](sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)

    def legs_msg(t, values):
        if joint_state:
            msg = T["sensor_msgs/msg/JointState"](header=T["std_msgs/msg/Header"](stamp=stamp(t), frame_id=""),
                                                  name=names[::-1], position=np.ascontiguousarray(to_si(values)[::-1]),
                                                  velocity=np.zeros(0), effort=np.zeros(0))
            return bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
        msg = T["std_msgs/msg/Float64MultiArray"](layout=T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
                                                  data=to_si(values))
        return bytes(ts.serialize_cdr(msg, "std_msgs/msg/Float64MultiArray"))

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    legs_type = "sensor_msgs/msg/JointState" if joint_state else "std_msgs/msg/Float64MultiArray"
    with Writer(path, version=9, storage_plugin=plugin) as w:
        legs_conn = w.add_connection("/legs", legs_type, typestore=ts)
        pose_conn = w.add_connection("/tracker/pose", "geometry_msgs/msg/PoseStamped", typestore=ts)
        m = sim.measured
        for j in range(len(m)):
            for i in range(5):
                t = t0 + j * hold + i * period
                values = m.legs[j] if i == 2 else m.legs[j] + rng.normal(0, 1e-3, model.n_legs)
                w.write(legs_conn, t, legs_msg(t, values))
            t = t0 + j * hold + 2 * period + 1_000_000
            q = quaternion_of(m.rotation[j])
            p = (np.append(m.position[j], 0.0) if m.position.shape[1] == 2 else m.position[j]) * mpu
            pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
                                               orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2],
                                                                                             w=q[3]))
            msg = T["geometry_msgs/msg/PoseStamped"](header=T["std_msgs/msg/Header"](stamp=stamp(t),
                                                                                    frame_id="base"), pose=pose)
            # logged when the tracker's message arrived, a little later than its stamp
            w.write(pose_conn, t + 3_000_000, bytes(ts.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped")))


@pytest.mark.parametrize("key, storage, joint_state, topics", [
    ("hexapod", "mcap", False, ()),
    ("3rpr", "sqlite3", True, ("--legs-topic", "/legs", "--pose-topic", "tracker/pose", "--max-dt", "0.004")),
])
def test_bag_calibrates_as_the_csv(key, storage, joint_state, topics, tmp_path, capsys):
    pytest.importorskip("rosbags")
    model, sim = simulated(key, seed=5)
    bag, data = tmp_path / "bag", tmp_path / "data.csv"
    _write_calibration_bag(bag, sim, model, storage, joint_state)
    S.write_csv(data, sim.measured)
    code, from_bag, err = calibrate(CONFIGS[key], bag, "--out", tmp_path / "from_bag.yaml", *topics, capsys=capsys)
    assert code == 0, err
    code, from_csv, err = calibrate(CONFIGS[key], data, "--out", tmp_path / "from_csv.yaml", capsys=capsys)
    assert code == 0, err
    assert from_bag["bag"] == {"legs_topic": "/legs", "pose_topic": "/tracker/pose", "legs_messages": 5 * S.POSES,
                               "pose_messages": S.POSES, "paired": S.POSES}
    assert from_bag["measurements"] == from_csv["measurements"] == S.POSES
    for a, b in zip(from_bag["parameters"], from_csv["parameters"]):
        assert a["name"] == b["name"] and abs(a["value"] - b["value"]) <= SAME_RTOL * model.scale
        assert abs(a["se"] - b["se"]) <= SAME_RTOL * model.scale


def test_bag_problems_are_one_line(tmp_path, capsys):
    pytest.importorskip("rosbags")
    model, sim = simulated("3rpr", seed=5, poses=20)
    bag = tmp_path / "bag"
    _write_calibration_bag(bag, sim, model, "mcap", False)
    for extra, words in ((("--pose-topic", "/nothing"), "has no topic /nothing"),
                         (("--legs-topic", "/tracker/pose"), "expected std_msgs/msg/Float64MultiArray"),
                         (("--max-dt", "0.0005"), "too few measurements: 0 to fit"),
                         (("--max-dt", "-1"), "--max-dt must be")):
        code, _, err = calibrate(RPR_YAML, bag, "--out", tmp_path / "n.yaml", *extra, capsys=capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1 and words in err, err
    (tmp_path / "empty").mkdir()
    code, _, err = calibrate(RPR_YAML, tmp_path / "empty", "--out", tmp_path / "n.yaml", capsys=capsys)
    assert code == 2 and "cannot read bag" in err


def test_nearest_pairs_are_mutual_and_within_max_dt():
    t_legs = np.array([0, 10, 20, 30, 40, 50])
    t_pose = np.array([11, 12, 38, 90])
    legs, poses = nearest_pairs(t_legs, t_pose, max_dt_ns=5)
    # pose 11 and leg 10 are each other's nearest; pose 12's nearest leg (10) prefers pose 11;
    # pose 38 pairs with leg 40; pose 90 is too far from leg 50
    assert legs.tolist() == [1, 4] and poses.tolist() == [0, 2]


# -- every option -------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def rpr_data(tmp_path_factory):
    model, sim = simulated("3rpr", seed=6)
    data = tmp_path_factory.mktemp("calib") / "rpr.csv"
    S.write_csv(data, sim.measured)
    return data, sim


def test_identify_offsets_only_leaves_the_joints_as_in_config(rpr_data, tmp_path, capsys):
    data, _ = rpr_data
    new = tmp_path / "new.yaml"
    code, out, err = calibrate(RPR_YAML, data, "--out", new, "--identify", "offsets", capsys=capsys)
    assert code == 0, err
    assert out["identify"] == ["leg_offsets"] and len(out["parameters"]) == 3
    assert all(p["group"] == "leg_offsets" for p in out["parameters"])
    text, original = new.read_text(), RPR_YAML.read_text()
    assert "  - [200.0, 0.0]\n" in text and "  - [40.0, 40.0]\n" in text          # base, platform untouched
    assert text.endswith(original.split("real_solutions:")[1])                      # the rest too
    assert out["rms_after"] < out["rms_before"]                                     # offsets alone help a little


def test_identify_joints_only(rpr_data, tmp_path, capsys):
    data, _ = rpr_data
    new = tmp_path / "new.yaml"
    code, out, err = calibrate(RPR_YAML, data, "--out", new, "--identify", "base", "platform", capsys=capsys)
    assert code == 0, err
    assert out["identify"] == ["base", "platform"] and "leg_offsets" not in yaml.safe_load(new.read_text())


@pytest.mark.parametrize("share, held", [(0.0, 0), (0.3, 60)])
def test_holdout_share(rpr_data, tmp_path, share, held, capsys):
    data, _ = rpr_data
    code, out, err = calibrate(RPR_YAML, data, "--out", tmp_path / "n.yaml", "--holdout", share, capsys=capsys)
    assert code == 0, err
    assert out["held_out"] == held and out["fitted"] == 200 - held
    assert (out["holdout_rms_after"] is None) == (held == 0)


def test_seed_chooses_the_held_out_measurements(rpr_data, tmp_path, capsys):
    data, _ = rpr_data
    runs = [calibrate(RPR_YAML, data, "--out", tmp_path / f"{s}.yaml", "--seed", s, capsys=capsys)[1] for s in (0, 7)]
    assert runs[0]["fitted"] == runs[1]["fitted"] == 160
    # another held-out choice: another fit (the estimates differ by a fraction of their errors)
    assert any(a["value"] != b["value"] for a, b in zip(runs[0]["parameters"], runs[1]["parameters"]))


def test_text_output_and_the_command(rpr_data, tmp_path):
    data, _ = rpr_data
    new = tmp_path / "new.yaml"
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "calibrate", str(RPR_YAML), str(data), "--out", str(new)],
                       capture_output=True, text=True, cwd=ROOT, timeout=TIMEOUT_S)
    assert p.returncode == 0, p.stderr
    for words in ("leg residual RMS (mm)", "held out", "condition number", "leg 3 offset", "+-", f"wrote {new}",
                  "held-out forward kinematics", "position error RMS (mm)", "rotation error max (deg)",
                  "observability", "O1", "O3"):
        assert words in p.stdout
    assert load_manipulator(new).leg_offsets is not None


def test_text_output_warns_of_directions_left_at_nominal(tmp_path):
    """A working-range campaign in text: each direction left at nominal is a warning line with its
    standard error and the poses that would identify it; the parameters in it say so; exit 0."""
    model, doc = load("3rpr")
    sim = S.simulate(model, start_pose(model, doc), np.random.default_rng(0), spread=WORKING_RANGE["3rpr"])
    data, new = tmp_path / "data.csv", tmp_path / "new.yaml"
    S.write_csv(data, sim.measured)
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "calibrate", str(RPR_YAML), str(data), "--out", str(new)],
                       capture_output=True, text=True, cwd=ROOT, timeout=TIMEOUT_S)
    assert p.returncode == 0, p.stderr
    warnings = [ln for ln in p.stdout.splitlines() if ln.startswith("warning: left at nominal (standard error")]
    assert warnings and all("add poses that move and rotate the platform" in w for w in warnings)
    assert "in directions left at nominal)" in p.stdout and new.exists()
    assert f"# {len(warnings)} parameter direction(s) the data did not identify stay as in" in new.read_text()


def test_flow_style_config_keeps_its_style_and_comments(tmp_path, capsys):
    model, sim = simulated("3rpr", seed=8)
    cfg = tmp_path / "mine.yaml"
    cfg.write_text("# my robot\nmanipulator: planar_3rpr   # kind\nunit: mm\n"
                   "base: [[0, 0], [200, 0], [0, 200]]   # A_i\n"
                   "platform: [[0, 0], [50, 0], [40, 40]]  # B_i\n\n# stroke\nleg_limits: [1, 500]\n"
                   "leg_offsets: [0, 0, 0]   # zero errors\n")
    data = tmp_path / "d.csv"
    S.write_csv(data, sim.measured)
    code, out, err = calibrate(cfg, data, "--out", tmp_path / "new.yaml", capsys=capsys)
    assert code == 0, err
    text = (tmp_path / "new.yaml").read_text()
    lines = text.splitlines()
    assert "# my robot" in lines and "manipulator: planar_3rpr   # kind" in lines and "# stroke" in lines
    assert any(ln.startswith("base: [[") and ln.endswith("# A_i") for ln in lines)
    assert any(ln.startswith("leg_offsets: [") and ln.endswith("# zero errors") for ln in lines)
    assert "leg_limits: [1, 500]" in lines


# -- bad input: exit 2, one line ---------------------------------------------------------------

def _csv(tmp_path, text):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    return p


HEADER = "leg_1,leg_2,leg_3,x,y,theta\n"


@pytest.mark.parametrize("make, extra, words", [
    (lambda t, d: _csv(t, HEADER + "".join(d.read_text().splitlines(True)[1:11])), (), "too few measurements"),
    (lambda t, d: _csv(t, "leg_1,leg_2,x,y,theta\n1,2,3,4,5\n"), (), "no column 'leg_3'"),
    (lambda t, d: _csv(t, "leg_1,leg_2,leg_3,x,y,theta,w\n"), (), "unknown column 'w'"),
    (lambda t, d: _csv(t, HEADER + "100,120,abc,1,2,0\n"), (), "'abc' is not a number"),
    (lambda t, d: _csv(t, HEADER + "100,120,150,1,2\n"), (), "5 values, expected 6"),
    (lambda t, d: _csv(t, HEADER + "100,120,-150,1,2,0\n"), (), "must be positive"),
    (lambda t, d: _csv(t, HEADER + "100,120,nan,1,2,0\n"), (), "not a finite number"),
    (lambda t, d: _csv(t, ""), (), "is empty"),
    (lambda t, d: t / "missing.csv", (), "does not exist"),
    (lambda t, d: d, ("--holdout", "1.5"), "--holdout"),
    (lambda t, d: d, ("--identify", "legs"), "invalid choice"),
    (lambda t, d: d, ("--max-dt", "0.01"), "--max-dt applies to a rosbag2"),
    (lambda t, d: d, ("--seed", "-1"), "non-negative"),
])
def test_bad_input_exit_2_one_line(make, extra, words, rpr_data, tmp_path, capsys):
    data = make(tmp_path, rpr_data[0])
    code, _, err = calibrate(RPR_YAML, data, "--out", tmp_path / "new.yaml", *extra, capsys=capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and words in lines[0], err
    assert not (tmp_path / "new.yaml").exists()


def test_poses_in_another_unit_are_refused(rpr_data, tmp_path, capsys):
    _, sim = rpr_data
    m = sim.measured
    data = tmp_path / "metres.csv"
    S.write_csv(data, I.Measurements(m.legs, m.position * 1e-3, m.rotation))     # positions in metres
    code, _, err = calibrate(RPR_YAML, data, "--out", tmp_path / "n.yaml", capsys=capsys)
    assert code == 2 and "the poses do not fit the legs" in err and len(err.strip().splitlines()) == 1


def test_quaternion_not_unit_is_refused(tmp_path, capsys):
    data = tmp_path / "q.csv"
    data.write_text("leg_1,leg_2,leg_3,leg_4,leg_5,leg_6,x,y,z,qx,qy,qz,qw\n" + "1250," * 6 + "0,0,1000,0,0,0,2\n")
    code, _, err = calibrate(HEX_YAML, data, "--out", tmp_path / "n.yaml", capsys=capsys)
    assert code == 2 and "has norm 2, not 1" in err


def test_out_must_not_be_config_or_data(rpr_data, tmp_path, capsys):
    data, _ = rpr_data
    cfg = tmp_path / "c.yaml"
    cfg.write_text(RPR_YAML.read_text())
    before = digest(cfg)
    for out, what in ((cfg, "is CONFIG"), (data, "is DATA")):
        code, _, err = calibrate(cfg, data, "--out", out, capsys=capsys)
        assert code == 2 and what in err
    assert digest(cfg) == before


def test_bad_input_from_the_command_has_no_traceback(tmp_path):
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "calibrate", str(RPR_YAML), str(tmp_path / "none.csv"),
                        "--out", str(tmp_path / "n.yaml")], capture_output=True, text=True, cwd=ROOT, timeout=TIMEOUT_S)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
    assert "does not exist" in p.stderr and p.stdout == ""


# -- leg_offsets in the core --------------------------------------------------------------------

def _with_offsets(tmp_path, offsets):
    doc = yaml.safe_load(RPR_YAML.read_text())
    doc["leg_offsets"] = offsets
    path = tmp_path / "offsets.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize("offsets, words", [
    ([0.1, 0.2], "one number per leg (3)"),
    ([0.1, 0.2, float("nan")], "non-finite"),
    ([0.1, 0.2, "a"], "list of 3 numbers"),
    ([0.1, 0.2, 150.0], "more than 10%"),
])
def test_leg_offsets_validation(tmp_path, offsets, words):
    with pytest.raises(ConfigError, match=words.replace("(", r"\(").replace(")", r"\)")):
        load_manipulator(_with_offsets(tmp_path, offsets))


def test_leg_offsets_are_added_by_the_command_line_and_the_node(tmp_path, capsys, rpr, rpr_solutions):
    """Sensors reading 0.2, -0.1, 0.3 mm short: the solve with the offsets finds the pose whose legs
    are the readings plus the offsets, through ``glpma-fk solve`` and through the node's service."""
    from glpma_ros.node.service import FkService
    offsets = np.array([0.2, -0.1, 0.3])
    path = _with_offsets(tmp_path, offsets.tolist())
    x = rpr_solutions[0]
    true_legs = rpr.inverse_kinematics(x)
    readings = true_legs - offsets
    pose = solve_pose(path, readings, x, capsys)
    expected = rpr.pose(x)
    # round-off of a converged solve relative to the geometry's scale (200 mm): 1e-9 mm is far below it
    assert np.allclose(pose["position"], expected.position, atol=1e-9 * rpr.scale)
    service = FkService({"manipulator_config": str(path), "initial_pose": list(x),
                         "time_budget_ms": GENEROUS_BUDGET_MS})
    assert "leg_offsets [0.2, -0.1, 0.3] mm added to the legs" in service.describe()     # the node's start line
    outcome = service.handle(readings * rpr.metres_per_unit, 0)
    assert outcome.pose is not None
    assert np.allclose(outcome.pose.position, expected.position * rpr.metres_per_unit, atol=1e-9 * rpr.scale * 1e-3)
    assert np.allclose(outcome.legs, true_legs, atol=1e-12 * rpr.scale)       # the legs the pose answers
    # the simulated controller sends what the sensors read: the legs less the offsets
    model = load_manipulator(path)
    p = model.pose(x)
    assert np.allclose(legs_for(model, p.position, p.orientation), readings, atol=1e-12 * rpr.scale)


def test_benchmark_section_measures_and_renders():
    """The benchmark's calibration rows (``glpma-fk bench --sections offline``), small: every row has
    its figures, the calibrated forward kinematics beats the nominal one, the table renders."""
    from glpma_tools.bench.offline import calibration, calibration_section
    rows = calibration(sizes=(120,), repeats=1, fk_poses=2)
    assert [(r["config"], r["campaign"]) for r in rows] == [
        ("planar_3rpr_seed", "workspace"), ("planar_3rpr_seed", "+- 10 mm, 11.5 deg"),
        ("hexapod_66_rolland", "workspace"), ("hexapod_66_rolland", "+- 20 mm, 8 deg")]
    for r in rows:
        assert r["measurements"] == 120 and r["fitted"] == 96 and r["O1"] > 0.0
        assert r["FK error calibrated mm (median / max)"][1] < r["FK error nominal mm (median / max)"][0]
        for key in ("held-out leg RMS mm (before / after)", "held-out FK position RMS mm (before / after)"):
            before, after = r[key]
            assert after < before
    assert rows[1]["left at nominal"] > 0 and rows[3]["left at nominal"] > 0     # the working range's weak directions
    text = "\n".join(calibration_section(rows))
    assert "### Calibration" in text and text.count("| hexapod_66_rolland |") == 2


def test_simulate_helper_writes_a_csv_the_command_reads(tmp_path, capsys):
    """``python -m glpma_tools.sim.calibration_data CONFIG OUT.csv [POSES] [SEED]`` (the README's example)."""
    out = tmp_path / "sim.csv"
    assert S.main(["planar_3rpr_seed", str(out), "120", "3"]) == 0
    assert "true offsets (mm)" in capsys.readouterr().err
    lines = out.read_text().splitlines()
    assert lines[0] == "leg_1,leg_2,leg_3,x,y,theta" and len(lines) == 121
    code, report, err = calibrate("planar_3rpr_seed", out, "--out", tmp_path / "n.yaml", capsys=capsys)
    assert code == 0 and report["measurements"] == 120, err
    assert S.main(["planar_3rpr_seed"]) == 2 and "usage" in capsys.readouterr().err


@pytest.mark.parametrize("key, name, spread", [("3rpr", "planar_3rpr_seed", ("10", "11.5")),
                                               ("hexapod", "hexapod_66_rolland", ("20", "8"))])
def test_simulate_spread_sets_the_campaigns_range(key, name, spread, tmp_path, capsys):
    """``--spread POSITION DEGREES``: every pose within +- POSITION of the known pose on each axis and
    the angle (rotation-vector components) within +- DEGREES, up to the instrument's noise."""
    model, doc = load(key)
    out = tmp_path / "sim.csv"
    assert S.main([name, str(out), "50", "1", "--spread", *spread]) == 0
    capsys.readouterr()
    meas = D.read_csv(out, model.n_legs, model.base.shape[1], model.unit)
    p0, R0 = start_pose(model, doc)
    d = model.base.shape[1]
    noise = 5 * S.NOISE_M / model.metres_per_unit          # the measured poses' noise, 5 sigma
    assert np.all(np.abs(meas.position - p0[:d]) <= float(spread[0]) + noise)
    limit = math.radians(float(spread[1]))
    for R in meas.rotation:
        dR = R @ R0[:d, :d].T
        angle = abs(math.atan2(dR[1, 0], dR[0, 0])) if d == 2 else \
            math.acos(min(1.0, (np.trace(dR) - 1.0) / 2.0))
        # hexapod: each rotation-vector component within the limit, so the angle within sqrt(3) of it;
        # the measured orientation's noise is ~2e-5 rad
        assert angle <= (limit if d == 2 else math.sqrt(3) * limit) + 1e-3
    assert S.main([name, str(out), "--spread", "-1", "8"]) == 2 and "--spread" in capsys.readouterr().err
