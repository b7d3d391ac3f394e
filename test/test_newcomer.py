"""A newcomer's first hour: config mistakes named, units that cannot bite, statuses the CLI shares
with the node, bad arguments in one line, ``--version``, ``| head -1`` without a traceback, a
``--help`` that describes every option, a params-file mistake refused, and the mock controller and
``glpma-fk modes`` working on what a user has."""
import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from conftest import CONFIG, HEX_YAML, ROOT, RPR_YAML, interrupt
from glpma_ros import __version__
from glpma_ros.cli.main import commands, main
from glpma_ros.config import load_manipulator, model_from_dict, unit_mistake
from glpma_ros.errors import ConfigError, GlpmaError, InputError
from glpma_ros.node.ros_args import check_params_files, load_params_file
from glpma_ros.runtime.compat import check_numba, inline_for

CONTRACT_SOLVE_KEYS = {"solver", "status", "fitness", "evaluations", "elapsed_s", "variables", "pose"}


def cli(*args, timeout=600, **kw):
    """``glpma-fk ARGS`` in a subprocess: (exit status, stdout, stderr)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    p = subprocess.run([sys.executable, "-m", "glpma_ros", *map(str, args)], capture_output=True, text=True,
                       cwd=ROOT, env=env, timeout=timeout, **kw)
    return p.returncode, p.stdout, p.stderr


def one_line_error(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# -- configs ---------------------------------------------------------------------------------------------

def seed_doc():
    return yaml.safe_load(RPR_YAML.read_text())


def test_config_without_unit_is_refused_with_the_key_named():
    doc = seed_doc()
    doc.pop("unit")
    with pytest.raises(ConfigError, match=r"missing key 'unit'"):
        model_from_dict(doc, "mine.yaml")


@pytest.mark.parametrize("key, hint", [("basee", "did you mean 'base'"), ("leg_limit", "did you mean 'leg_limits'"),
                                       ("colour", "known keys: manipulator, unit")])
def test_unknown_keys_are_named(key, hint):
    doc = seed_doc()
    doc[key] = 1
    with pytest.raises(ConfigError, match=f"mine.yaml: unknown key '{key}'.*{re.escape(hint)}"):
        model_from_dict(doc, "mine.yaml")


def test_a_typo_in_a_config_is_one_line_on_the_cli(tmp_path):
    text = RPR_YAML.read_text().replace("\nbase:", "\nbasee:")
    path = tmp_path / "typo.yaml"
    path.write_text(text)
    code, out, err = cli("solve", path, "--legs", 100, 120, 150)
    assert code == 2 and out == ""
    assert "unknown key 'basee' (did you mean 'base'?)" in one_line_error(err)


@pytest.mark.parametrize("config", [RPR_YAML, HEX_YAML])
def test_shipped_configs_have_leg_limits_holding_their_examples(config):
    model = load_manipulator(config)
    doc = yaml.safe_load(config.read_text())
    lo, hi = model.leg_limits
    assert lo < min(model.example_leg_lengths) and max(model.example_leg_lengths) < hi
    if "published_solutions" in doc:
        for x in doc["published_solutions"]:
            legs = model.inverse_kinematics(model.pose_variables(model.pose_state(np.array(x))))
            assert np.all((legs > lo) & (legs < hi))


# -- units -----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("config, legs, unit", [
    ("planar_3rpr_seed", [0.100, 0.120, 0.150], "metres"),
    ("hexapod_66_rolland", [1.25] * 6, "metres"),
])
def test_metres_given_to_a_mm_config_get_a_one_line_hint(config, legs, unit):
    code, out, err = cli("solve", config, "--legs", *legs)
    assert code == 2 and out == ""
    assert one_line_error(err) == f"error: leg lengths look like {unit}; this config is in mm"


def test_unit_rule_with_and_without_leg_limits(rpr):
    assert unit_mistake(rpr, [100, 120, 150]) is None
    assert unit_mistake(rpr, [60, 60, 60]) is None           # infeasible, not a unit mistake
    assert unit_mistake(rpr, [0.1, 0.12, 0.15]) == "m"
    assert unit_mistake(rpr, [100e3, 120e3, 150e3], given_unit="m") == "mm"   # mm on a metres topic
    doc = seed_doc()
    doc.pop("leg_limits")
    bare = model_from_dict(doc)          # band [scale/100, 100 scale] = [2, 20000] mm
    assert unit_mistake(bare, [0.1, 0.12, 0.15]) == "m"
    assert unit_mistake(bare, [10, 12, 15]) is None
    doc["unit"] = "m"
    doc["base"] = (np.array(doc["base"]) / 1000).tolist()
    doc["platform"] = (np.array(doc["platform"]) / 1000).tolist()
    doc.pop("example_leg_lengths")
    metric = model_from_dict(doc)
    assert unit_mistake(metric, [100, 120, 150]) == "mm"
    assert unit_mistake(metric, [0.1, 0.12, 0.15]) is None


def test_the_node_names_units_when_mm_come_on_the_metres_topic():
    from glpma_ros.node.service import FkService
    svc = FkService({"manipulator_config": str(RPR_YAML)})
    out = svc.handle([100.0, 120.0, 150.0], 0)
    assert out.pose is None and out.estimate is None
    assert out.reason == "leg lengths look like millimetres; topics are in metres (REP 103)"
    assert "no solve yet" in svc.summary() and "nan" not in svc.summary()


# -- the CLI says what the node says ---------------------------------------------------------------------

@pytest.mark.parametrize("legs, status", [([100, 120, 150], "converged"), ([60, 60, 60], "no_solution")])
@pytest.mark.parametrize("budget", [None, 5, 50])
def test_solve_reports_the_estimators_status(legs, status, budget):
    """Without a budget (evaluation caps) the status is exact; with one, the only other answer a
    busy machine may give is budget_exhausted, never a wrong status."""
    extra = [] if budget is None else ["--budget-ms", budget]
    code, out, err = cli("solve", "planar_3rpr_seed", "--legs", *legs, *extra, "--json")
    result = json.loads(out)
    assert CONTRACT_SOLVE_KEYS <= set(result)
    allowed = {status} if budget is None else {status, "budget_exhausted"}
    assert result["status"] in allowed, result
    if result["status"] != status:
        return
    assert code == (0 if status == "converged" else 1)
    assert result["load_s"] >= 0.0 and result["start"] == "cold"
    if status == "converged":
        model = load_manipulator(RPR_YAML)
        np.testing.assert_allclose(model.inverse_kinematics(result["variables"]), legs, atol=1e-9)


def test_solve_text_states_the_load_apart_and_warm_start():
    code, out, err = cli("solve", "planar_3rpr_seed", "--legs", 100, 120, 150.01,
                         "--near", 52.860968946, 84.886500470, -0.5840127840543605)
    assert code == 0, err
    assert "converged (warm start)" in out
    assert re.search(r"one-time load of the compiled solvers: [\d.]+ s \(not part of the solve time\)", out)


# -- bad arguments, version, pipes, help ------------------------------------------------------------------

@pytest.mark.parametrize("args, message", [
    (["solve", "planar_3rpr_seed", "--legs", "100", "120", "150", "--seed", "-1"], "--seed: '-1' must be"),
    (["solve-all", "planar_3rpr_seed", "--legs", "100", "120", "150", "--seed", "-1"], "--seed: '-1' must be"),
    (["solve", "planar_3rpr_seed", "--legs", "100", "120", "150", "--budget-ms", "0"], "--budget-ms"),
    (["solve", "planar_3rpr_seed", "--legs", "100", "120", "150", "--max-evals", "0"], "--max-evals"),
    (["solve", "planar_3rpr_seed", "--legs", "100", "120", "150", "--tolerance", "nan"], "--tolerance"),
    (["solve-all", "planar_3rpr_seed", "--legs", "100", "120", "150", "--runs", "0"], "--runs"),
    (["demo", "--solver", "foo"], "invalid choice: 'foo'"),
    (["precompile", "--solvers", "foo"], "unknown solver 'foo'"),
    (["solve"], "required"),
    ([], "required"),
])
def test_every_bad_argument_is_one_line_and_exit_2(args, message, capsys):
    assert main(args) == 2
    captured = capsys.readouterr()
    assert message in one_line_error(captured.err)


def test_version_matches_the_package():
    code, out, _ = cli("--version")
    assert code == 0 and out.strip() == f"glpma-fk {__version__}"
    assert ET.parse(ROOT / "package.xml").getroot().findtext("version") == __version__
    changelog = (ROOT / "README.md").read_text().split("## Changelog", 1)[1]
    # the newest release is this version (the changes of the next one gather under "- X.Y.Z -- unreleased:")
    first = next(line for line in changelog.splitlines() if line.startswith("- ") and "-- unreleased" not in line)
    assert first.startswith(f"- {__version__} -- "), first


def test_a_closed_pipe_ends_quietly():
    """``glpma-fk solve-all ... | head -1``: the reader is gone before the output is written."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "glpma_ros", "solve-all", "planar_3rpr_seed", "--legs", "100",
                             "120", "150", "--runs", "20"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            cwd=ROOT, env=env)
    proc.stdout.close()                      # as head does after its first line
    err = proc.stderr.read().decode()
    assert proc.wait(600) == 141
    assert "Traceback" not in err and "Exception ignored" not in err and "BrokenPipe" not in err, err
    shell = subprocess.run(f"'{sys.executable}' -m glpma_ros solve-all planar_3rpr_seed --legs 100 120 150 "
                           f"--runs 20 | head -1", shell=True, capture_output=True, text=True, cwd=ROOT, env=env,
                           timeout=600)
    assert shell.returncode == 0 and "distinct real assembly modes" in shell.stdout
    assert "Traceback" not in shell.stderr and "Exception ignored" not in shell.stderr, shell.stderr


def _subcommands():
    return sorted(commands())


def _options_of(help_text: str) -> tuple[set, set]:
    """(every option named in the usage, every option an option line describes)."""
    usage, _, body = help_text.partition("\n\n")
    named = set(re.findall(r"(?<![\w-])(--?[A-Za-z][\w-]*)", usage))
    described = set()
    lines = body.splitlines()
    for i, line in enumerate(lines):
        m = re.match(r"^( {2,4})(-.*)$", line)
        if not m:
            continue
        indent = len(m.group(1))
        signature, *description = re.split(r"\s{2,}", m.group(2), maxsplit=1)
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        continued = nxt.strip() and len(nxt) - len(nxt.lstrip()) > indent and not nxt.strip().startswith("-")
        if (description and description[0].strip()) or continued:
            described |= set(re.findall(r"(?<![\w-])(--?[A-Za-z][\w-]*)", signature))
    return named, described


@pytest.mark.parametrize("command", [None] + _subcommands())
def test_help_describes_every_option(command, capsys):
    if command == "bag":        # the optional extra: without it `bag --help` says which pip command installs it
        pytest.importorskip("rosbags", reason="glpma-fk bag needs the optional rosbags (pip install '.[bag]')")
    args = ["--help"] if command is None else [command, "--help"]
    code = main(args)
    text = capsys.readouterr().out
    assert code == 0 and text.startswith("usage:"), text
    assert "``" not in text and ":class:" not in text          # no raw reST
    named, described = _options_of(text)
    assert named, text
    assert named <= described, f"{command}: options without a description: {sorted(named - described)}"


# -- node parameters, mock controller, numba ---------------------------------------------------------------

def test_a_manipulator_yaml_as_params_file_is_refused(tmp_path):
    with pytest.raises(InputError, match=r"is a manipulator config, not a ROS 2 params file: pass it as "
                                         r"-p manipulator_config:="):
        load_params_file(str(RPR_YAML))
    with pytest.raises(InputError, match="manipulator config"):
        check_params_files(["--ros-args", "-p", "seed:=1", "--params-file", str(HEX_YAML)])
    check_params_files(["--ros-args", "--params-file", str(CONFIG / "params_3rpr.yaml")])    # a real one passes
    code, out, err = cli("node", "--transport", "dds", "--ros-args", "--params-file", RPR_YAML, timeout=120)
    assert code == 2
    assert "manipulator config, not a ROS 2 params file" in one_line_error(err)


@pytest.mark.parametrize("config, key", [(RPR_YAML, "real_solutions"), (HEX_YAML, "published_solutions")])
def test_mock_controller_drives_a_users_config_without_known_solutions(config, key):
    from glpma_ros.models.rotations import quaternion_from_matrix
    from glpma_tools.sim.trajectories import legs_for, start_pose
    doc = yaml.safe_load(config.read_text())
    doc.pop(key)
    model = model_from_dict(doc, "mine.yaml")
    position, rotation = start_pose(model, doc)
    legs = legs_for(model, position, quaternion_from_matrix(rotation))
    np.testing.assert_allclose(legs, model.example_leg_lengths, rtol=1e-9)
    doc.pop("example_leg_lengths")
    with pytest.raises(GlpmaError, match="example_leg_lengths"):
        start_pose(model_from_dict(doc, "mine.yaml"), doc)


def test_numba_floor():
    with pytest.raises(GlpmaError, match=r"numba 0\.56\.4\+dfsg is too old; glpma_ros needs numba >= 0\.58"):
        check_numba("0.56.4+dfsg")
    check_numba("0.58.1")
    check_numba()                            # the installed one


def test_numba_ir_inlining_only_where_the_inliner_is_fast():
    # before 0.59 nested inline="always" sites copy the callee's IR at each level: a precompile of tens of minutes
    assert inline_for("0.58.1") == "never"
    assert inline_for("0.59.0") == "always"
    assert inline_for("0.68.1") == "always"


# -- glpma-fk modes against a running node -----------------------------------------------------------------

def test_modes_asks_a_running_node(tmp_path, dds_env):
    pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")
    from test_dds_integration import SEED_X
    env = dds_env
    out, err = tmp_path / "node.out", tmp_path / "node.err"
    params = tmp_path / "params.yaml"
    params.write_text(yaml.safe_dump({"glpma_fk": {"ros__parameters": {
        "manipulator_config": str(RPR_YAML), "initial_pose": SEED_X, "time_budget_ms": 50.0,
        "diagnostics_period_s": 0.2}}}))
    with open(out, "w") as fo, open(err, "w") as fe:
        node = subprocess.Popen([sys.executable, "-m", "glpma_ros.node.dds.node", "--ros-args", "--params-file",
                                 str(params)], stdout=fo, stderr=fe, env=env, cwd=ROOT)
    try:
        import time
        deadline = time.monotonic() + 300
        while "ready" not in out.read_text():
            assert node.poll() is None and time.monotonic() < deadline, err.read_text()
            time.sleep(0.1)
        modes = [sys.executable, "-m", "glpma_ros", "modes", "--node", "glpma_fk", "--json", "--timeout", "60"]
        before = subprocess.run(modes, capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
        assert before.returncode == 1
        assert "no input received yet on leg_lengths" in one_line_error(before.stderr)
        send = ("from glpma_ros.node.dds import endpoints; from glpma_ros.node.dds.messages import Float64MultiArray; "
                "import time; p = endpoints.Participant(); w = p.writer('leg_lengths', Float64MultiArray); "
                "endpoints.wait_for_match([w], 30); w.write(Float64MultiArray(data=[0.1, 0.12, 0.15])); time.sleep(1)")
        subprocess.run([sys.executable, "-c", send], env=env, cwd=ROOT, timeout=120, check=True)
        after = subprocess.run(modes, capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
        assert after.returncode == 0, after.stderr
        answer = json.loads(after.stdout)
        assert answer["frame_id"] == "base" and len(answer["modes"]) == 2       # the seed's two real modes
        model = load_manipulator(RPR_YAML)
        for mode in answer["modes"]:
            x = model.variables_from_pose(np.array(mode["position"]) / model.metres_per_unit, mode["orientation"])
            np.testing.assert_allclose(model.inverse_kinematics(x), [100, 120, 150], atol=1e-6)
    finally:
        interrupt(node)


# -- the demo's verdict says only what happened ---------------------------------------------------------

def _demo_summary(**kw):
    s = {"inputs_sent": 500, "poses_received": 500, "poses_matched": 500, "poses_unpaired": 0, "poses_wrong": 0,
         "pose_ratio": 1.0, "counters_add_up": True, "latency_ms": {"p50": 0.4, "p99": 1.0, "max": 2.0},
         "load_average": [9.0, 9.0, 9.0], "cores": 2, "late_sends": 3, "lost_in_transport": 0,
         "node_counters": {"received": 500, "solved": 500, "rejected": 0, "dropped": 0}, "node_diagnostics": None}
    s.update(kw)
    return s


def test_demo_verdict_on_a_busy_machine_that_answered_everything():
    from glpma_tools.mock_controller import verdict
    ok, lines = verdict(_demo_summary())
    text = "\n".join(lines)
    assert ok and "500 of 500 inputs answered (100.0 %)" in text
    assert "fewer" not in text and "got no pose" not in text
    assert "the machine looked busy (load average 9.00 on 2 cores" in text and "every input got its pose" in text


def test_demo_verdict_names_the_inputs_without_a_pose():
    from glpma_tools.mock_controller import verdict
    counters = {"received": 500, "solved": 401, "rejected": 0, "dropped": 99}
    ok, lines = verdict(_demo_summary(poses_received=401, poses_matched=401, pose_ratio=0.802,
                                      node_counters=counters))
    text = "\n".join(lines)
    assert ok and "99 of 500 inputs got no pose; the machine looked busy (" in text
    assert "the node dropped 99 inputs for newer ones" in text
    quiet = _demo_summary(poses_received=499, poses_matched=499, pose_ratio=0.998, load_average=[0.1] * 3,
                          late_sends=0)
    ok, lines = verdict(quiet)
    assert lines[-1] == "1 of 500 inputs got no pose" and not any("busy" in line for line in lines)


# -- solve-all names its columns --------------------------------------------------------------------------

#: a printed value has 6 decimals: legs recomputed from the printed pose agree to a few units of the
#: last printed digit times the geometry's lever arms (the hexapod's platform joints sit ~1000 mm out)
PRINTED_LEG_TOL = {"planar_3rpr": 1e-4, "hexapod_66": 1e-2}


@pytest.mark.parametrize("config, legs", [(RPR_YAML, [100, 120, 150]), (HEX_YAML, [1250] * 6)])
def test_solve_all_text_names_its_columns(config, legs, capsys):
    from glpma_ros.cli.solve_all import mode_columns
    model = load_manipulator(config)
    assert main(["solve-all", str(config), "--legs", *map(str, legs), "--max-starts", "2000"]) == 0
    out = capsys.readouterr().out.splitlines()
    header = next(i for i, line in enumerate(out) if line.lstrip().startswith("#"))
    names = mode_columns(model)
    assert out[header].split()[1:] == " ".join(names).split()
    rows = [line.split() for line in out[header + 1:]]
    assert rows and all(len(r) == 1 + len(names) for r in rows)
    for r in rows:                     # each row's pose answers the legs asked for
        v = np.array(r[1:-1], dtype=float)
        if model.kind == "planar_3rpr":
            x = v
        else:
            x = model.variables_from_pose(v[:3], v[3:7])
            assert np.allclose(v[7:], x, atol=PRINTED_LEG_TOL[model.kind])   # the variables are the pose's
        assert np.allclose(model.inverse_kinematics(x), legs, atol=PRINTED_LEG_TOL[model.kind])
    help_text = subprocess.run([sys.executable, "-m", "glpma_ros", "solve-all", "--help"], capture_output=True,
                               text=True, cwd=ROOT, timeout=600).stdout
    assert "px py pz" in help_text and "qx qy qz qw" in help_text and "theta [rad]" in help_text


# -- config errors name every problem, the parser's own words, the shipped names ------------------------

def test_a_config_with_several_problems_names_them_all():
    doc = seed_doc()
    doc["units"] = doc.pop("unit")
    doc["platform"] = [[0, 0], [50, 0]]
    doc["leg_limits"] = [5, 1]
    with pytest.raises(ConfigError) as info:
        model_from_dict(doc, "mine.yaml")
    message = str(info.value)
    assert "\n" not in message and message.startswith("mine.yaml: 4 problems: ")
    for words in ("unknown key 'units' (did you mean 'unit'?)", "missing key 'unit'",
                  "'platform' must have 3 points of 2 coordinates", "'leg_limits' must satisfy 0 <= min < max"):
        assert words in message


def test_a_yaml_syntax_error_gives_the_parsers_message_and_position(tmp_path):
    path = tmp_path / "unclosed.yaml"
    path.write_text("manipulator: planar_3rpr\nunit: mm\nbase: [[0, 0], [200, 0], [0, 200]\n"   # no closing ]
                    "platform: [[0, 0], [50, 0], [40, 40]]\n")
    code, out, err = cli("solve", path, "--legs", 100, 120, 150)
    line = one_line_error(err)
    assert code == 2 and "invalid YAML: while parsing a flow sequence at line 3, column 7" in line
    assert "expected ',' or ']'" in line and "at line 4, column 1" in line


def test_an_unknown_config_name_lists_the_shipped_ones():
    code, out, err = cli("solve", "planar_3rpr", "--legs", 100, 120, 150)
    line = one_line_error(err)
    assert code == 2 and "no such file" in line
    assert "planar_3rpr_seed" in line and "hexapod_66_rolland" in line


# -- precompile says what it did, without guessing the time left -----------------------------------------

def test_precompile_counts_what_it_compiled_or_loaded():
    """One line per step, saying what Numba compiled or loaded (counted), and no guessed time left."""
    code, out, err = cli("precompile", "--solvers", "rcga")
    assert code == 0 and out == "", err
    steps = [line for line in err.splitlines() if re.match(r"precompile: \[\d+/\d+\]", line)]
    assert len(steps) == 4 and not any("left" in line for line in err.splitlines())
    assert [line.split()[2:4] for line in steps] == [["planar_3rpr", "rcga:"], ["hexapod_66", "rcga:"],
                                                      ["planar_3rpr", "solve-all:"], ["hexapod_66", "solve-all:"]]
    pattern = (r"precompile: \[\d/4\] (planar_3rpr|hexapod_66) (rcga|solve-all): (compiled \d+ functions?"
               r"(, loaded \d+)?|loaded \d+ compiled functions? from the cache|nothing new to load) in [\d.]+ s$")
    assert all(re.match(pattern, line) for line in steps), steps
    first = steps[0]               # a fresh process: the first step compiles or loads something
    assert "nothing new" not in first, first


def test_cache_counts_words():
    from glpma_ros.runtime.precompile import describe_cache_use
    assert describe_cache_use(0, 3) == "compiled 3 functions"
    assert describe_cache_use(2, 1) == "compiled 1 function, loaded 2"
    assert describe_cache_use(5, 0) == "loaded 5 compiled functions from the cache"
    assert describe_cache_use(0, 0) == "nothing new to load"
