"""Every real assembly mode: the fast multistart finds exactly the modes that the exact mode
(msolve) certifies, on random 3-RPRs and general 6-6 hexapods; the exact mode itself where the
``exact`` extra is installed, otherwise the certificates stored in test/data (written by
tools/assembly_modes_cases.py); stopping rule, limits, CLI and the node's reply."""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import HEX_YAML, ROOT, RPR_YAML, needs_msolve
from glpma_ros.errors import GlpmaError
from glpma_ros.models import Hexapod66, Planar3RPR
from glpma_ros.models.random_geometry import GENERATORS
from glpma_ros.modes import exact
from glpma_ros.modes import multistart_search as SA
from glpma_ros.modes.multistart import solve_all
from glpma_ros.node.service import FkService

DATA = ROOT / "test" / "data" / "assembly_modes_cases.json"
CASES = json.loads(DATA.read_text())["cases"]
MODELS = {"planar_3rpr": Planar3RPR, "hexapod_66": Hexapod66}
#: modes match when their platform joints are within this share of the scale
MATCH_RELATIVE = 1e-6
#: a regenerated geometry or leg length agrees with the stored one to this share of the scale: a few
#: units of round-off of the generator's arithmetic, whose last bits differ from CPU to CPU (BLAS
#: kernels, SIMD loops); a different draw of the generator differs by tens of per cent
REGENERATED_RELATIVE = 1e-12
#: a stored certified mode reproduces the stored legs to this share of the scale (they were polished
#: to round-off before they were stored)
STORED_MODE_LEGS_RELATIVE = 1e-9
#: hexapod cases whose exact solve is repeated here (msolve takes seconds each): the richest ones
EXACT_HEXAPOD_CASES = 3


def case_id(case):
    return f"{case['kind']}-seed{case['seed']}-{len(case['modes'])}modes"


def model_of(case):
    return MODELS[case["kind"]](np.array(case["base"]), np.array(case["platform"]))


def assert_same_modes(model, found, certified):
    """One-to-one within MATCH_RELATIVE of the scale: nothing missed, nothing spurious."""
    found, certified = [np.asarray(x) for x in found], [np.asarray(x) for x in certified]
    assert len(found) == len(certified), (len(found), len(certified))
    tol = MATCH_RELATIVE * model.scale
    D = np.array([[model.distance(f, c) for c in certified] for f in found])
    assert np.all(D.min(axis=1) <= tol), D.min(axis=1)
    assert sorted(D.argmin(axis=1)) == list(range(len(certified)))


def test_the_stored_cases_cover_what_issue_13_asks():
    counts = {kind: [len(c["modes"]) for c in CASES if c["kind"] == kind] for kind in MODELS}
    planar, hexapod = counts["planar_3rpr"], counts["hexapod_66"]
    assert len(planar) >= 20 and planar.count(4) >= 3 and planar.count(6) >= 3
    assert len(hexapod) >= 10 and sum(n >= 8 for n in hexapod) >= 3
    assert all(c["complex_solutions"] == (6 if c["kind"] == "planar_3rpr" else 40) for c in CASES)



@pytest.mark.parametrize("case", CASES, ids=case_id)
def test_the_stored_cases_are_the_generator_s(case):
    """A stored case is what its seed generates (to round-off) and its certified modes are real
    assembly modes of its legs."""
    model, legs, _ = GENERATORS[case["kind"]](np.random.default_rng(case["seed"]))
    tol = REGENERATED_RELATIVE * model.scale
    np.testing.assert_allclose(model.base, case["base"], rtol=0, atol=tol)
    np.testing.assert_allclose(model.platform, case["platform"], rtol=0, atol=tol)
    np.testing.assert_allclose(legs, case["legs"], rtol=0, atol=tol)
    stored = model_of(case)
    for mode in case["modes"]:
        np.testing.assert_allclose(stored.inverse_kinematics(np.asarray(mode)), case["legs"], rtol=0,
                                   atol=STORED_MODE_LEGS_RELATIVE * stored.scale)


@pytest.mark.parametrize("case", CASES, ids=case_id)
def test_multistart_finds_exactly_the_certified_modes(case):
    model = model_of(case)
    res = solve_all(model, case["legs"], method="multistart", seed=0)
    assert res.method == "multistart" and res.stop_reason == SA.STALLED
    assert_same_modes(model, [s.x for s in res.solutions], case["modes"])
    for s in res.solutions:                                        # polished to round-off
        assert s.fun < 1e-20 and np.max(np.abs(model.inverse_kinematics(s.x) - case["legs"])) < 1e-9


@needs_msolve
@pytest.mark.parametrize("case", [c for c in CASES if c["kind"] == "planar_3rpr"]
                         + sorted((c for c in CASES if c["kind"] == "hexapod_66"),
                                  key=lambda c: -len(c["modes"]))[:EXACT_HEXAPOD_CASES], ids=case_id)
def test_exact_mode_reproduces_the_stored_certificate(case):
    model = model_of(case)
    res = solve_all(model, case["legs"], method="exact")
    assert res.method == "exact" and res.complex_solutions == case["complex_solutions"]
    assert_same_modes(model, [s.x for s in res.solutions], case["modes"])
    assert all(s.fun < 1e-20 for s in res.solutions)


# -- the seed examples ---------------------------------------------------------------------------------

def test_multistart_seed_examples_two_and_sixteen(rpr, rpr_solutions, hexapod, hex_published):
    res = solve_all(rpr, rpr.example_leg_lengths)
    assert_same_modes(rpr, [s.x for s in res.solutions], rpr_solutions)
    res = solve_all(hexapod, hexapod.example_leg_lengths)
    assert len(res.solutions) == 16
    dev = np.array([[np.max(np.abs(p - s.x)) for p in hex_published] for s in res.solutions])
    assert sorted(dev.argmin(axis=1)) == list(range(16)) and dev.min(axis=1).max() < 0.05


@needs_msolve
def test_exact_seed_examples_two_of_six_and_sixteen_of_forty(rpr, hexapod):
    res = solve_all(rpr, rpr.example_leg_lengths, method="exact")
    assert (len(res.solutions), res.complex_solutions) == (2, 6)
    fast = solve_all(rpr, rpr.example_leg_lengths)
    assert_same_modes(rpr, [s.x for s in fast.solutions], [s.x for s in res.solutions])
    res = solve_all(hexapod, hexapod.example_leg_lengths, method="exact")
    assert (len(res.solutions), res.complex_solutions) == (16, 40)
    fast = solve_all(hexapod, hexapod.example_leg_lengths)
    assert_same_modes(hexapod, [s.x for s in fast.solutions], [s.x for s in res.solutions])


# -- the polynomial systems ------------------------------------------------------------------------------

def _evaluate(poly, point):
    return sum(float(c) * math.prod(v ** k for v, k in zip(point, m)) for m, c in poly.terms.items())


def test_the_polynomial_systems_vanish_at_a_known_mode(rpr, rpr_solutions, hexapod, hex_published):
    x, y, theta = rpr_solutions[0]
    for p in exact.planar_system(rpr, rpr.example_leg_lengths):
        assert abs(_evaluate(p, (x, y, math.cos(theta), math.sin(theta)))) < 1e-6 * rpr.scale ** 2
    # Study parameters of a pose between the frames moved to A_1 and B_1: e = its quaternion scaled
    # into the chart, translation t' = (p + R B_1) - A_1, f = t' e / 2
    model, legs, pose = GENERATORS["hexapod_66"](np.random.default_rng(1))
    P = model.pose(pose)
    qx, qy, qz, qw = P.orientation
    R = model.pose_state(pose)[0]
    e = np.array([qw, qx, qy, qz])
    e = e / float(sum(float(k) * v for k, v in zip(exact.CHART, e)))
    t = P.position + R @ model.platform[0] - model.base[0]
    f = 0.5 * np.array(exact.qmul((0.0, *t), tuple(e)))
    for p in exact.hexapod_system(model, legs):
        assert abs(_evaluate(p, (*e, *f))) < 1e-6 * max(1.0, max(abs(float(c)) for c in p.terms.values()))
    q, pos = exact.hexapod_pose(model, (*e, *f))
    np.testing.assert_allclose(model.variables_from_pose(pos, q), pose, atol=1e-6)


def test_msolve_output_is_parsed():
    text = ("[0, [0, \n2, \n2, \n['y', 'x'],\n[0, 1],\n[1,\n[[2, [-2, 0, 3]],\n[1, [0, 6]],\n[\n[[1, [0, -2]],\n1]\n"
            "]]]],[1,\n[[[3 / 2^3, 5 / 2^4], [-7 / 2^1, -3]], [[1, 1], [2, 2]]]\n]]:\n")
    dim, degree, distinct, names, boxes = exact.parse_output(text)
    assert (dim, degree, distinct, names) == (0, 2, 2, ["y", "x"])
    assert [[float(v) for v in iv] for iv in boxes[0]] == [[0.375, 0.3125], [-3.5, -3.0]]
    assert exact.parse_output("[-1]:\n")[0] == -1 and exact.parse_output("[1, 2, -1, []]:\n")[0] == 1


def test_polynomials_are_written_with_integer_coefficients():
    x, y = exact.Poly.var(2, 0), exact.Poly.var(2, 1)
    from fractions import Fraction
    assert (Fraction(3, 2) * x * x - Fraction(1, 3) * y + 1).to_msolve(("x", "y")) == "9*x^2-2*y+6"
    assert exact.rational(464.141) == Fraction(464141, 1000)


@needs_msolve
def test_exact_refuses_a_degenerate_geometry():
    tri = np.array([[0.0, 0.0], [100.0, 0.0], [30.0, 80.0]])
    model = Planar3RPR(tri, tri)               # congruent triangles, equal legs: a circle of translations
    with pytest.raises(exact.DegenerateSystemError, match="infinitely many solutions"):
        solve_all(model, [50.0, 50.0, 50.0], method="exact")


def test_exact_refuses_without_msolve(monkeypatch, rpr):
    monkeypatch.setattr(exact, "MSOLVE_DISTRIBUTION", "glpma-ros-no-such-distribution")
    monkeypatch.setenv("PATH", "")
    with pytest.raises(exact.ExactUnavailableError, match=r"pip install 'glpma_ros\[exact\]'"):
        solve_all(rpr, rpr.example_leg_lengths, method="exact")


# -- the multistart's rule and limits ---------------------------------------------------------------------

def test_stopping_rule_and_estimates_are_as_documented(hexapod):
    res = solve_all(hexapod, hexapod.example_leg_lengths, method="multistart", seed=3)
    n_new = res.starts - res.stall
    assert res.stop_reason == SA.STALLED
    assert res.stall >= max(SA.STALL_MIN, SA.STALL_FACTOR * n_new) > res.stall - 1     # stopped at once
    assert sum(res.hits) <= res.starts and len(res.hits) == len(res.solutions) and min(res.hits) >= 1
    assert res.good_turing == sum(h == 1 for h in res.hits) / res.starts and res.miss_probability is None
    assert res.unseen_share_bound == pytest.approx(1 - 0.05 ** (1 / res.stall))
    again = solve_all(hexapod, hexapod.example_leg_lengths, method="multistart", seed=3)
    assert again.starts == res.starts and [s.x.tolist() for s in again.solutions] == [s.x.tolist() for s in
                                                                                       res.solutions]


def test_limits_max_starts_budget_and_unreachable(rpr, monkeypatch):
    res = solve_all(rpr, rpr.example_leg_lengths, max_starts=7)
    assert res.starts == 7 and res.stop_reason == SA.MAX_STARTS_REACHED
    monkeypatch.setattr(SA, "BATCH", 8)        # batches smaller than the stopping rule's least starts
    res = solve_all(rpr, rpr.example_leg_lengths, budget_s=1e-9)
    assert res.starts == 8 and res.stop_reason == SA.BUDGET_EXHAUSTED            # checked after each batch
    monkeypatch.undo()
    res = solve_all(rpr, [1.0, 1.0, 1.0], method="multistart")     # base joints 200 mm apart: out of reach
    assert res.stop_reason == SA.UNREACHABLE and res.solutions == [] and res.starts == 0
    with pytest.raises(GlpmaError, match="runs counts G3-PCX"):
        solve_all(rpr, rpr.example_leg_lengths, method="multistart", runs=5)
    with pytest.raises(GlpmaError, match="unknown solve_all method"):
        solve_all(rpr, rpr.example_leg_lengths, method="newton")


def test_runs_alone_still_selects_the_papers_g3pcx(rpr):
    res = solve_all(rpr, rpr.example_leg_lengths, runs=5, seed=0)
    assert res.method == "g3pcx" and res.runs == 5


# -- command line ---------------------------------------------------------------------------------------

def run(*args, env=None):
    return subprocess.run([sys.executable, "-m", "glpma_ros", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, timeout=600, env=env)


def test_cli_help_names_every_option():
    p = run("solve-all", "--help")
    assert p.returncode == 0
    for option in ("--legs", "--method", "--exact", "--max-starts", "--budget-s", "--runs", "--seed", "--json"):
        assert option in p.stdout


def test_cli_multistart_json():
    p = run("solve-all", RPR_YAML, "--legs", 100, 120, 150, "--json", "--seed", 1, "--method", "multistart")
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert out["method"] == "multistart" and len(out["solutions"]) == 2 and out["runs"] == out["starts"] > 0
    assert {"miss_probability", "good_turing", "unseen_share_bound", "stop_reason", "evaluations"} <= set(out)
    assert out["miss_probability"] is None                  # not estimable by the multistart (solve_all's docstring)


@needs_msolve
def test_cli_exact_json_and_no_mode():
    p = run("solve-all", RPR_YAML, "--legs", 100, 120, 150, "--exact", "--json")
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert out["method"] == "exact" and out["complex_solutions"] == 6 and len(out["solutions"]) == 2
    p = run("solve-all", RPR_YAML, "--legs", 10, 12, 15, "--exact")
    assert p.returncode == 1 and "none of the 6 complex solutions is real" in p.stderr


@pytest.mark.parametrize("args, words", [
    (["--exact", "--method", "g3pcx"], "exclude each other"),
    (["--runs", 5, "--method", "multistart"], "--runs counts G3-PCX"),
    (["--max-starts", 5, "--method", "g3pcx"], "--max-starts and --budget-s"),
    (["--max-starts", 0], "--max-starts: '0' must be at least 1"),
    (["--budget-s", 0], "--budget-s must be positive"),
])
def test_cli_bad_combinations_exit_2_one_line(args, words):
    p = run("solve-all", RPR_YAML, "--legs", 100, 120, 150, *args)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and words in lines[0], p.stderr


def test_cli_exact_without_the_extra_exit_2_one_line():
    code = ("import sys, glpma_ros.modes.exact as e; e.MSOLVE_DISTRIBUTION = 'glpma-ros-no-such-distribution'; "
            "from glpma_ros.cli.main import main; sys.exit(main(sys.argv[1:]))")
    env = dict(os.environ, PATH="")
    p = subprocess.run([sys.executable, "-c", code, "solve-all", str(RPR_YAML), "--legs", "100", "120", "150",
                        "--exact"], capture_output=True, text=True, cwd=ROOT, timeout=300, env=env)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and "glpma_ros[exact]" in lines[0], p.stderr


def test_cli_no_mode_exit_1_with_the_reason():
    p = run("solve-all", RPR_YAML, "--legs", 1, 1, 1, "--method", "multistart")
    assert p.returncode == 1 and "cannot reach" in p.stderr
    p = run("solve-all", RPR_YAML, "--legs", 1, 1, 1)           # the homotopy: a certificate
    assert p.returncode == 1 and "certified: none of the 6 complex solutions is real" in p.stderr


# -- the node's ~/assembly_modes ---------------------------------------------------------------------------

def test_node_reply_says_how_many_starts():
    svc = FkService({"manipulator_config": str(HEX_YAML)})
    svc.modes.note_input([1.25] * 6, 0)
    result = svc.modes.compute(0)
    assert len(result.poses) == 16 and result.starts == 0          # the homotopy: no random starts
    svc.modes.note(result)
    values = svc.diagnostics().as_dict()
    assert values["assembly modes last starts"] == str(result.starts)
    assert values["assembly modes last"].startswith("16 modes in ")


def test_worker_process_reports_its_starts():
    from glpma_ros.node.modes_worker import ModesWorker
    worker = ModesWorker(RPR_YAML).start()
    try:
        modes = worker([100.0, 120.0, 150.0], SA.MAX_STARTS, 0)
    finally:
        worker.close()
    # the homotopy where a start system exists: certified, no random starts
    assert len(modes) == 2 and modes.starts == 0 and modes.stop_reason == "complete"
    assert modes.miss_probability == 0.0
    model = Planar3RPR(*(np.array(v) for v in _rpr_geometry()))
    here = solve_all(model, [100.0, 120.0, 150.0], seed=0)
    assert_same_modes(model, list(modes), [s.x for s in here.solutions])     # the same modes, to round-off


def _rpr_geometry():
    import yaml
    doc = yaml.safe_load(RPR_YAML.read_text())
    return doc["base"], doc["platform"]
