"""Models: residuals, inverse kinematics, Jacobians, poses, config validation."""
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from glpma_ros.config import load_manipulator, model_from_dict
from glpma_ros.errors import ConfigError, InputError
from glpma_ros.models import Hexapod66, Planar3RPR
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector


def test_rpr_seed_solutions_satisfy_legs(rpr, rpr_solutions):
    for x in rpr_solutions:
        np.testing.assert_allclose(rpr.inverse_kinematics(x), [100, 120, 150], atol=1e-7)
        assert rpr.fitness(x, rpr.example_leg_lengths)[0] < 1e-14


def test_population_fitness_matches_rows(rpr, hexapod, hex_published):
    X = np.vstack([hex_published, hex_published[:1] + 1.0])
    f = hexapod.fitness(X, hexapod.example_leg_lengths)
    for i, x in enumerate(X):
        r = hexapod.residuals(x, hexapod.example_leg_lengths)[0]
        assert f[i] == pytest.approx(float(r @ r), rel=1e-12)


def test_hexapod_degenerate_individual_is_infinite(hexapod):
    x = np.zeros(9)  # B1 = B2 = B3: no frame
    assert hexapod.fitness(x, hexapod.example_leg_lengths)[0] == np.inf


def _random_rotation(rng):
    return rotation_from_vector(rng.normal(size=3))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_hexapod_models_agree_on_leg_lengths(seed):
    """The 9-variable model and the 6-variable pose model give the same legs."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(-500, 500, (6, 3))
    platform = rng.uniform(-300, 300, (6, 3))
    assume(np.linalg.norm(np.cross(platform[1] - platform[0], platform[2] - platform[0])) > 1e3)
    m = Hexapod66(base, platform)
    R, p = _random_rotation(rng), rng.uniform(-200, 200, 3) + [0, 0, 800]
    x = m.pose_variables((R, p))
    legs_pose = np.linalg.norm(p + platform @ R.T - base, axis=1)
    np.testing.assert_allclose(m.inverse_kinematics(x), legs_pose, rtol=1e-12)
    # the 9-variable residuals vanish at the exact pose (to round-off)
    assert np.max(np.abs(m.residuals(x, legs_pose)[0][:6])) < 1e-9
    pose = m.pose(x)
    np.testing.assert_allclose(pose.position, p, atol=1e-9)
    assert np.linalg.norm(pose.orientation) == pytest.approx(1.0)
    np.testing.assert_allclose(matrix_from_quaternion(pose.orientation), R, atol=1e-12)
    np.testing.assert_allclose(m.variables_from_pose(pose.position, pose.orientation), x, atol=1e-9)


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_pose_jacobian_matches_finite_differences(kind, rpr, hexapod, rpr_solutions, hex_published):
    m, x = (rpr, rpr_solutions[0]) if kind == "rpr" else (hexapod, hex_published[3])
    legs = m.inverse_kinematics(x) * 1.01
    state = m.pose_state(x)
    r0, J = m.pose_residuals_jacobian(state, legs)
    h = 1e-6
    for k in range(m.n_pose):
        e = np.zeros(m.n_pose)
        e[k] = h
        rp, _ = m.pose_residuals_jacobian(m.pose_retract(state, e), legs)
        rm, _ = m.pose_residuals_jacobian(m.pose_retract(state, -e), legs)
        np.testing.assert_allclose((rp - rm) / (2 * h), J[:, k], rtol=1e-5, atol=1e-6)


def test_rpr_pose_is_rotation_about_z(rpr):
    pose = rpr.pose(np.array([1.0, 2.0, 0.5]))
    np.testing.assert_allclose(pose.position, [1, 2, 0])
    np.testing.assert_allclose(pose.orientation, [0, 0, math.sin(0.25), math.cos(0.25)])


def test_quaternion_round_trip():
    rng = np.random.default_rng(1)
    for _ in range(50):
        R = _random_rotation(rng)
        np.testing.assert_allclose(matrix_from_quaternion(quaternion_from_matrix(R)), R, atol=1e-12)


GOOD = {"manipulator": "planar_3rpr", "unit": "mm", "base": [[0, 0], [200, 0], [0, 200]],
        "platform": [[0, 0], [50, 0], [40, 40]]}


@pytest.mark.parametrize("change, message", [
    ({"manipulator": "scara"}, "'manipulator' must be one of"),
    ({"unit": "furlong"}, "'unit' must be one of"),
    ({"base": [[0, 0], [200, 0]]}, "'base' must have 3 to 12 points"),
    ({"platform": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]}, "'platform' must have 3 points of 2"),
    ({"platform": [[0, 0], [50, 0], [40, 40], [0, 10]]}, "'platform' must have 3 points of 2"),
    ({"platform": [[0, 0], [50, 0], [100, 0]]}, "collinear"),
    ({"platform": [[0, 0], [0, 0], [40, 40]]}, "coincide"),
    ({"base": [["a", 0], [200, 0], [0, 200]]}, "'base' must be a list"),
    ({"base": [[float("nan"), 0], [200, 0], [0, 200]]}, "non-finite"),
    ({"leg_limits": [100, 50]}, "leg_limits"),
    ({"example_leg_lengths": [1, 2]}, "expected 3 leg lengths"),
])
def test_config_errors_name_the_problem(change, message):
    with pytest.raises(ConfigError, match=message):
        model_from_dict({**GOOD, **change})


def test_config_missing_key_and_unreadable(tmp_path):
    with pytest.raises(ConfigError, match="missing key 'platform'"):
        model_from_dict({k: v for k, v in GOOD.items() if k != "platform"})
    with pytest.raises(ConfigError, match="cannot read"):
        load_manipulator(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("base: [1, 2\n")
    with pytest.raises(ConfigError, match="invalid YAML"):
        load_manipulator(bad)


@pytest.mark.parametrize("legs, message", [
    ([100, 120], "expected 3 leg lengths"),
    ([100, 120, float("nan")], "finite"),
    ([100, 120, float("inf")], "finite"),
    ([100, -120, 150], "positive"),
    ([100, 0, 150], "positive"),
])
def test_bad_legs_rejected_with_reason(rpr, legs, message):
    with pytest.raises(InputError, match=message):
        rpr.check_legs(legs)


def test_leg_limits(rpr):
    m = model_from_dict({**GOOD, "leg_limits": [50, 160]})
    m.check_legs([100, 120, 150])
    with pytest.raises(InputError, match="outside the configured limits"):
        m.check_legs([100, 120, 170])


def test_planar_model_is_planar3rpr(rpr):
    assert isinstance(rpr, Planar3RPR) and rpr.metres_per_unit == 0.001
