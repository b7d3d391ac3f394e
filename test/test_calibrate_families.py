"""glpma-fk calibrate on the actuated families (the one leg model): for each family a simulated campaign from a
perturbed true geometry (glpma_tools/sim/calibration_data.py: origins, platform joints and crank tips moved by up to
1 mm, rods off by up to 1 mm, rails tilted by up to 1 mrad, actuator offsets up to 2 mrad / 0.5 mm, 0.01 mm noise)
is calibrated from the nominal config: the parameters return to the truth -- up to the leg model's gauge
directions, which no data can see and which stay at nominal -- within a few standard errors, and the calibrated
model's pose error shrinks to the noise.  The CLI end to end on a revolute and a prismatic family; the Jacobian
against finite differences; bad input in one line, exit 2."""
import hashlib
import json
import math

import numpy as np
import pytest
import yaml
from test_calibrate import _write_calibration_bag

from conftest import CONFIG, GENEROUS_BUDGET_S
from glpma_ros.calibration import data as D
from glpma_ros.calibration import identify as I
from glpma_ros.cli.main import main
from glpma_ros.config import load_document, load_manipulator, model_from_dict
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models.legs import PRISMATIC, REVOLUTE
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix
from glpma_tools.sim import calibration_data as S
from glpma_tools.sim.trajectories import start_pose

FAMILIES = {"delta": "delta_irb360", "linear_delta": "linear_delta_kossel_mini", "rus_6": "rus6_simulator",
            "pus_6": "pus6_rail_hexapod", "planar_3rrr": "planar_3rrr_symmetric",
            "planar_3prr": "planar_3prr_triangle"}
#: the report's group key -> the calibration geometry's field
FIELDS = {"origin": "base", "crank": "crank", "axis": "axis", "rod": "rods", "platform": "platform",
          "actuator_offsets": "offsets"}
#: parameters allowed beyond 3 standard errors in one calibration: of 24-66 honest estimates 0.06-0.18 are
#: expected beyond 3 (0.27 % each), so one is allowed, and none beyond Z_MAX (6e-5 each beyond 4)
ALLOWED_BEYOND_3 = 1
Z_MAX = 4.0
#: the gauge alignment of the truth (aligned_truth) is exact for the linear gauges; for a crank turned about
#: its axis it conserves angle - offset, which the identification's steps conserve to first order in the crank
#: radius' own change (about a millimetre in 150: 0.7 %) times the crank's turn (up to 1 mm / 150 mm): a few
#: micrometres at the crank tip (1e-5 of the 283-mm Delta's size), added to each tolerance in weighted units
GAUGE_CURVATURE_SHARE = 1e-5
#: the calibrated forward kinematics must shrink the held-out pose error by at least this factor (from ~1-3 mm
#: to the noise's ~0.02-0.03 mm: a factor 30-100; 10 leaves room for an unlucky draw)
POSE_ERROR_SHRINK = 10.0
#: and reach the true pose within this (mm, the platform joints' largest displacement) from noise-free readings of
#: the true geometry, where the nominal config is off by more than NOMINAL_OFF_MM: a tenth of the joint errors
#: calibrated (the weakest directions' standard errors, up to 0.3 mm on the rotary hexapod, reach the pose
#: through the legs' lever arms: a few hundredths of a millimetre)
FK_BOUND_MM = 0.1
NOMINAL_OFF_MM = 0.3
#: two runs on the same measurements (CSV in config units, bag in SI: read back in config units) agree to round-off:
#: the conversion loses ~1e-16 relative, the identification amplifies it by its condition number (~1e3), so 1e-9
#: of the geometry's size is far above round-off and far below any standard error (a revolute offset, in radians,
#: is far below it too: its standard errors are ~1e-5 rad)
SAME_RTOL = 1e-9
#: the campaign of a family whose default one (S.simulate's poses about home, 1 mm build errors, laser-tracker
#: noise) does not fit it: the shipped 6-RUS is a desktop servo platform (16 mm horns, 95 mm rods nearly
#: vertical).  Its origin height and rod length move a joint almost alike, and with 10 micrometres of noise their
#: difference stays above the identification's limit (1e-3 of its 85 mm size) even over its whole workspace; and
#: a 1 mm error on a 16 mm horn bends the horn's gauge orbit (GAUGE_CURVATURE_SHARE) some fifty times more than on
#: a 150 mm crank.  So its campaign is the one such a robot gets: poses over its workspace (+-20 mm, +-0.5 rad),
#: build errors of a desktop part (0.1 mm), measured by a coordinate measuring machine (2 micrometres).  The shipped
#: 6-PUS is as small (75 mm rods, 76 mm of stroke): with the default campaign (poses +-8 mm about home, 1 mm errors,
#: 10 micrometres of noise) 18 directions stay below the identification's limit; its campaign is the same kind,
#: over its workspace (+-15 mm, +-0.3 rad)
CAMPAIGN = {"rus_6": {"spread": (20.0, 0.5), "noise_m": 2e-6, "joint_error_m": 1e-4},
            "pus_6": {"spread": (15.0, 0.3), "noise_m": 2e-6, "joint_error_m": 1e-4}}
#: fresh poses the forward kinematics is checked at, and the evaluation cap of each solve
FK_POSES = 3
MAX_EVALS = 20_000
#: the analytic Jacobian against central differences: a step of 1e-6 (config unit or radian) gives a truncation
#: error ~1e-12 relative and a round-off error ~1e-16 x 1000 mm / 1e-6 = 1e-7 on metre-sized legs; 1e-6 of the
#: largest derivative is above both and far below any real mistake (a sign, a missing term: O(1))
FD_STEP = 1e-6
FD_RTOL = 1e-6


def load(name):
    path = CONFIG / f"{name}.yaml"
    doc = load_document(path)
    return path, doc, model_from_dict(doc, str(path))


def calibrate(*args, capsys):
    """``glpma-fk calibrate ... --json`` in this process: (exit status, JSON or None, stderr)."""
    code = main(["calibrate", *map(str, args), "--json"])
    captured = capsys.readouterr()
    return code, (json.loads(captured.out) if code == 0 else None), captured.err


def digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _turn(crank, axis, phi):
    """``crank`` turned by ``phi`` about ``axis`` (planar: about +z)."""
    c, s = math.cos(phi), math.sin(phi)
    if crank.size == 2:
        return np.array([c * crank[0] - s * crank[1], s * crank[0] + c * crank[1]])
    return crank * c + np.cross(axis, crank) * s + axis * float(axis @ crank) * (1.0 - c)


def _angle(crank, reference, axis):
    """The angle from ``reference`` to ``crank`` about ``axis`` (planar: +z), in the plane across the axis."""
    if crank.size == 2:
        return math.atan2(reference[0] * crank[1] - reference[1] * crank[0], float(reference @ crank))
    return math.atan2(float(axis @ np.cross(reference, crank)), float(reference @ crank - (axis @ reference)
                                                                       * (axis @ crank)))


def aligned_truth(truth, nominal, meas, groups):
    """The true geometry moved along the leg model's gauge orbits (which change no leg residual) to where the
    identification ends: its steps are orthogonal to every gauge direction, so from nominal it keeps the gauge
    coordinates of nominal -- for a crank turned about its axis against its offset, ``angle - offset`` (the
    turn's direction is (turn, -1) in angle and offset, equal weights); for the linear gauges (a Delta's origin
    and platform joint together, origin and crank along the axis, a rail's origin against its offset) the
    projection of the weighted parameters on them."""
    g = truth.copy()
    if g.kind == REVOLUTE:
        for i in range(g.n_legs):
            axis = None if g.axis is None or g.dim == 2 else g.axis[i]
            angle = _angle(g.crank[i], nominal.crank[i], axis)
            phi = 0.5 * ((g.offsets[i] - nominal.offsets[i]) - angle)   # (angle + phi) - (o - phi) = -o_nominal
            g.crank[i] = _turn(g.crank[i], axis, phi)
            g.offsets[i] -= phi
    weights = I.parameter_weights(nominal, meas, groups)
    theta, theta0 = I.parameter_vector(g, groups), I.parameter_vector(nominal, groups)
    for i, found in enumerate(I.gauge_vectors(g, groups)):
        G = np.array([v for name, _, v in found if name not in ("crank_turn", "unit_axis")]).T
        if not G.size:
            continue
        Gw = G * weights[i][:, None]
        alpha = -np.linalg.lstsq(Gw, (theta[i] - theta0[i]) * weights[i], rcond=None)[0]
        theta[i] += G @ alpha
    return I.with_parameters(g, theta, groups)


def truth_value(truth, p) -> float:
    value = getattr(truth, FIELDS[p["group"]])[p["leg"] - 1]
    return float(value if np.ndim(value) == 0 else value["xyz".index(p["axis"])])


def fk_error_mm(model, readings, position, rotation) -> float:
    """Largest platform-joint displacement between the forward kinematics of ``model`` (the Estimator, from
    the true pose, evaluation-capped) for ``readings`` and the true pose (mm)."""
    d = position.shape[0]
    pos3, R3 = np.zeros(3), np.eye(3)
    pos3[:d], R3[:d, :d] = position, rotation
    est = Estimator(model, time_budget_s=GENEROUS_BUDGET_S, max_evals=MAX_EVALS,
                    initial_pose=model.variables_from_pose(pos3, quaternion_from_matrix(R3)))
    e = est.estimate(model.legs_from_sensors(readings))
    assert e.converged, e.message
    R_hat = matrix_from_quaternion(e.pose.orientation)[:d, :d]
    p_hat = np.asarray(e.pose.position)[:d]
    points = np.asarray(model.platform, dtype=float)
    error = (p_hat + points @ R_hat.T) - (position + points @ rotation.T)
    return float(np.linalg.norm(error, axis=1).max()) * model.metres_per_unit * 1e3


@pytest.mark.parametrize("family", list(FAMILIES))
def test_family_parameters_return_to_the_truth_and_the_pose_error_shrinks(family, tmp_path, capsys):
    path, doc, model = load(FAMILIES[family])
    campaign = CAMPAIGN.get(family, {})
    sim = S.simulate(model, start_pose(model, doc), np.random.default_rng(0), **campaign)
    data, new = tmp_path / "data.csv", tmp_path / "new.yaml"
    S.write_csv(data, sim.measured, sim.nominal.translation)
    config_digest = digest(path)
    code, out, err = calibrate(path, data, "--out", new, capsys=capsys)
    assert code == 0, err
    assert digest(path) == config_digest                                  # CONFIG never modified
    assert out["kind"] == family and out["unidentifiable"] == [] and out["gauges"]
    assert out["offset_unit"] == ("rad" if sim.nominal.kind == REVOLUTE else "mm")
    assert all(g["rank_deficient"] and g["se"] is None and g["text"] for g in out["gauges"])
    # the parameters, against the truth moved along the gauges to where the identification ends
    groups = I.kind_groups(sim.nominal.kind)
    fit = sim.measured.subset(np.sort(np.random.default_rng(0).permutation(len(sim.measured))[40:]))
    truth = aligned_truth(sim.truth, sim.nominal, fit, groups)
    labels = I.parameter_labels(sim.nominal.dim, groups)
    weight = {(g, i): w for i, row in enumerate(I.parameter_weights(sim.nominal, fit, groups))
              for (g, _), w in zip(labels, row)}
    slack = GAUGE_CURVATURE_SHARE * model.scale
    z = {}
    for p in out["parameters"]:
        w = weight[("offsets" if p["group"] == "actuator_offsets" else p["group"], p["leg"] - 1)]
        z[p["name"]] = (p["value"] - truth_value(truth, p)) / (p["se"] + slack / w)
    beyond = {k: round(v, 2) for k, v in z.items() if abs(v) > 3.0}
    assert len(beyond) <= ALLOWED_BEYOND_3 and max(abs(v) for v in z.values()) <= Z_MAX, beyond
    # the leg residuals to the noise; the held-out pose error shrinks
    noise = campaign.get("noise_m", S.NOISE_M) / model.metres_per_unit
    assert out["rms_after"] < 3 * noise < out["rms_before"]
    pose = out["holdout_pose"]
    assert pose["after"]["solved"] == pose["before"]["solved"] == out["held_out"]
    assert pose["after"]["position_rms"] * POSE_ERROR_SHRINK < pose["before"]["position_rms"]
    # NEW.yaml loads; its forward kinematics finds the true poses from the true geometry's readings
    new_model = load_manipulator(new)
    fresh = S.simulate(model, start_pose(model, doc), np.random.default_rng(1), FK_POSES, **campaign).true_poses
    readings = S.true_actuator_readings(sim.truth, fresh.position, fresh.rotation, model.actuator_limits)
    for q, position, rotation in zip(readings, fresh.position, fresh.rotation):
        assert fk_error_mm(new_model, q, position, rotation) <= FK_BOUND_MM
        assert fk_error_mm(model, q, position, rotation) > NOMINAL_OFF_MM


@pytest.mark.parametrize("family", list(FAMILIES))
def test_family_jacobian_is_the_derivative_of_the_residuals(family):
    """Each column of the weighted Jacobian against central differences of the leg residuals, and each gauge
    direction a null direction of it (no residual moves)."""
    _, doc, model = load(FAMILIES[family])
    sim = S.simulate(model, start_pose(model, doc), np.random.default_rng(3), 20)
    geometry, meas = sim.truth, sim.measured
    groups = I.kind_groups(geometry.kind)
    weights = I.parameter_weights(geometry, meas, groups)
    _, J = I.residuals_jacobian(geometry, meas, groups, weights)
    theta = I.parameter_vector(geometry, groups)
    k = theta.shape[1]
    labels = I.parameter_labels(geometry.dim, groups)
    for c in range(k):
        if labels[c][0] == "axis":
            continue                       # a unit vector, renormalised: test_rail_direction_column_...
        plus, minus = theta.copy(), theta.copy()
        plus[:, c] += FD_STEP
        minus[:, c] -= FD_STEP
        fd = (I.leg_residuals(I.with_parameters(geometry, plus, groups), meas)
              - I.leg_residuals(I.with_parameters(geometry, minus, groups), meas)).T / (2 * FD_STEP)
        analytic = J[:, :, c] * weights[:, c][:, None]
        assert np.allclose(analytic, fd, rtol=0, atol=FD_RTOL * max(1.0, np.abs(fd).max())), labels[c]
    for i, found in enumerate(I.gauge_vectors(geometry, groups)):
        for name, _, v in found:
            moved = J[i] @ (v * weights[i])
            assert np.abs(moved).max() <= FD_RTOL * np.abs(J[i]).max(), (name, i)


def test_rail_direction_column_against_finite_differences_across_the_rail():
    """A rail's direction is a unit vector: its columns are the derivative across the rail (the length of the
    direction is no parameter: the gauge "unit_axis")."""
    _, doc, model = load(FAMILIES["pus_6"])
    sim = S.simulate(model, start_pose(model, doc), np.random.default_rng(4), 20)
    geometry, meas = sim.truth, sim.measured
    groups = I.kind_groups(PRISMATIC)
    weights = I.parameter_weights(geometry, meas, groups)
    _, J = I.residuals_jacobian(geometry, meas, groups, weights)
    cols = [c for c, (g, _) in enumerate(I.parameter_labels(3, groups)) if g == "axis"]
    for i in range(geometry.n_legs):
        a = geometry.axis[i]
        across = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        across /= np.linalg.norm(across)
        h = FD_STEP
        r = []
        for sign in (1.0, -1.0):
            g = geometry.copy()
            g.axis[i] = (a + sign * h * across) / np.linalg.norm(a + sign * h * across)
            r.append(I.leg_residuals(g, meas)[:, i])
        fd = (r[0] - r[1]) / (2 * h)
        analytic = J[i][:, cols] @ (across * weights[i][cols])
        assert np.allclose(analytic, fd, atol=FD_RTOL * np.abs(fd).max())


@pytest.mark.parametrize("family", ["planar_3rrr", "linear_delta", "delta"])
def test_cli_end_to_end_writes_new_yaml_keeps_the_input_and_its_comments(family, tmp_path, capsys):
    """The documented commands on revolute and prismatic families (the README's Delta example among them): the
    simulator writes the CSV (a Delta's without orientation columns), calibrate exits 0, writes NEW.yaml with
    each leg's identified entries rewritten in place (comments kept), actuator_offsets added, everything else
    as in CONFIG; the text report names the gauges and says the units."""
    path, doc, model = load(FAMILIES[family])
    data, new = tmp_path / "m.csv", tmp_path / "new.yaml"
    assert S.main([FAMILIES[family], str(data), "120", "5"]) == 0
    header = data.read_text().splitlines()[0].split(",")
    dim = model.base.shape[1]
    translation = family in ("delta", "linear_delta")
    revolute = family != "linear_delta"
    assert header == [f"leg_{i + 1}" for i in range(model.n_legs)] + list(D.pose_columns(dim, translation))
    capsys.readouterr()
    before = path.read_text()
    assert main(["calibrate", FAMILIES[family], str(data), "--out", str(new)]) == 0
    text = capsys.readouterr().out
    assert path.read_text() == before
    assert "gauge directions (no measurement separates them; kept at nominal):" in text
    assert ("offsets in rad" in text) == revolute and f"wrote {new}" in text
    new_text, new_doc = new.read_text(), yaml.safe_load(new.read_text())
    comments = [ln.split("#", 1)[1] for ln in before.splitlines() if "#" in ln]
    assert all(c in new_text for c in comments)                         # every comment kept
    assert new_text.startswith("# Calibrated by glpma-fk calibrate")
    assert {k: v for k, v in new_doc.items() if k not in ("legs", "actuator_offsets")} == \
        {k: v for k, v in doc.items() if k != "legs"}
    assert len(new_doc["actuator_offsets"]) == model.n_legs
    keep = {"actuator"} | ({"axis"} if revolute else set())      # a revolute axis is not identified
    for old, leg in zip(doc["legs"], new_doc["legs"]):
        assert {k: old[k] for k in keep if k in old} == {k: leg[k] for k in keep if k in leg}
        assert leg["rod"] != old["rod"] and leg["origin"] != old["origin"]
    new_model = load_manipulator(new)
    assert np.allclose(new_model.actuator_offsets, new_doc["actuator_offsets"], rtol=0, atol=1e-15)
    # --identify restricts to the family's groups; a group the legs do not have is one line, exit 2
    code, out, err = calibrate(FAMILIES[family], data, "--out", tmp_path / "rod.yaml", "--identify", "rod",
                               capsys=capsys)
    assert code == 0 and out["identify"] == ["rod"] and {p["group"] for p in out["parameters"]} == {"rod"}
    other = "axis" if revolute else "crank"
    code, _, err = calibrate(FAMILIES[family], data, "--out", tmp_path / "x.yaml", "--identify", other,
                             capsys=capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and f"--identify {other}" in err
    assert not (tmp_path / "x.yaml").exists()


def _delta_csv(tmp_path, rows, header="leg_1,leg_2,leg_3,x,y,z"):
    p = tmp_path / "delta.csv"
    p.write_text(header + "\n" + "\n".join(rows) + "\n")
    return p


@pytest.mark.parametrize("make, words", [
    (lambda t: _delta_csv(t, ["0.1,0.2,0.3,1,2,-1000,0,0,0.5,0.8660254"], "leg_1,leg_2,leg_3,x,y,z,qx,qy,qz,qw"),
     "only translates"),
    (lambda t: _delta_csv(t, ["0.1,0.2,0.3,1,2,-1000,0,0"], "leg_1,leg_2,leg_3,x,y,z,qx,qy"),
     "qx qy qz qw"),
    (lambda t: _delta_csv(t, ["0.1,0.2,0.3,1,2"]), "5 values"),
    (lambda t: _delta_csv(t, ["0.1,0.2,0.3,1,2,-1000"] * 40), "the poses do not fit the legs"),
])
def test_family_bad_input_exit_2_one_line(make, words, tmp_path, capsys):
    """A tilted pose for a platform that only translates, half an orientation, a short row, poses that do
    not belong to the readings: one line naming the problem, exit 2, nothing written."""
    data = make(tmp_path)
    code, _, err = calibrate("delta_irb360", data, "--out", tmp_path / "new.yaml", capsys=capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and words in err, err
    assert "Traceback" not in err and not (tmp_path / "new.yaml").exists()


@pytest.mark.parametrize("family, storage, joint_state", [("delta", "mcap", False), ("linear_delta", "sqlite3", True)])
def test_family_bag_calibrates_as_the_csv(family, storage, joint_state, tmp_path, capsys):
    """A rosbag2 of the actuator readings as the node takes them (radians; metres for a prismatic actuator) and the
    tracker's PoseStamped (metres) identifies what the CSV of the same measurements does."""
    pytest.importorskip("rosbags")
    path, doc, model = load(FAMILIES[family])
    sim = S.simulate(model, start_pose(model, doc), np.random.default_rng(5))
    bag, data = tmp_path / "bag", tmp_path / "data.csv"
    _write_calibration_bag(bag, sim, model, storage, joint_state, to_si=model.readings_to_si)
    S.write_csv(data, sim.measured, sim.nominal.translation)
    code, from_bag, err = calibrate(path, bag, "--out", tmp_path / "from_bag.yaml", capsys=capsys)
    assert code == 0, err
    code, from_csv, err = calibrate(path, data, "--out", tmp_path / "from_csv.yaml", capsys=capsys)
    assert code == 0, err
    assert from_bag["bag"]["paired"] == from_bag["measurements"] == from_csv["measurements"] == S.POSES
    for a, b in zip(from_bag["parameters"], from_csv["parameters"]):
        assert a["name"] == b["name"] and abs(a["value"] - b["value"]) <= SAME_RTOL * model.scale
