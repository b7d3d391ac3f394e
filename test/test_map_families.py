"""glpma-fk map on the actuated families: the Delta's slices counted by its closed form (checked against the
multistart), the 6-RUS and the 3-RRR by the multistart, every family's coordinates and defaults."""
import json
import subprocess
import sys

import numpy as np
import pytest
from test_families_outputs import FAMILY_CONFIGS

from conftest import CONFIG, ROOT
from glpma_ros.config import load_manipulator
from glpma_ros.modes.multistart import solve_all
from glpma_tools.bench.report import APART
from glpma_tools.workspace_map.grid import OUTSIDE, coordinates_of, pose_variables

DELTA_YAML = CONFIG / "delta_irb360.yaml"


def _map(*args):
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "map", *map(str, args)], capture_output=True, text=True,
                       cwd=ROOT, timeout=900)
    return p


def _load(out):
    with np.load(out / "assembly_modes.npz") as f:
        return {k: f[k] for k in f.files}


@pytest.mark.parametrize("config, names", [
    ("delta_irb360.yaml", ("x", "y", "z")),
    ("rus6_simulator.yaml", ("x", "y", "z", "roll", "pitch", "yaw")),
    ("planar_3rrr_symmetric.yaml", ("x", "y", "theta")),
])
def test_family_coordinates(config, names):
    assert coordinates_of(load_manipulator(CONFIG / config)) == names


def test_delta_map_counts_the_closed_form_modes(tmp_path):
    """The default for the Delta is its closed form: two mirror modes wherever the legs reach; the multistart
    (an independent method) finds the same count at every point."""
    p = _map(DELTA_YAML, "--out", tmp_path, "--limits", -200, 200, -150, 150, "--resolution", 3, 2, "--workers", 1,
             "--json", "--at", "z=-1000")
    assert p.returncode == 0, p.stderr
    summary = json.loads(p.stdout)
    assert summary["method"] == "the closed form" and summary["points"] == 6
    data = _load(tmp_path)
    assert str(data["method"]) == "closed_form" and list(data["fixed_names"]) == ["z"]
    model = load_manipulator(DELTA_YAML)
    counts = data["counts"].reshape(-1)
    assert np.all(counts == 2)          # this slice is inside the Delta's reach: every point has its two modes
    for k, (y, x) in enumerate((y, x) for y in data["axis_1"] for x in data["axis_0"]):
        legs = model.inverse_kinematics(pose_variables(model, {"x": x, "y": y, "z": -1000.0}))
        assert len(solve_all(model, legs, method="multistart", seed=k).solutions) == counts[k]


def test_delta_map_marks_points_out_of_reach(tmp_path):
    """A slice partly beyond the arms' reach: those points have no valid legs (count -1)."""
    p = _map(DELTA_YAML, "--out", tmp_path, "--axes", "x", "z", "--limits", 0, 1500, -1100, -1000,
             "--resolution", 2, 2, "--workers", 1, "--json")
    assert p.returncode == 0, p.stderr
    counts = _load(tmp_path)["counts"]
    assert np.all(counts[:, 0] == 2) and np.all(counts[:, 1] == OUTSIDE)


@pytest.mark.parametrize("config", ["rus6_simulator.yaml", "planar_3rrr_symmetric.yaml"])
def test_full_pose_families_map_by_the_multistart(tmp_path, config):
    """Default method (the multistart), default ranges: each mapped pose is one of its legs' modes (count >= 1)."""
    path = CONFIG / config
    model = load_manipulator(path)
    x0 = model.pose(model.home_variables()).position
    p = _map(path, "--out", tmp_path, "--limits", x0[0] - 5, x0[0] + 5, x0[1] - 5, x0[1] + 5, "--resolution", 2, 2,
             "--workers", 1, "--json", "--max-starts", 300)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["method"] == "the multistart (at most 300 starts per point)"
    counts = _load(tmp_path)["counts"]
    assert counts.shape == (2, 2) and np.all(counts >= 1)


@pytest.mark.parametrize("args, words", [
    ([DELTA_YAML, "--axes", "x", "roll"], "not 'roll'"),
    ([CONFIG / "rus6_simulator.yaml", "--method", "closed_form"], "no closed-form"),
    ([DELTA_YAML, "--exact", 2], "actuated family"),
])
def test_bad_family_maps_are_one_line(tmp_path, args, words):
    p = _map(*args, "--out", tmp_path / "out", "--resolution", 2)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and words in p.stderr, p.stderr


def test_bench_families_script_reports_every_family(tmp_path):
    """tools/bench_families.py: a row per family beside the leg-length models, measured in one run, kept in
    BENCHMARKS.md when glpma-fk bench rewrites it (report.APART)."""
    assert "doc/bench/families.md" in APART
    out = tmp_path / "families.md"
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "bench_families.py"), "--steps", "40", "--cold", "2",
                        "--markdown", str(out)], capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    for label in ("3-RPR", "6-6 hexapod", "load average", "closed_form", "calls after an untimed one", "reference p50",
                  *(c[:-5] for c in FAMILY_CONFIGS)):
        assert label in text
    bad = subprocess.run([sys.executable, str(ROOT / "tools" / "bench_families.py"), "--cold", "0"],
                         capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1
