"""Covariance and velocity of the pose (glpma_ros.estimation.covariance, glpma_ros.estimation.velocity) and the node's
pose_estimate_cov / twist_estimate through the service.

* the compiled leg Jacobian equals both models' pose Jacobians;
* Monte Carlo: 2,000 estimator solves (evaluation cap, generous budget) of legs perturbed with
  N(0, sigma^2), at the seed poses and near a singularity of each manipulator, give an empirical
  covariance within 10 % (Frobenius, relative) of the published one, which is symmetric PSD;
* at an exact singularity the covariance is finite, capped, and /diagnostics says so;
* twist from JointState velocities of a known trajectory = the true twist to 1e-9 (relative);
  without velocities, the finite difference of poses, within the trajectory's discretisation error.
"""
import math

import numpy as np
import pytest
import yaml

from conftest import HEX_YAML, RPR_YAML
from glpma_ros.estimation.covariance import UNOBSERVED_VARIANCE, VARIANCE_CAP, PoseJacobian
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.estimation.velocity import finite_difference_twist, rotation_vector_between
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector
from glpma_ros.node.outputs import TWIST_FROM_POSES, TWIST_FROM_VELOCITIES
from glpma_ros.node.service import FkService, JointStateInput

SIGMA_M = 1e-5                 # the parameter's default
MC_SAMPLES = 2000
MC_TOLERANCE = 0.10            # Frobenius, relative
#: a pose "near a singularity": reciprocal condition number of the scaled Jacobian
NEAR_CONDITIONING = 2e-3
#: near a singularity the pose moves ~ sigma / conditioning: a smaller noise keeps it linear
NEAR_SIGMA_M = 1e-8
MAX_EVALS = 20000
GENEROUS_BUDGET_S = 30.0


# -- helpers ---------------------------------------------------------------------------------------------

def known_poses(model, path):
    """(position (config unit), quaternion) of the config's listed solutions."""
    doc = yaml.safe_load(path.read_text())
    if model.kind == "planar_3rpr":
        xs = [np.array([s["x"], s["y"], math.radians(s["theta_deg"])]) for s in doc["real_solutions"]]
    else:
        xs = [np.array(s, dtype=float) for s in doc["published_solutions"]]
    return xs


def scaled_conditioning_and_det(jac, x, model):
    pose = model.pose(x)
    J = jac.at(pose.position * model.metres_per_unit, pose.orientation)[:, jac.columns].copy()
    J[:, jac.columns >= 3] /= jac.length
    s = np.linalg.svd(J, compute_uv=False)
    return s[-1] / s[0], np.linalg.det(J)


def pose_between(model, xa, xb, s):
    """Solver variables of the pose a fraction ``s`` of the way from ``xa`` to ``xb`` (position
    linear, rotation along the geodesic)."""
    pa, pb = model.pose(xa), model.pose(xb)
    w = np.array(rotation_vector_between(pa.orientation, pb.orientation))
    R = rotation_from_vector(s * w) @ matrix_from_quaternion(pa.orientation)
    return model.variables_from_pose((1 - s) * pa.position + s * pb.position, quaternion_from_matrix(R))


def singular_and_near(model, xa, xb):
    """Between two assembly modes whose Jacobian determinants differ in sign: the singular pose
    (bisection on the determinant) and a pose of conditioning NEAR_CONDITIONING before it."""
    jac = PoseJacobian(model)
    lo, hi = 0.0, 1.0
    sign_lo = np.sign(scaled_conditioning_and_det(jac, xa, model)[1])
    assert sign_lo != np.sign(scaled_conditioning_and_det(jac, xb, model)[1])
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.sign(scaled_conditioning_and_det(jac, pose_between(model, xa, xb, mid), model)[1]) == sign_lo:
            lo = mid
        else:
            hi = mid
    singular = pose_between(model, xa, xb, lo)
    a, b = 0.0, lo
    for _ in range(100):
        mid = 0.5 * (a + b)
        if scaled_conditioning_and_det(jac, pose_between(model, xa, xb, mid), model)[0] > NEAR_CONDITIONING:
            a = mid
        else:
            b = mid
    return singular, pose_between(model, xa, xb, a)


def pose_error(model, x_true, x_est):
    """(position (m), rotation vector (rad)) of the estimate relative to the truth, ROS order."""
    pt, pe = model.pose(x_true), model.pose(x_est)
    dp = (np.asarray(pe.position) - np.asarray(pt.position)) * model.metres_per_unit
    return np.concatenate((dp, rotation_vector_between(pt.orientation, pe.orientation)))


def published_covariance(model, x, sigma):
    jac = PoseJacobian(model)
    pose = model.pose(x)
    capped = jac.solve(pose.position, pose.orientation, sigma, None, model.metres_per_unit)
    return jac.covariance.copy(), capped, jac.columns


def monte_carlo(model, x, sigma, seed):
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS, initial_pose=x, seed=seed)
    rng = np.random.default_rng(seed)
    legs = model.inverse_kinematics(x)
    errors = []
    for _ in range(MC_SAMPLES):
        est.reset(x)
        e = est.estimate(legs + rng.normal(0.0, sigma / model.metres_per_unit, legs.size))
        assert e.converged, e.message
        errors.append(pose_error(model, x, e.x))
    return np.cov(np.array(errors).T)


def assert_symmetric_psd(cov, cols):
    """Symmetric; the measured block positive semi-definite to round-off, and nothing couples
    it to the unobserved components."""
    assert np.array_equal(cov, cov.T)
    block = cov[np.ix_(cols, cols)]
    eig = np.linalg.eigvalsh(block)
    assert eig.min() >= -1e-12 * eig.max()
    others = np.setdiff1d(np.arange(6), cols)
    assert not cov[np.ix_(others, cols)].any()
    assert np.all(np.diag(cov)[others] == UNOBSERVED_VARIANCE)
    return block


def check_against_monte_carlo(model, x, sigma, seed):
    cov, capped, cols = published_covariance(model, x, sigma)
    assert not capped
    block = assert_symmetric_psd(cov, cols)
    empirical = monte_carlo(model, x, sigma, seed)[np.ix_(cols, cols)]
    rel = np.linalg.norm(empirical - block) / np.linalg.norm(block)
    print(f"{model.kind}: Monte Carlo vs published covariance, Frobenius relative {rel:.3f}")
    assert rel <= MC_TOLERANCE, (rel, np.diag(empirical), np.diag(block))
    return rel


@pytest.fixture(scope="module")
def rpr_modes(rpr):
    return known_poses(rpr, RPR_YAML)


@pytest.fixture(scope="module")
def hex_modes(hexapod):
    return known_poses(hexapod, HEX_YAML)


# -- the Jacobian ------------------------------------------------------------------------------------------

def test_leg_jacobian_is_the_models_pose_jacobian(rpr, hexapod, rpr_modes, hex_modes):
    for model, xs in ((rpr, rpr_modes), (hexapod, hex_modes)):
        mpu = model.metres_per_unit
        jac = PoseJacobian(model)
        for x in xs:
            pose = model.pose(x)
            legs = model.inverse_kinematics(x)
            J = jac.at(pose.position * mpu, pose.orientation)
            _, Jm = model.pose_residuals_jacobian(model.pose_state(x), legs)
            Jm = Jm.copy()
            Jm[:, 2 if model.kind == "planar_3rpr" else slice(3, 6)] *= mpu   # rotation columns, metres
            np.testing.assert_allclose(J[:, jac.columns], Jm, rtol=0, atol=1e-12)
            if model.kind == "planar_3rpr":
                assert not J[:, 2:5].any()


def test_the_jacobian_is_the_derivative_of_the_legs_for_fixed_axis_rotations(hexapod, hex_modes):
    """Column k of J = d legs / d(twist component k) with R <- exp(w) R (rotations about the
    fixed base axes), by central differences of the inverse kinematics."""
    model, x = hexapod, hex_modes[10]
    mpu, h = model.metres_per_unit, 1e-6
    pose = model.pose(x)
    R = matrix_from_quaternion(pose.orientation)
    J = PoseJacobian(model).at(pose.position * mpu, pose.orientation)
    for k in range(6):
        legs = []
        for sign in (1, -1):
            d = np.zeros(6)
            d[k] = sign * h
            q = quaternion_from_matrix(rotation_from_vector(d[3:]) @ R)
            legs.append(model.inverse_kinematics(model.variables_from_pose(pose.position + d[:3] / mpu, q)) * mpu)
        np.testing.assert_allclose((legs[0] - legs[1]) / (2 * h), J[:, k], atol=1e-7)


# -- covariance ------------------------------------------------------------------------------------------

def test_planar_unobserved_components_get_the_large_variance(rpr, rpr_modes):
    cov, capped, cols = published_covariance(rpr, rpr_modes[0], SIGMA_M)
    for k in (2, 3, 4):
        assert cov[k, k] == UNOBSERVED_VARIANCE
        assert not np.delete(cov[k], k).any()
    assert 0 < cov[0, 0] < 1e-6 and 0 < cov[5, 5] < 1e-6 and not capped


@pytest.mark.parametrize("mode", [0, 1])
def test_3rpr_covariance_matches_monte_carlo_at_the_seed_poses(rpr, rpr_modes, mode):
    check_against_monte_carlo(rpr, rpr_modes[mode], SIGMA_M, seed=mode)


@pytest.mark.parametrize("mode", [10, 0])
def test_hexapod_covariance_matches_monte_carlo_at_published_poses(hexapod, hex_modes, mode):
    check_against_monte_carlo(hexapod, hex_modes[mode], SIGMA_M, seed=mode)


@pytest.mark.parametrize("which", ["planar_3rpr", "hexapod_66"])
def test_covariance_matches_monte_carlo_near_a_singularity(rpr, hexapod, rpr_modes, hex_modes, which):
    model, (xa, xb) = (rpr, (rpr_modes[0], rpr_modes[1])) if which == "planar_3rpr" else \
        (hexapod, (hex_modes[10], hex_modes[11]))
    _, near = singular_and_near(model, xa, xb)
    cond, _ = scaled_conditioning_and_det(PoseJacobian(model), near, model)
    assert cond == pytest.approx(NEAR_CONDITIONING, rel=1e-6)
    check_against_monte_carlo(model, near, NEAR_SIGMA_M, seed=7)
    # the covariance grows towards the singularity: far larger than at the seed pose
    far, _, cols = published_covariance(model, xa, NEAR_SIGMA_M)
    close, _, _ = published_covariance(model, near, NEAR_SIGMA_M)
    block = np.ix_(cols, cols)
    assert np.trace(close[block]) > 100 * np.trace(far[block])


@pytest.mark.parametrize("which", ["planar_3rpr", "hexapod_66"])
def test_at_a_singularity_the_covariance_is_capped_finite_and_reported(rpr, hexapod, rpr_modes, hex_modes,
                                                                       which):
    model, (xa, xb), config = (rpr, (rpr_modes[0], rpr_modes[1]), RPR_YAML) if which == "planar_3rpr" else \
        (hexapod, (hex_modes[10], hex_modes[11]), HEX_YAML)
    singular, _ = singular_and_near(model, xa, xb)
    cov, capped, cols = published_covariance(model, singular, SIGMA_M)
    assert capped and np.all(np.isfinite(cov))
    assert_symmetric_psd(cov, cols)
    lengths = np.where(cols >= 3, PoseJacobian(model).length, 1.0)       # rotations as arcs (m)
    scaled = cov[np.ix_(cols, cols)] * np.outer(lengths, lengths)
    assert np.linalg.eigvalsh(scaled).max() == pytest.approx(VARIANCE_CAP, rel=1e-6)
    # through the node: the pose is published, the covariance capped, /diagnostics says so
    service = FkService({"manipulator_config": str(config), "initial_pose": list(singular), "time_budget_ms": 1000.0})
    out = service.handle(model.inverse_kinematics(singular) * model.metres_per_unit, 1)
    assert out.pose is not None, out.reason
    extras = service.extras(out)
    assert extras.covariance_capped and all(math.isfinite(v) for v in extras.covariance)
    report = service.diagnostics()
    assert "covariance capped" in report.message and report.level == 1
    assert report.as_dict()["covariance capped (singular pose)"] == "1"


# -- velocity -----------------------------------------------------------------------------------------------

OMEGA = 2 * math.pi / 4.0      # the trajectories' angular frequency (one loop in 4 s)
#: stamps are wall-clock times (ns since 1970): differences must not go through float seconds
EPOCH_NS = 1_795_000_000 * 10**9


def rpr_trajectory(x0, scale):
    """t -> (position (config unit), R, velocity (unit/s), angular velocity (rad/s), acceleration)."""
    a, b, c, w = 0.05 * scale, 0.04 * scale, 0.15, OMEGA

    def at(t):
        p = np.array([x0[0] + a * math.sin(w * t), x0[1] + b * math.sin(2 * w * t), 0.0])
        theta = x0[2] + c * math.sin(w * t)
        v = np.array([a * w * math.cos(w * t), 2 * b * w * math.cos(2 * w * t), 0.0])
        acc = np.array([-a * w * w * math.sin(w * t), -4 * b * w * w * math.sin(2 * w * t), 0.0])
        return p, rotation_from_vector(np.array([0.0, 0.0, theta])), v, np.array([0, 0, c * w * math.cos(w * t)]), acc
    return at


def hexapod_trajectory(p0, R0, scale):
    """A helix with a rotation about z and a tilt about x (fixed axes): R = Rz(alpha) Rx(beta) R0."""
    r, h, a, b, w = 0.02 * scale, 0.03 * scale, 0.1, 0.03, OMEGA

    def at(t):
        p = p0 + np.array([r * (math.cos(w * t) - 1), r * math.sin(w * t), h * math.sin(w * t / 4)])
        v = np.array([-r * w * math.sin(w * t), r * w * math.cos(w * t), h * w / 4 * math.cos(w * t / 4)])
        acc = np.array([-r * w * w * math.cos(w * t), -r * w * w * math.sin(w * t),
                        -h * w * w / 16 * math.sin(w * t / 4)])
        alpha, beta = a * math.sin(w * t), b * math.sin(2 * w * t)
        Rz = rotation_from_vector(np.array([0.0, 0.0, alpha]))
        R = Rz @ rotation_from_vector(np.array([beta, 0.0, 0.0])) @ R0
        omega = a * w * math.cos(w * t) * np.array([0.0, 0.0, 1.0]) + 2 * b * w * math.cos(2 * w * t) * Rz[:, 0]
        return p, R, v, omega, acc
    return at


def leg_state(model, p, R, v, omega):
    """Leg lengths and their rates (config unit) from the geometry: l = |p + R CB - A|,
    dl/dt = e . (v + omega x R CB) / l."""
    base, platform = model.base, model.platform
    if base.shape[1] == 2:
        base = np.hstack((base, np.zeros((3, 1))))
        platform = np.hstack((platform, np.zeros((3, 1))))
    w = platform @ R.T
    e = p + w - base
    lengths = np.linalg.norm(e, axis=1)
    rates = np.einsum("ij,ij->i", e, v + np.cross(omega, w)) / lengths
    return lengths, rates


def trajectory_for(model, xs):
    if model.kind == "planar_3rpr":
        return rpr_trajectory(xs[0], model.scale)
    pose = model.pose(xs[10])
    return hexapod_trajectory(np.asarray(pose.position), matrix_from_quaternion(pose.orientation), model.scale)


def joint_state_service(config, x0, **params):
    return FkService({"manipulator_config": str(config), "initial_pose": list(x0), "input_type": "joint_state",
                      "time_budget_ms": 1000.0, **params})


@pytest.mark.parametrize("which", ["planar_3rpr", "hexapod_66"])
def test_twist_from_joint_state_velocities_is_the_true_twist(rpr, hexapod, rpr_modes, hex_modes, which):
    model, xs, config = (rpr, rpr_modes, RPR_YAML) if which == "planar_3rpr" else (hexapod, hex_modes, HEX_YAML)
    mpu = model.metres_per_unit
    at = trajectory_for(model, xs)
    p, R, _, _, _ = at(0.0)
    service = joint_state_service(config, model.variables_from_pose(p, quaternion_from_matrix(R)))
    names = tuple(f"leg_{i + 1}" for i in range(model.n_legs))
    length = model.scale * mpu
    worst = 0.0
    for k, t in enumerate(np.linspace(0.0, 4.0, 41)):
        p, R, v, omega, _ = at(t)
        lengths, rates = leg_state(model, p, R, v, omega)
        if k == 5:   # the analytic leg rates are the derivative of the inverse kinematics
            h = 1e-5
            numeric = (leg_state(model, *at(t + h)[:2], v, omega)[0] - leg_state(model, *at(t - h)[:2], v, omega)[0])
            np.testing.assert_allclose(numeric / (2 * h), rates, rtol=1e-6, atol=1e-9 * model.scale)
        stamp = EPOCH_NS + int(round(t * 1e9))
        out = service.handle(JointStateInput(names, tuple(lengths * mpu), tuple(rates * mpu)), stamp)
        assert out.pose is not None, out.reason
        extras = service.extras(out)
        assert extras.twist_source == TWIST_FROM_VELOCITIES and extras.stamp_ns == stamp
        linear, angular = (np.array(part) for part in extras.twist)
        truth = np.concatenate((v * mpu, length * omega))
        got = np.concatenate((linear, length * angular))
        worst = max(worst, np.linalg.norm(got - truth) / np.linalg.norm(truth))
    print(f"{model.kind}: twist from velocities, worst relative error {worst:.2e}")
    assert worst <= 1e-9, worst
    assert service.diagnostics().as_dict()["twist source"] == TWIST_FROM_VELOCITIES


@pytest.mark.parametrize("which", ["planar_3rpr", "hexapod_66"])
def test_finite_difference_twist_without_velocities(rpr, hexapod, rpr_modes, hex_modes, which):
    """JointStates without velocities at 1 kHz: the twist is the backward difference of the
    poses -- the mean twist of each interval to round-off, and within dt/2 * max acceleration
    of the true twist at the stamp."""
    model, xs, config = (rpr, rpr_modes, RPR_YAML) if which == "planar_3rpr" else (hexapod, hex_modes, HEX_YAML)
    mpu, dt = model.metres_per_unit, 1e-3
    at = trajectory_for(model, xs)
    p, R, _, _, _ = at(0.0)
    service = joint_state_service(config, model.variables_from_pose(p, quaternion_from_matrix(R)))
    names = tuple(f"leg_{i + 1}" for i in range(model.n_legs))
    times = np.arange(0.0, 4.0, 0.05)[:, None] + np.array([0.0, dt])      # pairs of inputs dt apart
    grid, h = np.linspace(0, 4, 4001), 1e-6
    acc_max = max(np.linalg.norm(at(t)[4]) for t in grid) * mpu
    angular_acc_max = max(np.linalg.norm(at(t + h)[3] - at(t - h)[3]) / (2 * h) for t in grid)
    for t0, t1 in times:
        published = []
        for t in (t0, t1):
            p, R, v, omega, _ = at(t)
            out = service.handle(JointStateInput(names, tuple(leg_state(model, p, R, v, omega)[0] * mpu)),
                                 EPOCH_NS + int(round(t * 1e9)))
            assert out.pose is not None, out.reason
            published.append(service.extras(out))
        extras = published[1]
        assert extras.twist_source == TWIST_FROM_POSES
        linear, angular = (np.array(part) for part in extras.twist)
        p0, R0, _, _, _ = at(t0)
        p1, R1, v1, omega1, _ = at(t1)
        mean_v = (p1 - p0) * mpu / dt
        mean_w = np.array(rotation_vector_between(quaternion_from_matrix(R0), quaternion_from_matrix(R1))) / dt
        np.testing.assert_allclose(linear, mean_v, rtol=0, atol=1e-6 * np.linalg.norm(mean_v) + 1e-12)
        np.testing.assert_allclose(angular, mean_w, rtol=0, atol=1e-6 * np.linalg.norm(mean_w) + 1e-12)
        assert np.linalg.norm(linear - v1 * mpu) <= 0.5 * dt * acc_max * 1.01 + 1e-9
        assert np.linalg.norm(angular - omega1) <= 0.5 * dt * angular_acc_max * 1.05 + 1e-9
    assert service.diagnostics().as_dict()["twist source"] == TWIST_FROM_POSES


def test_finite_difference_of_poses_is_exact_for_constant_twist():
    v, w, dt = np.array([0.1, -0.2, 0.3]), np.array([0.4, -0.1, 0.25]), 0.01
    R0 = rotation_from_vector(np.array([0.3, -1.0, 2.0]))
    R1 = rotation_from_vector(w * dt) @ R0                 # fixed-axis rotation by w dt
    q0, q1 = quaternion_from_matrix(R0), quaternion_from_matrix(R1)
    linear, angular = finite_difference_twist((1.0, 2.0, 3.0), q0, tuple(np.array([1.0, 2.0, 3.0]) + v * dt),
                                              -q1, dt)   # the sign of a quaternion does not matter
    np.testing.assert_allclose(linear, v, atol=1e-12)
    np.testing.assert_allclose(angular, w, atol=1e-12)
    assert rotation_vector_between(q0, q0) == (0.0, 0.0, 0.0)
    big = rotation_from_vector(np.array([0.0, 3.0, 0.0])) @ R0
    np.testing.assert_allclose(rotation_vector_between(q0, quaternion_from_matrix(big)), [0.0, 3.0, 0.0], atol=1e-12)
