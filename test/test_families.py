"""The actuated families (one leg model, glpma_ros.models.legs / actuated / families): the rotary Delta."""
import json
import math
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
from glpma_ros.models.legs import REVOLUTE, actuator_roots, leg_vector_into
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
#: the budget of the evaluation-capped cold solves: a bound for a hang, not a timing figure (the first call in a
#: process may compile on a busy machine; the evaluation cap ends the search)
CAPPED_BUDGET_S = 600.0


@pytest.fixture(scope="module")
def delta():
    return load_manipulator(DELTA_YAML)


def random_poses(delta, rng, n):
    """``n`` poses in the working region whose actuators are within their limits."""
    out = []
    while len(out) < n:
        r, a = WORK_RADIUS * math.sqrt(rng.uniform()), rng.uniform(-math.pi, math.pi)
        p = np.array([r * math.cos(a), r * math.sin(a), rng.uniform(*WORK_Z)])
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


def test_example_and_known_solutions(delta):
    legs = delta.legs_from_sensors(delta.example_actuator_positions)
    closed = delta.closed_form(legs)
    assert len(closed) == 2
    for x in delta.known_solutions:
        # the YAML's solutions are written to 1e-9 mm
        assert min(np.max(np.abs(x - c)) for c in closed) < 1e-6
        assert np.max(np.abs(delta.residuals(x, legs))) < 1e-6


def test_inverse_then_closed_form_round_trip(delta):
    rng = np.random.default_rng(1)
    for p in random_poses(delta, rng, 50):
        q = delta.actuator_positions(p)
        closed = delta.closed_form(delta.legs_from_sensors(q))
        assert len(closed) == 2
        assert delta.preferred_order(closed)[0] == pytest.approx(p, abs=ROUND_OFF_REL * delta.scale)


def test_revolute_roots_reach_the_point(delta):
    rng = np.random.default_rng(2)
    for p in random_poses(delta, rng, 20):
        distal = p + delta.platform
        for i in range(3):
            for q in actuator_roots(REVOLUTE, delta.origin[i], delta.axis[i], delta.crank[i], delta.rods[i], distal[i]):
                w = delta.leg_vector(np.where(np.arange(3) == i, q, 0.0))
                tip = w[3 + 3 * i:6 + 3 * i]
                assert np.linalg.norm(distal[i] - tip) == pytest.approx(delta.rods[i], abs=1e-9 * delta.scale)


@pytest.mark.parametrize("method, kwargs", [("multistart", {}), ("g3pcx", {"runs": 20})])
def test_solve_all_iterative_methods_find_the_closed_form_modes(delta, method, kwargs):
    """solve-all's default for a Delta is the closed form; the iterative methods find the same two modes."""
    rng = np.random.default_rng(3)
    for p in random_poses(delta, rng, 3):
        legs = delta.legs_from_sensors(delta.actuator_positions(p))
        closed = solve_all(delta, legs)
        assert closed.method == "closed_form" and len(closed.solutions) == 2
        found = solve_all(delta, legs, method=method, seed=4, **kwargs)
        assert len(found.solutions) == 2
        for a, b in zip(closed.solutions, found.solutions):
            assert np.max(np.abs(a.x - b.x)) <= ROUND_OFF_REL * delta.scale


def test_warm_tracking_reproduces_the_trajectory(delta):
    from glpma_tools.sim.trajectories import variables_along
    truth = variables_along(delta, delta.known_solutions[0], 400)
    est = Estimator(delta, time_budget_s=GENEROUS_BUDGET_S, initial_pose=truth[0])
    for x in truth:
        e = est.estimate(delta.legs_from_sensors(delta.actuator_positions(x)))
        assert e.converged and e.start == "warm", e.message
        assert np.max(np.abs(e.x - x)) <= ROUND_OFF_REL * delta.scale


def test_cold_estimates_report_the_working_mode(delta):
    """Without a previous pose the closed form's working mode (platform below the arms) is reported."""
    rng = np.random.default_rng(5)
    for p in random_poses(delta, rng, 20):
        e = Estimator(delta, time_budget_s=GENEROUS_BUDGET_S).estimate(delta.actuator_positions(p))
        assert e.converged and "closed form" in e.message
        assert np.max(np.abs(e.x - p)) <= ROUND_OFF_REL * delta.scale


@pytest.mark.parametrize("solver", ["g3pcx", "rcga", "glpma"])
def test_cold_iterative_solves_succeed_from_random_starts(delta, solver):
    """The evolutionary solvers (the closed form aside) from the cold range, evaluation-capped: every run
    converges to one of the two modes."""
    rng = np.random.default_rng(6)
    low, high = cold_range(delta)
    for k, p in enumerate(random_poses(delta, rng, 10)):
        legs = delta.legs_from_sensors(delta.actuator_positions(p))
        r = solvers.solve(solver, delta, legs, rng=np.random.default_rng(k), init_range=(low, high),
                          polish=True, max_evals=20_000)
        assert r.success, (solver, k, r.message if hasattr(r, "message") else r)
        modes = delta.closed_form(legs)
        assert min(np.max(np.abs(r.x - m)) for m in modes) <= 1e-6 * delta.scale


def test_local_solver_from_random_starts_in_reach(delta):
    """The compiled Levenberg-Marquardt from starts drawn in the legs' reach (solve-all's multistart starts)
    converges to a mode from every start within its iteration cap."""
    from glpma_ros.modes.starts import StartSampler
    rng = np.random.default_rng(7)
    solver = LocalSolver(delta)
    for p in random_poses(delta, rng, 5):
        legs = delta.legs_from_sensors(delta.actuator_positions(p))
        starts = StartSampler(delta, legs).draw(rng, 50)
        modes = delta.closed_form(legs)
        for s in starts:
            r = solver.solve(np.ascontiguousarray(s), legs, max_iter=100)
            assert r.converged
            assert min(np.max(np.abs(r.x - m)) for m in modes) <= ROUND_OFF_REL * delta.scale


@pytest.mark.parametrize("reading, message", [
    ([0.1, 0.2], "expected 3 actuator positions for delta, got 2"),
    ([0.1, math.nan, 0.0], "actuator positions must be finite"),
    ([0.1, 2.0, 0.0], "actuator 2 at 2 rad is outside its limits [-0.6981, 1.3963] rad"),
])
def test_bad_readings_are_rejected_with_a_reason(delta, reading, message):
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        Estimator(delta).estimate(delta.legs_from_sensors(reading))


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


def test_rus_solve_all_matches_the_crank_tip_6_6(rus):
    """The independent check: with the actuators' positions known, each crank tip is known, and the problem is the
    6-6 hexapod whose base joints are the crank tips and whose leg lengths are the rods (today's model, its own
    kernels); both find the config's eight modes."""
    from glpma_ros.models import Hexapod66
    legs = rus.legs_from_sensors(rus.example_actuator_positions)
    six_six = Hexapod66(rus.proximal_points(legs), rus.platform, unit="mm")
    tol = ROUND_OFF_REL * rus.scale * 10      # both polished to round-off; the YAML's modes are written to 1e-9 mm
    ours = solve_all(rus, legs, seed=1)
    theirs = solve_all(six_six, rus.rods_of(legs), seed=2)
    _match([s.x for s in ours.solutions], rus.known_solutions, tol)
    _match([s.x for s in theirs.solutions], rus.known_solutions, tol)


def test_rus_warm_tracking_reproduces_the_trajectory(rus):
    from glpma_tools.sim.trajectories import variables_along
    truth = variables_along(rus, rus.known_solutions[0], 400)
    est = Estimator(rus, time_budget_s=GENEROUS_BUDGET_S, initial_pose=truth[0])
    for x in truth:
        e = est.estimate(rus.actuator_positions(x))
        assert e.converged and e.start == "warm", e.message
        assert rus.distance(e.x, x) <= ROUND_OFF_REL * rus.scale


def test_rus_cold_estimates_converge_from_random_poses(rus):
    """Cold (no previous pose), evaluation-capped: every estimate converges to an assembly mode of its reading
    (leg residuals at round-off); which mode a cold start reports is not determined."""
    from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector
    rng = np.random.default_rng(8)
    home = rus.pose(rus.known_solutions[0])
    poses = []
    while len(poses) < 10:      # random poses within 80 mm and 0.15 rad of the working mode, where the cranks reach
        R = rotation_from_vector(rng.uniform(-0.15, 0.15, 3)) @ matrix_from_quaternion(home.orientation)
        x = rus.variables_from_pose(home.position + rng.uniform(-80.0, 80.0, 3), quaternion_from_matrix(R))
        try:
            rus.actuator_positions(x)
        except ValueError:
            continue
        poses.append(x)
    for k, x in enumerate(poses):
        legs = rus.legs_from_sensors(rus.actuator_positions(x))
        e = Estimator(rus, time_budget_s=CAPPED_BUDGET_S, seed=k, max_evals=500_000).estimate(legs)
        assert e.converged, e.message
        assert e.max_residual <= ROUND_OFF_REL * rus.scale


def test_rus_bad_readings_are_rejected(rus):
    with pytest.raises(InputError, match="expected 6 actuator positions for rus_6, got 3"):
        rus.check_legs([0.0, 0.0, 0.0])
    with pytest.raises(InputError, match=r"actuator 4 at 1.5 rad is outside its limits \[-1.309, 1.309\] rad"):
        rus.check_legs([0.0, 0.0, 0.0, 1.5, 0.0, 0.0])


def test_bad_commands_refuse_actuated_families_in_one_line():
    for argv in (["map", "delta_irb360", "--out", "unused"],
                 ["calibrate", "rus6_simulator", "unused.csv", "--out", "x.yaml"]):
        r = subprocess.run([sys.executable, "-m", "glpma_ros", *argv], capture_output=True, text=True, cwd=ROOT)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert "actuated family" in r.stderr


# -- planar 3-RRR: the 3-RPR's model with the crank tips as base joints ------------------------------------------

RRR_YAML = CONFIG / "planar_3rrr_symmetric.yaml"


@pytest.fixture(scope="module")
def rrr():
    return load_manipulator(RRR_YAML)


def test_rrr_solve_all_matches_the_crank_tip_3rpr(rrr):
    """With the cranks' angles known each crank tip is known: the 3-RPR whose base joints are the crank tips and
    whose legs are the rods (today's model, its own kernels) has the same modes, the config's two."""
    from glpma_ros.models import Planar3RPR
    legs = rrr.legs_from_sensors(rrr.example_actuator_positions)
    for x in rrr.known_solutions:
        assert np.max(np.abs(rrr.residuals(x, legs))) < 1e-6     # written to 1e-9
    rpr = Planar3RPR(rrr.proximal_points(legs), rrr.platform, unit="mm")
    tol = ROUND_OFF_REL * rrr.scale * 10
    _match([s.x for s in solve_all(rrr, legs, seed=1).solutions], rrr.known_solutions, tol)
    _match([s.x for s in solve_all(rpr, rrr.rods_of(legs), seed=2).solutions], rrr.known_solutions, tol)


def test_rrr_warm_tracking_reproduces_the_trajectory(rrr):
    from glpma_tools.sim.trajectories import variables_along
    truth = variables_along(rrr, rrr.known_solutions[0], 400)
    est = Estimator(rrr, time_budget_s=GENEROUS_BUDGET_S, initial_pose=truth[0])
    for x in truth:
        e = est.estimate(rrr.actuator_positions(x))
        assert e.converged and e.start == "warm", e.message
        assert rrr.distance(e.x, x) <= ROUND_OFF_REL * rrr.scale


def test_rrr_cold_estimates_converge_from_random_poses(rrr):
    rng = np.random.default_rng(9)
    done = 0
    while done < 10:            # random poses within 60 mm and 0.3 rad of the working mode, where the cranks reach
        x = rrr.known_solutions[0] + np.concatenate((rng.uniform(-60.0, 60.0, 2), rng.uniform(-0.3, 0.3, 1)))
        try:
            q = rrr.actuator_positions(x)
        except ValueError:
            continue
        e = Estimator(rrr, time_budget_s=CAPPED_BUDGET_S, seed=done, max_evals=100_000).estimate(q)
        assert e.converged, e.message
        assert e.max_residual <= ROUND_OFF_REL * rrr.scale
        done += 1


def test_rrr_cli_solve_all_table(rrr):
    q = [str(v) for v in rrr.example_actuator_positions]
    r = subprocess.run([sys.executable, "-m", "glpma_ros", "solve-all", "planar_3rrr_symmetric", "--legs", *q],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert "2 distinct real assembly modes" in r.stdout and "theta [rad]" in r.stdout
