"""Property-based fuzzing of the core's edges: arbitrary leg arrays into the
estimator, arbitrary YAML documents into the config loader, arbitrary
arguments into the CLI.  Never an uncaught exception; every rejection names
its reason; no pose for an input that did not converge; no NaN out.
The number of cases tried is printed (``-s``) and asserted."""
import io
import math
from contextlib import redirect_stderr, redirect_stdout

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import GENEROUS_BUDGET_S, RPR_YAML
from glpma_ros.cli import main as cli
from glpma_ros.config import model_from_dict
from glpma_ros.errors import ConfigError, InputError
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.solvers.lm import LEG_RTOL

CASES = {"estimator": 0, "config": 0, "cli": 0}

floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, 2.2e-308, 1e-300, 1e300, 1.7e308, -1.0, 100.0, 120.0, 150.0]),
    st.floats(min_value=1.0, max_value=500.0),
)


@pytest.fixture(scope="module")
def estimator(rpr, rpr_solutions):
    # a generous budget: each input's outcome is decided by the work done, the same on a busy machine
    return Estimator(rpr, initial_pose=rpr_solutions[0], time_budget_s=GENEROUS_BUDGET_S)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(legs=st.lists(floats, min_size=0, max_size=8))
def test_estimator_never_crashes(estimator, legs):
    CASES["estimator"] += 1
    before = None if estimator.last_x is None else estimator.last_x.copy()
    try:
        e = estimator.estimate(legs)
    except InputError as exc:
        assert str(exc) and "\n" not in str(exc)
        np.testing.assert_array_equal(estimator.last_x, before)   # state kept
        return
    assert e.status in ("converged", "no_solution", "budget_exhausted", "near_singular", "max_evals")
    assert (e.pose is not None) == e.converged
    if e.converged:
        assert np.all(np.isfinite(e.x)) and np.all(np.isfinite(e.pose.position))
        assert np.all(np.isfinite(e.pose.orientation))
        # converged: the largest leg residual within LEG_RTOL of the scale (or of the legs, if longer)
        assert e.max_residual <= LEG_RTOL * max(estimator.model.scale, max(legs))
        np.testing.assert_allclose(estimator.model.inverse_kinematics(e.x), legs, rtol=1e-12,
                                   atol=1e-12 * estimator.model.scale)
    else:
        assert e.message
        np.testing.assert_array_equal(estimator.last_x, before)
    assert math.isfinite(e.conditioning)


scalars = st.one_of(st.none(), st.booleans(), st.integers(-10, 10), st.floats(), st.text(max_size=5))
points = st.lists(st.one_of(scalars, st.lists(st.one_of(scalars, st.floats(-500, 500)), max_size=4)), max_size=7)


@st.composite
def documents(draw):
    doc = {}
    for key, strategy in (("manipulator", st.one_of(st.sampled_from(["planar_3rpr", "hexapod_66"]), scalars)),
                          ("unit", st.one_of(st.sampled_from(["mm", "m", "cm"]), scalars)),
                          ("base", points), ("platform", points),
                          ("leg_limits", st.one_of(st.none(), st.lists(scalars, max_size=3))),
                          ("example_leg_lengths", st.one_of(st.none(), st.lists(floats, max_size=7)))):
        if draw(st.booleans()) or key in ("manipulator",):
            doc[key] = draw(strategy)
    return draw(st.one_of(st.just(doc), scalars, st.lists(scalars, max_size=3)))


@settings(max_examples=400, deadline=None)
@given(doc=documents())
def test_config_loader_never_crashes(doc):
    CASES["config"] += 1
    try:
        model = model_from_dict(doc, "fuzz.yaml")
    except ConfigError as exc:
        assert str(exc).startswith("fuzz.yaml: ") and "\n" not in str(exc)
    else:
        assert model.n_legs in (3, 6)


@settings(max_examples=200, deadline=None)
@given(base=st.lists(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=2), min_size=3, max_size=3),
       platform=st.lists(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=2), min_size=3, max_size=3))
def test_degenerate_geometry_rejected_or_usable(base, platform):
    """Coincident or collinear joints: a ConfigError; anything accepted evaluates finitely."""
    CASES["config"] += 1
    try:
        model = model_from_dict({"manipulator": "planar_3rpr", "unit": "mm", "base": base,
                                 "platform": platform}, "geom.yaml")
    except ConfigError as exc:
        assert "coincide" in str(exc) or "collinear" in str(exc)
        return
    assert np.isfinite(model.fitness(np.zeros(3), np.ones(3))[0])


def _yaml_text_documents():
    return st.text(alphabet=st.sampled_from(list("abm:_ -[],.0123456789\n{}'\"#")), max_size=80)


@settings(max_examples=200, deadline=None)
@given(text=_yaml_text_documents())
def test_config_text_never_crashes(tmp_path_factory, text):
    CASES["config"] += 1
    path = tmp_path_factory.mktemp("fuzz") / "c.yaml"
    path.write_text(text)
    from glpma_ros.config import load_manipulator
    try:
        load_manipulator(path)
    except ConfigError as exc:
        assert "\n" not in str(exc)


words = st.one_of(st.sampled_from(["solve", "solve-all", str(RPR_YAML), "--legs", "--json", "--runs", "--seed",
                                   "--solver", "glpma", "--near", "--init-range", "--budget-ms", "--max-evals",
                                   "--tolerance", "--no-polish", "nan", "inf", "-1", "0", "1e309", "100",
                                   "120", "150", "x"]),
                  st.text(max_size=6))


@settings(max_examples=150, deadline=None)
@given(argv=st.lists(words, max_size=9))
def test_cli_never_tracebacks(argv):
    CASES["cli"] += 1
    if "--runs" in argv:   # keep each example quick
        argv = [a if a not in ("100", "120", "150", "1e309") else "1" for a in argv]
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = cli.main([a for a in argv if a not in ("bench", "demo", "node")] + ["--max-evals", "2000"]
                        if argv[:1] == ["solve"] else [a for a in argv if a not in ("bench", "demo", "node")])
    assert code in (0, 1, 2)
    if code == 2:
        lines = err.getvalue().strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:")


def test_report_cases(capsys):
    with capsys.disabled():
        print(f"\nfuzz cases tried: {CASES}")
    assert sum(CASES.values()) >= 1000
