"""Offline tools, each through its command-line entry point as a user runs it: ``glpma-fk bag``
throughput on a recorded 3-RPR run and where its time goes, a fleet of bags on each engine,
``glpma-fk map``: the default 3-RPR map and a 6-6 slice on local processes and on a Dask cluster
(a ``LocalCluster`` of as many workers as local processes), and the multistart's mode counts against
the papers' G3-PCX runs and msolve's certified counts, and ``glpma-fk calibrate``'s time and accuracy
on simulated data."""
from __future__ import annotations

import json
import contextlib
import io
import tempfile
import time
from pathlib import Path

import numpy as np

from glpma_ros.config import config_dir, load_manipulator

#: messages of the recorded run (one loop of the simulated motion at 1 kHz)
BAG_MESSAGES = 10_000
#: the maps' grids (points per axis; the command's default) and the process counts they are timed with
MAP_RESOLUTION = 101
MAP_WORKERS = (1, 2)
#: the comparison of the counting methods: the default map's grid, G3-PCX runs per point (the papers'
#: way, the maps' default before the multistart) and the points certified by msolve (glpma-fk map --exact)
COMPARE_RESOLUTION = MAP_RESOLUTION
COMPARE_RUNS = 50
EXACT_POINTS = 50
#: the fleet: bags and inputs per bag
FLEET_BAGS = 4
#: log time of the first message and the period of the recorded legs (1 kHz)
T0_NS = 1_700_000_000_000_000_000
PERIOD_NS = 1_000_000


def _write_legs_bag(path: Path, legs_m) -> None:
    """An MCAP rosbag2 with ``/leg_lengths`` (std_msgs/msg/Float64MultiArray, metres) at 1 kHz."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/leg_lengths", "std_msgs/msg/Float64MultiArray", typestore=ts)
        for i, row in enumerate(legs_m):
            msg = T["std_msgs/msg/Float64MultiArray"](layout=layout, data=np.asarray(row, dtype=float))
            w.write(conn, T0_NS + i * PERIOD_NS, bytes(ts.serialize_cdr(msg, "std_msgs/msg/Float64MultiArray")))


def _quiet_json(main, argv, ok=(0,)) -> dict:
    """Run a tool's ``main(argv)`` with ``--json`` and return its JSON summary (exit statuses ``ok``)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    if code not in ok:
        raise RuntimeError(f"exit status {code}")
    return json.loads(out.getvalue().strip().splitlines()[-1])


def bag_throughput(messages: int = BAG_MESSAGES) -> dict:
    """``glpma-fk bag`` on a recorded 3-RPR run of ``messages`` inputs (the node's parameters of
    ``config/params_3rpr.yaml``): poses per second of wall and of CPU time."""
    from glpma_tools import bag
    from glpma_tools.sim.trajectories import variables_along
    model = load_manipulator(config_dir() / "planar_3rpr_seed.yaml")
    x0 = model.variables_from_pose(*_first_pose(model))
    xs = variables_along(model, x0, messages)
    legs_m = np.array([model.inverse_kinematics(x) for x in xs]) * model.metres_per_unit
    with tempfile.TemporaryDirectory(prefix="glpma_bench_bag_") as tmp:
        src, dst = Path(tmp) / "recorded", Path(tmp) / "estimated"
        _write_legs_bag(src, legs_m)
        t0 = time.perf_counter()
        summary = _quiet_json(bag.main, [str(src), str(dst), "--json", "--no-progress", "--ros-args",
                                         "--params-file", str(config_dir() / "params_3rpr.yaml")])
        wall = time.perf_counter() - t0
    return {"messages": messages, "converged": summary["converged"], "rejected": summary["rejected"],
            "assembly-mode changes": summary["assembly_mode_changes"], "wall s (incl. warm-up)": wall,
            "run s": summary["elapsed_s"], "poses/s": summary["poses_per_s"],
            "poses per CPU s": summary["converged"] / summary["cpu_s"] if summary["cpu_s"] else None}


def _first_pose(model):
    from glpma_tools.sim.trajectories import start_pose
    import yaml
    from glpma_ros.models.rotations import quaternion_from_matrix
    doc = yaml.safe_load((config_dir() / "planar_3rpr_seed.yaml").read_text())
    p, R = start_pose(model, doc)
    return p, quaternion_from_matrix(R)


def bag_breakdown(messages: int = BAG_MESSAGES) -> dict:
    """Where ``glpma-fk bag``'s CPU time goes, per input (µs of this process's CPU time): reading the
    bag, decoding the legs, the node's service (validation, estimator, statistics), the
    assembly-mode watch, encoding the pose and /tf and writing the four messages of an input (the
    copy, pose, /tf, status), measured one part at a time on the same recorded run."""
    import logging
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    from glpma_ros.node import params as P
    from glpma_ros.node.ros_args import parse_ros_args
    from glpma_ros.node.service import FkService
    from glpma_ros.node.dds import cdr
    from glpma_tools.bag_run import decode_float64_multi_array
    from glpma_tools.bag_run import OFFLINE_BUDGET_MS, BranchWatch
    model = load_manipulator(config_dir() / "planar_3rpr_seed.yaml")
    from glpma_tools.sim.trajectories import variables_along
    xs = variables_along(model, model.variables_from_pose(*_first_pose(model)), messages)
    legs_m = np.array([model.inverse_kinematics(x) for x in xs]) * model.metres_per_unit
    ts = get_typestore(Stores.ROS2_JAZZY)
    ros = parse_ros_args(["--ros-args", "--params-file", str(config_dir() / "params_3rpr.yaml")])
    values, _ = P.resolve({**ros.overrides, "time_budget_ms": OFFLINE_BUDGET_MS})
    service = FkService(values, logger=logging.getLogger("bench.bag"), node_name="glpma_fk")
    service.warm_up(solvers=(values["solver"],))
    per = {}
    with tempfile.TemporaryDirectory(prefix="glpma_bench_bag_") as tmp:
        src = Path(tmp) / "recorded"
        _write_legs_bag(src, legs_m)
        c = time.process_time()
        with Reader(src) as reader:
            raws = [(t, bytes(raw)) for _, t, raw in reader.messages()]
        per["read the bag"] = time.process_time() - c
        c = time.process_time()
        legs = [decode_float64_multi_array(raw, ts) for _, raw in raws]
        per["decode the legs"] = time.process_time() - c
        c = time.process_time()
        outcomes = [service.handle(l, t) for l, (t, _) in zip(legs, raws)]
        per["the node's service (validate, estimate, statistics)"] = time.process_time() - c
        watch = BranchWatch(model)
        c = time.process_time()
        for o in outcomes:
            watch(o.estimate.x, o.legs)
        per["assembly-mode watch"] = time.process_time() - c
        encode = cdr.Encoder()          # as glpma-fk bag writes them (the node's codec)
        c = time.process_time()
        encoded = [(encode.pose_stamped(o.pose.stamp_ns, "base", o.pose.position, o.pose.orientation),
                    encode.tf_message(o.pose.stamp_ns, "base", "platform", o.pose.position, o.pose.orientation))
                   for o in outcomes]
        per["encode pose and /tf"] = time.process_time() - c
        status = bytes(100)
        with Writer(Path(tmp) / "written", version=9, storage_plugin=StoragePlugin.MCAP) as w:
            conns = [w.add_connection(f"/t{k}", "std_msgs/msg/Float64MultiArray", typestore=ts) for k in range(4)]
            c = time.process_time()
            for (t, raw), (p, f) in zip(raws, encoded):
                w.write(conns[0], t, raw)
                w.write(conns[1], t, p)
                w.write(conns[2], t, f)
                w.write(conns[3], t, status)
            per["write 4 messages (rosbags MCAP writer)"] = time.process_time() - c
    total = bag_throughput(messages)
    per_input = {k: v / messages * 1e6 for k, v in per.items()}
    whole = 1e6 / total["poses per CPU s"] if total["poses per CPU s"] else None
    return {"inputs": messages, "CPU µs per input": per_input, "whole run CPU µs per input": whole,
            "run": total}


def bag_fleet(messages: int = BAG_MESSAGES, bags: int = FLEET_BAGS, workers=MAP_WORKERS) -> dict:
    """``glpma-fk bag`` on ``bags`` recordings of ``messages / bags`` inputs each (``--out-dir``), on
    one process, on local processes and on a Dask cluster: wall time and whether every engine wrote
    the same poses and statuses."""
    from glpma_tools import bag
    from glpma_tools.sim.trajectories import variables_along
    from rosbags.rosbag2 import Reader
    model = load_manipulator(config_dir() / "planar_3rpr_seed.yaml")
    each = max(1, messages // bags)
    xs = variables_along(model, model.variables_from_pose(*_first_pose(model)), each * bags)
    legs_m = np.array([model.inverse_kinematics(x) for x in xs]) * model.metres_per_unit
    params = ["--ros-args", "--params-file", str(config_dir() / "params_3rpr.yaml")]
    rows, outputs = [], []
    with tempfile.TemporaryDirectory(prefix="glpma_bench_fleet_") as tmp:
        fleet = Path(tmp) / "fleet"
        for k in range(bags):
            _write_legs_bag(fleet / f"run{k}", legs_m[k * each:(k + 1) * each])
        engines = [(f"{n} process(es)", ["--workers", str(n)]) for n in workers]
        with _dask_cluster(max(workers)) as address:
            if address:
                engines.append((f"Dask, {max(workers)} workers", ["--scheduler", address]))
            for label, options in engines:
                out = Path(tmp) / label.replace(" ", "_").replace(",", "")
                t0 = time.perf_counter()
                summary = _quiet_json(bag.main, [str(fleet), "--out-dir", str(out), *options, "--json",
                                                 "--no-progress", *params])
                rows.append({"engine": label, "wall s": time.perf_counter() - t0,
                             "converged": summary["total"]["converged"]})
                digest = []
                for k in range(bags):
                    with Reader(out / f"run{k}") as r:
                        digest.append([bytes(raw) for c, _, raw in r.messages() if c.topic == "/glpma_fk/status"])
                outputs.append(digest)
    return {"bags": bags, "inputs per bag": each, "runs": rows,
            "same statuses on every engine": all(o == outputs[0] for o in outputs)}


class _dask_cluster:
    """A local Dask cluster of ``n`` single-threaded worker processes, or None without the extra."""

    def __init__(self, n: int):
        self.n, self.cluster = n, None

    def __enter__(self):
        try:
            import distributed
        except ImportError:
            return None
        self.cluster = distributed.LocalCluster(n_workers=self.n, threads_per_worker=1, processes=True,
                                                dashboard_address=None)
        return self.cluster.scheduler_address

    def __exit__(self, *exc):
        if self.cluster is not None:
            self.cluster.close()


def _map_run(config: str, options: list, tmp: str) -> tuple[float, dict, bytes]:
    from glpma_tools import workspace_map
    t0 = time.perf_counter()
    # with --exact, exit status 1 says a count differs from msolve's: a result, reported in the table
    summary = _quiet_json(workspace_map.main, [config, "--out", tmp, "--no-progress", "--json", *options],
                          ok=(0, 1) if "--exact" in options else (0,))
    wall = time.perf_counter() - t0
    with np.load(Path(tmp) / "assembly_modes.npz") as f:
        counts = f["counts"]
    return wall, summary, counts


def map_scaling(resolution: int = MAP_RESOLUTION, workers=MAP_WORKERS, config: str = "planar_3rpr_seed",
                at: tuple = ()) -> dict:
    """``glpma-fk map CONFIG`` (default method, the multistart) on a ``resolution``² grid with 1 and 2
    local processes and on a Dask cluster of 2 workers: wall time (spawning and loading the workers
    included), points per second, and whether the mode counts are identical."""
    rows, counts = [], []
    options = ["--resolution", str(resolution), *(["--at", *at] if at else [])]
    with _dask_cluster(max(workers)) as address:
        engines = [(f"{n} process(es)", ["--workers", str(n)]) for n in workers]
        if address:
            engines.append((f"Dask, {max(workers)} workers", ["--scheduler", address]))
        for label, extra in engines:
            with tempfile.TemporaryDirectory(prefix="glpma_bench_map_") as tmp:
                wall, summary, c = _map_run(config, options + extra, tmp)
            counts.append(c)
            rows.append({"engine": label, "wall s": wall, "points/s": summary["points"] / wall,
                         "modes": summary["modes"]})
    base = rows[0]["wall s"]
    for r in rows:
        r["speed-up"] = base / r["wall s"]
    return {"config": config, "grid": f"{resolution} x {resolution}", "at": " ".join(at), "runs": rows,
            "identical counts": all(np.array_equal(c, counts[0]) for c in counts)}


def map_methods(resolution: int = COMPARE_RESOLUTION, runs: int = COMPARE_RUNS, exact: int = EXACT_POINTS) -> dict:
    """The seed 3-RPR map counted both ways on the same grid: the multistart (default) and the papers'
    ``runs`` polished G3-PCX searches per point; where they differ, and msolve's certified count at
    ``exact`` points of the multistart's map (``--exact``) when the extra is installed."""
    from glpma_ros.exact import ExactUnavailableError, msolve_executable
    options = ["--resolution", str(resolution), "--workers", str(max(MAP_WORKERS))]
    with tempfile.TemporaryDirectory(prefix="glpma_bench_map_") as tmp:
        wall_g, _, g = _map_run("planar_3rpr_seed", [*options, "--method", "g3pcx", "--runs", str(runs)], tmp)
    try:
        msolve_executable()
        check = ["--exact", str(exact)]
    except ExactUnavailableError:
        check = []
    with tempfile.TemporaryDirectory(prefix="glpma_bench_map_") as tmp:
        wall_m, summary, m = _map_run("planar_3rpr_seed", [*options, *check], tmp)
        with np.load(Path(tmp) / "assembly_modes.npz") as f:
            axes = (f["axis_0"], f["axis_1"])
    out = {"grid": f"{resolution} x {resolution}", "g3pcx runs": runs, "g3pcx wall s": wall_g,
           "multistart wall s": wall_m, "points": int(m.size), "same count": int(np.sum(m == g)),
           "multistart more": int(np.sum(m > g)), "multistart fewer": int(np.sum(m < g)),
           "where they differ (x, y: g3pcx, multistart)": "; ".join(
               f"{x:g}, {y:g}: {g[r, c]}, {m[r, c]}" for (r, c), x, y in _differing(axes, g, m))}
    if check:
        e = summary["exact_check"]
        out.update({"certified points": len(e["points"]), "agree with msolve": e["agree"],
                    "differ from msolve": len(e["disagree"]), "undecided": len(e["skipped"])})
    return out


def _differing(axes, a, b):
    """``((row, column), x, y)`` of the grid points where the counts ``a`` and ``b`` differ."""
    return [((r, c), float(axes[0][c]), float(axes[1][r])) for r, c in np.argwhere(a != b)]


def measure(bag_messages: int, map_resolution: int, quick: bool = False, hexapod: bool = True) -> dict:
    """The offline section: the bag's breakdown and fleet, the maps on each engine (the 6-6 slice when
    ``hexapod``), the methods."""
    return {"bag": bag_breakdown(bag_messages), "fleet": bag_fleet(bag_messages),
            "map": map_scaling(map_resolution),
            "hexapod map": map_scaling(map_resolution, workers=(max(MAP_WORKERS),), config="hexapod_66_rolland")
            if hexapod else None,
            "methods": map_methods(map_resolution if quick else COMPARE_RESOLUTION, 5 if quick else COMPARE_RUNS,
                                   5 if quick else EXACT_POINTS),
            "calibration": calibration()}


#: ``glpma-fk calibrate`` is timed on these numbers of measurements (issue 22: 200 and 10,000), each
#: this many times (the median and the smallest are reported: a shared machine only adds time)
CALIBRATION_SIZES = (200, 10_000)
CALIBRATION_REPEATS = 5
#: fresh true poses at which the forward kinematics with the nominal and with the calibrated config
#: is compared with the truth
CALIBRATION_FK_POSES = 20


def calibration(sizes=CALIBRATION_SIZES, repeats: int = CALIBRATION_REPEATS,
                fk_poses: int = CALIBRATION_FK_POSES) -> list:
    """``glpma-fk calibrate`` on simulated data (issue 22's protocol, :mod:`glpma_tools.calibrate.simulate`)
    for the 3-RPR and the hexapod, through its entry point: wall and CPU time of the whole command
    (CSV read, identification, NEW.yaml) and of the identification alone, the leg residual RMS on the
    held-out measurements, and the forward kinematics' pose error (largest platform-joint displacement)
    with the nominal and with the calibrated config at fresh poses."""
    from glpma_ros.config import load_document, model_from_dict
    from glpma_ros.estimator import Estimator
    from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix
    from glpma_tools.calibrate import main as calibrate_main
    from glpma_tools.calibrate.simulate import simulate, true_readings, write_csv
    from glpma_tools.sim.trajectories import start_pose
    rows = []
    for name in ("planar_3rpr_seed", "hexapod_66_rolland"):
        path = config_dir() / f"{name}.yaml"
        doc = load_document(path)
        model = model_from_dict(doc, str(path))
        center = start_pose(model, doc)
        for size in sizes:
            sim = simulate(model, center, np.random.default_rng(0), size)
            with tempfile.TemporaryDirectory(prefix="glpma_bench_calibrate_") as tmp:
                data, new = Path(tmp) / "data.csv", Path(tmp) / "new.yaml"
                write_csv(data, sim.measured)
                walls, cpus, ident = [], [], []
                for _ in range(repeats):
                    t0, c0 = time.perf_counter(), time.process_time()
                    out = _quiet_json(calibrate_main, [str(path), str(data), "--out", str(new), "--json"])
                    walls.append(time.perf_counter() - t0)
                    cpus.append(time.process_time() - c0)
                    ident.append(out["identify_s"])
                calibrated = model_from_dict(load_document(new), str(new))
            fresh = simulate(model, center, np.random.default_rng(1), fk_poses).true_poses
            readings = true_readings(sim.truth, fresh.position, fresh.rotation)
            errors = {"nominal": [], "calibrated": []}
            for legs, p, R in zip(readings, fresh.position, fresh.rotation):
                for label, m in (("nominal", model), ("calibrated", calibrated)):
                    p3 = np.append(p, 0.0) if len(p) == 2 else p
                    R3 = np.eye(3)
                    R3[:len(p), :len(p)] = R
                    x = m.variables_from_pose(p3, quaternion_from_matrix(R3))
                    e = Estimator(m, time_budget_s=60.0, initial_pose=x).estimate(m.legs_from_sensors(legs))
                    d = len(p)
                    R_hat = matrix_from_quaternion(e.pose.orientation)[:d, :d]
                    at = np.asarray(e.pose.position)[:d] + sim.truth.platform @ R_hat.T
                    errors[label].append(float(np.linalg.norm(at - (p + sim.truth.platform @ R.T), axis=1).max()))
            mm = model.metres_per_unit * 1e3
            rows.append({"manipulator": name, "measurements": size, "fitted": out["fitted"],
                         "wall s median": float(np.median(walls)), "wall s min": float(min(walls)),
                         "cpu s median": float(np.median(cpus)), "identify s median": float(np.median(ident)),
                         "iterations": out["iterations"],
                         "held-out RMS before mm": out["holdout_rms_before"] * mm,
                         "held-out RMS after mm": out["holdout_rms_after"] * mm,
                         "FK error nominal mm (median / max)": (float(np.median(errors["nominal"])) * mm,
                                                                max(errors["nominal"]) * mm),
                         "FK error calibrated mm (median / max)": (float(np.median(errors["calibrated"])) * mm,
                                                                   max(errors["calibrated"]) * mm),
                         "weak directions": len(out["weak"])})
    return rows
