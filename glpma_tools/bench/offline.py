"""Offline tools through their entry points, as a user runs them: ``glpma-fk bag`` (throughput, where its time goes,
a fleet of bags), ``glpma-fk map`` (on each engine, its counting methods), ``glpma-fk calibrate`` (time, accuracy)."""
from __future__ import annotations

import contextlib
import io
import json
import logging
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from glpma_ros.calibration import main as calibrate_main
from glpma_ros.config import config_dir, load_document, model_from_dict
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.models.rotations import matrix_from_quaternion, quaternion_from_matrix
from glpma_ros.modes.exact import ExactUnavailableError, msolve_executable
from glpma_ros.node import params as P
from glpma_ros.node.dds import cdr
from glpma_ros.node.dds.rosbag import FLOAT64_MULTI_ARRAY, decode_float64_multi_array
from glpma_ros.node.ros_args import parse_ros_args
from glpma_ros.node.service import FkService
from glpma_tools import bag, workspace_map
from glpma_tools.bag_outcome import OFFLINE_BUDGET_MS, BranchWatch
from glpma_tools.sim.calibration_data import simulate, true_readings, write_csv
from glpma_tools.sim.trajectories import start_pose

from .markdown import dict_table, key_values, md_blocks, prose
from .scenarios import load
from .transport import params_file

#: the process counts the maps are timed with
MAP_WORKERS = (1, 2)
#: the counting methods compared: G3-PCX runs per point (the papers' way) ...
COMPARE_RUNS = 50
#: ... and the points msolve certifies (glpma-fk map --exact)
EXACT_POINTS = 50
#: both with --quick
QUICK_RUNS = 5
#: the bags of the fleet
FLEET_BAGS = 4
#: log time of the first message of the recorded legs, and their period (1 kHz)
T0_NS = 1_700_000_000_000_000_000
PERIOD_NS = 1_000_000
#: ``glpma-fk calibrate`` is timed on these numbers of measurements, each this many times (the median and
#: the smallest are reported: a shared machine only adds time); its forward kinematics checked at fresh true poses
CALIBRATION_SIZES = (200, 10_000)
CALIBRATION_REPEATS = 5
CALIBRATION_FK_POSES = 20
#: a tracker campaign in the robot's working range (the README's example, the tests' campaign): poses within
#: +- (position, config unit; angle, radians) of the known pose, where some directions are only weakly
#: identifiable and stay at nominal; measured at the first of the sizes
CALIBRATION_WORKING_RANGE = {"planar_3rpr_seed": (10.0, 0.2), "hexapod_66_rolland": (20.0, math.radians(8.0))}
PARAMS_3RPR = ["--ros-args", "--params-file", str(params_file("planar_3rpr"))]
#: what the breakdown writes per input, as glpma-fk bag does: the input's copy, the pose, /tf and a status (a
#: stand-in of this many bytes)
WRITTEN = ("/leg_lengths", "/pose", "/tf", "/status")
STATUS_BYTES = 100


def _recorded_legs(n: int) -> np.ndarray:
    """``n`` leg readings (metres) along the simulated loop of the seed 3-RPR."""
    sc = load("3rpr")
    return sc.along(n)[1] * sc.model.metres_per_unit


def _write_bag(path: Path, records, typestore) -> None:
    """An MCAP rosbag2 of ``(topic, log time ns, CDR bytes)`` records, each topic a Float64MultiArray."""
    from rosbags.rosbag2 import StoragePlugin, Writer  # the bag extra: optional, imported where used
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for topic, t, raw in records:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, FLOAT64_MULTI_ARRAY, typestore=typestore)
            w.write(conns[topic], t, raw)


def _write_legs_bag(path: Path, legs_m, typestore) -> None:
    """A recording of ``/leg_lengths`` (metres) at 1 kHz."""
    T = typestore.types
    layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    messages = (T[FLOAT64_MULTI_ARRAY](layout=layout, data=np.asarray(row, dtype=float)) for row in legs_m)
    _write_bag(path, (("/leg_lengths", T0_NS + i * PERIOD_NS, bytes(typestore.serialize_cdr(m, FLOAT64_MULTI_ARRAY)))
                      for i, m in enumerate(messages)), typestore)


def _read_bag(path: Path, topic: str | None = None) -> list:
    """``(log time ns, CDR bytes)`` of the messages of the bag at ``path`` (on ``topic``; None: all)."""
    from rosbags.rosbag2 import Reader  # the bag extra: optional, imported where used
    with Reader(path) as reader:
        return [(t, bytes(raw)) for c, t, raw in reader.messages() if topic in (None, c.topic)]


def _typestore():
    """The ROS 2 Jazzy message types of ``rosbags``."""
    from rosbags.typesys import Stores, get_typestore  # the bag extra: optional, imported where used
    return get_typestore(Stores.ROS2_JAZZY)


def _run_json(main, argv, ok=(0,)) -> tuple[float, float, dict]:
    """A tool's ``main(argv)`` run with ``--json`` (exit statuses ``ok``): wall s, CPU s of this process, summary."""
    out = io.StringIO()
    t0, c0 = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if code not in ok:
        raise RuntimeError(f"exit status {code}")
    return wall, cpu, json.loads(out.getvalue().strip().splitlines()[-1])


def bag_breakdown(messages: int) -> dict:
    """``glpma-fk bag`` on a recorded 3-RPR run of ``messages`` inputs (``config/params_3rpr.yaml``): its figures,
    poses per second of wall and of CPU time; and where its CPU time goes per input (µs), one part of its loop at a
    time on the same inputs: reading the bag, decoding the legs, the node's service (validation, estimator,
    statistics), the assembly-mode watch, encoding the pose and /tf, writing the four messages of an input."""
    ts = _typestore()
    values, _ = P.resolve({**parse_ros_args(PARAMS_3RPR).overrides, "time_budget_ms": OFFLINE_BUDGET_MS})
    service = FkService(values, logger=logging.getLogger("bench.bag"), node_name="glpma_fk")
    service.warm_up(solvers=(values["solver"],))
    encode, cpu_us = cdr.Encoder(), {}          # pose and /tf as glpma-fk bag writes them (the node's codec)

    def timed(part: str, work):
        """``work()``, its CPU time (this process's) per input kept under ``part``."""
        c0 = time.process_time()
        value = work()
        cpu_us[part] = (time.process_time() - c0) / messages * 1e6
        return value

    def watch(outcomes):
        w = BranchWatch(service.model)
        for o in outcomes:
            w(o.estimate.x, o.legs)

    def encoded(pose):
        return (encode.pose_stamped(pose.stamp_ns, "base", pose.position, pose.orientation),
                encode.tf_message(pose.stamp_ns, "base", "platform", pose.position, pose.orientation))
    with tempfile.TemporaryDirectory(prefix="glpma_bench_bag_") as tmp:
        src = Path(tmp) / "recorded"
        _write_legs_bag(src, _recorded_legs(messages), ts)
        raws = timed("read the bag", lambda: _read_bag(src))
        legs = timed("decode the legs", lambda: [decode_float64_multi_array(raw, ts) for _, raw in raws])
        outcomes = timed("the node's service (validate, estimate, statistics)",
                         lambda: [service.handle(legs_m, t) for legs_m, (t, _) in zip(legs, raws)])
        timed("assembly-mode watch", lambda: watch(outcomes))
        poses = timed("encode pose and /tf", lambda: [encoded(o.pose) for o in outcomes])
        timed("write 4 messages (rosbags MCAP writer)", lambda: _write_bag(Path(tmp) / "written", (
            (topic, t, data) for (t, raw), (pose, tf) in zip(raws, poses)
            for topic, data in zip(WRITTEN, (raw, pose, tf, bytes(STATUS_BYTES)))), ts))
        wall, _, summary = _run_json(bag.main, [str(src), str(Path(tmp) / "estimated"), "--json", "--no-progress",
                                                *PARAMS_3RPR])
    per_cpu_s = summary["converged"] / summary["cpu_s"] if summary["cpu_s"] else None
    cpu_us["the whole run (the parts above plus the loop itself)"] = 1e6 / per_cpu_s if per_cpu_s else None
    return {"CPU µs per input": cpu_us, "run": {
        "messages": messages, "converged": summary["converged"], "rejected": summary["rejected"],
        "assembly-mode changes": summary["assembly_mode_changes"], "wall s (incl. warm-up)": wall,
        "run s": summary["elapsed_s"], "poses/s": summary["poses_per_s"], "poses per CPU s": per_cpu_s}}


@contextlib.contextmanager
def _engines(workers=MAP_WORKERS):
    """``[(label, options)]`` of the engines: ``--workers N`` local processes, and a local Dask cluster of
    ``max(workers)`` single-threaded worker processes (``--scheduler``) with the extra."""
    engines = [(f"{n} process(es)", ["--workers", str(n)]) for n in workers]
    try:
        import distributed  # the map extra: optional, imported where used
    except ImportError:
        yield engines
        return
    with distributed.LocalCluster(n_workers=max(workers), threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        yield engines + [(f"Dask, {max(workers)} workers", ["--scheduler", cluster.scheduler_address])]


def bag_fleet(messages: int, bags: int = FLEET_BAGS) -> dict:
    """``glpma-fk bag`` on ``bags`` recordings of ``messages / bags`` inputs each (``--out-dir``) on each engine: wall
    time and whether every engine wrote the same statuses."""
    each, ts = max(1, messages // bags), _typestore()
    legs_m = _recorded_legs(each * bags)
    rows, statuses = [], []
    with tempfile.TemporaryDirectory(prefix="glpma_bench_fleet_") as tmp, _engines() as engines:
        fleet = Path(tmp) / "fleet"
        for k in range(bags):
            _write_legs_bag(fleet / f"run{k}", legs_m[k * each:(k + 1) * each], ts)
        for n, (label, options) in enumerate(engines):
            out = Path(tmp) / f"out{n}"
            wall, _, summary = _run_json(bag.main, [str(fleet), "--out-dir", str(out), *options, "--json",
                                                    "--no-progress", *PARAMS_3RPR])
            rows.append({"engine": label, "wall s": wall, "converged": summary["total"]["converged"]})
            statuses.append([raw for k in range(bags) for _, raw in _read_bag(out / f"run{k}", "/glpma_fk/status")])
    return {"bags": bags, "inputs per bag": each, "runs": rows,
            "same statuses on every engine": all(s == statuses[0] for s in statuses)}


def _map_run(config: str, options: list) -> tuple[float, dict, np.ndarray, tuple]:
    """``glpma-fk map CONFIG OPTIONS``: wall s, its JSON summary, the counts with the double modes of each point
    (shape 2 x rows x columns) and the grid's axes."""
    with tempfile.TemporaryDirectory(prefix="glpma_bench_map_") as tmp:
        # with --exact, exit status 1 says a count differs from msolve's: a result, reported in the table
        wall, _, summary = _run_json(workspace_map.main, [config, "--out", tmp, "--no-progress", "--json", *options],
                                     ok=(0, 1) if "--exact" in options else (0,))
        with np.load(Path(tmp) / "assembly_modes.npz") as f:
            return wall, summary, np.stack((f["counts"], f["double_modes"])), (f["axis_0"], f["axis_1"])


def map_scaling(resolution: int, workers=MAP_WORKERS, config: str = "planar_3rpr_seed") -> dict:
    """``glpma-fk map CONFIG`` (default method, the multistart) on a ``resolution``² grid on each engine: wall time
    (spawning and loading the workers included), points per second; the first engine's mode counts (and the points
    on a singularity), and whether they (and the double modes) are identical on every engine."""
    rows, counts, summaries = [], [], []
    with _engines(workers) as engines:
        for label, extra in engines:
            wall, summary, c, _ = _map_run(config, ["--resolution", str(resolution), *extra])
            counts.append(c)
            summaries.append(summary)
            rows.append({"engine": label, "wall s": wall, "points/s": summary["points"] / wall,
                         "speed-up": (rows[0]["wall s"] if rows else wall) / wall})
    return {"config": config, "grid": f"{resolution} x {resolution}", "runs": rows, "modes": summaries[0]["modes"],
            "on_singularity": summaries[0]["on_singularity"],
            "identical counts": all(np.array_equal(c, counts[0]) for c in counts)}


def map_methods(resolution: int, runs: int = COMPARE_RUNS, exact: int = EXACT_POINTS) -> dict:
    """The seed 3-RPR map counted both ways on the same grid: the multistart (default) and the papers' ``runs``
    polished G3-PCX searches per point; where they differ, and msolve's certified count at ``exact`` points of the
    multistart's map (``--exact``) when the extra is installed."""
    options = ["--resolution", str(resolution), "--workers", str(max(MAP_WORKERS))]
    wall_g, _, (g, _), _ = _map_run("planar_3rpr_seed", [*options, "--method", "g3pcx", "--runs", str(runs)])
    try:
        msolve_executable()
        check = ["--exact", str(exact)]
    except ExactUnavailableError:
        check = []
    wall_m, summary, (m, _), axes = _map_run("planar_3rpr_seed", [*options, *check])
    out = {"grid": f"{resolution} x {resolution}", "g3pcx runs": runs, "g3pcx wall s": wall_g,
           "multistart wall s": wall_m, "points": int(m.size), "same count": int(np.sum(m == g)),
           "multistart more": int(np.sum(m > g)), "multistart fewer": int(np.sum(m < g)),
           "where they differ (x, y: g3pcx, multistart)": "; ".join(
               f"{float(axes[0][c]):g}, {float(axes[1][r]):g}: {g[r, c]}, {m[r, c]}" for r, c in np.argwhere(m != g))}
    if check:
        e = summary["exact_check"]
        out.update({"certified points": len(e["points"]), "agree with msolve": e["agree"],
                    "differ from msolve": len(e["disagree"]), "undecided": len(e["skipped"])})
    return out


def measure(bag_messages: int, map_resolution: int, quick: bool = False, hexapod: bool = True) -> dict:
    """The offline section: the bag's breakdown and fleet, the maps on each engine (the 6-6 slice when ``hexapod``),
    the methods, the calibration."""
    runs, exact = (QUICK_RUNS, QUICK_RUNS) if quick else (COMPARE_RUNS, EXACT_POINTS)
    return {"bag": bag_breakdown(bag_messages), "fleet": bag_fleet(bag_messages), "map": map_scaling(map_resolution),
            "hexapod map": map_scaling(map_resolution, workers=(max(MAP_WORKERS),), config="hexapod_66_rolland")
            if hexapod else None,
            "methods": map_methods(map_resolution, runs, exact), "calibration": calibration()}


def _fk_error(model, sim, legs, p, R) -> float:
    """The largest displacement of a platform joint between the forward kinematics (the node's estimator, started at
    the true pose) of ``legs`` with ``model`` and the true pose ``p, R``."""
    d = len(p)
    R3 = np.eye(3)
    R3[:d, :d] = R
    x = model.variables_from_pose(np.append(p, 0.0) if d == 2 else p, quaternion_from_matrix(R3))
    e = Estimator(model, time_budget_s=60.0, initial_pose=x).estimate(model.legs_from_sensors(legs))
    at = np.asarray(e.pose.position)[:d] + sim.truth.platform @ matrix_from_quaternion(e.pose.orientation)[:d, :d].T
    return float(np.linalg.norm(at - (p + sim.truth.platform @ R.T), axis=1).max())


def calibration(sizes=CALIBRATION_SIZES, repeats: int = CALIBRATION_REPEATS,
                fk_poses: int = CALIBRATION_FK_POSES) -> list:
    """``glpma-fk calibrate`` on simulated data (the protocol of :mod:`glpma_tools.sim.calibration_data`) for the
    3-RPR and the hexapod, through its entry point: wall and CPU time of the whole command (CSV read, identification,
    NEW.yaml, the held-out forward kinematics) and of the identification alone, the leg residual RMS and the forward
    kinematics' position error on the held-out measurements, the observability O1, and the forward kinematics' pose
    error (:func:`_fk_error`) with the nominal and with the calibrated config at fresh poses; poses over the
    workspace at every size, and in the working range (:data:`CALIBRATION_WORKING_RANGE`) at the first: rows under
    the report's column names."""
    rows = []
    for name in ("planar_3rpr_seed", "hexapod_66_rolland"):
        path = config_dir() / f"{name}.yaml"
        doc = load_document(path)
        model = model_from_dict(doc, str(path))
        center, mm = start_pose(model, doc), model.metres_per_unit * 1e3
        for size, spread in [(size, None) for size in sizes] + [(sizes[0], CALIBRATION_WORKING_RANGE[name])]:
            sim = simulate(model, center, np.random.default_rng(0), size, spread=spread)
            with tempfile.TemporaryDirectory(prefix="glpma_bench_calibrate_") as tmp:
                data, new = Path(tmp) / "data.csv", Path(tmp) / "new.yaml"
                write_csv(data, sim.measured)
                walls, cpus, outs = zip(*(_run_json(calibrate_main, [str(path), str(data), "--out", str(new), "--json"])
                                          for _ in range(repeats)))
                calibrated = model_from_dict(load_document(new), str(new))
            out = outs[-1]
            fresh = simulate(model, center, np.random.default_rng(1), fk_poses, spread=spread).true_poses
            readings = true_readings(sim.truth, fresh.position, fresh.rotation)
            errors = {label: [_fk_error(m, sim, *args) * mm for args in zip(readings, fresh.position, fresh.rotation)]
                      for label, m in (("nominal", model), ("calibrated", calibrated))}
            campaign = "workspace" if spread is None else \
                f"+- {spread[0]:g} {model.unit}, {math.degrees(spread[1]):.3g} deg"
            pose = out["holdout_pose"]
            rows.append({"config": name, "campaign": campaign, "measurements": size, "fitted": out["fitted"],
                         "command wall s (median / min)": (float(np.median(walls)), float(min(walls))),
                         "command CPU s": float(np.median(cpus)),
                         "identification ms": float(np.median([o["identify_s"] for o in outs])) * 1e3,
                         "Gauss-Newton iterations": out["iterations"],
                         "held-out leg RMS mm (before / after)": (out["holdout_rms_before"] * mm,
                                                                  out["holdout_rms_after"] * mm),
                         "held-out FK position RMS mm (before / after)": (pose["before"]["position_rms"] * mm,
                                                                          pose["after"]["position_rms"] * mm),
                         "O1": out["observability"]["o1"],
                         **{f"FK error {k} mm (median / max)": (float(np.median(v)), max(v))
                            for k, v in errors.items()},
                         "weak directions": len(out["weak"]), "left at nominal": len(out["unidentifiable"])})
    return rows


def offline_section(res, md_path) -> list[str]:
    """``glpma-fk bag``: throughput, where the time goes, a fleet on each engine; ``glpma-fk map``: the
    default 3-RPR map and a 6-6 slice on each engine, the counting methods compared; ``glpma-fk calibrate``."""
    o = res["offline"]
    fleet, methods = o["fleet"], o["methods"]
    out = md_blocks(
        "## Offline: bag processing and workspace maps", prose("offline"),
        key_values("glpma-fk bag (3-RPR, MCAP)", o["bag"]["run"]),
        key_values("where the CPU time of one input goes", o["bag"]["CPU µs per input"], "µs"),
        dict_table(fleet["runs"], f"glpma-fk bag --out-dir ({fleet['bags']} bags of {fleet['inputs per bag']:,} "
                                  "inputs)"),
        f"Same statuses on every engine: {'yes' if fleet['same statuses on every engine'] else 'NO'}.")
    for mp in filter(None, (o["map"], o["hexapod map"])):
        sing = mp["on_singularity"]
        singular = "; on a singularity (a double mode): {:,} ({})".format(
            sum(sing.values()), ", ".join(f"{k} distinct: {v:,}" for k, v in sing.items())) if sing else ""
        out += md_blocks(dict_table(mp["runs"], f"glpma-fk map {mp['config']} ({mp['grid']})"),
                         "Mode counts (points per count, first engine): "
                         + ", ".join(f"{k}: {v:,}" for k, v in mp["modes"].items())
                         + f"{singular}; identical on every engine: {'yes' if mp['identical counts'] else 'NO'}.")
    out += md_blocks(key_values(f"counting methods, seed 3-RPR map {methods['grid']}",
                                {k: v for k, v in methods.items() if k != "grid"}))
    return out + (calibration_section(o["calibration"]) if o["calibration"] else [])


def calibration_section(rows) -> list[str]:
    """``glpma-fk calibrate``: time for 200 and 10,000 measurements, accuracy before and after."""
    return md_blocks("### Calibration", prose("offline", "calibration", repeats=CALIBRATION_REPEATS,
                                              fk_poses=CALIBRATION_FK_POSES), dict_table(rows))
