"""glpma-fk solve / solve-all as the contract states: JSON shape, exit status 2
with one line on stderr for bad input, no traceback."""
import json
import subprocess
import sys

import pytest

from conftest import HEX_YAML, ROOT, RPR_YAML
from glpma_ros.cli.main import main

#: a bound for a hung command, not a timing figure: a cold Numba cache on a busy machine takes minutes
TIMEOUT_S = 600


def run(*args):
    return subprocess.run([sys.executable, "-m", "glpma_ros", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, timeout=TIMEOUT_S)


def run_json(*args, returncode=0):
    """The command's JSON output, once its exit status (``None``: 0 or 1, a result either way) and
    stderr say it ran to the end."""
    p = run(*args)
    ok = p.returncode in (0, 1) if returncode is None else p.returncode == returncode
    assert ok and "Traceback" not in p.stderr, f"exit status {p.returncode}\n{p.stderr}"
    return json.loads(p.stdout)


def test_solve_json():
    p = run("solve", RPR_YAML, "--legs", 100, 120, 150, "--json", "--seed", 3)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    # the documented keys (more may be added, none removed)
    assert {"solver", "status", "fitness", "evaluations", "elapsed_s", "variables", "pose"} <= set(out)
    assert out["status"] == "converged" and out["fitness"] < 1e-20 and out["solver"] == "glpma"
    assert len(out["variables"]) == 3 and out["pose"]["position"][2] == 0.0
    assert len(out["pose"]["orientation"]) == 4


def test_solve_near_warm_start_selects_branch():
    out = run_json("solve", RPR_YAML, "--legs", 100, 120, 150, "--near", 97, 20, 1.5, "--json", "--solver", "g3pcx")
    assert out["status"] == "converged"
    assert abs(out["variables"][0] - 97.996115113) < 1e-6


def test_solve_no_polish_reports_status():
    out = run_json("solve", RPR_YAML, "--legs", 100, 120, 150, "--json", "--no-polish", "--solver", "rcga",
                   "--max-evals", 500, returncode=1)
    assert out["status"] == "max_evals" and out["evaluations"] <= 500


def test_solve_all_json():
    p = run("solve-all", HEX_YAML, "--legs", *[1250] * 6, "--json", "--runs", 200)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert len(out["solutions"]) == 16 and out["runs"] == 200
    assert set(out["solutions"][0]) == {"variables", "pose", "fitness"}


@pytest.mark.parametrize("args, words", [
    (["solve", RPR_YAML, "--legs", 100, 120], "expected 3 leg lengths"),
    (["solve", RPR_YAML, "--legs", 100, 120, "nan"], "finite"),
    (["solve", RPR_YAML, "--legs", 100, 120, "inf"], "finite"),
    (["solve", RPR_YAML, "--legs", 100, -120, 150], "positive"),
    (["solve", "missing.yaml", "--legs", 1, 2, 3], "cannot read"),
    (["solve", RPR_YAML, "--legs", 100, 120, "abc"], "invalid float"),
    (["solve", RPR_YAML, "--legs", 1, 2, 3, "--solver", "newton"], "invalid choice"),
    (["solve", RPR_YAML, "--legs", 1, 2, 3, "--near", 1, 2], "expected 3 solver variables"),
    (["solve", RPR_YAML, "--legs", 1, 2, 3, "--init-range", 5, 1], "--init-range"),
    (["solve-all", HEX_YAML, "--legs", 1, 2, 3], "expected 6 leg lengths"),
    (["solve-all", RPR_YAML, "--legs", 1, 2, 3, "--runs", 0], "--runs"),
    (["frobnicate"], "invalid choice"),
    ([], "required"),
])
def test_bad_input_exit_2_one_line(args, words, capsys):
    """In this process (a new interpreter per case costs seconds on a busy machine: the two cases
    below run as commands)."""
    assert main([str(a) for a in args]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], captured.err
    assert captured.out == ""


@pytest.mark.parametrize("args, words", [
    (["solve", RPR_YAML, "--legs", 100, 120], "expected 3 leg lengths"),
    (["solve", "missing.yaml", "--legs", 1, 2, 3], "cannot read"),
])
def test_bad_input_exit_2_one_line_from_the_command(args, words):
    p = run(*args)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], p.stderr
    assert "Traceback" not in p.stderr and p.stdout == ""


def test_bad_config_file(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("manipulator: planar_3rpr\nunit: mm\nbase: [[0,0],[1,0],[0,1]]\nplatform: [[0,0],[1,0],[2,0]]\n")
    assert main(["solve", str(bad), "--legs", "1", "1", "1"]) == 2
    err = capsys.readouterr().err
    assert "collinear" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("config, legs", [(RPR_YAML, [100, 120, 150]), (HEX_YAML, [1250] * 6)],
                         ids=["3rpr", "hexapod"])
def test_solve_papers_protocol_init_range(config, legs, rpr, hexapod):
    """The papers' protocol from the command line: a uniform initial range for every variable
    (the papers' -50..50 and -1000..1000) and the evolutionary solver alone, capped at the papers'
    evaluations; then the same range with the refinement, which must converge."""
    from glpma_ros.solvers import PAPER_SETTINGS
    from glpma_ros.solvers.common import DEFAULT_TOLERANCE
    model = rpr if config == RPR_YAML else hexapod
    paper = PAPER_SETTINGS[model.kind]
    low, high = paper["init_range"]
    papers = run_json("solve", config, "--legs", *legs, "--init-range", low, high, "--no-polish",
                      "--max-evals", paper["max_evals"], "--json", returncode=None)
    # the papers' success rate is not 100 % on the hexapod: converged, or out of evaluations
    assert papers["status"] in ("converged", "max_evals") and papers["evaluations"] > 0
    if model.kind == "planar_3rpr":
        assert papers["status"] == "converged" and papers["fitness"] < DEFAULT_TOLERANCE
    polished = run_json("solve", config, "--legs", *legs, "--init-range", low, high, "--json")
    assert polished["status"] == "converged"
    # the pose reproduces the legs (round-off relative to the scale)
    back = model.inverse_kinematics(polished["variables"])
    assert max(abs(b - l) for b, l in zip(back, legs)) <= 1e-9 * model.scale


def test_solve_all_methods_and_limits():
    """solve-all's options with valid values: the multistart under a start cap and a generous
    wall-clock budget finds the seed's two modes; --method g3pcx with --runs does too."""
    ms = run_json("solve-all", RPR_YAML, "--legs", 100, 120, 150, "--method", "multistart", "--max-starts", 5000,
                  "--budget-s", 600, "--seed", 1, "--json")
    assert ms["method"] == "multistart" and len(ms["solutions"]) == 2 and ms["starts"] <= 5000
    assert ms["load_s"] >= 0 and ms["elapsed_s"] >= 0
    g3 = run_json("solve-all", RPR_YAML, "--legs", 100, 120, 150, "--method", "g3pcx", "--runs", 20, "--json")
    assert g3["method"] == "g3pcx" and g3["runs"] == 20 and len(g3["solutions"]) == 2
