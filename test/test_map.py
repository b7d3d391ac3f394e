"""glpma-fk map: the seed 3-RPR at its published orientation, on every engine."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import yaml
from matplotlib.colors import to_rgba

from conftest import HEX_YAML, ROOT, RPR_YAML, needs_msolve
from glpma_ros.models.hexapod_66 import quaternion_from_matrix, rotation_from_vector
from glpma_ros.modes.multistart import solve_all
from glpma_tools import workspace_map as W
from glpma_tools.workspace_map.plot import count_colour, draw_map

#: the published example: legs 100 120 150 mm, real_solutions[0] of the seed config
EXAMPLE = yaml.safe_load(RPR_YAML.read_text())["real_solutions"][0]
STEP = 25.0          # grid spacing (mm); the example's pose is the grid's centre node
HALF = 4             # nodes on each side of the centre
CHECK_RUNS = 300     # the independent check: the papers' G3-PCX method, more runs, other seeds
#: conditioning computed by two processes from the same pose: equal up to round-off of the SVD
#: (relative to the value, which lies in (0, 1])
CONDITIONING_RTOL = 1e-12


def seed_spec(runs=0, method=W.DEFAULT_METHOD):
    """The grid around the published example; ``runs``: G3-PCX runs (method g3pcx) or the
    multistart's cap on the starts (0 = solve_all's)."""
    n = 2 * HALF + 1
    limits = tuple((c - HALF * STEP, c + HALF * STEP) for c in (EXAMPLE["x"], EXAMPLE["y"]))
    return W.MapSpec("planar_3rpr", ("x", "y"), limits, (n, n), (("theta", EXAMPLE["theta_deg"]),), runs, 0,
                     method)


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


def assert_same_map(a, b):
    """Counts and signs are integers; the conditioning agrees to round-off, NaN where no legs."""
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[2], b[2])
    assert np.allclose(a[1], b[1], rtol=CONDITIONING_RTOL, atol=0.0, equal_nan=True)


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
        assert_same_map(_counts(out), reference)


def test_rerun_skips_finished_chunks(tmp_path, config_text):
    spec = seed_spec(runs=3, method="g3pcx")
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
    other = W.compute_map(config_text, str(RPR_YAML), seed_spec(runs=4, method="g3pcx"), tmp_path, workers=1,
                          progress=False)
    assert other.chunks_reused == 0                      # another map: its own chunks
    multistart = W.compute_map(config_text, str(RPR_YAML), seed_spec(), tmp_path, workers=1, progress=False)
    assert multistart.chunks_reused == 0                 # another method: its own chunks too


def test_hexapod_slice_poses(hexapod, tmp_path):
    """Any two pose coordinates; roll, pitch, yaw compose as Rz Ry Rx (REP 103)."""
    r, p, y = 10.0, -20.0, 30.0
    R = (rotation_from_vector(np.radians([0, 0, y])) @ rotation_from_vector(np.radians([0, p, 0]))
         @ rotation_from_vector(np.radians([r, 0, 0])))
    q = W.quaternion_from_rpy(*np.radians([r, p, y]))
    assert np.allclose(q, quaternion_from_matrix(R), atol=1e-12)
    spec = W.MapSpec("hexapod_66", ("x", "z"), ((-100.0, 100.0), (800.0, 1000.0)), (2, 3),
                     (("y", 50.0), ("roll", r), ("pitch", p), ("yaw", y)), 0, 0)
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
    ([RPR_YAML, "--out", "{tmp}", "--method", "multistart", "--runs", 5], "--runs counts G3-PCX"),
    ([RPR_YAML, "--out", "{tmp}", "--method", "g3pcx", "--max-starts", 5], "--max-starts"),
    ([RPR_YAML, "--out", "{tmp}", "--max-starts", 0], "--max-starts"),
    ([RPR_YAML, "--out", "{tmp}", "--exact", 0], "--exact"),
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
             "--workers", 1, "--chunk-size", 3, "--json", "--at", "theta=10", "--method", "multistart",
             "--max-starts", 500)
    assert p.returncode == 0, p.stderr
    summary = json.loads(p.stdout)
    assert summary["points"] == 6 and summary["engine"] == "this process"
    assert summary["method"] == "the multistart (at most 500 starts per point)"
    assert summary["uncertified"] is None                # the multistart certifies nothing
    with np.load(tmp_path / "assembly_modes.npz") as f:
        assert f["counts"].shape == (2, 3) and list(f["fixed_names"]) == ["theta"] and f["fixed_values"][0] == 10
        assert str(f["method"]) == "multistart" and int(f["runs"]) == 500
        assert np.all(f["certified"] == -1)


def test_default_method_is_the_homotopy_and_max_starts_selects_the_multistart(rpr, hexapod):
    from glpma_tools.workspace_map.cli import build_parser, make_spec
    for model, config in ((rpr, RPR_YAML), (hexapod, "hexapod_66_rolland")):
        assert make_spec(model, build_parser().parse_args([str(config), "--out", "x"])).method == "homotopy"
    assert make_spec(rpr, build_parser().parse_args([str(RPR_YAML), "--out", "x", "--max-starts", "5"])).method \
        == "multistart"


def test_cli_on_a_dask_scheduler(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        p = _cli(RPR_YAML, "--out", tmp_path, "--resolution", 2, "--max-starts", 200,
                 "--scheduler", c.scheduler_address, "--json")
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["engine"].startswith("Dask")


def test_cli_help_describes_every_option():
    h = _cli("--help")
    assert h.returncode == 0
    for option in ("--out", "--axes", "--limits", "--resolution", "--at", "--method", "--runs", "--max-starts",
                   "--exact", "--seed", "--workers", "--scheduler", "--chunk-size", "--no-progress", "--json"):
        assert option in h.stdout


def test_cli_runs_the_papers_g3pcx_counts(tmp_path):
    """--runs N (alone, or with --method g3pcx) keeps the papers' way; the summary says which."""
    p = _cli(RPR_YAML, "--out", tmp_path, "--resolution", 2, "--workers", 1, "--json", "--runs", 2)
    assert p.returncode == 0, p.stderr
    summary = json.loads(p.stdout)
    assert summary["method"] == "2 polished G3-PCX runs per point"
    with np.load(tmp_path / "assembly_modes.npz") as f:
        assert str(f["method"]) == "g3pcx" and int(f["runs"]) == 2


def test_points_without_valid_legs_are_named_and_drawn_with_a_legend_entry(tmp_path, rpr):
    """The JSON names them (no count "-1" among the mode counts); the figure gives every class drawn
    a legend entry, each count in its fixed colour."""
    limits = rpr.leg_limits[1] * 3       # the grid's corners are beyond the longest leg allowed
    p = _cli(RPR_YAML, "--out", tmp_path, "--resolution", 3, "--workers", 1, "--json", "--limits", -limits, limits,
             -limits, limits)
    assert p.returncode == 0, p.stderr
    summary = json.loads(p.stdout)
    assert summary["no_valid_legs"] > 0 and "-1" not in summary["modes"]
    assert summary["no_valid_legs"] + sum(summary["modes"].values()) == 9
    with np.load(tmp_path / "assembly_modes.npz") as f:
        data = {k: f[k] for k in ("counts", "conditioning", "jacobian_sign")}
    spec = W.MapSpec("planar_3rpr", ("x", "y"), ((-limits, limits), (-limits, limits)), (3, 3), (("theta", 0.0),),
                     0, 0)
    legend = draw_map(tmp_path / "again.png", data, spec, rpr)
    labels = [label for label, _ in legend]
    classes = sorted(set(data["counts"].reshape(-1).tolist()))
    assert labels[:len(classes)] == ["no valid legs" if c == W.OUTSIDE else
                                     f"{c} real mode{'' if c == 1 else 's'}" for c in classes]
    for (_, colour), c in zip(legend, classes):
        assert np.allclose(colour, to_rgba(count_colour(c)))


def test_a_mode_count_has_the_same_colour_in_every_map():
    """Colours are fixed per count (not per map): distinct for the 41 counts a 6-6 can have
    (0 .. 40, wrapping after the palette's 38), none of them the grey of the points without legs."""
    colours = [to_rgba(count_colour(c)) for c in range(38)]
    assert len({tuple(np.round(c, 6)) for c in colours}) == 38
    grey = to_rgba(count_colour(W.OUTSIDE))
    assert all(not np.allclose(c, grey) for c in colours)
    assert np.allclose(to_rgba(count_colour(4)), to_rgba(count_colour(4 + 38)))


@needs_msolve
def test_exact_spot_check_certifies_a_sample(tmp_path):
    """--exact K: K points of the finished map certified by msolve; all agree on the seed 3-RPR."""
    p = _cli(RPR_YAML, "--out", tmp_path, "--resolution", 4, "--workers", 1, "--json", "--exact", 3)
    assert p.returncode == 0, p.stderr
    check = json.loads(p.stdout)["exact_check"]
    assert len(check["points"]) == 3 and check["agree"] == 3 and check["disagree"] == []


def test_exact_without_msolve_is_one_line_before_the_map(tmp_path, monkeypatch, capsys):
    from glpma_ros.modes import exact
    from glpma_ros.modes.exact import ExactUnavailableError
    from glpma_tools.workspace_map import exact_check

    def missing():
        raise ExactUnavailableError("the exact mode needs msolve: pip install 'glpma_ros[exact]'")
    # msolve missing, also where the exact extra is installed: both the module and the map's check look it up
    monkeypatch.setattr(exact, "msolve_executable", missing)
    monkeypatch.setattr(exact_check, "msolve_executable", missing)
    assert W.main([str(RPR_YAML), "--out", str(tmp_path / "out"), "--resolution", "2", "--exact", "3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--exact" in err and "glpma_ros[exact]" in err
    assert not (tmp_path / "out").exists()              # refused before anything was computed
