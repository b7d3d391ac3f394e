"""Every Gough-Stewart design (joints coinciding in pairs: 6-3, 3-6, 3-3) and redundant legs with the
isolation of a faulty one: validation, solves, solve-all, the node's service and diagnostics,
the CLI and the shipped configs.  Every solve has an evaluation cap or a generous budget; nothing here
depends on how busy the machine is."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import yaml

from conftest import CONFIG, GENEROUS_BUDGET_MS, GENEROUS_BUDGET_S, needs_msolve
from glpma_ros.config import load_manipulator, model_from_dict
from glpma_ros.errors import ConfigError
from glpma_ros.estimation.estimator import STATUS_CONVERGED, STATUS_INCONSISTENT, Estimator
from glpma_ros.estimation.redundancy import CONSISTENCY_LEVEL, chi2_limit
from glpma_ros.models.random_geometry import random_hexapod_33, random_hexapod_63
from glpma_ros.models.rotations import quaternion_from_matrix, rotation_from_vector
from glpma_ros.modes.multistart import solve_all
from glpma_ros.node.diagnostics import WARN
from glpma_ros.node.leg_health import FAILED_AFTER
from glpma_ros.node.service import FkService
from glpma_tools.sim.trajectories import Plan

#: a 6-3 design (two legs on each platform joint) as a user reported it, verbatim
ISSUE_63 = {"manipulator": "hexapod_66", "unit": "mm",
            "base": [[100, 0, 0], [50, 86.6, 0], [-50, 86.6, 0], [-100, 0, 0], [-50, -86.6, 0], [50, -86.6, 0]],
            "platform": [[50, 0, 0], [50, 0, 0], [-25, 43.3, 0], [-25, 43.3, 0], [-25, -43.3, 0], [-25, -43.3, 0]]}
SHIPPED = ("hexapod_63_stewart", "hexapod_33_octahedral", "hexapod_7legs", "hexapod_8legs")
#: evaluation cap of each search stage in these tests (the statuses come from work done)
MAX_EVALS = 20_000
#: leg residuals "at round-off": a few hundred units in the last place of the longest leg (lm.LEG_RTOL)
ROUND_OFF = 1e-12


def _pose_x(model, position, rotation_vector):
    return model.variables_from_pose(position, quaternion_from_matrix(rotation_from_vector(np.array(rotation_vector))))


def _round_off(model, e, legs):
    return np.max(np.abs(model.inverse_kinematics(e.x) - legs)) <= ROUND_OFF * max(model.scale, np.max(legs))


# -- validation ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("base_pairs, platform_pairs", [((0, 1, 2, 3, 4, 5), (0, 0, 1, 1, 2, 2)),    # 6-3
                                                         ((0, 0, 1, 1, 2, 2), (0, 1, 2, 3, 4, 5)),    # 3-6
                                                         ((0, 1, 1, 2, 2, 0), (0, 0, 1, 1, 2, 2))])   # 3-3
def test_coincident_joints_are_accepted(base_pairs, platform_pairs):
    def ring(r, phase):
        return [[r * math.cos(phase + k * math.pi / 3), r * math.sin(phase + k * math.pi / 3), 0.0] for k in range(6)]
    base, platform = ring(200.0, 0.1), ring(100.0, 0.4)
    doc = {"manipulator": "hexapod_66", "unit": "mm", "base": [base[i] for i in base_pairs],
           "platform": [platform[i] for i in platform_pairs]}
    model = model_from_dict(doc)
    # the solver variables are three distinct platform joints off one line, named after them
    assert len({tuple(p) for p in model.frame.tolist()}) == 3
    assert model.variable_names[:3] == ("x1", "y1", "z1") and len(model.variable_names) == 9


@pytest.mark.parametrize("change, message", [
    ({"platform": [[50, 0, 0]] * 3 + [[-25, 43.3, 0]] * 3}, "'platform' joints leave the pose undetermined"),
    ({"platform": [[0, 0, 0], [10, 0, 0], [20, 0, 0], [30, 0, 0], [40, 0, 0], [50, 0, 0]]},
     "'platform' joints leave the pose undetermined"),
    ({"base": [[100, 0, 0]] * 3 + [[-100, 0, 0]] * 3}, "'base' joints leave the pose undetermined"),
    ({"platform": [[50, 0, 0]] * 6}, "all 'platform' joints coincide"),
    ({"base": [[100, 0, 0], [100, 0, 0], [-50, 86.6, 0], [-100, 0, 0], [-50, -86.6, 0], [50, -86.6, 0]]},
     "legs 1 and 2 join the same two joints"),
    ({"base": [[100, 0, 0]] * 13, "platform": [[50, 0, 0]] * 13}, "must have 6 to 12 points"),
    ({"platform": ISSUE_63["platform"][:5]}, "'platform' must have 6 points"),
])
def test_undetermined_hexapods_are_refused_in_one_line(change, message):
    with pytest.raises(ConfigError, match=message) as err:
        model_from_dict({**ISSUE_63, **change})
    assert "\n" not in str(err.value)


def test_the_cli_refuses_an_undetermined_config_in_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({**ISSUE_63, "platform": [[50, 0, 0]] * 3 + [[-25, 43.3, 0]] * 3}))
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve", str(bad), "--legs", *["130"] * 6],
                       capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "undetermined" in r.stderr


# -- coincident joints: solves, solve-all ----------------------------------------------------------------------
def test_issue_63_solves_warm_and_cold_to_round_off():
    model = model_from_dict(ISSUE_63)
    x = _pose_x(model, [3.0, -2.0, 120.0], [0.05, -0.03, 0.1])
    legs = model.inverse_kinematics(x)
    cold = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS).estimate(legs)
    assert cold.status == STATUS_CONVERGED and cold.start == "cold" and _round_off(model, cold, legs)
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, initial_pose=x)
    x2 = _pose_x(model, [3.5, -2.2, 121.0], [0.05, -0.02, 0.11])       # the next pose along a motion
    warm = est.estimate(model.inverse_kinematics(x2))
    assert warm.status == STATUS_CONVERGED and warm.start == "warm"
    assert model.distance(warm.x, x2) <= 1e-9 * model.scale       # the same assembly mode, to round-off


@pytest.mark.parametrize("generator", [random_hexapod_63, random_hexapod_33])
def test_random_shared_joint_designs_track_to_round_off(generator):
    model, legs, x = generator(np.random.default_rng(3))
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, initial_pose=x)
    for step in range(1, 6):       # a small motion: the warm path follows it
        xs = x + step * 0.2 * np.tile([1.0, -0.5, 0.3], 3)
        target = model.pose_variables(model.pose_state(xs))
        e = est.estimate(model.inverse_kinematics(target))
        assert e.status == STATUS_CONVERGED and e.start == "warm"
        assert model.distance(e.x, target) <= 1e-9 * model.scale


@needs_msolve
@pytest.mark.parametrize("case", ["reported 6-3", "random 3-3"])
def test_exact_agrees_with_the_multistart_on_shared_joints(case):
    if case == "reported 6-3":
        model = model_from_dict(ISSUE_63)
        legs = np.array([130.0, 148.0, 130.0, 148.0, 130.0, 148.0])
    else:
        model, legs, _ = random_hexapod_33(np.random.default_rng(5))
    exact = solve_all(model, legs, method="exact")
    multi = solve_all(model, legs, seed=0)
    # a design with shared joints has fewer complex solutions than the general 6-6's 40 (16 for these)
    assert 0 < exact.complex_solutions < 40
    assert len(exact.solutions) == len(multi.solutions) > 0
    for s in exact.solutions:      # the same modes: polished to round-off, compared at a share of the scale
        assert min(model.distance(s.x, m.x) for m in multi.solutions) <= 1e-6 * model.scale


# -- redundant legs ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def seven():
    return load_manipulator(CONFIG / "hexapod_7legs.yaml")


def test_chi2_limit_is_the_quantile():
    # the chi-square law with 1 degree of freedom is that of Z^2: its 0.999 quantile is z_0.9995^2
    z = 3.2905267314919255           # standard normal 0.9995 quantile
    assert chi2_limit(1) == pytest.approx(z * z, rel=1e-9)      # rel: the quantile to near round-off
    assert chi2_limit(0) == 0.0 and CONSISTENCY_LEVEL == 0.999


def test_seven_legs_least_squares_pose_converges_with_consistent_noise(seven):
    rng = np.random.default_rng(7)
    legs0 = seven.example_leg_lengths
    est = Estimator(seven, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS)
    sigma = est.leg_noise_std
    assert sigma == pytest.approx(1e-5 / 1e-3)      # 1e-5 m in the config's mm (rel: unit conversion)
    statuses = []
    for _ in range(20):
        e = est.estimate(legs0 + rng.normal(0.0, sigma, seven.n_legs))
        statuses.append(e.status)
        assert e.consistency <= e.consistency_limit == pytest.approx(chi2_limit(1))
    assert set(statuses) == {STATUS_CONVERGED}


def test_the_consistency_test_is_the_same_in_every_unit(seven, tmp_path):
    """The same legs, noise and fault in mm and in m: the same statuses and chi-square statistics."""
    doc = yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())
    in_m = model_from_dict({**doc, "unit": "m", "base": (np.array(doc["base"]) / 1e3).tolist(),
                            "platform": (np.array(doc["platform"]) / 1e3).tolist(), "leg_limits": [0.1, 5.0],
                            "example_leg_lengths": (np.array(doc["example_leg_lengths"]) / 1e3).tolist(),
                            "published_solutions": (np.array(doc["published_solutions"]) / 1e3).tolist()})
    rng = np.random.default_rng(11)
    noise = rng.normal(0.0, 1e-5, (6, 7))             # metres
    noise[3:, 2] += 0.02                               # leg 3 off by 2000 sigma in the last three inputs
    results = []
    for model, mpu in ((seven, 1e-3), (in_m, 1.0)):
        est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, leg_noise_std=1e-5 / mpu,
                        initial_pose=np.array(doc["published_solutions"][0]) * (1e-3 / mpu))
        results.append([est.estimate(model.example_leg_lengths + n / mpu) for n in noise])
    for a, b in zip(*results):
        assert a.status == b.status and a.suspect_leg == b.suspect_leg
        # the statistic is dimensionless: equal up to the round-off of the residuals (relative to the legs)
        assert a.consistency == pytest.approx(b.consistency, rel=1e-6, abs=1e-6)
    assert [r.status for r in results[0]] == [STATUS_CONVERGED] * 3 + [STATUS_INCONSISTENT] * 3


def test_two_redundant_legs_isolate_a_fault_from_one_cold_input():
    """With 8 legs the leave-one-out poses still have a residual: the faulty leg is found without history."""
    doc = yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())
    doc["base"].append([-300.0, -350.0, -178.7])
    doc["platform"].append([150.0, 200.0, 236.4])
    doc.pop("example_leg_lengths")
    model = model_from_dict(doc)
    x = np.array(doc["published_solutions"][0])
    legs = model.inverse_kinematics(x) + np.random.default_rng(2).normal(0.0, 0.01, 8)
    legs[5] += 10.0                                     # 1000 sigma on leg 6
    e = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS).estimate(legs)
    assert e.status == STATUS_INCONSISTENT and e.suspect_leg == 5 and e.excluded_leg == 5 and e.publishable
    assert model.distance(e.x, x) <= 0.5                # within the noise's effect (mm), not the fault's
    off = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, exclude_faulty_leg=False)
    e = off.estimate(legs)
    assert e.status == STATUS_INCONSISTENT and e.suspect_leg == 5 and e.pose is None and not e.publishable


def test_planar_with_four_legs():
    doc = {"manipulator": "planar_3rpr", "unit": "mm", "base": [[0, 0], [200, 0], [0, 200], [200, 200]],
           "platform": [[0, 0], [50, 0], [40, 40], [10, 45]]}
    model = model_from_dict(doc)
    assert model.n_legs == 4 and model.redundancy == 1
    x = np.array([60.0, 70.0, 0.3])
    legs = model.inverse_kinematics(x)
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS)
    e = est.estimate(legs)
    assert e.status == STATUS_CONVERGED and _round_off(model, e, legs)
    e = est.estimate(legs + np.array([0.0, 0.0, 0.0, 1.0]))     # 100 sigma (0.01 mm) on leg 4
    assert e.status == STATUS_INCONSISTENT and e.suspect_leg == 3 and e.excluded_leg == 3
    assert model.distance(e.x, x) <= 1e-6 * model.scale        # the other three legs are exact


# -- the node: a faulty sensor mid-run -----------------------------------------------------------------------------
def test_the_node_names_a_corrupted_leg_and_keeps_publishing_correct_poses():
    """The 7-leg hexapod along the demo's trajectory (leg noise 1e-5 m), leg 4 off by 1000 sigma for a while:
    the node names leg_4, publishes the pose of the other six, reports leg_4 failed (WARN) after
    FAILED_AFTER inputs, and clears it once the leg agrees again."""
    plan = Plan("hexapod_7legs")
    model, mpu = plan.model, plan.mpu
    sigma_m = 1e-5
    p0, R0 = plan.start
    x0 = model.variables_from_pose(p0, quaternion_from_matrix(R0))
    svc = FkService({"manipulator_config": str(CONFIG / "hexapod_7legs.yaml"), "time_budget_ms": GENEROUS_BUDGET_MS,
                     "leg_noise_std": sigma_m, "initial_pose": [float(v) for v in x0]})
    rng = np.random.default_rng(21)
    fault = range(20, 20 + FAILED_AFTER + 10)
    reports = {}
    for k in range(20 + FAILED_AFTER + 20):
        position, rotation = plan.pose_at(k / 100.0)            # 100 Hz, the demo's hexapod rate
        legs_m = model.inverse_kinematics(model.variables_from_pose(position, quaternion_from_matrix(rotation))) * mpu
        legs_m = legs_m + rng.normal(0.0, sigma_m, model.n_legs)
        if k in fault:
            legs_m[3] += 1000 * sigma_m
        out = svc.handle(legs_m, k)
        e = out.estimate
        assert out.pose is not None, e.message                   # a pose for every input
        err = np.linalg.norm(np.array(out.pose.position) - np.asarray(position) * mpu)
        # the noise through six legs moves the pose by a few sigma / conditioning; the fault would by ~1e-2 m
        assert err <= 30 * sigma_m, (k, err, e.message)
        if k in fault:
            assert e.status == STATUS_INCONSISTENT and e.suspect_leg == 3 and e.excluded_leg == 3, (k, e.message)
        if k in (fault[0] + FAILED_AFTER - 2, fault[0] + FAILED_AFTER, fault[-1] + 5):
            reports[k] = svc.diagnostics()
    before, during, after = (reports[k] for k in sorted(reports))
    assert before.as_dict()["failed legs"] == "none"
    assert during.level == WARN and during.as_dict()["failed legs"] == "leg_4" and "failed leg leg_4" in during.message
    assert during.as_dict()["leg left out last"] == "leg_4"
    assert after.as_dict()["failed legs"] == "none" and after.as_dict()["leg left out last"] == "none"


def test_a_pose_without_a_leg_gets_the_covariance_of_the_other_legs(seven):
    from glpma_ros.estimation.covariance import PoseJacobian
    x0 = yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())["published_solutions"][0]
    svc = FkService({"manipulator_config": str(CONFIG / "hexapod_7legs.yaml"), "time_budget_ms": GENEROUS_BUDGET_MS,
                     "initial_pose": x0})
    legs_m = seven.example_leg_lengths * 1e-3
    full = svc.extras(svc.handle(legs_m, 0))
    bad = legs_m.copy()
    bad[2] += 0.01                                        # 1000 sigma on leg 3
    out = svc.handle(bad, 1)
    assert out.estimate.excluded_leg == 2
    without = svc.extras(out)
    six = model_from_dict({"manipulator": "hexapod_66", "unit": "mm", "base": np.delete(seven.base, 2, 0).tolist(),
                           "platform": np.delete(seven.platform, 2, 0).tolist()})
    six.metres_per_unit = 1e-3
    jac = PoseJacobian(six)
    jac.solve(np.array(out.pose.position), np.array(out.pose.orientation), 1e-5)
    # the same formula on the same six legs: equal to round-off relative to the largest variance
    cov = np.array(without.covariance).reshape(6, 6)
    assert np.allclose(cov, jac.covariance, rtol=0, atol=1e-9 * np.abs(jac.covariance).max())
    assert np.trace(cov) > np.trace(np.array(full.covariance).reshape(6, 6))    # one leg fewer: larger


def test_exclude_faulty_leg_off_publishes_nothing_and_says_why(seven):
    x0 = yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())["published_solutions"][0]
    svc = FkService({"manipulator_config": str(CONFIG / "hexapod_7legs.yaml"), "time_budget_ms": GENEROUS_BUDGET_MS,
                     "initial_pose": x0, "exclude_faulty_leg": False})
    legs_m = seven.example_leg_lengths * 1e-3
    assert svc.handle(legs_m, 0).pose is not None
    bad = legs_m.copy()
    bad[0] += 0.01
    out = svc.handle(bad, 1)
    assert out.pose is None and out.reason.startswith("inconsistent_legs") and "leg 1" in out.reason
    assert svc.diagnostics().as_dict()["rejected: inconsistent_legs"] == "1"
    ok, why = svc.set_parameters({"exclude_faulty_leg": True})
    assert ok, why


def test_covariance_uses_every_leg(seven):
    from glpma_ros.estimation.covariance import PoseJacobian
    x = np.array(yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())["published_solutions"][0])
    pose = seven.pose(x)
    jac = PoseJacobian(seven)
    jac.solve(pose.position * 1e-3, pose.orientation, 1e-5)
    six = model_from_dict({"manipulator": "hexapod_66", "unit": "mm", "base": seven.base[:6].tolist(),
                           "platform": seven.platform[:6].tolist()})
    six.metres_per_unit = 1e-3
    jac6 = PoseJacobian(six)
    jac6.solve(pose.position * 1e-3, pose.orientation, 1e-5)
    assert jac.J.shape == (7, 6)
    # a seventh measurement can only shrink the variances
    assert np.all(np.diag(jac.covariance) <= np.diag(jac6.covariance) * (1 + 1e-9))   # 1e-9: round-off
    assert np.trace(jac.covariance) < np.trace(jac6.covariance)


# -- shipped configs and the CLI ---------------------------------------------------------------------------------
#: leg noise of the solve-all tests: ten times the default (1e-5 m), in the config's mm
COARSE_NOISE_MM = 0.1


def _coarse_legs(seven):
    """The 7-leg hexapod's example legs read with COARSE_NOISE_MM of noise (seeded): consistent at that
    noise, far beyond the default's consistency limit."""
    return seven.example_leg_lengths + np.random.default_rng(3).normal(0.0, COARSE_NOISE_MM, seven.n_legs)


def _near_published(seven, x):
    """A mode at coarse noise lies within a few noise widths of the published pose (mm): the least-squares
    pose moves by about sigma times the Jacobian's gain, well under 5 mm here."""
    x0 = np.array(yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())["published_solutions"][0])
    return np.max(np.abs(np.asarray(x) - x0)) < 50 * COARSE_NOISE_MM


def test_solve_all_judges_redundant_modes_against_the_given_leg_noise(seven):
    legs = _coarse_legs(seven)
    assert solve_all(seven, legs, seed=0).solutions == []     # default noise: the residuals are inconsistent
    for method in ("multistart", "g3pcx"):
        kw = {"runs": 20, "max_evals": MAX_EVALS} if method == "g3pcx" else {}
        found = solve_all(seven, legs, method=method, seed=0, leg_noise_std=COARSE_NOISE_MM, **kw).solutions
        # the pose of the legs is among them, and every mode's residuals pass the test at that noise (at
        # 0.1 mm a second least-squares pose below the base passes too: the seventh leg barely tells them apart)
        assert any(_near_published(seven, s.x) for s in found), method
        limit = chi2_limit(seven.redundancy) * COARSE_NOISE_MM ** 2
        assert all(np.sum((seven.inverse_kinematics(s.x) - legs) ** 2) <= limit for s in found), method
    with pytest.raises(Exception, match="leg_noise_std must be positive"):
        solve_all(seven, legs, leg_noise_std=-1.0)


def test_cli_solve_all_takes_the_leg_noise(seven):
    legs = [*map(repr, _coarse_legs(seven).tolist())]
    cmd = [sys.executable, "-m", "glpma_ros", "solve-all", "hexapod_7legs", "--legs", *legs]
    assert subprocess.run(cmd, capture_output=True, text=True).returncode == 1        # default noise: none
    r = subprocess.run(cmd + ["--leg-noise-std", str(COARSE_NOISE_MM), "--json"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert any(_near_published(seven, m["variables"]) for m in out["solutions"])


@pytest.mark.parametrize("in_child", [False, True])
def test_the_node_assembly_modes_use_its_leg_noise_std(seven, in_child):
    """~/assembly_modes judges a redundant mode against the node's leg_noise_std (metres), in this
    thread and in the worker process the node uses."""
    svc = FkService({"manipulator_config": str(CONFIG / "hexapod_7legs.yaml"),
                     "leg_noise_std": COARSE_NOISE_MM * 1e-3})
    svc.modes.note_input((_coarse_legs(seven) * 1e-3).tolist(), 0)      # metres on the topic
    worker = svc.modes.worker().start() if in_child else None
    try:
        result = svc.modes.compute(0, solve=worker)
    finally:
        if worker is not None:
            worker.close()
    x0 = np.array(yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())["published_solutions"][0])
    published = np.array(seven.pose(x0).position) * 1e-3                    # metres, as the reply
    # within a few noise widths of the published position (metres; the default noise would find none)
    assert any(np.max(np.abs(np.array(p) - published)) < 50 * COARSE_NOISE_MM * 1e-3 for p, _ in result.poses)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_configs_solve_their_example_legs(name):
    model = load_manipulator(CONFIG / f"{name}.yaml")
    doc = yaml.safe_load((CONFIG / f"{name}.yaml").read_text())
    x = np.array(doc["published_solutions"][0])
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, initial_pose=x)
    e = est.estimate(model.example_leg_lengths)
    assert e.status == STATUS_CONVERGED and model.distance(e.x, x) <= 1e-6 * model.scale


def test_cli_solve_redundant_json_names_the_faulty_leg(seven):
    legs = seven.example_leg_lengths.copy()
    legs[6] += 10.0                                            # 1000 x the default noise (0.01 mm)
    x0 = yaml.safe_load((CONFIG / "hexapod_7legs.yaml").read_text())["published_solutions"][0]
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve", "hexapod_7legs", "--legs",
                        *map(repr, legs.tolist()), "--near", *map(repr, x0), "--leg-noise-std", "0.01",
                        "--max-evals", str(MAX_EVALS), "--json"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr          # --near is the history: the pose without leg 7 continues it
    out = json.loads(r.stdout)
    assert out["status"] == STATUS_INCONSISTENT and out["leg_noise_std"] == 0.01
    assert out["suspect_leg"] == out["excluded_leg"] == 7 and out["pose"] is not None
    assert out["consistency"] > out["consistency_limit"] and "left out" in out["message"]


@needs_msolve
def test_cli_solve_all_exact_refuses_redundant_legs(seven):
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve-all", "hexapod_7legs", "--exact", "--legs",
                        *map(repr, seven.example_leg_lengths.tolist())], capture_output=True, text=True)
    assert r.returncode == 2 and "redundant legs" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("name", SHIPPED)
def test_demo_and_mock_controller_take_the_new_configs(name):
    """``demo --manipulator NAME`` (or a path) drives the node with the config's kind's params file, this
    config and a warm start at the mock controller's start pose (the DDS run itself: test_demo.py)."""
    from glpma_tools.demo import manipulator_spec
    label, spec = manipulator_spec(name)
    assert label == name and spec["params"] == "params_hexapod.yaml"
    args = dict(a.split(":=", 1) for a in spec["extra_args"] if ":=" in a)
    assert args["manipulator_config"] == str((CONFIG / f"{name}.yaml").resolve()) and args["joint_names"] == "[]"
    plan = Plan(str(CONFIG / f"{name}.yaml"))                 # the mock controller's trajectory (a path)
    model = plan.model
    x_start = model.variables_from_pose(plan.start[0], quaternion_from_matrix(plan.start[1]))
    assert np.allclose(yaml.safe_load(args["initial_pose"]), x_start, rtol=0, atol=1e-9 * model.scale)  # repr
    legs = model.inverse_kinematics(x_start)
    assert np.allclose(legs, model.example_leg_lengths, rtol=0, atol=1e-6 * model.scale)   # 9 decimals in the file


def test_demo_refuses_an_unknown_manipulator_in_one_line(tmp_path):
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "demo", "--manipulator", str(tmp_path / "nope.yaml")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "nope.yaml" in r.stderr


def test_package_functions_carry_the_digest_of_every_compiled_module():
    """A change to one kernel file recompiles the compiled functions of other files that carry its code."""
    from glpma_ros.models import kernels
    from glpma_ros.runtime import numba_cache
    from glpma_ros.solvers import g3pcx
    for fn in (kernels.population_fitness, g3pcx.g3pcx_generations):
        stamp = fn._cache._cache_file._source_stamp
        assert isinstance(stamp, tuple) and stamp[1] == numba_cache.package_digest()


def test_the_benchmark_keeps_the_section_measured_apart(tmp_path):
    """``glpma-fk bench`` rewrites BENCHMARKS.md; the section tools/bench_gough.py wrote stays in it."""
    from glpma_tools.bench.report import APART, measured_apart
    section = tmp_path / APART[0]
    section.parent.mkdir(parents=True)
    section.write_text("## Gough-Stewart designs and redundant legs\n\nfigures\n")
    assert measured_apart(str(tmp_path / "BENCHMARKS.md"))[0].startswith("## Gough-Stewart designs")
    assert measured_apart(str(tmp_path / "elsewhere" / "BENCHMARKS.md")) == []


def test_bench_gough_script_runs_and_reports_every_design(tmp_path):
    out = tmp_path / "gough.md"
    r = subprocess.run([sys.executable, str(CONFIG.parent / "tools" / "bench_gough.py"), "--steps", "20", "--loops",
                        "1", "--markdown", str(out)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    for label in ("6-6", "6-3", "3-3", "7 legs", "10 x leg_noise_std", "1000 x leg_noise_std", "load average"):
        assert label in text


# -- a faulty sensor, live: the demo's node over DDS, the mock controller's --fault ---------------------------------
@pytest.mark.timing
def test_demo_with_a_faulty_leg_publishes_right_poses_and_names_the_leg(tmp_path, dds_env, dds_domain):
    pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")
    env = dds_env
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "demo", "--manipulator", "hexapod_7legs", "--duration", "2",
                        "--fault", "4", "0.01", "--out", str(tmp_path), "--domain-id", str(dds_domain)],
                       cwd=CONFIG.parent, env=env, capture_output=True, text=True, timeout=400)
    assert r.returncode == 0, r.stdout + r.stderr
    s = json.loads((tmp_path / "demo_hexapod_7legs.json").read_text())
    assert s["ok"] and s["poses_wrong"] == 0 and s["poses_received"] >= 1       # every pose right, fault or not
    assert s["fault"] == {"leg": 4, "step_m": 0.01, "from_s": 1.0}
    health = s["leg_health"]
    if health["inputs with inconsistent legs"] not in (None, "0"):   # some faulty inputs were solved
        assert health["legs left out"].startswith("leg_4: ") and health["leg left out last"] == "leg_4"


def test_fault_options_refuse_bad_legs_in_one_line():
    for argv in (["demo", "--manipulator", "hexapod_7legs", "--fault", "9", "0.01"],
                 ["demo", "--manipulator", "hexapod_7legs", "--fault", "1.5", "0.01"]):
        r = subprocess.run([sys.executable, "-m", "glpma_ros", *argv], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--fault" in r.stderr, argv
    r = subprocess.run([sys.executable, "-m", "glpma_tools.mock_controller", "--config", "hexapod_7legs", "--fault",
                        "0.5", "0.01"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--fault" in r.stderr


def test_a_plan_with_a_fault_sends_the_step_and_keeps_the_truth():
    plan = Plan("hexapod_7legs", fault=(3, 0.01, 1.0))
    legs, position, q = plan.sample(0.5)
    assert plan.measured(legs, 0.5) is legs                        # before the fault: the true legs
    later = plan.sample(2.0)[0]
    step = plan.measured(later, 2.0) - later
    assert np.allclose(step, [0, 0, 0, 10.0, 0, 0, 0], rtol=0, atol=1e-9)   # 0.01 m in the config's mm
    with pytest.raises(Exception, match="faulty leg must be 1 to 7"):
        Plan("hexapod_7legs", fault=(7, 0.01, 1.0))


def test_the_bag_status_names_the_faulty_leg(tmp_path, capsys):
    pytest.importorskip("rosbags", reason="the bag extra (rosbags) is not installed")
    from test_bag import TS, read_bag, write_legs_bag

    from glpma_tools import bag as B
    from glpma_tools import bag_run as C
    plan = Plan("hexapod_7legs")
    x0 = plan.start_variables()
    legs_m = np.array([plan.sample(k / 100.0)[0] for k in range(40)]) * plan.mpu
    legs_m[20:, 3] += 0.01                                             # leg 4 10 mm too long from input 20 on
    src, dst = tmp_path / "in", tmp_path / "out"
    write_legs_bag(src, "mcap", legs_m)
    assert B.main([str(src), str(dst), "--no-progress", "--json", "--ros-args", "-p",
                   f"manipulator_config:={CONFIG / 'hexapod_7legs.yaml'}", "-p",
                   "initial_pose:=[" + ", ".join(repr(float(v)) for v in x0) + "]"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["converged"] == 40                                  # a pose for every input, faulty or not
    out, _ = read_bag(dst)
    statuses = [TS.deserialize_cdr(raw, C.DIAGNOSTIC_STATUS) for _, raw in out["/glpma_fk/status"]]
    values = [dict((kv.key, kv.value) for kv in s.values) for s in statuses]
    assert all(v["status"] == "converged" and s.level == 0 for s, v in zip(statuses[:20], values[:20]))
    for s, v in zip(statuses[20:], values[20:]):
        assert s.level == 1 and v["status"] == "inconsistent_legs" and "leg 4" in s.message
        assert v["suspect_leg"] == v["excluded_leg"] == "leg_4"
