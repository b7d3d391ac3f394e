"""The parameter homotopy (glpma_ros/modes/homotopy.py): every assembly mode with a root-count certificate.

Dietmaier's 6-6 with 40 real modes for every seed; 50 random 3-RPRs and 50 random 6-6s whose real modes
msolve certified (test/data/homotopy_cases.json, written by tools/homotopy_cases.py; a few fresh ones against
msolve itself where the exact extra is installed); the coincident-joint designs and redundant legs; targets
next to a fold (two modes merging): the right count or ``complete: false``, never a silent miss; the
incomplete answer and its fallback; the command line."""
import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from conftest import HAVE_MSOLVE, ROOT, RPR_YAML, needs_msolve
from glpma_ros.config import load_manipulator, model_from_dict, resolve_config
from glpma_ros.models import Hexapod66, Planar3RPR
from glpma_ros.models.random_geometry import GENERATORS, random_hexapod_33, random_hexapod_63
from glpma_ros.modes import homotopy as H
from glpma_ros.modes import monodromy, path_tracker
from glpma_ros.modes.homotopy_families import Planar3RPRFamily
from glpma_ros.modes.multistart import default_method, solve_all

DATA = ROOT / "test" / "data" / "homotopy_cases.json"
CASES = json.loads(DATA.read_text())["cases"]
MODELS = {"planar_3rpr": Planar3RPR, "hexapod_66": Hexapod66}
#: modes match when their platform joints are within this share of the scale: both sides are polished to
#: round-off, so they agree to about 1e-12 of the scale; 1e-6 leaves room for ill-conditioned modes
MATCH_RELATIVE = 1e-6

#: Dietmaier 1998, "The Stewart-Gough platform of general geometry can have 40 real postures" (metres; the
#: geometry as in martyushev/fkSGP genSGP.py, type 100)
DIETMAIER = {"manipulator": "hexapod_66", "unit": "m",
             "base": [[0, 0, 0], [1.107915, 0, 0], [0.549094, 0.756063, 0], [0.735077, -0.223935, 0.525991],
                      [0.514188, -0.526063, -0.368418], [0.590473, 0.094733, -0.205018]],
             "platform": [[0, 0, 0], [0.542805, 0, 0], [0.956919, -0.528915, 0], [0.665885, -0.353482, 1.402538],
                          [0.478359, 1.158742, 0.107672], [-0.137087, -0.235121, 0.353913]],
             "leg_limits": [0.1, 3.0]}
DIETMAIER_LEGS = [1.0, 0.645275, 1.086284, 1.503439, 1.281933, 0.771071]
#: seeds (gammas and patches) tried on Dietmaier's case
DIETMAIER_SEEDS = range(10)


def assert_same_modes(model, found, certified):
    """One-to-one within MATCH_RELATIVE of the scale: nothing missed, nothing spurious."""
    found, certified = [np.asarray(x) for x in found], [np.asarray(x) for x in certified]
    assert len(found) == len(certified), (len(found), len(certified))
    if not certified:
        return
    D = np.array([[model.distance(f, c) for c in certified] for f in found])
    assert np.all(D.min(axis=1) <= MATCH_RELATIVE * model.scale), D.min(axis=1)
    assert sorted(D.argmin(axis=1)) == list(range(len(certified)))


@pytest.fixture(scope="module")
def dietmaier():
    return model_from_dict(DIETMAIER)


def test_start_systems_hold_every_solution_of_their_generic_member():
    for name, count in (("planar_3rpr", 6), ("hexapod_66", 40)):
        start = monodromy.load_start_system(name)
        assert start.solutions.shape == (count, start.family.n_unknowns)
        Q = start.family.quadrics(start.params)
        w = np.concatenate([start.solutions, np.ones((count, 1))], axis=1)
        # residuals of a solution polished in double precision: round-off of coefficients of order one
        assert np.abs(np.einsum("pm,imn,pn->pi", w, Q, w)).max() < 1e-9
        assert len(path_tracker.distinct(start.solutions)) == count


def test_dietmaier_forty_of_forty_complete_for_every_seed(dietmaier):
    for seed in DIETMAIER_SEEDS:
        res = solve_all(dietmaier, DIETMAIER_LEGS, method="homotopy", seed=seed)
        assert res.complete and not res.fallback, seed
        assert (res.paths, res.complex_solutions, res.real_solutions) == (40, 40, 40), seed
        for s in res.solutions:      # polished to round-off: metres, a few units of 1e-16 per leg
            assert np.max(np.abs(dietmaier.inverse_kinematics(s.x) - DIETMAIER_LEGS)) < 1e-9


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c['kind']}-{c['seed']}-{len(c['modes'])}modes")
def test_random_geometries_match_msolve_s_certified_modes(case):
    model = MODELS[case["kind"]](np.array(case["base"]), np.array(case["platform"]))
    res = solve_all(model, case["legs"], method="homotopy", seed=case["seed"])
    assert res.complete and not res.fallback
    assert res.complex_solutions == case["complex_solutions"]
    assert_same_modes(model, [s.x for s in res.solutions], case["modes"])


def test_the_stored_cases_are_fifty_of_each_kind():
    kinds = [c["kind"] for c in CASES]
    assert kinds.count("planar_3rpr") == 50 and kinds.count("hexapod_66") == 50


@needs_msolve
@pytest.mark.parametrize("kind", ["planar_3rpr", "hexapod_66", "hexapod_63", "hexapod_33"])
def test_fresh_geometries_match_msolve(kind):
    generator = {"hexapod_63": random_hexapod_63, "hexapod_33": random_hexapod_33}.get(kind) or GENERATORS[kind]
    rng = np.random.default_rng(3434)
    for _ in range(3):
        model, legs, _ = generator(rng)
        res = solve_all(model, legs, method="homotopy", seed=1)
        certified = solve_all(model, legs, method="exact")
        assert res.complete and not res.fallback
        assert res.complex_solutions == certified.complex_solutions
        assert_same_modes(model, [s.x for s in res.solutions], [s.x for s in certified.solutions])


def test_coincident_joint_designs_are_certified_by_their_sixteen():
    for config in ("hexapod_63_stewart", "hexapod_33_octahedral"):
        model = load_manipulator(resolve_config(config))
        legs = model.example_leg_lengths
        res = solve_all(model, legs, method="homotopy", seed=0)
        assert res.complete and res.complex_solutions == H.COINCIDENT_ROOT_COUNT and res.paths == 40
        assert res.solutions
        for s in res.solutions:      # config unit mm: round-off of legs of hundreds of mm
            assert np.max(np.abs(model.inverse_kinematics(s.x) - legs)) < 1e-9


def test_redundant_legs_keep_the_consistent_modes():
    model = load_manipulator(resolve_config("hexapod_7legs"))
    x0 = np.array(yaml.safe_load(resolve_config("hexapod_7legs").read_text())["published_solutions"][0])
    legs = model.inverse_kinematics(x0)
    res = solve_all(model, legs, method="homotopy", seed=0)
    assert res.method == "homotopy" and res.solutions
    # every mode explains all seven legs to round-off (exact legs), and the pose of the legs is one of them
    for s in res.solutions:
        assert np.max(np.abs(model.inverse_kinematics(s.x) - legs)) < 1e-6
    assert min(model.distance(s.x, x0) for s in res.solutions) < 1e-6 * model.scale


# -- near a fold ---------------------------------------------------------------------------------------------
def _fold(model, legs_a, legs_b, seed=0, iterations=60):
    """The legs on the segment a -> b where the number of real modes changes, by bisection on the homotopy's
    complete counts (stopped where the two merging modes are too close for a complete answer), and the
    counts on either side."""
    def count(s):
        res = H.solve(model, (1 - s) * legs_a + s * legs_b, seed=seed)
        return len(res.real) if res.complete else None
    lo, hi = 0.0, 1.0
    n_lo, n_hi = count(lo), count(hi)
    assert None not in (n_lo, n_hi) and n_lo != n_hi
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        n = count(mid)
        if n is None:
            break
        if n == n_lo:
            lo = mid
        else:
            hi, n_hi = mid, n
    return lo, hi, n_lo, n_hi


def _segment_with_a_fold(model, rng):
    """Legs of a random pose and legs scaled until the count of real modes changes."""
    gen = GENERATORS[model.kind]
    while True:
        model, legs, _ = gen(rng)
        n0 = len(H.solve(model, legs).real)
        for factor in (0.9, 0.8, 1.1, 1.2, 0.7, 1.3):
            legs_b = legs * factor
            if len(H.solve(model, legs_b).real) != n0:
                return model, legs, legs_b


@pytest.mark.parametrize("kind", ["planar_3rpr", "hexapod_66"])
def test_near_a_fold_the_count_is_right_or_incomplete(kind):
    model, legs_a, legs_b = _segment_with_a_fold(GENERATORS[kind](np.random.default_rng(7))[0],
                                                 np.random.default_rng(34))
    lo, hi, n_lo, n_hi = _fold(model, legs_a, legs_b)
    assert abs(n_lo - n_hi) == 2                      # real modes are born and die in pairs
    for k in (4, 6, 8, 10, 12):       # from a ten-thousandth of the segment to round-off of the fold
        for s, n in ((lo - 10.0 ** -k, n_lo), (hi + 10.0 ** -k, n_hi)):
            res = H.solve(model, (1 - s) * legs_a + s * legs_b, seed=k)
            if res.complete:           # never a silent miss: the count of the side
                assert len(res.real) == n, (k, s)
            else:
                assert res.paths_failed or res.complex_solutions < res.root_count
    if HAVE_MSOLVE:                    # and where msolve can tell, the answer is msolve's (a 6-6 takes msolve
        #                                a minute on a busy machine: one side)
        for s in (lo - 1e-6, hi + 1e-6)[:2 if kind == "planar_3rpr" else 1]:
            legs = (1 - s) * legs_a + s * legs_b
            res = solve_all(model, legs, method="homotopy")
            certified = solve_all(model, legs, method="exact")
            assert res.complete
            assert_same_modes(model, [x.x for x in res.solutions], [x.x for x in certified.solutions])


# -- an incomplete answer -----------------------------------------------------------------------------------
def test_failed_paths_are_named_and_never_certified(dietmaier, monkeypatch):
    starved = path_tracker.SETTINGS.copy()
    starved[9] = 3                                     # MAX_STEPS: three steps cannot reach t = 1
    monkeypatch.setattr(H, "SETTINGS", starved)
    monkeypatch.setattr(H, "CAREFUL_SETTINGS", starved)
    res = H.solve(dietmaier, np.array(DIETMAIER_LEGS))
    assert not res.complete and res.paths_failed and res.complex_solutions < 40
    assert set(res.paths_failed) <= set(range(40)) and res.outcomes.get("max_steps")
    full = solve_all(dietmaier, DIETMAIER_LEGS, method="homotopy")
    if HAVE_MSOLVE:                                    # the fallback: msolve's certified modes
        assert full.complete and full.fallback == "exact" and full.real_solutions == 40
    else:
        assert not full.complete and full.paths_failed


# -- defaults and the command line -------------------------------------------------------------------------------
def test_homotopy_is_the_default_where_a_start_system_exists(rpr, hexapod):
    assert default_method(rpr) == default_method(hexapod) == "homotopy"
    res = solve_all(rpr, rpr.example_leg_lengths)
    assert res.method == "homotopy" and res.complete and res.real_solutions == 2
    assert solve_all(rpr, rpr.example_leg_lengths, max_starts=50).method == "multistart"


def _run(*args):
    return subprocess.run([sys.executable, "-m", "glpma_ros", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, timeout=600)


def test_cli_homotopy_json_and_text(tmp_path):
    config = tmp_path / "dietmaier.yaml"
    config.write_text(json.dumps(DIETMAIER))            # JSON is YAML
    p = _run("solve-all", config, "--legs", *DIETMAIER_LEGS, "--json", "--seed", 2)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert out["method"] == "homotopy" and out["complete"] is True and out["paths_failed"] == []
    assert (out["paths"], out["complex_solutions"], out["real_solutions"], len(out["solutions"])) == (40, 40, 40, 40)
    assert {"runs", "elapsed_s", "load_s", "evaluations"} <= set(out)
    p = _run("solve-all", RPR_YAML, "--legs", 100, 120, 150, "--method", "homotopy")
    assert p.returncode == 0, p.stderr
    assert "2 distinct real assembly modes from 6 homotopy paths" in p.stdout and "complete:" in p.stdout
    p = _run("solve-all", RPR_YAML, "--legs", 10, 12, 15)
    assert p.returncode == 1 and "certified: none of the 6 complex solutions is real" in p.stderr


def test_map_counts_with_the_homotopy(tmp_path, rpr):
    """glpma-fk map --method homotopy: every count of a small 3-RPR map off its singular lines is what
    solve-all's homotopy gives at that point's legs (the same seed per point) and is certified."""
    from glpma_tools.workspace_map.grid import MapSpec, point_seed, pose_variables
    args = [RPR_YAML, "--out", tmp_path, "--limits", 40, 80, 10, 30, "--resolution", 3, 3, "--workers", 1, "--json",
            "--method", "homotopy", "--at", "theta=0"]
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "map", *map(str, args)], capture_output=True, text=True,
                       cwd=ROOT, timeout=600)
    assert p.returncode == 0, p.stderr
    summary = json.loads(p.stdout)
    assert summary["method"] == "the parameter homotopy" and summary["uncertified"] == {}
    with np.load(tmp_path / "assembly_modes.npz") as f:
        counts = f["counts"]
        assert np.all(f["certified"] == 1)
    spec = MapSpec("planar_3rpr", ("x", "y"), ((40.0, 80.0), (10.0, 30.0)), (3, 3), (("theta", 0.0),), 0, 0,
                   "homotopy")
    for index in range(spec.n_points):
        legs = rpr.inverse_kinematics(pose_variables(rpr, spec.coordinates(index)))
        res = solve_all(rpr, legs, method="homotopy", seed=point_seed(0, index))
        assert res.complete and counts.ravel()[index] == res.real_solutions


# -- the shipped maps against msolve ------------------------------------------------------------------------------
MAP_DATA = ROOT / "test" / "data" / "homotopy_map_cases.json"
MAP_CASES = json.loads(MAP_DATA.read_text())["maps"]
#: the 6-6 slice's points where the multistart counted 10 and msolve certifies 12 (grid indices)
SLICE_TEN_POINTS = {5745, 6050}
#: points of the 6-6 slice's sample the homotopy may leave uncertified: on the first 1,414 points of that map,
#: 4.5 % were before the confirming homotopies were repeated, and 5 of the 25 first of them after
MAX_UNCERTIFIED_66 = 3


@pytest.mark.parametrize("config", sorted(MAP_CASES))
def test_default_maps_count_msolve_s_certified_modes(config):
    """glpma-fk map CONFIG (its defaults: the homotopy) at 50 sampled grid points and the named ones: the count
    msolve certified there (test/data/homotopy_map_cases.json, tools/homotopy_map_cases.py), no double mode, and
    the homotopy's own certificate at (nearly) every point: all of them on the 3-RPR (root count 6); on the seed
    6-6, a design with 28 finite poses certified by every path accounted for, the confirming homotopies may
    disagree at a few points (a point so marked is the map's "not certified" class, never a silent miss)."""
    from glpma_tools.workspace_map.cli import build_parser, make_spec
    from glpma_tools.workspace_map.grid import solve_point
    model = load_manipulator(resolve_config(config))
    spec = make_spec(model, build_parser().parse_args([config, "--out", "unused"]))
    assert spec.method == "homotopy"
    points = MAP_CASES[config]["points"]
    assert sum(not c.get("named") for c in points) == 50
    if config == "hexapod_66_rolland":
        assert {c["index"] for c in points if c.get("named")} == SLICE_TEN_POINTS
    uncertified = []
    for case in points:
        coords = spec.coordinates(case["index"])
        # the grid is the one certified: its coordinates are computed by the same linspace, so they agree to
        # round-off of the config's numbers
        assert all(abs(coords[k] - v) <= 1e-9 * (1.0 + abs(v)) for k, v in case["coordinates"].items())
        count, _, _, double, certified = solve_point(model, spec, case["index"])
        assert (count, double) == (case["real_solutions"], 0), case["index"]
        if certified != 1:
            uncertified.append(case["index"])
    assert len(uncertified) <= (0 if config == "planar_3rpr_seed" else MAX_UNCERTIFIED_66), uncertified


def test_the_documented_start_system_build_gives_every_solution_of_a_generic_member(tmp_path):
    """``python -m glpma_ros.modes.monodromy --build-start-systems --family planar_3rpr --out DIR``: the 6 solutions
    of a generic complex 3-RPR, each a root of the family's quadrics at the stored member; the shipped file is
    untouched."""
    shipped = (monodromy.START_SYSTEMS / "planar_3rpr.npz").read_bytes()
    p = subprocess.run([sys.executable, "-m", "glpma_ros.modes.monodromy", "--build-start-systems",
                        "--family", "planar_3rpr", "--out", str(tmp_path)], cwd=ROOT, capture_output=True,
                       text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert sorted(f.name for f in tmp_path.iterdir()) == ["planar_3rpr.npz"]
    data = np.load(tmp_path / "planar_3rpr.npz")
    z = data["solutions"]
    assert int(data["root_count"]) == 6 and z.shape == (6, 4)
    assert len(path_tracker.distinct(z)) == 6
    Q = Planar3RPRFamily().quadrics(data["params"])
    w = np.concatenate([z, np.ones((6, 1))], axis=1)
    # the endpoints are Newton-polished in double precision: residuals at round-off of order-one coordinates
    assert np.abs(np.einsum("pm,imn,pn->pi", w, Q, w)).max() < 1e-9
    assert (monodromy.START_SYSTEMS / "planar_3rpr.npz").read_bytes() == shipped
    bad = subprocess.run([sys.executable, "-m", "glpma_ros.modes.monodromy", "--build-start-systems",
                          "--family", "delta", "--out", str(tmp_path)], cwd=ROOT, capture_output=True, text=True,
                         timeout=120)
    assert bad.returncode == 2 and "invalid choice: 'delta'" in bad.stderr
