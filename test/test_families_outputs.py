"""The actuated families' pose covariance and twist (glpma_ros.estimation.covariance with the actuated Jacobian
dq/d(p, w)), for every shipped family config: checked against finite differences of the inverse kinematics,
in the core and through the service (the node's outputs, transport-free)."""
import math

import numpy as np
import pytest
import yaml

from conftest import CONFIG, GENEROUS_BUDGET_MS
from glpma_ros.config import load_manipulator
from glpma_ros.estimation.covariance import UNOBSERVED_VARIANCE, PoseJacobian
from glpma_ros.models.families import is_family
from glpma_ros.models.legs import REVOLUTE
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix
from glpma_ros.node.outputs import TWIST_FROM_VELOCITIES
from glpma_ros.node.params import DEFAULT_ANGLE_NOISE_RAD
from glpma_ros.node.service import FkService

#: every shipped config of an actuated family (a family added with its config is tested here as well)
FAMILY_CONFIGS = sorted(p.name for p in CONFIG.glob("*.yaml") if is_family(yaml.safe_load(p.read_text())))
#: central-difference step of the pose (m; rad for rotations): the truncation error (step^2 times the third
#: derivative, at the robots' 0.1-1 m sizes) and the round-off (1e-16 / step) both stay below 1e-8 relative
STEP = 1e-5
#: the finite-difference Jacobian agrees to this share of its largest entry (truncation and round-off above)
FD_REL = 1e-6
#: a length leg's noise (m) and a revolute actuator's (rad) in the tests: different, so each is seen to count
LEG_NOISE_M = 1e-5


def _rotation(w):
    """The rotation matrix of the rotation vector ``w`` (Rodrigues)."""
    angle = float(np.linalg.norm(w))
    if angle == 0.0:
        return np.eye(3)
    k = np.asarray(w) / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def actuators_si(model, x):
    """The actuator readings of solver variables ``x`` in SI (rad, m), as on the topics."""
    return model.readings_to_si(model.actuator_positions(x))


def numeric_jacobian(model, x, columns):
    """d q / d(p, w) (SI) by central differences of the inverse kinematics: a displacement of the platform origin
    and a rotation about the fixed base axes, the pose components ``columns`` (ROS order)."""
    pose = model.pose(x)
    R0, mpu = matrix_from_quaternion(pose.orientation), model.metres_per_unit
    J = np.zeros((model.n_legs, 6))
    for c in columns:
        q = []
        for sign in (1.0, -1.0):
            d = np.zeros(6)
            d[c] = sign * STEP
            p = np.asarray(pose.position) + d[:3] / mpu
            xs = model.variables_from_pose(p, quaternion_from_matrix(_rotation(d[3:]) @ R0))
            q.append(actuators_si(model, xs))
        J[:, c] = (q[0] - q[1]) / (2 * STEP)
    return J


def noise_of(model):
    return np.where(model.actuators == REVOLUTE, DEFAULT_ANGLE_NOISE_RAD, LEG_NOISE_M)


@pytest.fixture(scope="module", params=FAMILY_CONFIGS)
def family(request):
    model = load_manipulator(CONFIG / request.param)
    x = np.array(model.known_solutions[0] if model.known_solutions is not None else model.home_variables())
    return model, x


def test_every_family_is_tested():
    assert {"delta_irb360.yaml", "rus6_simulator.yaml", "planar_3rrr_symmetric.yaml"} <= set(FAMILY_CONFIGS)


def test_actuated_jacobian_is_the_inverse_kinematics_derivative(family):
    model, x = family
    jac = PoseJacobian(model)
    pose, legs = model.pose(x), model.inverse_kinematics(x)
    J = jac.at(np.asarray(pose.position) * model.metres_per_unit, pose.orientation, legs)
    expected = numeric_jacobian(model, x, jac.columns)
    assert np.max(np.abs(J[:, jac.columns] - expected[:, jac.columns])) <= FD_REL * np.max(np.abs(expected))


def test_covariance_and_twist_of_the_actuator_noise(family):
    """Sigma = (J^T W J)^-1 with W = diag(1 / sigma_i^2) (each actuator's own noise) on the measured columns; the
    twist solves J t = dq/dt; the rest: a translating platform's rotations are fixed (zero), a planar one's
    off-plane components unobserved."""
    model, x = family
    jac = PoseJacobian(model)
    pose, legs = model.pose(x), model.inverse_kinematics(x)
    J = numeric_jacobian(model, x, jac.columns)[:, jac.columns]
    sigma = noise_of(model)
    expected = np.linalg.inv(J.T @ (J / sigma[:, None] ** 2))
    rng = np.random.default_rng(3)
    true_twist = rng.normal(scale=0.1, size=jac.columns.size)
    capped = jac.solve(np.asarray(pose.position), np.asarray(pose.orientation), LEG_NOISE_M, J @ true_twist,
                       model.metres_per_unit, legs, DEFAULT_ANGLE_NOISE_RAD)
    assert not capped
    cov = jac.covariance
    # the finite-difference Jacobian's relative error (FD_REL) enters the inverse about as many times over as
    # the condition number of the weighted Jacobian (below 1e3 at the configs' known solutions)
    tol = 1e3 * FD_REL
    assert np.allclose(cov[np.ix_(jac.columns, jac.columns)], expected, rtol=tol, atol=tol * np.abs(expected).max())
    assert np.allclose(jac.twist[jac.columns], true_twist, rtol=tol, atol=tol * np.abs(true_twist).max())
    others = [c for c in range(6) if c not in jac.columns]
    translation = model.n_vars == 3 and model.dim == 3
    assert np.all(np.diag(cov)[others] == (0.0 if translation else UNOBSERVED_VARIANCE))
    assert np.all(jac.twist[others] == 0.0)
    assert np.allclose(cov, cov.T, rtol=0, atol=1e-12 * np.abs(cov).max())   # symmetric: round-off only


def test_revolute_noise_scales_the_covariance(family):
    """Every actuator revolute: twice the angle noise, four times the covariance (round-off only)."""
    model, x = family
    if not np.all(model.actuators == REVOLUTE):
        pytest.skip("a family with other actuators: the leg noise counts too")
    jac = PoseJacobian(model)
    pose, legs = model.pose(x), model.inverse_kinematics(x)
    covs = []
    for s in (DEFAULT_ANGLE_NOISE_RAD, 2 * DEFAULT_ANGLE_NOISE_RAD):
        jac.solve(np.asarray(pose.position), np.asarray(pose.orientation), LEG_NOISE_M, None,
                  model.metres_per_unit, legs, s)
        covs.append(jac.covariance.copy())
    m = np.ix_(jac.columns, jac.columns)
    assert np.allclose(covs[1][m], 4 * covs[0][m], rtol=1e-9, atol=0)


def test_service_publishes_covariance_and_twist_of_the_joint_velocities(family):
    """Through the node's service: a JointState with the actuators' positions (rad) and velocities (rad/s) gives
    pose_estimate_cov's covariance and twist_estimate from the joint velocities, the model's ones at the pose."""
    model, x = family
    names = [f"act_{i + 1}" for i in range(model.n_legs)]
    svc = FkService({"manipulator_config": str(model.source), "joint_names": names,
                     "input_type": "joint_state", "time_budget_ms": GENEROUS_BUDGET_MS,
                     "initial_pose": [float(v) for v in x], "actuator_noise_std": DEFAULT_ANGLE_NOISE_RAD,
                     "leg_noise_std": LEG_NOISE_M})
    q = actuators_si(model, x)
    jac = PoseJacobian(model)
    J = numeric_jacobian(model, x, jac.columns)
    true_twist = np.zeros(6)
    true_twist[jac.columns] = np.random.default_rng(5).normal(scale=0.05, size=jac.columns.size)
    out = svc.handle_joint_state(names, q.tolist(), 1_000, velocities=(J @ true_twist).tolist())
    assert out.pose is not None, out.reason
    extras = svc.extras(out)
    assert extras.covariance is not None and extras.twist_source == TWIST_FROM_VELOCITIES
    pose = model.pose(x)
    jac.solve(np.asarray(pose.position), np.asarray(pose.orientation), LEG_NOISE_M, None, model.metres_per_unit,
              model.inverse_kinematics(x), DEFAULT_ANGLE_NOISE_RAD)
    # the published pose is the solve's (round-off, 1e-9 of the scale) and the covariance is smooth in it
    assert np.allclose(np.array(extras.covariance).reshape(6, 6), jac.covariance, rtol=1e-6,
                       atol=1e-6 * np.abs(jac.covariance[np.ix_(jac.columns, jac.columns)]).max())
    got = np.concatenate(extras.twist)
    assert np.allclose(got, true_twist, rtol=0, atol=1e-5 * np.abs(true_twist).max())   # FD Jacobian error
    values = svc.diagnostics().as_dict()
    assert float(values["actuator noise std (rad)"]) == DEFAULT_ANGLE_NOISE_RAD      # the parameter, as set
