"""Offline tools: ``glpma-fk bag`` throughput on a recorded 3-RPR run and ``glpma-fk map`` speed-up
with local processes, each through its command-line entry point as a user runs it."""
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
