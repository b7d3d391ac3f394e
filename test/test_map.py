"""glpma-fk map: the seed 3-RPR at its published orientation, on every engine."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import yaml

from conftest import HEX_YAML, ROOT, RPR_YAML
from glpma_ros.models.hexapod_66 import quaternion_from_matrix, rotation_from_vector
from glpma_ros.solve_all import solve_all
from glpma_tools import workspace_map as W

#: the published example: legs 100 120 150 mm, real_solutions[0] of the seed config
EXAMPLE = yaml.safe_load(RPR_YAML.read_text())["real_solutions"][0]
STEP = 25.0          # grid spacing (mm); the example's pose is the grid's centre node
HALF = 4             # nodes on each side of the centre
RUNS = W.DEFAULT_RUNS
CHECK_RUNS = 300     # the independent check: more runs, other seeds


def seed_spec(runs=RUNS):
    n = 2 * HALF + 1
    limits = tuple((c - HALF * STEP, c + HALF * STEP) for c in (EXAMPLE["x"], EXAMPLE["y"]))
    return W.MapSpec("planar_3rpr", ("x", "y"), limits, (n, n), (("theta", EXAMPLE["theta_deg"]),), runs, 0)


@pytest.fixture(scope="module")
def config_text():
    return yaml.safe_dump(yaml.safe_load(RPR_YAML.read_text()), sort_keys=True)


@pytest.fixture(scope="module")
def serial_map(tmp_path_factory, config_text):
    out = tmp_path_factory.mktemp("map-serial")
    result = W.compute_map(config_text, str(RPR_YAML), seed_spec(), out, workers=1, progress=False)
    return out, result


def _counts(out):
    with np.load(out / "assembly_modes.npz") as f:
        return f["counts"], f["conditioning"], f["jacobian_sign"]


def test_published_example_has_two_modes(serial_map, rpr):
    out, result = serial_map
    counts, cond, _ = _counts(out)
    assert counts.shape == (2 * HALF + 1, 2 * HALF + 1) and counts.dtype == np.int16
    spec = seed_spec()
    centre = HALF * spec.shape[0] + HALF
    x = W.pose_variables(rpr, spec.coordinates(centre))
    assert np.allclose(rpr.inverse_kinematics(x), [100.0, 120.0, 150.0], atol=1e-6)
    assert counts[HALF, HALF] == 2
    assert cond[HALF, HALF] == pytest.approx(rpr.conditioning(x, rpr.inverse_kinematics(x)))
    assert result.computed == spec.n_points and result.chunks_reused == 0
    png = (out / "assembly_modes.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_counts_agree_with_independent_solve_all(serial_map, rpr):
    counts = _counts(serial_map[0])[0].reshape(-1)
    spec = seed_spec()
    rng = np.random.default_rng(2024)
    for index in rng.choice(spec.n_points, size=20, replace=False):
        x = W.pose_variables(rpr, spec.coordinates(index))
        legs = rpr.inverse_kinematics(x)
        modes = solve_all(rpr, legs, runs=CHECK_RUNS, seed=10_000 + int(index))
        assert len(modes.solutions) == counts[index], spec.coordinates(index)


def test_same_map_on_local_processes_and_dask(serial_map, tmp_path, config_text):
    distributed = pytest.importorskip("distributed")
    reference = _counts(serial_map[0])
    spec = seed_spec()
    local = W.compute_map(config_text, str(RPR_YAML), spec, tmp_path / "local", workers=2, progress=False)
    assert local.engine == "2 processes" and local.chunks_computed == spec.shape[1]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        dask = W.compute_map(config_text, str(RPR_YAML), spec, tmp_path / "dask", scheduler=cluster.scheduler_address,
                             chunk_size=7, progress=False)
    assert dask.engine.startswith("Dask") and dask.chunks_computed == math.ceil(spec.n_points / 7)
    for out in (tmp_path / "local", tmp_path / "dask"):
        counts, cond, sign = _counts(out)
        assert counts.tobytes() == reference[0].tobytes()
        # the same points solved in other processes: the same figures to round-off (conditioning is a
        # ratio of singular values, relative round-off ~1e-15; NaN where no mode was found)
        np.testing.assert_allclose(cond, reference[1], rtol=1e-9, equal_nan=True)
        assert np.array_equal(sign, reference[2])


def test_rerun_skips_finished_chunks(tmp_path, config_text):
    spec = seed_spec(runs=3)
    first = W.compute_map(config_text, str(RPR_YAML), spec, tmp_path, workers=1, progress=False)
    chunk_files = sorted((tmp_path / "chunks").glob("*/*.npz"))
    assert len(chunk_files) == spec.shape[1] and first.chunks_computed == spec.shape[1]
    reference = _counts(tmp_path)[0]
    chunk_files[2].unlink()
    chunk_files[5].write_bytes(b"truncated")          # an interrupted write is computed again
    again = W.compute_map(config_text, str(RPR_YAML), spec, tmp_path, workers=1, progress=False)
    assert again.chunks_computed == 2 and again.chunks_reused == spec.shape[1] - 2
    assert again.computed == 2 * spec.shape[0]
    assert _counts(tmp_path)[0].tobytes() == reference.tobytes()
    other = W.compute_map(config_text, str(RPR_YAML), seed_spec(runs=4), tmp_path, workers=1, progress=False)
    assert other.chunks_reused == 0                      # another map: its own chunks


def test_hexapod_slice_poses(hexapod, tmp_path):
    """Any two pose coordinates; roll, pitch, yaw compose as Rz Ry Rx (REP 103)."""
    r, p, y = 10.0, -20.0, 30.0
    R = (rotation_from_vector(np.radians([0, 0, y])) @ rotation_from_vector(np.radians([0, p, 0]))
         @ rotation_from_vector(np.radians([r, 0, 0])))
    q = W.quaternion_from_rpy(*np.radians([r, p, y]))
    assert np.allclose(q, quaternion_from_matrix(R), atol=1e-12)
    spec = W.MapSpec("hexapod_66", ("x", "z"), ((-100.0, 100.0), (800.0, 1000.0)), (2, 3),
                     (("y", 50.0), ("roll", r), ("pitch", p), ("yaw", y)), 1, 0)
    coords = spec.coordinates(5)
    assert coords["x"] == 100.0 and coords["z"] == 1000.0
    pose = hexapod.pose(W.pose_variables(hexapod, coords))
    assert np.allclose(pose.position, [100.0, 50.0, 1000.0]) and np.allclose(pose.orientation, q)
    text = yaml.safe_dump(yaml.safe_load(HEX_YAML.read_text()), sort_keys=True)
    result = W.compute_map(text, str(HEX_YAML), spec, tmp_path, workers=1, progress=False)
    counts, cond, _ = _counts(tmp_path)
    assert counts.shape == (3, 2) and np.all(counts >= 0) and np.all((cond > 0) & (cond < 1))
    assert result.points == 6


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "glpma_ros", "map", *map(str, args)], capture_output=True,
                          text=True, cwd=ROOT, timeout=300)


@pytest.mark.parametrize("args, words", [
    (["missing.yaml", "--out", "{tmp}"], "cannot read"),
    ([RPR_YAML, "--out", "{tmp}", "--resolution", 1_000_000, 1_000_000], "GiB"),
    ([RPR_YAML, "--out", "{tmp}", "--axes", "x", "z"], "not 'z'"),
    ([RPR_YAML, "--out", "{tmp}", "--at", "yaw=3"], "--at expects"),
    ([RPR_YAML, "--out", "{tmp}", "--limits", 5, 1, 0, 1], "LOW < HIGH"),
    ([RPR_YAML, "--out", "{tmp}", "--resolution", 1], "at least 2"),
    ([RPR_YAML, "--out", "{tmp}", "--runs", 0], "--runs"),
    ([RPR_YAML, "--out", "{tmp}", "--resolution", 3, "--scheduler", "tcp://127.0.0.1:9"], "Dask scheduler"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, words):
    if words == "Dask scheduler":   # without the optional extra the one line names its pip command instead
        pytest.importorskip("distributed", reason="glpma-fk map --scheduler needs the optional dask.distributed")
    p = _cli(*[a.format(tmp=tmp_path / "out") if isinstance(a, str) else a for a in args])
    assert p.returncode == 2, p.stderr
    assert p.stderr.count("\n") == 1 and p.stderr.startswith("error: glpma-fk map:") and words in p.stderr, p.stderr


def test_cli_writes_the_map(tmp_path):
    p = _cli(RPR_YAML, "--out", tmp_path, "--axes", "x", "y", "--limits", 20, 80, 50, 110, "--resolution", 3, 2,
             "--runs", 2, "--workers", 1, "--chunk-size", 3, "--json", "--at", "theta=10")
    assert p.returncode == 0, p.stderr
    summary = json.loads(p.stdout)
    assert summary["points"] == 6 and summary["engine"] == "this process"
    with np.load(tmp_path / "assembly_modes.npz") as f:
        assert f["counts"].shape == (2, 3) and list(f["fixed_names"]) == ["theta"] and f["fixed_values"][0] == 10


def test_cli_on_a_dask_scheduler(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        p = _cli(RPR_YAML, "--out", tmp_path, "--resolution", 2, "--runs", 2, "--scheduler", c.scheduler_address,
                 "--json")
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["engine"].startswith("Dask")


def test_cli_help_describes_every_option():
    h = _cli("--help")
    assert h.returncode == 0
    for option in ("--out", "--axes", "--limits", "--resolution", "--at", "--runs", "--seed", "--workers",
                   "--scheduler", "--chunk-size", "--no-progress", "--json"):
        assert option in h.stdout
