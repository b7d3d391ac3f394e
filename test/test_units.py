"""Unit-proof numerics: the same manipulator written in mm, cm and m gives the same pose (in its unit),
leg residuals at round-off relative to its scale, and the same work (evaluation counts), cold and warm."""
import numpy as np
import pytest
import yaml

from conftest import HEX_YAML, RPR_YAML
from glpma_ros.config import model_from_dict
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.solvers import local
from glpma_tools.sim.trajectories import variables_along

#: config unit -> length of one millimetre in it
PER_MM = {"mm": 1.0, "cm": 0.1, "m": 0.001}
ROUND_OFF = 1e-12


def scaled(path, unit):
    """The config at ``path`` (in mm) rewritten in ``unit``."""
    doc = yaml.safe_load(path.read_text())
    f = PER_MM[unit]
    doc = dict(doc, unit=unit, base=(np.array(doc["base"]) * f).tolist(),
               platform=(np.array(doc["platform"]) * f).tolist(),
               example_leg_lengths=[v * f for v in doc["example_leg_lengths"]],
               leg_limits=[v * f for v in doc["leg_limits"]])
    return model_from_dict(doc, f"{path.name} in {unit}")


def in_mm(model, x):
    """Solver variables converted back to mm (3-RPR theta stays in radians)."""
    f = np.full(model.n_vars, 1.0 / PER_MM[model.unit])
    if model.kind == "planar_3rpr":
        f[2] = 1.0
    return np.asarray(x) * f


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rpr_cold_estimate_is_the_same_in_mm_cm_and_m(seed):
    results = {}
    for unit in PER_MM:
        model = scaled(RPR_YAML, unit)
        legs = np.array([100.0, 120.0, 150.0]) * PER_MM[unit]
        e = Estimator(model, seed=seed, time_budget_s=10.0).estimate(legs)     # generous: work decides
        assert e.converged, (unit, e.message)
        assert e.max_residual <= ROUND_OFF * model.scale
        assert np.max(np.abs(model.inverse_kinematics(e.x) - legs)) <= ROUND_OFF * model.scale
        results[unit] = (in_mm(model, e.x), e.evaluations)
    x_mm, n_mm = results["mm"]
    for unit, (x, n) in results.items():
        np.testing.assert_allclose(x, x_mm, atol=1e-9)        # the same assembly mode, same pose
        assert abs(n - n_mm) <= 0.1 * n_mm, (unit, n, n_mm)   # the same work


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_warm_tracking_is_the_same_in_mm_cm_and_m(kind, rpr, rpr_solutions, hexapod, hex_published):
    from glpma_ros.solvers.refine import polish
    if kind == "rpr":
        truth_mm = variables_along(rpr, rpr_solutions[0], 100)
    else:
        x0, *_ = polish(hexapod, hex_published[7], hexapod.example_leg_lengths, np.random.default_rng(0))
        truth_mm = variables_along(hexapod, x0, 100)
    runs = {}
    for unit in PER_MM:
        model = scaled(RPR_YAML if kind == "rpr" else HEX_YAML, unit)
        truth = truth_mm / in_mm(model, np.ones(model.n_vars))
        est = Estimator(model, initial_pose=truth[0], time_budget_s=10.0)
        xs, evals = [], []
        for x in truth[1:]:
            legs = model.inverse_kinematics(x)
            e = est.estimate(legs)
            assert e.converged and e.start == "warm"
            assert e.max_residual <= ROUND_OFF * model.scale
            assert model.distance(e.x, x) <= ROUND_OFF * model.scale
            xs.append(in_mm(model, e.x))
            evals.append(e.evaluations)
        runs[unit] = (np.array(xs), np.array(evals))
    scale_mm = scaled(RPR_YAML if kind == "rpr" else HEX_YAML, "mm").scale
    for unit, (xs, evals) in runs.items():
        np.testing.assert_allclose(xs, runs["mm"][0], atol=ROUND_OFF * scale_mm)
        # the same work: a step may take one evaluation more or less where round-off decides the last test
        assert np.max(np.abs(evals - runs["mm"][1])) <= 1, unit


def test_local_solve_converges_to_the_same_relative_residual_in_every_unit():
    for unit, f in PER_MM.items():
        model = scaled(RPR_YAML, unit)
        x0 = np.array([50.0 * f, 80.0 * f, -0.5])
        r = local.local_solve(model, x0, np.array([100.0, 120.0, 150.0]) * f)
        assert r.converged and r.max_residual <= ROUND_OFF * model.scale
        assert r.nit <= 8
