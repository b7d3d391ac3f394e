"""Offline tools: ``glpma-fk bag`` throughput on a recorded 3-RPR run, ``glpma-fk map`` speed-up
with local processes and ``glpma-fk calibrate``'s time and accuracy on simulated data, each through its
command-line entry point as a user runs it."""
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
#: grid of the map (points per axis) and the process counts it is timed with
MAP_RESOLUTION = 24
MAP_WORKERS = (1, 2)
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


def _quiet_json(main, argv) -> dict:
    """Run a tool's ``main(argv)`` with ``--json`` and return its JSON summary."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    if code != 0:
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


def map_scaling(resolution: int = MAP_RESOLUTION, workers=MAP_WORKERS) -> dict:
    """``glpma-fk map`` of the seed 3-RPR on a ``resolution``² grid with 1 and 2 local processes:
    wall time, speed-up, and whether the mode counts are identical."""
    from glpma_tools import workspace_map
    rows, counts = [], []
    for n in workers:
        with tempfile.TemporaryDirectory(prefix="glpma_bench_map_") as tmp:
            t0 = time.perf_counter()
            _quiet_json(workspace_map.main, ["planar_3rpr_seed", "--out", tmp, "--resolution", str(resolution),
                                             "--workers", str(n), "--no-progress", "--json"])
            wall = time.perf_counter() - t0
            counts.append(np.load(Path(tmp) / "assembly_modes.npz")["counts"].tobytes())
        rows.append((n, wall))
    base = rows[0][1]
    return {"grid": f"{resolution} x {resolution}",
            "runs": [{"processes": n, "wall s": w, "speed-up": base / w} for n, w in rows],
            "identical counts": all(c == counts[0] for c in counts)}


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
