"""The node without a transport: parameters, --ros-args, units, validation, publish decision,
statistics, runtime parameter changes, and the newest-input worker."""
import math
import threading
import time

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import CONFIG, GENEROUS_BUDGET_MS, HEX_YAML, RPR_YAML
from glpma_ros.errors import ConfigError, InputError
from glpma_ros.node import params as P
from glpma_ros.node import ros_args
from glpma_ros.node.diagnostics import WARN
from glpma_ros.node.loops import LatestInput, SolveLoop
from glpma_ros.node.service import FkService
from glpma_ros.node.stats import LogThrottle

SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]
SEED_LEGS_M = [0.100, 0.120, 0.150]
#: what the service computes is under test, not how fast: the same answers on a busy machine
BUDGET = {"time_budget_ms": GENEROUS_BUDGET_MS}
#: seconds a test waits for the worker thread (a bound for a hang, not a timing figure)
WAIT_S = 60.0


def pose_of(model, x):
    """Expected (position m, quaternion) of solver variables ``x``."""
    pose = model.pose(np.asarray(x, dtype=float))
    return np.asarray(pose.position) * model.metres_per_unit, np.asarray(pose.orientation)


@pytest.fixture(scope="module", autouse=True)
def compiled():
    """Numba compiles (or loads its cache) on first use: do it once, outside the time budgets."""
    for path in (RPR_YAML, HEX_YAML):
        FkService({"manipulator_config": str(path)}).warm_up()


@pytest.fixture
def service():
    return FkService({"manipulator_config": str(RPR_YAML), "initial_pose": SEED_X, **BUDGET})


# -- parameters and --ros-args ----------------------------------------------------------------

def test_every_contract_parameter_is_declared_with_a_description():
    for name in ("manipulator_config", "solver", "time_budget_ms", "tolerance", "frame_id", "initial_pose"):
        assert name in P.SPECS and P.SPECS[name].description
    assert P.SPECS["solver"].choices == ("glpma", "g3pcx", "rcga", "sa", "gasa", "de")
    assert P.defaults()["initial_pose"] == []


def test_ros_args_parameters_params_file_and_order(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("glpma_fk:\n  ros__parameters:\n    solver: g3pcx\n    tolerance: 1e-18\n"
                 "    time_budget_ms: 3\n/**:\n  ros__parameters:\n    frame_id: world\n"
                 "other_node:\n  ros__parameters:\n    solver: rcga\n")
    args = ros_args.parse_ros_args(["--ros-args", "--params-file", str(f), "-p", "time_budget_ms:=4.5",
                             "-p", "initial_pose:=[1, 2, 0.5]", "-p", "glpma_fk:seed:=7",
                             "-p", "other_node:seed:=9", "-p", "frame_id:=123", "--", "rest"])
    values, warnings = P.resolve(args.overrides)
    assert values["solver"] == "g3pcx"
    assert values["tolerance"] == 1e-18             # YAML 1.1 reads 1e-18 as a string; ROS as a double
    assert values["time_budget_ms"] == 4.5          # later -p wins over the file
    assert values["initial_pose"] == [1.0, 2.0, 0.5]
    assert values["seed"] == 7
    assert values["frame_id"] == "123"              # a string parameter keeps the text
    assert args.other == ["rest"] and not warnings


def test_ros_args_node_rename_selects_params_file_section(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("fk2:\n  ros__parameters:\n    solver: rcga\n")
    args = ros_args.parse_ros_args(["--ros-args", "-r", "__node:=fk2", "--params-file", str(f)])
    assert args.node_name == "fk2" and args.overrides == {"solver": "rcga"}


def test_unknown_parameter_is_a_warning_not_an_error():
    values, warnings = P.resolve({"no_such_thing": 1})
    assert values == P.defaults() and "no_such_thing" in warnings[0]


@pytest.mark.parametrize("argv, message", [
    (["--ros-args", "-p"], "expects an argument"),
    (["--ros-args", "-p", "solver"], "NAME:=VALUE"),
    (["--ros-args", "bogus"], "unexpected ROS argument"),
    (["--ros-args", "--params-file", "/nonexistent.yaml"], "cannot read params file"),
])
def test_ros_args_errors_are_one_line(argv, message):
    with pytest.raises(InputError, match=message):
        ros_args.parse_ros_args(argv)


@pytest.mark.parametrize("name, value, message", [
    ("solver", "cmaes", "one of glpma, g3pcx, rcga, sa, gasa, de"),
    ("time_budget_ms", 0.0, "> 0"),
    ("time_budget_ms", "fast", "must be a number"),
    ("tolerance", -1.0, "> 0"),
    ("population", 2, "at least 4"),
    ("population", 1.5, "integer"),
    ("polish", "yes", "true or false"),
    ("initial_pose", [1.0, float("nan"), 0.0], "finite"),
    ("initial_pose", "1 2 3", "list of numbers"),
    ("frame_id", "", "must not be empty"),
    ("qos_depth", 0, ">= 1"),
])
def test_invalid_parameter_values_are_rejected_with_a_reason(name, value, message):
    with pytest.raises(InputError, match=message):
        P.coerce(name, value)


@settings(max_examples=200, deadline=None)
@given(name=st.sampled_from(sorted(P.SPECS)),
       value=st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=8),
                       st.lists(st.floats(), max_size=10)))
def test_coerce_accepts_or_raises_input_error_only(name, value):
    try:
        P.coerce(name, value)
    except InputError as exc:
        assert "\n" not in str(exc)


# -- construction ----------------------------------------------------------------------------------

def test_bad_configuration_is_a_one_line_error(tmp_path):
    with pytest.raises(ConfigError):
        FkService({"manipulator_config": str(tmp_path / "missing.yaml")})
    with pytest.raises(InputError, match="initial_pose"):
        FkService({"manipulator_config": str(RPR_YAML), "initial_pose": [1.0, 2.0]})


#: a mode other than the one initial_pose names is farther than this share of the scale from it (the shipped
#: initial poses are the tracked mode, written to 1e-3 mm or closer)
OTHER_MODE_SHARE = 1e-2


def test_shipped_params_files_are_valid():
    """Every shipped params file loads without a warning, starts the service on its manipulator and answers
    the config's example input (the leg lengths, or the actuator readings in radians / metres) with the
    mode its initial_pose names."""
    names = sorted(p.name for p in CONFIG.glob("params_*.yaml"))
    assert {"params_3rpr.yaml", "params_hexapod.yaml", "params_delta.yaml", "params_rus6.yaml",
            "params_linear_delta.yaml", "params_pus6.yaml"} <= set(names)
    for name in names:
        values, warnings = P.resolve(ros_args.load_params_file(str(CONFIG / name)))
        assert not warnings, (name, warnings)
        svc = FkService(dict(values, time_budget_ms=GENEROUS_BUDGET_MS))   # correctness here, not speed
        model = svc.model
        assert model.n_vars == len(values["initial_pose"])
        if getattr(model, "actuated", False):
            reading = model.readings_to_si(model.example_actuator_positions)
        else:
            reading = np.asarray(model.example_leg_lengths) * model.metres_per_unit
        out = svc.handle(reading.tolist(), 1)
        assert out.pose is not None and out.estimate.converged, (name, out.reason)
        assert model.distance(out.estimate.x, values["initial_pose"]) < OTHER_MODE_SHARE * model.scale, name


# -- solving, units, stamps ------------------------------------------------------------------------------

def test_converged_input_gives_a_pose_in_metres_stamped_with_the_arrival(service):
    out = service.handle(SEED_LEGS_M, stamp_ns=1_234_567_890_123)
    assert out.reason is None and out.pose is not None
    position, quaternion = pose_of(service.model, SEED_X)
    assert out.pose.stamp_ns == 1_234_567_890_123
    assert out.pose.frame_id == "base"
    np.testing.assert_allclose(out.pose.position, position, atol=1e-9)
    np.testing.assert_allclose(out.pose.orientation, quaternion, atol=1e-9)
    assert out.estimate.start == "warm"


def test_config_in_metres_gives_the_same_pose(tmp_path):
    doc = yaml.safe_load(RPR_YAML.read_text())
    doc["unit"] = "m"
    doc["base"] = (np.array(doc["base"]) / 1000).tolist()
    doc["platform"] = (np.array(doc["platform"]) / 1000).tolist()
    doc["leg_limits"] = (np.array(doc["leg_limits"]) / 1000).tolist()
    doc.pop("example_leg_lengths")
    path = tmp_path / "rpr_m.yaml"
    path.write_text(yaml.safe_dump(doc))
    x_m = [SEED_X[0] / 1000, SEED_X[1] / 1000, SEED_X[2]]
    svc = FkService({"manipulator_config": str(path), "initial_pose": x_m, "tolerance": 1e-26, **BUDGET})
    out = svc.handle(SEED_LEGS_M, 0)
    assert out.pose is not None, out.reason
    np.testing.assert_allclose(out.pose.position, [x_m[0], x_m[1], 0.0], atol=1e-9)


def test_hexapod_tracks_a_published_solution():
    doc = yaml.safe_load(HEX_YAML.read_text())
    svc = FkService({"manipulator_config": str(HEX_YAML), "initial_pose": doc["published_solutions"][10],
                     **BUDGET})
    x = svc.model.pose_variables(svc.model.pose_state(np.array(doc["published_solutions"][10])))
    legs_m = svc.model.inverse_kinematics(x) * svc.model.metres_per_unit
    out = svc.handle(legs_m, 0)
    assert out.pose is not None, out.reason
    position, quaternion = pose_of(svc.model, x)
    np.testing.assert_allclose(out.pose.position, position, atol=1e-9)
    assert abs(abs(float(np.dot(out.pose.orientation, quaternion))) - 1.0) < 1e-12


# -- rejections -------------------------------------------------------------------------------------------

@pytest.fixture
def limited_config(tmp_path):
    doc = yaml.safe_load(RPR_YAML.read_text())
    doc["leg_limits"] = [50.0, 250.0]
    path = tmp_path / "rpr_limits.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


BAD_INPUTS = [
    ([0.1, 0.12], "expected 3 leg lengths"),
    ([0.1, 0.12, 0.15, 0.2], "expected 3 leg lengths"),
    ([0.1, float("nan"), 0.15], "finite"),
    ([0.1, float("inf"), 0.15], "finite"),
    ([0.1, -0.12, 0.15], "positive"),
    ([0.1, 0.0, 0.15], "positive"),
    ([0.1, 0.12, 0.30], "limits"),
    ([0.06, 0.06, 0.06], "no_solution"),          # within limits, but no real assembly
]


def test_every_bad_input_is_rejected_with_a_reason_and_the_state_is_kept(limited_config):
    svc = FkService({"manipulator_config": str(limited_config), "initial_pose": SEED_X, **BUDGET})
    assert svc.handle(SEED_LEGS_M, 0).pose is not None
    for legs, reason in BAD_INPUTS:
        out = svc.handle(legs, 1)
        assert out.pose is None and reason in out.reason, (legs, out.reason)
        assert "\n" not in out.reason
    out = svc.handle([0.1, 0.12, 0.1501], 2)      # tracking resumes from the warm state
    assert out.pose is not None and out.estimate.start == "warm"
    assert abs(out.pose.position[0] - SEED_X[0] / 1000) < 1e-3

    report = svc.diagnostics()
    values = report.as_dict()
    assert report.level == WARN and "rejected" in report.message
    assert values["inputs rejected"] == str(len(BAD_INPUTS))
    assert values["inputs solved"] == "2"
    assert values["rejected: no_solution"] == "1"
    assert values["rejected: leg lengths must be finite (got NaN or inf)"] == "2"
    assert any(k.startswith("rejected: ") and "limits" in k for k in values)
    # a quiet period after that reads OK again
    svc.handle([0.1, 0.12, 0.1502], 3)
    assert svc.diagnostics().level == 0


def test_a_tuple_of_the_right_length_that_is_not_numbers_gets_the_reason(service):
    # a message's legs arrive as a tuple (the fast path's input): values that do not divide or compare are
    # named as such, not an internal error
    for legs in ((0.5j, 0.06, 0.06), ("a", 0.06, 0.06)):
        out = service.handle(legs, 0)
        assert out.pose is None and out.reason == "leg lengths are not numbers", (legs, out.reason)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(legs=st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=7))
def test_handle_never_raises(service, legs):
    out = service.handle(legs, 0)
    assert (out.pose is None) != (out.reason is None)


def test_rejections_are_logged_once_per_second_per_reason(service):
    lines = []

    class Log:
        def warning(self, msg):
            lines.append(msg)
        info = error = debug = warning

    service.log = Log()
    now = [0.0]                     # the throttle's clock: the result does not depend on the machine's
    service.log_throttle = LogThrottle(clock=lambda: now[0])
    for _ in range(50):
        service.handle([1.0], 0)
    assert len(lines) == 1 and "expected 3 leg lengths" in lines[0]
    now[0] = 1.5
    service.handle([1.0], 0)
    assert len(lines) == 2 and "(+49 similar suppressed)" in lines[1]


def test_log_throttle_counts_suppressed_lines():
    now = [0.0]
    throttle = LogThrottle(1.0, clock=lambda: now[0])
    assert throttle("a") == 0
    assert throttle("a") is None and throttle("a") is None
    assert throttle("b") == 0
    now[0] = 1.5
    assert throttle("a") == 2


# -- runtime parameter changes -------------------------------------------------------------------------------

def test_switching_solver_mid_run_keeps_the_warm_state(service):
    assert service.handle(SEED_LEGS_M, 0).pose is not None
    for solver, third in (("g3pcx", 0.1502), ("rcga", 0.1504), ("glpma", 0.1506)):
        assert service.set_parameters({"solver": solver}) == (True, "")
        out = service.handle([0.1, 0.12, third], 0)
        assert out.pose is not None, out.reason
        assert out.estimate.solver == solver and out.estimate.start == "warm"
    assert service.diagnostics().as_dict()["solver"] == "glpma"


def test_invalid_runtime_values_are_rejected_and_the_old_values_kept(service):
    before = dict(service.params)
    for change, message in (({"solver": "nelder-mead"}, "one of"),
                            ({"time_budget_ms": -1.0}, "> 0"),
                            ({"initial_pose": [1.0]}, "initial_pose"),
                            ({"qos_depth": 5}, "read-only"),
                            ({"manipulator_config": str(HEX_YAML)}, "read-only"),
                            ({"no_such": 1}, "unknown parameter"),
                            ({"solver": "g3pcx", "tolerance": 0.0}, "tolerance")):   # atomic: nothing applied
        ok, reason = service.set_parameters(change)
        assert not ok and message in reason, (change, reason)
        assert service.params == before
    assert service.handle(SEED_LEGS_M, 0).estimate.solver == "glpma"


def test_runtime_changes_apply(service):
    assert service.set_parameters({"frame_id": "world", "time_budget_ms": 4000.0, "tolerance": 1e-22}) == (True, "")
    out = service.handle(SEED_LEGS_M, 0)
    assert out.pose.frame_id == "world"
    assert service.estimator.time_budget_s == pytest.approx(4.0)
    assert out.estimate.fitness < 1e-22


def test_new_initial_pose_restarts_tracking_from_it(service):
    doc = yaml.safe_load(RPR_YAML.read_text())
    other = doc["real_solutions"][1]
    x_other = [other["x"], other["y"], math.radians(other["theta_deg"])]
    assert service.set_parameters({"initial_pose": x_other}) == (True, "")
    out = service.handle(SEED_LEGS_M, 0)       # same legs, the other assembly mode
    position, _ = pose_of(service.model, x_other)
    np.testing.assert_allclose(out.pose.position, position, atol=1e-9)
    assert service.set_parameters({"initial_pose": []}) == (True, "")
    assert service.diagnostics().as_dict()["warm state"].startswith("no")


def test_the_warm_state_is_the_estimators_and_survives_a_parameter_change(service):
    out = service.handle([0.1, 0.12, 0.1501], 1)
    assert out.pose is not None, out.reason
    # the same array, handed on (not recomputed): equal element for element
    np.testing.assert_array_equal(service.warm_x, service.estimator.warm_x)
    np.testing.assert_array_equal(service.warm_x, out.estimate.x)
    assert service.set_parameters({"tolerance": 1e-18}) == (True, "")
    np.testing.assert_array_equal(service.estimator.warm_x, out.estimate.x)     # the rebuilt estimator's
    assert service.diagnostics().as_dict()["warm state"] == "yes"


# -- the worker ----------------------------------------------------------------------------------------------------

def test_latest_input_keeps_only_the_newest():
    box = LatestInput()
    assert box.put(1) is False
    assert box.put(2) is True          # 1 was replaced: dropped
    assert box.get(0.01) == 2
    assert box.get(0.01) is None
    box.close()
    assert box.get(10) is None         # returns at once when closed


def test_solve_loop_solves_the_newest_input_and_counts_dropped(service):
    published, release = [], threading.Event()

    def publish(pose):
        published.append(pose)
        release.wait(WAIT_S)            # hold the worker while more inputs arrive

    loop = SolveLoop(service, publish, stats=service.stats, modes=service.modes).start()
    try:
        loop.submit(SEED_LEGS_M, 1)
        deadline = time.monotonic() + WAIT_S
        while not published and time.monotonic() < deadline:
            time.sleep(0.001)
        for k in range(2, 6):           # the worker is busy: each replaces the previous
            loop.submit([0.1, 0.12, 0.15 + k * 1e-5], k)
        release.set()
        while len(published) < 2 and time.monotonic() < deadline:
            time.sleep(0.001)
    finally:
        loop.stop()
    assert [p.stamp_ns for p in published] == [1, 5]
    values = service.diagnostics().as_dict()
    assert values["inputs dropped"] == "3" and values["inputs received"] == "5"


# -- transport choice ---------------------------------------------------------------------------------------

def test_node_entry_chooses_the_transport(monkeypatch, capsys):
    pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")
    from glpma_ros.node import entry as node_entry
    from glpma_ros.node.dds import node as dds_node
    calls = []
    monkeypatch.setattr(node_entry, "rclpy_available", lambda: False)
    monkeypatch.setattr(dds_node, "main", lambda argv: calls.append(argv) or 0)
    assert node_entry.main(["--transport", "auto", "--ros-args", "-p", "solver:=rcga"]) == 0
    assert calls == [["--ros-args", "-p", "solver:=rcga"]]
    assert node_entry.main(["--transport", "rclpy"]) == 2
    assert "rclpy is not importable" in capsys.readouterr().err
    assert node_entry.main(["--transport", "zmq"]) == 2


def test_a_message_s_legs_get_the_config_s_leg_offsets(tmp_path):
    """Readings from sensors that measure |B - A| less a fixed offset (the config's ``leg_offsets``, what
    ``glpma-fk calibrate`` identifies) are answered with the pose whose legs are reading + offset, on the
    everyday input's one-call way (a message's tuple of floats, warm, inside the band) and the long way (any
    other sequence) alike."""
    doc = yaml.safe_load(RPR_YAML.read_text())
    offsets = [0.8, -0.5, 1.2]                       # mm, the config's unit
    path = tmp_path / "offsets.yaml"
    path.write_text(yaml.safe_dump({**doc, "leg_offsets": offsets}))
    plain = FkService({"manipulator_config": str(RPR_YAML), **BUDGET})
    svc = FkService({"manipulator_config": str(path), "initial_pose": SEED_X, **BUDGET})
    model = svc.model
    for k, dx in enumerate((0.0, 0.4, 0.8, 1.2)):
        x = np.array(SEED_X) + np.array([dx, -dx, 0.002 * k])
        legs_mm = model.inverse_kinematics(x)                       # |B - A|
        readings_m = tuple(((legs_mm - offsets) * model.metres_per_unit).tolist())
        out = svc.handle(readings_m, 0)
        assert out.pose is not None, (k, out.reason)
        position, orientation = pose_of(model, x)
        # the pose is the one of the legs solved to round-off: a micrometre bounds it with room to spare
        np.testing.assert_allclose(out.pose.position, position, atol=1e-6)
        np.testing.assert_allclose(np.abs(np.dot(out.pose.orientation, orientation)), 1.0, atol=1e-9)
        long_way = svc.handle(list(readings_m), 0)
        assert long_way.pose is not None, (k, long_way.reason)
        np.testing.assert_allclose(long_way.pose.position, position, atol=1e-6)
        # without the offsets the same readings are other legs: not this pose
        other = plain.handle(readings_m, 0)
        assert other.pose is None or np.max(np.abs(np.asarray(other.pose.position) - position)) > 1e-4, k
