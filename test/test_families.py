"""The actuated families (one leg model, glpma_ros.models.legs / actuated / families): the rotary and the linear
Delta (translation, closed form), the 6-RUS and 6-PUS (full pose), the planar 3-RRR and 3-PRR."""
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest
import yaml

from conftest import CONFIG, GENEROUS_BUDGET_S, ROOT
from glpma_ros import solvers
from glpma_ros.config import load_manipulator, model_from_dict
from glpma_ros.errors import ConfigError, InputError
from glpma_ros.estimation.estimator import Estimator, cold_range
from glpma_ros.models.legs import PRISMATIC, actuator_roots, leg_vector_into
from glpma_ros.modes.multistart import solve_all
from glpma_ros.solvers.local import LocalSolver

DELTA_YAML = CONFIG / "delta_irb360.yaml"
#: a converged pose is exact to round-off: 1e-9 of the geometry's scale is far above the ~1e-13 a
#: polished solve leaves and far below any error of the method
ROUND_OFF_REL = 1e-9
#: the Delta's working region used by the tests (mm): the platform centre within this radius of the axis
#: and between these heights, where the legs reach within their limits
WORK_RADIUS = 250.0
WORK_Z = (-1250.0, -850.0)
#: the translating families' working regions (config, (radius, z range) in mm): the IRB 360's above; the
#: Kossel mini's printable radius (90 mm) and heights up to 200 mm above the bed
TRANSLATING = {"delta": ("delta_irb360", (WORK_RADIUS, WORK_Z)),
               "linear_delta": ("linear_delta_kossel_mini", (90.0, (0.0, 200.0)))}
#: the full-pose families (config, (position, angle) spread of the random poses about the working mode, mm and
#: rad, where the legs reach within their limits)
FULL_POSE = {"rus_6": ("rus6_simulator", (6.0, 0.1)), "pus_6": ("pus6_rail_hexapod", (10.0, 0.1)),
             "planar_3rrr": ("planar_3rrr_symmetric", (60.0, 0.3)),
             "planar_3prr": ("planar_3prr_triangle", (40.0, 0.3))}
#: every shipped family's config
ALL_FAMILIES = {k: v[0] for k, v in {**TRANSLATING, **FULL_POSE}.items()}
#: the budget of the evaluation-capped cold solves: a bound for a hang, not a timing figure (the first call in a
#: process may compile on a busy machine; the evaluation cap ends the search)
CAPPED_BUDGET_S = 600.0


@pytest.fixture(scope="module")
def delta():
    return load_manipulator(DELTA_YAML)


_MODELS = {}


def family_model(family):
    """The shipped config's model of ``family`` (read once per test process)."""
    if family not in _MODELS:
        _MODELS[family] = load_manipulator(CONFIG / f"{ALL_FAMILIES[family]}.yaml")
    return _MODELS[family]


@pytest.fixture(scope="module", params=sorted(TRANSLATING))
def translating(request):
    return family_model(request.param)


def random_poses(delta, rng, n):
    """``n`` poses in the working region of a translating family whose actuators are within their limits."""
    radius, heights = TRANSLATING[delta.kind][1]
    out = []
    while len(out) < n:
        r, a = radius * math.sqrt(rng.uniform()), rng.uniform(-math.pi, math.pi)
        p = np.array([r * math.cos(a), r * math.sin(a), rng.uniform(*heights)])
        try:
            delta.actuator_positions(p)
        except ValueError:
            continue
        out.append(p)
    return out


def test_leg_vector_is_the_one_leg_model(delta):
    """P_i(q) = origin + Rot(axis, q) crank (Rodrigues), checked against a rotation matrix built independently."""
    q = np.array([0.3, -0.2, 1.1])
    w = delta.leg_vector(q)
    assert np.allclose(w[:3], delta.rods)
    for i in range(3):
        a, c = delta.axis[i], delta.crank[i]
        K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        R = np.eye(3) + math.sin(q[i]) * K + (1 - math.cos(q[i])) * K @ K
        # 1e-9 mm on 700 mm arms: round-off of two formulas of one rotation
        assert np.allclose(w[3 + 3 * i:6 + 3 * i], delta.origin[i] + R @ c, atol=1e-9)
    assert np.allclose(delta.sensors_from_legs(w), q, atol=1e-12)     # the inverse, to round-off in radians


def test_length_legs_are_todays_legs():
    """A length actuator: fixed proximal point, the reading is the rod (today's RPR / UPS legs)."""
    origin = np.array([[1.0, 2.0, 3.0]])
    out = np.empty(4)
    leg_vector_into(np.array([0]), origin, np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1), np.array([7.5]), out)
    assert out.tolist() == [7.5, 1.0, 2.0, 3.0]       # copies, no arithmetic


def test_example_and_known_solutions(translating):
    legs = translating.legs_from_sensors(translating.example_actuator_positions)
    closed = translating.closed_form(legs)
    assert len(closed) == 2
    for x in translating.known_solutions:
        # the YAML's solutions are written to 1e-9 mm
        assert min(np.max(np.abs(x - c)) for c in closed) < 1e-6
        assert np.max(np.abs(translating.residuals(x, legs))) < 1e-6


def test_inverse_then_closed_form_round_trip(translating):
    rng = np.random.default_rng(1)
    for p in random_poses(translating, rng, 50):
        q = translating.actuator_positions(p)
        closed = translating.closed_form(translating.legs_from_sensors(q))
        assert len(closed) == 2
        assert translating.preferred_order(closed)[0] == pytest.approx(p, abs=ROUND_OFF_REL * translating.scale)


def test_actuator_roots_reach_the_point(translating):
    """Each leg's inverse kinematics (both roots: arm up / down, carriage above / below) puts the rod's
    proximal end at the rod's length from the platform joint."""
    rng = np.random.default_rng(2)
    model = translating
    for p in random_poses(model, rng, 20):
        distal = p + model.platform
        for i in range(3):
            roots = actuator_roots(int(model.actuators[i]), model.origin[i], model.axis[i], model.crank[i],
                                   model.rods[i], distal[i])
            assert len(roots) == 2
            for q in roots:
                w = model.leg_vector(np.where(np.arange(3) == i, q, 0.0))
                tip = w[3 + 3 * i:6 + 3 * i]
                assert np.linalg.norm(distal[i] - tip) == pytest.approx(model.rods[i], abs=1e-9 * model.scale)


def test_prismatic_leg_vector_is_the_carriage():
    """P_i(q) = origin + q axis for a rail (the linear Delta's carriages), and its inverse."""
    model = family_model("linear_delta")
    assert np.all(model.actuators == PRISMATIC)
    q = np.array([120.0, 250.5, 401.25])
    w = model.leg_vector(q)
    assert np.allclose(w[:3], model.rods)
    # 1e-12 mm: one multiply-add on numbers of a few hundred mm
    assert np.allclose(w[3:].reshape(3, 3), model.origin + q[:, None] * model.axis, atol=1e-12)
    assert np.allclose(model.sensors_from_legs(w), q, atol=1e-12)


@pytest.mark.parametrize("method, kwargs", [("multistart", {}), ("g3pcx", {"runs": 20})])
def test_solve_all_iterative_methods_find_the_closed_form_modes(translating, method, kwargs):
    """solve-all's default for a Delta is the closed form; the iterative methods find the same two modes."""
    rng = np.random.default_rng(3)
    for p in random_poses(translating, rng, 3):
        legs = translating.legs_from_sensors(translating.actuator_positions(p))
        closed = solve_all(translating, legs)
        assert closed.method == "closed_form" and len(closed.solutions) == 2
        found = solve_all(translating, legs, method=method, seed=4, **kwargs)
        assert len(found.solutions) == 2
        for a, b in zip(closed.solutions, found.solutions):
            assert np.max(np.abs(a.x - b.x)) <= ROUND_OFF_REL * translating.scale


@pytest.mark.parametrize("family", sorted(ALL_FAMILIES))
def test_warm_tracking_reproduces_the_trajectory(family):
    """Warm (compiled Levenberg-Marquardt from the previous pose) along the tools' trajectory about the working
    mode: every pose reproduced to round-off."""
    from glpma_tools.sim.trajectories import variables_along
    model = family_model(family)
    truth = variables_along(model, model.known_solutions[0], 400)
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, initial_pose=truth[0])
    for x in truth:
        e = est.estimate(model.actuator_positions(x))
        assert e.converged and e.start == "warm", e.message
        assert model.distance(e.x, x) <= ROUND_OFF_REL * model.scale


def test_cold_estimates_report_the_working_mode(translating):
    """Without a previous pose the closed form's working mode (platform below the arms) is reported."""
    rng = np.random.default_rng(5)
    for p in random_poses(translating, rng, 20):
        e = Estimator(translating, time_budget_s=GENEROUS_BUDGET_S).estimate(translating.actuator_positions(p))
        assert e.converged and "closed form" in e.message
        assert np.max(np.abs(e.x - p)) <= ROUND_OFF_REL * translating.scale


@pytest.mark.parametrize("solver", ["g3pcx", "rcga", "glpma"])
def test_cold_iterative_solves_succeed_from_random_starts(translating, solver):
    """The evolutionary solvers (the closed form aside) from the cold range, evaluation-capped: every run
    converges to one of the two modes."""
    rng = np.random.default_rng(6)
    low, high = cold_range(translating)
    for k, p in enumerate(random_poses(translating, rng, 10)):
        legs = translating.legs_from_sensors(translating.actuator_positions(p))
        r = solvers.solve(solver, translating, legs, rng=np.random.default_rng(k), init_range=(low, high),
                          polish=True, max_evals=20_000)
        assert r.success, (solver, k, r.message if hasattr(r, "message") else r)
        modes = translating.closed_form(legs)
        assert min(np.max(np.abs(r.x - m)) for m in modes) <= 1e-6 * translating.scale


def test_local_solver_from_random_starts_in_reach(translating):
    """The compiled Levenberg-Marquardt from starts drawn in the legs' reach (solve-all's multistart starts)
    converges to a mode from every start within its iteration cap."""
    from glpma_ros.modes.starts import StartSampler
    rng = np.random.default_rng(7)
    solver = LocalSolver(translating)
    for p in random_poses(translating, rng, 5):
        legs = translating.legs_from_sensors(translating.actuator_positions(p))
        starts = StartSampler(translating, legs).draw(rng, 50)
        modes = translating.closed_form(legs)
        for s in starts:
            r = solver.solve(np.ascontiguousarray(s), legs, max_iter=100)
            assert r.converged
            assert min(np.max(np.abs(r.x - m)) for m in modes) <= ROUND_OFF_REL * translating.scale


@pytest.mark.parametrize("reading, message", [
    ([0.1, 0.2], "expected 3 actuator positions for delta, got 2"),
    ([0.1, math.nan, 0.0], "actuator positions must be finite"),
    ([0.1, 2.0, 0.0], "actuator 2 at 2 rad is outside its limits [-0.6981, 1.3963] rad"),
])
def test_bad_readings_are_rejected_with_a_reason(delta, reading, message):
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        Estimator(delta).estimate(delta.legs_from_sensors(reading))


@pytest.mark.parametrize("family, reading, message", [
    ("linear_delta", [300.0, 500.0, 300.0], "actuator 2 at 500 mm is outside its limits [80, 437.3] mm"),
    ("pus_6", [400.0] * 5, "expected 6 actuator positions for pus_6, got 5"),
    ("planar_3prr", [200.0, 200.0, math.inf], "actuator positions must be finite"),
    ("planar_3prr", [10.0, 200.0, 200.0], "actuator 1 at 10 mm is outside its limits [20, 400] mm"),
])
def test_bad_carriage_readings_are_rejected_in_the_config_unit(family, reading, message):
    model = family_model(family)
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        model.legs_from_sensors(reading)


@pytest.mark.parametrize("family", sorted(ALL_FAMILIES))
def test_si_readings_are_the_config_unit_readings(family):
    """The node's input (radians; metres for a rail) converted in one compiled call is the leg vector of the
    readings in the config's units, and a bad one gets the same reason."""
    model = family_model(family)
    q = model.example_actuator_positions
    si = model.readings_to_si(q)
    # the same divisions, up to the round trip through metres (a few units in the last place)
    np.testing.assert_allclose(model.legs_from_si(si), model.legs_from_sensors(q), rtol=1e-14, atol=0.0)
    np.testing.assert_allclose(model.legs_from_si(si.tolist()), model.legs_from_si(si), rtol=1e-15, atol=0.0)
    for bad in (si[:-1], np.r_[si[:-1], math.nan], np.r_[si[:-1], 1e3]):
        with pytest.raises(InputError) as expected:
            model.legs_from_sensors(model.readings_from_si(bad))
        with pytest.raises(InputError, match=re.escape(str(expected.value))):
            model.legs_from_si(bad)


def test_cli_solve_and_solve_all(delta):
    q = [str(v) for v in delta.example_actuator_positions]
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve-all", "delta_irb360", "--legs", *q, "--json"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["method"] == "closed_form" and len(out["solutions"]) == 2
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve", "delta_irb360", "--legs", *q, "--json"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    pose = json.loads(r.stdout)["pose"]["position"]
    assert np.max(np.abs(np.array(pose) - delta.known_solutions[0])) < 1e-6 * delta.scale
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve", "delta_irb360", "--legs", "0.1", "2.0", "0"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == ["error: actuator 2 at 2 rad is outside its limits [-0.6981, 1.3963] rad"]


def test_service_answers_angles_and_joint_states(delta):
    from glpma_ros.node.service import FkService
    svc = FkService({"manipulator_config": str(DELTA_YAML), "joint_names": ["arm_1", "arm_2", "arm_3"],
                     "time_budget_ms": GENEROUS_BUDGET_S * 1e3})
    assert svc.input_topic == "actuator_positions"
    q = delta.example_actuator_positions
    out = svc.handle(q.tolist(), 1)
    assert out.pose is not None, out.reason
    # metres on the pose topic
    assert np.max(np.abs(np.array(out.pose.position) - delta.known_solutions[0] * 1e-3)) < 1e-9
    out = svc.handle_joint_state(["x", "arm_3", "arm_1", "arm_2"], [9.0, q[2], q[0], q[1]], 2)
    assert out.pose is not None and np.max(np.abs(np.array(out.pose.position) - delta.known_solutions[0] * 1e-3)) < 1e-9
    bad = svc.handle([0.1, 2.0, 0.0], 3)
    assert bad.pose is None and bad.reason == "actuator 2 at 2 rad is outside its limits [-0.6981, 1.3963] rad"


@pytest.mark.parametrize("change, message", [
    ({"platform_motion": "full"}, "'platform_motion' of delta is 'translation'"),
    ({"legs": []}, "'legs' must list the 3 legs of delta"),
    ({"actuator_limits": [[0, 1]]}, "'actuator_limits' must be 3"),
    ({"legs[0].rod": -1}, r"legs\[1\].rod must be a positive length"),
    ({"legs[1].actuator": "prismatic"}, r"legs\[2\]: actuator must be 'revolute'"),
    ({"legs[2].crank": [0, 0, 1], "legs[2].axis": [0, 0, 1]}, r"legs\[3\].crank must not be along the axis"),
    ({"legz": 1}, "unknown key 'legz' \\(did you mean 'legs'\\?\\)"),
])
def test_config_errors_name_the_problem(change, message):
    doc = yaml.safe_load(DELTA_YAML.read_text())
    for key, value in change.items():
        if key.startswith("legs["):
            i, field = int(key[5]), key.split(".")[1]
            doc["legs"][i][field] = value
        else:
            doc[key] = value
    with pytest.raises(ConfigError, match=message):
        model_from_dict(doc)


@pytest.mark.parametrize("family, change, message", [
    ("linear_delta", {"legs[0].crank": [1, 0, 0]}, r"legs\[1\]: unknown key 'crank' \(a rail has no crank\)"),
    ("linear_delta", {"legs[1].axis": [0, 0, 0]}, r"legs\[2\].axis must not be zero"),
    ("planar_3prr", {"legs[2].axis": [0, 0, 1]}, r"legs\[3\].axis must be 2 finite numbers"),
    ("pus_6", {"legs[0].actuator": "revolute"}, r"legs\[1\]: actuator must be 'prismatic'"),
    ("pus_6", {"platform_motion": "translation"}, "'platform_motion' of pus_6 is 'full'"),
])
def test_rail_config_errors_name_the_problem(family, change, message):
    doc = yaml.safe_load((CONFIG / f"{ALL_FAMILIES[family]}.yaml").read_text())
    for key, value in change.items():
        if key.startswith("legs["):
            doc["legs"][int(key[5])][key.split(".")[1]] = value
        else:
            doc[key] = value
    with pytest.raises(ConfigError, match=message):
        model_from_dict(doc)


def test_service_answers_carriage_positions_in_metres():
    """A prismatic family's readings go on actuator_positions in metres (REP 103), the pose comes back in metres."""
    from glpma_ros.node.service import FkService
    model = family_model("linear_delta")
    svc = FkService({"manipulator_config": str(CONFIG / "linear_delta_kossel_mini.yaml"),
                     "joint_names": ["tower_x", "tower_y", "tower_z"], "time_budget_ms": GENEROUS_BUDGET_S * 1e3})
    assert svc.input_topic == "actuator_positions"
    q_m = model.example_actuator_positions * 1e-3
    out = svc.handle(q_m.tolist(), 1)
    assert out.pose is not None, out.reason
    # metres; the known solution is written to 1e-9 mm
    assert np.max(np.abs(np.array(out.pose.position) - model.known_solutions[0] * 1e-3)) < 1e-9
    # a JointState's prismatic joints in metres too, picked by joint_names
    out = svc.handle_joint_state(["tower_z", "other", "tower_x", "tower_y"], [q_m[2], 7.0, q_m[0], q_m[1]], 3)
    assert out.pose is not None and np.max(np.abs(np.array(out.pose.position) - model.known_solutions[0] * 1e-3)) < 1e-9
    bad = svc.handle([0.3, 0.5, 0.3], 2)
    assert bad.pose is None and bad.reason == "actuator 2 at 500 mm is outside its limits [80, 437.3] mm"


# -- 6-RUS: full pose, the hexapod's model with the crank tips as base joints ------------------------------------

RUS_YAML = CONFIG / "rus6_simulator.yaml"


@pytest.fixture(scope="module")
def rus():
    return load_manipulator(RUS_YAML)


def _match(found, expected, tol):
    """Every expected mode has a found one within ``tol`` (solver variables) and the counts agree."""
    assert len(found) == len(expected)
    for x in expected:
        assert min(np.max(np.abs(np.asarray(f) - x)) for f in found) <= tol


def test_rus_known_solutions_satisfy_the_legs(rus):
    legs = rus.legs_from_sensors(rus.example_actuator_positions)
    for x in rus.known_solutions:
        # written to 1e-9 mm: residuals (mm) and rigidity terms (mm^2) far below 1e-5
        assert np.max(np.abs(rus.residuals(x, legs))) < 1e-5


@pytest.mark.parametrize("family", ["rus_6", "pus_6"])
def test_spatial_solve_all_matches_the_proximal_point_6_6(family):
    """The independent check: with the actuators' positions known, each proximal point (crank tip, carriage) is
    known, and the problem is the 6-6 hexapod whose base joints are those points and whose leg lengths are the
    rods (today's model, its own kernels, solved by its default method); both find the config's modes."""
    from glpma_ros.models import Hexapod66
    model = family_model(family)
    legs = model.legs_from_sensors(model.example_actuator_positions)
    six_six = Hexapod66(model.proximal_points(legs), model.platform, unit="mm")
    tol = ROUND_OFF_REL * model.scale * 10    # both polished to round-off; the YAML's modes are written to 1e-9 mm
    ours = solve_all(model, legs, seed=1)
    theirs = solve_all(six_six, model.rods_of(legs), seed=2)
    _match([s.x for s in ours.solutions], model.known_solutions, tol)
    _match([s.x for s in theirs.solutions], model.known_solutions, tol)


@pytest.mark.parametrize("family, solver", [(f, "glpma") for f in sorted(FULL_POSE)]
                         + [("pus_6", "g3pcx"), ("planar_3prr", "g3pcx")])
def test_full_pose_cold_estimates_converge_from_random_poses(family, solver):
    """Cold (no previous pose), evaluation-capped: every estimate converges to an assembly mode of its reading
    (leg residuals at round-off); which mode a cold start reports is not determined."""
    from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector
    model = family_model(family)
    spread, angle = FULL_POSE[family][1]
    rng = np.random.default_rng(8)
    home = model.pose(model.known_solutions[0])
    poses = []
    while len(poses) < 10:      # random poses about the working mode, where the legs reach
        if model.dim == 2:
            x = model.known_solutions[0] + np.concatenate((rng.uniform(-spread, spread, 2),
                                                           rng.uniform(-angle, angle, 1)))
        else:
            R = rotation_from_vector(rng.uniform(-angle, angle, 3)) @ matrix_from_quaternion(home.orientation)
            x = model.variables_from_pose(home.position + rng.uniform(-spread, spread, 3), quaternion_from_matrix(R))
        try:
            model.actuator_positions(x)
        except ValueError:
            continue
        poses.append(x)
    evals = 500_000 if model.dim == 3 else 100_000      # the hexapods' and the planar models' caps
    for k, x in enumerate(poses):
        legs = model.legs_from_sensors(model.actuator_positions(x))
        e = Estimator(model, solver=solver, time_budget_s=CAPPED_BUDGET_S, seed=k, max_evals=evals).estimate(legs)
        assert e.converged, e.message
        assert e.max_residual <= ROUND_OFF_REL * model.scale


def test_rus_bad_readings_are_rejected(rus):
    with pytest.raises(InputError, match="expected 6 actuator positions for rus_6, got 3"):
        rus.check_legs([0.0, 0.0, 0.0])
    with pytest.raises(InputError, match=r"actuator 4 at 1.6 rad is outside its limits \[-1.5708, 1.5708\] rad"):
        rus.check_legs([0.0, 0.0, 0.0, 1.6, 0.0, 0.0])


# -- planar 3-RRR: the 3-RPR's model with the crank tips as base joints ------------------------------------------

@pytest.mark.parametrize("family", ["planar_3rrr", "planar_3prr"])
def test_planar_solve_all_matches_the_proximal_point_3rpr(family):
    """With the actuators' positions known each proximal point (crank tip, carriage) is known: the 3-RPR whose base
    joints are those points and whose legs are the rods (today's model, its own kernels) has the same modes, the
    config's."""
    from glpma_ros.models import Planar3RPR
    model = family_model(family)
    legs = model.legs_from_sensors(model.example_actuator_positions)
    for x in model.known_solutions:
        assert np.max(np.abs(model.residuals(x, legs))) < 1e-6     # written to 1e-9
    rpr = Planar3RPR(model.proximal_points(legs), model.platform, unit="mm")
    tol = ROUND_OFF_REL * model.scale * 10
    _match([s.x for s in solve_all(model, legs, seed=1).solutions], model.known_solutions, tol)
    _match([s.x for s in solve_all(rpr, model.rods_of(legs), seed=2).solutions], model.known_solutions, tol)


@pytest.mark.parametrize("family, words", [
    ("planar_3rrr", ["2 distinct real assembly modes", "theta [rad]"]),
    ("planar_3prr", ["2 distinct real assembly modes", "theta [rad]"]),
    ("linear_delta", ["2 distinct real assembly modes", "closed form"]),
    ("pus_6", ["4 distinct real assembly modes"]),
])
def test_cli_solve_all_table(family, words):
    model = family_model(family)
    q = [str(v) for v in model.example_actuator_positions]
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve-all", ALL_FAMILIES[family], "--legs", *q],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    for w in words:
        assert w in r.stdout, r.stdout
