"""The manipulator's URDF (``glpma-fk urdf``) and every joint's state (``~/mechanism_joint_states``).

* for every shipped config the URDF parses with a URDF library (yourdfpy) and, with the joint
  states the node computes for its poses -- along a trajectory, in several assembly modes -- every
  leg's chain, composed by that library's joint transforms, ends at its platform joint, the platform
  link is at the pose and the actuators are at the leg lengths (an actuated family's: at the motors'
  readings), within 1e-9 m / 1e-9 rad;
* the joints' rates are those of the twist (finite differences of the joint positions);
* the JointState's wire form is Cyclone DDS's own; the command's options and bad input.
"""
import io
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from conftest import CONFIG, GENEROUS_BUDGET_MS, RPR_YAML
from glpma_ros.cli.main import main
from glpma_ros.config import load_manipulator, resolve_config, shipped_configs
from glpma_ros.description.mechanism import Mechanism
from glpma_ros.models.legs import PRISMATIC
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix, rotation_from_vector
from glpma_ros.node.service import FkService, JointStateInput

yourdfpy = pytest.importorskip("yourdfpy")

#: the node's poses are solved to round-off (1e-13 of the legs); composing a chain of six joint
#: transforms adds a few ulps: 1e-9 m / 1e-9 rad is far above both and far below any real error
TOL = 1e-9
#: poses along the trajectory per assembly mode, and the trajectory's size (share of the geometry's)
STEPS = 8
AMPLITUDE = 0.02
#: assembly modes of hexapod_66_rolland.yaml tried (of its 16): a spread above and below the base
ROLLAND_MODES = (0, 1, 4, 10, 11, 15)


def known_modes(name: str) -> list:
    """Solver variables of the config's known assembly modes (config unit, radians)."""
    doc = yaml.safe_load((CONFIG / f"{name}.yaml").read_text())
    if "real_solutions" in doc:
        return [[s["x"], s["y"], math.radians(s["theta_deg"])] for s in doc["real_solutions"]]
    if "known_solutions" in doc:                  # an actuated family: the modes the inverse kinematics' branch
        model = load_manipulator(resolve_config(name))    # (choose_root) reads as the example reading
        q0 = np.asarray(doc["example_actuator_positions"], dtype=float)
        # 1e-6 of the scale: the modes are written to 1e-9 mm, a reading of the other branch is far off
        return [x for x in doc["known_solutions"]
                if np.abs(model.actuator_positions(np.asarray(x, dtype=float)) - q0).max() < 1e-6 * model.scale
                and _in_reach(model, x)]
    modes = doc["published_solutions"]
    return [modes[k] for k in ROLLAND_MODES] if name == "hexapod_66_rolland" else modes


def _in_reach(model, x0) -> bool:
    """The legs reach every pose of the test trajectory about ``x0`` within their actuator limits (a mode near
    the limits' edge may leave them: it is not a mode the test can drive)."""
    try:
        for x in trajectory(model, x0):
            model.actuator_positions(x)
    except ValueError:
        return False
    return True


def is_planar(model) -> bool:
    return model.kind == "planar_3rpr" or getattr(model, "dim", 3) == 2


def translates_only(model) -> bool:
    """The Delta: the platform's orientation is fixed."""
    return model.n_vars == 3 and not is_planar(model)


def trajectory(model, x0) -> list:
    """Poses (solver variables) along a closed loop around the pose of ``x0``: a circle and a
    wobble of the platform (none for a platform that only translates), small enough to stay on
    ``x0``'s assembly mode."""
    pose = model.pose(model.canonical(x0) if is_planar(model) else x0)
    p0, R0 = np.asarray(pose.position), matrix_from_quaternion(pose.orientation)
    r = AMPLITUDE * model.scale
    out = []
    for k in range(STEPS):
        t = 2.0 * math.pi * k / STEPS
        if is_planar(model):
            dp, w = np.array([r * math.sin(t), r * (math.cos(t) - 1.0), 0.0]), np.array([0.0, 0.0, 0.1 * math.sin(t)])
        else:
            dp = np.array([r * math.sin(t), r * (math.cos(t) - 1.0), 0.5 * r * math.sin(2 * t)])
            w = 0.0 * dp if translates_only(model) else 0.05 * np.array([math.sin(t), math.cos(t) - 1.0,
                                                                              math.sin(2 * t)])
        R = rotation_from_vector(w) @ R0
        out.append(model.variables_from_pose(p0 + dp, quaternion_from_matrix(R)))
    return out


def urdf_of(name: str, tmp_path, *extra) -> str:
    out = tmp_path / f"{name}.urdf"
    assert main(["urdf", name, "--out", str(out), *extra]) == 0
    return out.read_text()


def load(text: str):
    robot = yourdfpy.URDF.load(io.StringIO(text), build_scene_graph=True, load_meshes=False)
    assert robot.validate(), robot.errors
    return robot


@pytest.mark.parametrize("name", shipped_configs())
def test_every_leg_of_the_urdf_ends_at_its_platform_joint(name, tmp_path):
    model = load_manipulator(resolve_config(name))
    robot = load(urdf_of(name, tmp_path))
    metres = model.metres_per_unit
    worst = {"end": 0.0, "platform": 0.0, "actuator": 0.0, "angle": 0.0}
    poses = 0
    for x0 in known_modes(name):
        svc = FkService({"manipulator_config": str(CONFIG / f"{name}.yaml"), "initial_pose": list(map(float, x0)),
                         "publish_joint_states": True, "time_budget_ms": GENEROUS_BUDGET_MS})
        for k, x in enumerate(trajectory(model, x0)):
            actuated = getattr(model, "actuated", False)
            # what the actuators read at x: leg lengths (metres), or the motors' angles (radians; rails: metres)
            legs = (model.readings_to_si(model.actuator_positions(x)) if actuated
                    else model.inverse_kinematics(x) * metres)
            outcome = svc.handle(list(legs), 1_000_000_000 + k)
            assert outcome.pose is not None, outcome.reason
            ex = svc.extras(outcome)
            assert ex.stamp_ns == outcome.pose.stamp_ns           # stamped as the pose
            names = [j.name for j in robot.robot.joints if j.type != "fixed"]
            assert sorted(ex.joint_names) == sorted(names)        # every moving joint of the URDF
            robot.update_cfg(dict(zip(ex.joint_names, ex.joint_positions)))
            p, R = np.array(outcome.pose.position), matrix_from_quaternion(outcome.pose.orientation)
            B = p + model_platform_m(model) @ R.T                 # the platform joints at the pose
            for i in range(model.n_legs):
                T = robot.get_transform(f"leg{i + 1}_end", "base_link")
                worst["end"] = max(worst["end"], float(np.abs(T[:3, 3] - B[i]).max()))
                worst["angle"] = max(worst["angle"], float(np.abs(T[:3, :3] - R).max()))
            T = robot.get_transform("platform_link", "base_link")
            worst["platform"] = max(worst["platform"], float(np.abs(T[:3, 3] - p).max()),
                                    float(np.abs(T[:3, :3] - R).max()))
            # the pose is the truth's (the mode tracked), and the actuators are at the leg lengths
            truth = model.pose(x)
            assert np.abs(np.array(outcome.pose.position) - truth.position * metres).max() < TOL
            actuators = [q for n, q in zip(ex.joint_names, ex.joint_positions) if n.endswith("_actuator")]
            worst["actuator"] = max(worst["actuator"], float(np.abs(np.array(actuators) - legs).max()))
            poses += 1
    assert poses >= STEPS
    assert max(worst.values()) < TOL, worst


def model_platform_m(model) -> np.ndarray:
    pts = np.asarray(model.platform) * model.metres_per_unit
    return np.hstack((pts, np.zeros((len(pts), 1)))) if pts.shape[1] == 2 else pts


@pytest.mark.parametrize("name", ["planar_3rpr_seed", "hexapod_66_rolland", "hexapod_33_octahedral", "delta_irb360",
                                  "rus6_simulator", "planar_3rrr_symmetric", "linear_delta_kossel_mini",
                                  "pus6_rail_hexapod", "planar_3prr_triangle"])
def test_joint_rates_are_the_twist_s(name):
    """Each joint's rate = the finite difference of its position over a small step of the twist
    (central difference: error O(dt^2) ~ 1e-10 of the rates' size, checked to 1e-6)."""
    model = load_manipulator(resolve_config(name))
    mech = Mechanism(model)
    rng = np.random.default_rng(7)
    planar = is_planar(model)
    dt = 1e-6
    for x0 in known_modes(name)[:2]:
        pose = model.pose(x0)
        p, q = pose.position * model.metres_per_unit, pose.orientation
        v = rng.normal(size=3) * 0.1
        w = rng.normal(size=3)
        if planar:
            v[2], w[:2] = 0.0, 0.0
        if translates_only(model):
            w[:] = 0.0
        rates = mech.velocities(p, q, v, w)
        R = matrix_from_quaternion(q)
        at = [mech.positions(p + v * h, quaternion_from_matrix(rotation_from_vector(w * h) @ R)) for h in (dt, -dt)]
        fd = (at[0] - at[1]) / (2 * dt)
        assert np.abs(rates - fd).max() < 1e-6 * max(1.0, np.abs(rates).max())


def test_node_joint_rates_follow_the_legs_rates():
    """With joint_states velocities in, the twist is exact and the actuators' rates are the legs'."""
    x0 = known_modes("planar_3rpr_seed")[0]
    svc = FkService({"manipulator_config": str(RPR_YAML), "initial_pose": x0, "input_type": "joint_state",
                     "publish_joint_states": True, "time_budget_ms": GENEROUS_BUDGET_MS})
    legs_m = tuple(load_manipulator(RPR_YAML).inverse_kinematics(x0) * 1e-3)
    rates = (0.01, -0.02, 0.005)
    out = svc.handle(JointStateInput(("leg_1", "leg_2", "leg_3"), legs_m, rates), 5)
    ex = svc.extras(out)
    got = [v for n, v in zip(ex.joint_names, ex.joint_velocities) if n.endswith("_actuator")]
    np.testing.assert_allclose(got, rates, rtol=0, atol=1e-12)   # a 3x3 solve and back: round-off


def test_joint_states_are_off_by_default_and_the_twist_stays_unpublished():
    x0 = known_modes("planar_3rpr_seed")[0]
    svc = FkService({"manipulator_config": str(RPR_YAML), "initial_pose": x0, "time_budget_ms": GENEROUS_BUDGET_MS})
    legs = list(load_manipulator(RPR_YAML).inverse_kinematics(x0) * 1e-3)
    assert svc.extras(svc.handle(legs, 1)).joint_names is None
    ok, _ = svc.set_parameters({"publish_joint_states": True})
    assert ok
    # joint states subscribed, twist_estimate not: the twist is computed for the rates, not published
    svc.extras(svc.handle(legs, 2), subscribed={"joint_states"})
    ex = svc.extras(svc.handle([v * (1 + 1e-4) for v in legs], 3), subscribed={"joint_states"})
    assert ex.joint_names is not None and len(ex.joint_velocities) == len(ex.joint_names)
    assert not ex.twist_out
    from glpma_ros.node.dds.cdr import Encoder
    assert [name for name, _ in Encoder().extras(ex)] == ["joint_states"]


def test_joint_state_bytes_are_cyclone_dds_s():
    pytest.importorskip("cyclonedds")
    from glpma_ros.node.dds import messages as M
    from glpma_ros.node.dds.cdr import Encoder
    rng = np.random.default_rng(3)
    enc = Encoder()
    for frame in ("", "base", "robot_base_link"):
        for names in ([], ["a"], ["leg1_u1", "leg1_u2", "leg1_actuator"], [f"j{k}" * (k + 1) for k in range(9)]):
            stamp = int(rng.integers(0, 2**31 * 10**9))
            pos = tuple(float(v) for v in rng.normal(size=len(names)))
            for vel in ((), tuple(float(v) for v in rng.normal(size=len(names)))):
                msg = M.JointState(M.Header(M.Time.from_ns(stamp), frame), list(names), list(pos), list(vel), [])
                raw = msg.serialize()
                raw += b"\0" * (-len(raw) % 4)
                assert enc.joint_state(stamp, frame, names, pos, vel) == raw


def test_urdf_prefix_meshes_and_names(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    (meshes / "base_link.stl").write_bytes(b"solid x\nendsolid x\n")
    (meshes / "leg_rod.dae").write_text("<COLLADA/>")
    text = urdf_of("hexapod_63_stewart", tmp_path, "--prefix", "left_", "--meshes", str(meshes), "--name", "bot")
    root = ET.fromstring(text)
    assert root.get("name") == "bot"
    links = {link.get("name"): link for link in root.iter("link")}
    joints = {j.get("name"): j for j in root.iter("joint")}
    assert "left_base_link" in links and "left_platform_link" in links
    for i in range(1, 7):
        for part in ("u1", "u2", "actuator", "s1", "s2", "s3"):
            assert f"left_leg{i}_{part}" in joints
    assert joints["left_platform_mount"].get("type") == "fixed"
    assert joints["left_leg1_actuator"].find("limit").get("lower") == "0.15"     # leg_limits 150 mm
    mesh = links["left_base_link"].find("visual/geometry/mesh")
    assert mesh.get("filename") == (meshes / "base_link.stl").resolve().as_uri()
    for i in range(1, 7):
        assert links[f"left_leg{i}_rod"].find("visual/geometry/mesh").get("filename").endswith("leg_rod.dae")
    assert links["left_leg1_cylinder"].find("visual/geometry/cylinder") is not None     # no mesh: simple
    load(text)


def test_urdf_to_stdout_and_bad_input(tmp_path, capsys):
    assert main(["urdf", "planar_3rpr_seed"]) == 0
    out = capsys.readouterr().out
    names = [j.get("name") for j in ET.fromstring(out.split("\n", 2)[2]).iter("joint")]
    assert names[:3] == ["leg1_base", "leg1_actuator", "leg1_platform"] and names[-1] == "platform_mount"
    for argv, message in ((["urdf", "no_such_config"], "no_such_config"),
                          (["urdf", "planar_3rpr_seed", "--prefix", "a b"], "--prefix"),
                          (["urdf", "planar_3rpr_seed", "--meshes", str(tmp_path / "none")], "not a folder"),
                          (["urdf", str(RPR_YAML), "--out", str(RPR_YAML)], "never overwritten")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


# -- passive-joint limits ----------------------------------------------------------------------------


def _config_with_limits(tmp_path, name: str, limits) -> str:
    doc = yaml.safe_load((CONFIG / f"{name}.yaml").read_text())
    doc["passive_joint_limits"] = limits
    path = tmp_path / f"{name}_limits.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def test_a_pose_beyond_a_passive_joint_limit_is_published_and_named(tmp_path):
    """hexapod_63_stewart's example pose bends its joints 29.5-34.9 degrees: with 33-degree cones the legs
    beyond are named on /diagnostics (WARN, the status stays converged); with the shipped 40 none is."""
    doc = yaml.safe_load((CONFIG / "hexapod_63_stewart.yaml").read_text())
    x0 = doc["published_solutions"][0]
    for limits, beyond in (({"universal_cone_deg": 40.0, "spherical_cone_deg": 40.0}, False),
                           ({"universal_cone_deg": 33.0, "spherical_cone_deg": [40, 40, 40, 40, 33, 40]}, True)):
        path = _config_with_limits(tmp_path, "hexapod_63_stewart", limits)
        model = load_manipulator(path)
        svc = FkService({"manipulator_config": path, "initial_pose": x0, "time_budget_ms": GENEROUS_BUDGET_MS})
        assert svc.extras_on()
        out = svc.handle(list(model.inverse_kinematics(x0) * 1e-3), 1)
        assert out.pose is not None and out.estimate.status == "converged"
        svc.extras(out, subscribed=set())         # checked even with no extra output subscribed
        report = svc.diagnostics()
        values = report.as_dict()
        if beyond:
            # legs 5 (34.8 deg) universal; leg 5 spherical (34.9 > 33); nothing else is over 33
            assert values["joint limit"] == ("leg 5 universal 34.8 deg > 33.0 deg; leg 5 spherical 34.9 deg > "
                                             "33.0 deg"), values["joint limit"]
            assert report.level == 1 and "joint_limit: leg 5 universal 34.8 deg > 33.0 deg" in report.message
            assert values["poses beyond a joint limit"] == "1"
        else:
            assert values["joint limit"] == "none" and report.level == 0, report.message
        assert 0.0 < float(values["conditioning last"]) <= 1.0


def test_planar_revolute_ranges_and_the_urdf_limits(tmp_path):
    # real solution 1: the legs at 58.1, 151.5, -43.8 deg from the base's x axis, the platform joints at
    # -91.5, 175.1, 10.3 deg: leg 2's base joint beyond [-90, 150], leg 1's platform joint beyond [-90, 170]
    x0 = known_modes("planar_3rpr_seed")[0]
    path = _config_with_limits(tmp_path, "planar_3rpr_seed", {"base_revolute_deg": [[-90, 180], [-90, 150], [-90, 40]],
                                                              "platform_revolute_deg": [[-90, 170], [-180, 180],
                                                                                        [-170, 170]]})
    model = load_manipulator(path)
    svc = FkService({"manipulator_config": path, "initial_pose": x0, "time_budget_ms": GENEROUS_BUDGET_MS})
    svc.extras(svc.handle(list(model.inverse_kinematics(x0) * 1e-3), 1))
    assert svc.diagnostics().as_dict()["joint limit"] == ("leg 2 base revolute 151.5 deg > 150.0 deg; "
                                                          "leg 1 platform revolute -91.5 deg < -90.0 deg")
    robot = ET.fromstring(urdf_of(path, tmp_path).split("\n", 2)[2])
    limits = {j.get("name"): j.find("limit") for j in robot.iter("joint")}
    assert float(limits["leg3_base"].get("upper")) == pytest.approx(math.radians(40.0), abs=1e-15)
    assert float(limits["leg1_platform"].get("lower")) == pytest.approx(math.radians(-90.0), abs=1e-15)
    assert float(limits["leg2_platform"].get("upper")) == pytest.approx(math.pi, abs=1e-15)


@pytest.mark.parametrize("limits, message", [
    ({"cone": 3}, "no key 'cone'"),
    ({"universal_cone_deg": 0}, "between 0 and 180"),
    ({"universal_cone_deg": [30, 30]}, "one per leg"),
    ({"base_revolute_deg": [10, 5]}, "min < max"),
    ([30], "must be a mapping")])
def test_bad_passive_limits_are_refused_in_one_line(tmp_path, limits, message):
    from glpma_ros.errors import ConfigError
    name = "planar_3rpr_seed" if "base_revolute_deg" in str(limits) else "hexapod_63_stewart"
    with pytest.raises(ConfigError, match=message) as exc:
        load_manipulator(_config_with_limits(tmp_path, name, limits))
    assert "\n" not in str(exc.value)



@pytest.mark.parametrize("name", shipped_configs())
def test_urdfdom_check_urdf_parses_it(name, tmp_path):
    """urdfdom's own parser (what robot_state_publisher links): ``check_urdf`` from Debian's liburdfdom-tools."""
    import shutil
    import subprocess
    if shutil.which("check_urdf") is None:
        pytest.skip("check_urdf (liburdfdom-tools) is not installed")
    urdf_of(name, tmp_path, "--prefix", "r1_")
    p = subprocess.run(["check_urdf", str(tmp_path / f"{name}.urdf")], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and "Successfully Parsed XML" in p.stdout, p.stdout + p.stderr
    assert "root Link: r1_base_link" in p.stdout and p.stdout.count("r1_platform_link") == 1


@pytest.mark.parametrize("name, parts", [
    ("delta_irb360", ("actuator", "u1", "u2", "s1", "s2", "s3")),
    ("rus6_simulator", ("actuator", "u1", "u2", "s1", "s2", "s3")),
    ("planar_3rrr_symmetric", ("actuator", "elbow", "platform")),
    ("linear_delta_kossel_mini", ("actuator", "u1", "u2", "s1", "s2", "s3")),
    ("pus6_rail_hexapod", ("actuator", "u1", "u2", "s1", "s2", "s3")),
    ("planar_3prr_triangle", ("actuator", "elbow", "platform"))])
def test_actuated_family_joint_names_and_motor_limits(name, parts, tmp_path):
    """The families' joints as doc/interface.md names them, leg by leg; the motors' URDF limits are the
    config's actuator_limits (written as the shortest repr of the same double: compared exactly; a rail's in
    metres: the config's times the unit, to round-off); a rail's actuator is prismatic, its link the carriage."""
    model = load_manipulator(resolve_config(name))
    rails = bool(np.all(model.actuators == PRISMATIC))
    root = ET.fromstring(urdf_of(name, tmp_path, "--prefix", "r_").split("\n", 2)[2])
    moving = [j for j in root.iter("joint") if j.get("type") != "fixed"]
    assert [j.get("name") for j in moving] == [f"r_leg{i}_{p}" for i in range(1, model.n_legs + 1) for p in parts]
    assert [j.get("type") for j in moving] == ["prismatic" if rails and p == "actuator" else "revolute"
                                               for _ in range(model.n_legs) for p in parts]
    for i in range(model.n_legs):
        limit = moving[i * len(parts)].find("limit")
        got = (float(limit.get("lower")), float(limit.get("upper")))
        if rails:   # metres: one multiply by the unit, 1e-15 m of round-off
            assert np.allclose(got, model.actuator_limits[i] * model.metres_per_unit, rtol=0, atol=1e-15)
        else:
            assert got == tuple(model.actuator_limits[i])
        assert moving[i * len(parts)].find("parent").get("link") == "r_base_link"
    text = ET.tostring(root, encoding="unicode")
    assert ("r_leg1_carriage" if rails else "r_leg1_crank") in text
    load(text)
