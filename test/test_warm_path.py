"""The compiled warm path (glpma_ros/solvers/lm.py): the same poses as a plain NumPy Newton iteration
on the models' own pose parameterisation, to round-off, on the tracking trajectories of both
manipulators; its figures (conditioning, stationarity, distance, pose, fitness) equal the models'
NumPy ones; the small linear algebra it carries (Jacobi SVD, Kabsch fit, quaternions) equals NumPy's."""
import math

import numpy as np
import pytest

from conftest import CONFIG
from glpma_ros.config import load_document, load_manipulator, model_from_dict
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models import linalg, pose_kernels
from glpma_ros.models.hexapod_66 import kabsch, quaternion_from_matrix, rotation_from_vector
from glpma_ros.solvers import lm, local, refine
from glpma_tools.sim.trajectories import start_pose, variables_along

#: leg residuals and pose differences "at round-off": this share of the geometry's scale
ROUND_OFF = 1e-12


def numpy_newton(model, x0, legs, iterations=8):
    """Reference: undamped Gauss-Newton in the model's pose parameterisation, NumPy only (the
    method the compiled path replaces), run to round-off."""
    state = model.pose_state(x0)
    for _ in range(iterations):
        r, J = model.pose_residuals_jacobian(state, legs)
        state = model.pose_retract(state, np.linalg.lstsq(J, -r, rcond=None)[0])
    return model.canonical(model.pose_variables(state))


def _steps(model, truth):
    return [(truth[k - 1], model.inverse_kinematics(truth[k]), truth[k]) for k in range(1, len(truth))]


@pytest.fixture(scope="module")
def hex_start(hexapod, hex_published):
    x, f, *_ = refine.polish(hexapod, hex_published[7], hexapod.example_leg_lengths, np.random.default_rng(0))
    return x


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_warm_tracking_equals_numpy_newton_to_round_off(kind, rpr, rpr_solutions, hexapod, hex_start):
    """Each step from the previous estimate: converged in the warm stage, the pose of the NumPy Newton
    iteration from the same start to round-off, on the same assembly mode as the trajectory."""
    if kind == "rpr":
        model, truth = rpr, variables_along(rpr, rpr_solutions[0], 300)
    else:
        model, truth = hexapod, variables_along(hexapod, hex_start, 300)
    est = Estimator(model, initial_pose=truth[0], time_budget_s=1.0)
    evaluations = []
    for k in range(1, len(truth)):
        start = est.last_x.copy()
        legs = model.inverse_kinematics(truth[k])
        e = est.estimate(legs)
        assert e.converged and e.start == "warm", (k, e.message)
        reference = numpy_newton(model, start, legs)
        assert model.distance(e.x, reference) <= ROUND_OFF * model.scale, (k, model.distance(e.x, reference))
        assert model.distance(e.x, truth[k]) <= ROUND_OFF * model.scale      # no assembly-mode change
        assert e.max_residual <= ROUND_OFF * model.scale
        assert np.max(np.abs(model.inverse_kinematics(e.x) - legs)) <= ROUND_OFF * model.scale
        evaluations.append(e.evaluations)
    # steady tracking: a few Levenberg-Marquardt steps plus the final evaluation, no search
    assert max(evaluations) <= 10, max(evaluations)


@pytest.mark.parametrize("kind", ["rpr", "hexapod"])
def test_kernel_figures_equal_the_models_numpy_ones(kind, rpr, rpr_solutions, hexapod, hex_start):
    model, x_true = (rpr, rpr_solutions[1]) if kind == "rpr" else (hexapod, hex_start)
    rng = np.random.default_rng(5)
    for _ in range(20):
        legs = model.inverse_kinematics(x_true) * (1.0 + 1e-3 * rng.standard_normal(model.n_legs))
        x0 = x_true + model.spread_vector(1e-2 * model.scale) * rng.standard_normal(model.n_vars)
        r = local.local_solve(model, x0, legs)
        assert r.converged and r.max_residual <= lm.LEG_RTOL * max(model.scale, legs.max())
        assert model.distance(r.x, numpy_newton(model, x0, legs)) <= ROUND_OFF * model.scale
        assert r.conditioning == pytest.approx(model.conditioning(r.x, legs), rel=1e-9)
        assert r.distance == pytest.approx(model.distance(r.x, x0), rel=1e-12, abs=1e-12 * model.scale)
        assert r.fitness == pytest.approx(float(model.fitness(r.x, legs)[0]), rel=1e-9, abs=1e-30)
        pose = model.pose(r.x)
        np.testing.assert_allclose(r.position, pose.position, atol=ROUND_OFF * model.scale)
        np.testing.assert_allclose(r.orientation, pose.orientation, atol=1e-12)
        # stationarity |J^T r| / (|J| |r|) with the column-scaled Jacobian, at a point off the solution
        a = local.local_solve(model, x0, legs, max_iter=0)
        res, J = model.pose_residuals_jacobian(model.pose_state(a.x), legs)
        J = J * model.pose_column_scale
        expected = np.linalg.norm(J.T @ res) / (np.linalg.norm(J) * np.linalg.norm(res))
        assert a.stationarity == pytest.approx(expected, rel=1e-9)
        assert a.nit == 0 and a.nfev == 1


def test_jacobi_svd_equals_numpy():
    rng = np.random.default_rng(0)
    for n in (3, 6):
        for cond in (1.0, 1e-4, 1e-12, 0.0):
            A = rng.standard_normal((n, n)) @ np.diag(np.r_[np.ones(n - 1), cond])
            A = A @ np.linalg.qr(rng.standard_normal((n, n)))[0]
            work, V, s = A.copy(), np.empty((n, n)), np.empty(n)
            linalg.jacobi_svd(work, V, s)
            expected = np.linalg.svd(A, compute_uv=False)
            np.testing.assert_allclose(np.sort(s)[::-1], expected, rtol=0, atol=1e-14 * expected[0])
            np.testing.assert_allclose(V.T @ V, np.eye(n), atol=1e-14)
            np.testing.assert_allclose(A @ V, work, atol=1e-13 * expected[0])


def test_jacobi_svd_options_keep_the_singular_values():
    """``vectors=False`` gives the singular values alone; ``negligible`` leaves a round-off column of a
    rank-deficient matrix alone (the Kabsch fit of three points in the plane z = 0: a zero row), with the
    singular values and V of NumPy's SVD all the same."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        A = rng.standard_normal((6, 6))
        full, V, s = A.copy(), np.empty((6, 6)), np.empty(6)
        linalg.jacobi_svd(full, V, s)
        values, V2, s2 = A.copy(), np.zeros((6, 6)), np.empty(6)
        linalg.jacobi_svd(values, V2, s2, 0.0, False)
        # the same rotations of A in the same order: equal to a few units in the last place
        np.testing.assert_allclose(s2, s, rtol=1e-15, atol=0.0)
        assert not V2.any()                                   # V untouched
        points = np.c_[rng.standard_normal((3, 2)), np.zeros(3)]
        targets = rng.standard_normal((3, 3))
        H = (points - points.mean(axis=0)).T @ (targets - targets.mean(axis=0))
        work, V3, s3 = H.copy(), np.empty((3, 3)), np.empty(3)
        linalg.jacobi_svd(work, V3, s3, linalg.KABSCH_NEGLIGIBLE)
        expected = np.linalg.svd(H, compute_uv=False)
        # the columns left alone are below KABSCH_NEGLIGIBLE of |H|: far inside this tolerance
        np.testing.assert_allclose(np.sort(s3)[::-1], expected, rtol=0, atol=1e-14 * expected[0])
        np.testing.assert_allclose(V3.T @ V3, np.eye(3), atol=1e-14)
        np.testing.assert_allclose(H @ V3, work, atol=1e-13 * expected[0])


def test_kabsch_start_of_a_planar_platform_equals_the_rigid_fit():
    """The 6-RUS's frame joints lie in the plane z = 0 of the platform (its Kabsch matrix has a zero row): the
    compiled fit equals the model's NumPy one."""
    model = load_manipulator(CONFIG / "rus6_simulator.yaml")
    legs = model.legs_from_sensors(model.example_actuator_positions)
    rng = np.random.default_rng(4)
    for _ in range(20):
        x = model.known_solutions[0] + rng.normal(0, 5.0, 9)
        a = local.local_solve(model, x, legs, max_iter=0)
        R, p = kabsch(model.frame, x.reshape(3, 3))
        # round-off of a fit of points some 100 mm from the origin
        np.testing.assert_allclose(a.x, (p + model.frame @ R.T).reshape(-1), atol=1e-11)


def test_quaternions_and_rodrigues_equal_the_models(hexapod):
    rng = np.random.default_rng(1)
    M = np.empty((3, 3))
    q = np.empty(4)
    back = np.empty(9)
    for w in [rng.normal(0, 2.0, 3) for _ in range(50)] + [np.array([math.pi, 0, 0]), np.array([0, 1e-10, 0])]:
        R = rotation_from_vector(w)
        pose_kernels.rotation_from_vector_into(w[0], w[1], w[2], M)
        np.testing.assert_allclose(M, R, atol=1e-15)
        pose_kernels.quaternion_from_rows(R.reshape(-1), q)
        np.testing.assert_allclose(q, quaternion_from_matrix(R), atol=1e-15)
        pose_kernels.rows_from_quaternion(q, back)
        np.testing.assert_allclose(back.reshape(3, 3), R, atol=1e-15)


def test_kabsch_start_equals_the_models_rigid_fit(hexapod, hex_start):
    """A non-rigid nine-variable start is read in as the model's least-squares rigid fit."""
    rng = np.random.default_rng(2)
    for _ in range(20):
        x = hex_start + rng.normal(0, 5.0, 9)
        a = local.local_solve(hexapod, x, hexapod.example_leg_lengths, max_iter=0)
        R, p = kabsch(hexapod.platform[:3], x.reshape(3, 3))
        np.testing.assert_allclose(a.x, (p + hexapod.platform[:3] @ R.T).reshape(-1), atol=1e-11)
        np.testing.assert_allclose(a.position, p, atol=1e-11)


def test_refine_uses_the_compiled_lm(rpr, rpr_solutions, hexapod, hex_published):
    """One implementation: refine.levenberg_marquardt returns the kernel's solve; refine.polish also
    meets the papers' absolute threshold on the hexapod (round-off search on its nine variables)."""
    x0 = rpr_solutions[0] + [1.0, -1.0, 0.02]
    x, f, nfev, nit = refine.levenberg_marquardt(rpr, x0, rpr.example_leg_lengths)
    r = local.local_solve(rpr, x0, rpr.example_leg_lengths, max_iter=50, ftol=1e-20)
    np.testing.assert_array_equal(x, r.x)
    assert (f, nfev, nit) == (r.leg_fitness, r.nfev, r.nit) and f < 1e-20
    for k in (0, 7, 10):
        x, f, *_ = refine.polish(hexapod, hex_published[k], hexapod.example_leg_lengths, np.random.default_rng(0))
        assert f < 1e-20
        assert np.max(np.abs(hexapod.inverse_kinematics(x) - 1250.0)) <= 1e-12 * hexapod.scale


def test_multistart_reports_the_first_converged_start_and_counts_all(rpr):
    legs = rpr.example_leg_lengths
    solver = local.LocalSolver(rpr)
    starts = np.ascontiguousarray(np.random.default_rng(3).uniform(-50.0, 50.0, (40, 3)))
    singles = [solver.solve(np.ascontiguousarray(s), legs, max_iter=6) for s in starts]
    first = next(k for k, s in enumerate(singles) if s.converged)
    assert first > 0                    # with 6 iterations some starts fail: the order matters here
    r = solver.multistart(starts, legs, max_iter=6)
    assert r.converged
    np.testing.assert_array_equal(r.x, singles[first].x)
    assert r.nfev == sum(s.nfev for s in singles[:first + 1]) and r.nit == sum(s.nit for s in singles[:first + 1])
    # none converges: the least leg fitness is reported
    r = solver.multistart(starts, np.array([60.0, 60.0, 60.0]), max_iter=6)
    singles = [solver.solve(np.ascontiguousarray(s), np.array([60.0, 60.0, 60.0]), max_iter=6) for s in starts]
    assert not r.converged and r.leg_fitness == min(s.leg_fitness for s in singles)


def test_bad_legs_are_refused_by_the_kernel(rpr, rpr_solutions):
    solver = local.LocalSolver(rpr)
    for legs in ([np.nan, 1.0, 1.0], [1.0, -1.0, 1.0], [0.0, 1.0, 1.0], [np.inf, 1.0, 1.0]):
        assert solver.solve(rpr_solutions[0], np.array(legs)) is None
    with pytest.raises(ValueError):
        local.local_solve(rpr, rpr_solutions[0], [1.0, 1.0])


def test_jacobi_svd_from_a_basis_and_its_upkeep():
    """Started from an orthogonal basis V0 (``from_V``, on A V0): the singular values of A and right singular
    vectors V with A V = U diag(s), as from the identity; ``orthonormalise_columns`` restores a basis drifted
    off orthogonal and refuses one that is not nearly orthogonal."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        A = rng.standard_normal((6, 6))
        V0 = np.linalg.qr(rng.standard_normal((6, 6)))[0]
        work, V, s = A @ V0, V0.copy(), np.empty(6)
        linalg.jacobi_svd(work, V, s, 0.0, True, True)
        expected = np.linalg.svd(A, compute_uv=False)
        # a few units in the last place of the largest singular value, as from the identity (test above)
        np.testing.assert_allclose(np.sort(s)[::-1], expected, rtol=0, atol=1e-14 * expected[0])
        np.testing.assert_allclose(V.T @ V, np.eye(6), atol=1e-14)
        np.testing.assert_allclose(A @ V, work, atol=1e-13 * expected[0])
        drifted = V0 + 1e-9 * rng.standard_normal((6, 6))
        assert linalg.orthonormalise_columns(drifted)
        np.testing.assert_allclose(drifted.T @ drifted, np.eye(6), atol=1e-15 * 6)
        assert not linalg.orthonormalise_columns(np.ones((6, 6)))     # dependent columns
        assert not linalg.orthonormalise_columns(np.full((6, 6), np.nan))


@pytest.mark.parametrize("name", ["hexapod_66_rolland.yaml", "rus6_simulator.yaml", "pus6_rail_hexapod.yaml"])
def test_memo_of_the_last_solve_changes_nothing_but_the_work(name):
    """A spatial solve that starts from the variables the last one returned resumes its pose state, and the
    conditioning starts from the last right singular vectors (lm's memo): along a trajectory, the same
    variables and figures, to round-off, as a solver without a memo (a fresh one for every step)."""
    path = CONFIG / name
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    p0, R0 = start_pose(model, doc)
    truth = variables_along(model, model.variables_from_pose(p0, quaternion_from_matrix(R0)), 200)
    kept = local.LocalSolver(model)
    x = truth[0]
    for k in range(1, len(truth)):
        legs = np.ascontiguousarray(model.inverse_kinematics(truth[k]), dtype=float)
        memo = kept.solve(x, legs)
        fresh = local.LocalSolver(model).solve(np.array(x), legs)
        assert memo.converged and fresh.converged
        # both at round-off of the same pose: ROUND_OFF of the scale
        assert model.distance(memo.x, fresh.x) <= ROUND_OFF * model.scale, k
        # the conditioning from another start of the same Jacobi SVD: a few units in the last place of
        # the largest singular value, relative to the smallest (conditioning about 0.1 here)
        assert memo.conditioning == pytest.approx(fresh.conditioning, rel=1e-12), k
        # (not the iteration counts: starts a few units in the last place apart may take one polish step more)
        x = memo.x                       # the next start: exactly what the memo holds
    work = kept.work[:lm.workspace_size(model.n_legs, model.n_pose, model.n_res)]
    assert work[-model.n_pose ** 2 - lm.M_BASIS + lm.M_RESUME_OK] == 1.0    # the resume did apply


@pytest.mark.parametrize("name", ["planar_3rpr_seed.yaml", "hexapod_66_rolland.yaml", "delta_irb360.yaml",
                                  "planar_3prr_triangle.yaml", "rus6_simulator.yaml", "pus6_rail_hexapod.yaml"])
def test_warm_kernel_reads_the_models_constants_from_its_buffer(name):
    """The warm path's call (``lm.warm_kernel``: the constants and the work space in one buffer,
    ``lm.warm_buffer``) returns what ``lm_kernel`` returns with them as arguments, from the same start, on fresh
    work space."""
    path = CONFIG / name
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    p0, R0 = start_pose(model, doc)
    truth = variables_along(model, model.variables_from_pose(p0, quaternion_from_matrix(R0)), 20)
    settings = local.make_settings(model, max_iter=lm.POLISH_STEPS + 20)
    for k in range(1, len(truth)):
        legs = np.ascontiguousarray(model.inverse_kinematics(truth[k]), dtype=float)
        before = np.ascontiguousarray(model.inverse_kinematics(truth[k - 1]), dtype=float)
        a, b = local.LocalSolver(model), local.LocalSolver(model)
        out_a, out_b = np.empty(a.n_out), np.empty(b.n_out)
        lm.lm_kernel(a.kind, a.data, a.platform, a.frame, legs, truth[k - 1], truth[k - 1], before, settings, out_a,
                     a.work)
        lm.warm_kernel(b.warm_buffer(settings), legs, truth[k - 1], before, out_b)
        # the same arithmetic on the same values: equal but for the last bit at most
        np.testing.assert_allclose(out_b, out_a, rtol=1e-15, atol=0.0)
