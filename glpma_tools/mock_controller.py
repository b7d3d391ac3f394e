"""A simulated manipulator controller for the ``glpma_fk`` node, over Cyclone DDS.

It moves the platform along a known trajectory, publishes the leg lengths the
inverse kinematics gives for each pose on ``leg_lengths`` at a fixed rate, listens
to ``pose_estimate`` and compares every pose with the truth:

* 3-RPR: a smooth closed loop (a Lissajous figure in x, y with a swing of theta)
  around one of the config's ``real_solutions``;
* hexapod: a helix of the platform origin with a rotation about (and a tilt of)
  the vertical, around one of the config's ``published_solutions``.

With ``input_type="joint_state"`` (``--input joint_state``) it publishes
``sensor_msgs/JointState`` on ``joint_states`` instead: the legs under ``joint_names``
(default ``leg_1`` .. ``leg_n``) mixed with a few other joints (:data:`EXTRA_JOINTS`), in
a new random order in every message, ``header.stamp`` = the send time -- the node's
``input_type:=joint_state`` must pick the legs out by name.

A pose is matched to the input it answers by its ``header.stamp`` (the arrival
time of that input at the node, on the same clock when both run on one machine; the
JointState's own stamp for joint_state input), the leg lengths of the pose telling
apart neighbouring inputs.  The summary has
the tracking error (metres, radians), the end-to-end latency (input sent -> pose
received) p50/p99/max, inputs sent and poses received.

Command line: ``python -m glpma_tools.mock_controller --config planar_3rpr_seed --rate 200
--duration 5 [--input joint_state [--joint-names A B C]] [--json]``; as a library: :func:`run`
returns the summary.
"""
from __future__ import annotations

import argparse
import bisect
import json
import math
import sys
import threading
import time
from pathlib import Path
from dataclasses import dataclass

import numpy as np

from glpma_ros.config import load_document, model_from_dict, resolve_config
from glpma_ros.errors import GlpmaError
from glpma_ros.models.rotations import quaternion_from_matrix, rotation_from_vector

#: default solution of each manipulator to move around (index in the config's list)
DEFAULT_SOLUTION = {"planar_3rpr": 0,      # real_solutions[0], the one of 001 Table 1
                    "hexapod_66": 10}      # platform above the base, centred, well conditioned
#: seconds per loop / helix turn
PERIOD_S = 4.0
#: other joints of the robot sent with the legs in a JointState (name, position)
EXTRA_JOINTS = (("gripper_finger", 0.02), ("wrist_roll", -0.7), ("base_yaw", 1.3))
INPUT_TYPES = ("float64_multi_array", "joint_state")


# -- trajectories --------------------------------------------------------------------------------

def _rot_z(angle: float) -> np.ndarray:
    return rotation_from_vector(np.array([0.0, 0.0, angle]))


def start_pose(model, doc: dict, solution: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(position, rotation matrix) of a known solution of the config (config unit)."""
    kind = model.kind
    key = "real_solutions" if kind == "planar_3rpr" else "published_solutions"
    if solution is None and not doc.get(key):
        return _solved_start_pose(model)
    index = DEFAULT_SOLUTION[kind] if solution is None else int(solution)
    if kind == "planar_3rpr":
        sols = doc.get("real_solutions") or []
        if not 0 <= index < len(sols):
            raise GlpmaError(f"the config has {len(sols)} real_solutions; cannot use solution {index}")
        s = sols[index]
        return np.array([s["x"], s["y"], 0.0], dtype=float), _rot_z(math.radians(s["theta_deg"]))
    sols = doc.get("published_solutions") or []
    if not 0 <= index < len(sols):
        raise GlpmaError(f"the config has {len(sols)} published_solutions; cannot use solution {index}")
    R, p = model.pose_state(np.asarray(sols[index], dtype=float))   # rigid fit of B1, B2, B3
    return np.asarray(p, dtype=float), np.asarray(R, dtype=float)


def _solved_start_pose(model) -> tuple[np.ndarray, np.ndarray]:
    """A user's own config without known solutions: start where its ``example_leg_lengths`` put
    the platform (one cold solve, no time limit)."""
    from glpma_ros.estimator import Estimator
    from glpma_ros.models.rotations import matrix_from_quaternion
    if model.example_leg_lengths is None:
        raise GlpmaError("the config has no known solutions and no example_leg_lengths to start from; "
                         "add example_leg_lengths (a pose's leg lengths)")
    e = Estimator(model, time_budget_s=60.0).estimate(model.example_leg_lengths)
    if not e.converged:
        raise GlpmaError(f"cannot start from the config's example_leg_lengths: {e.message}")
    return np.asarray(e.pose.position, dtype=float), matrix_from_quaternion(e.pose.orientation)


def trajectory(model, p0: np.ndarray, R0: np.ndarray, amplitude: float = 1.0, period_s: float = PERIOD_S):
    """``t -> (position, rotation matrix)`` starting at ``(p0, R0)`` at ``t = 0``; sizes are
    relative to the geometry's scale, times ``amplitude``."""
    w = 2.0 * math.pi / period_s
    s = model.scale * amplitude
    if model.kind == "planar_3rpr":
        def pose_at(t):
            p = p0 + np.array([0.05 * s * math.sin(w * t), 0.04 * s * math.sin(2 * w * t), 0.0])
            return p, _rot_z(0.15 * amplitude * math.sin(w * t)) @ R0
    else:
        def pose_at(t):
            radius, rise, twist = 0.02 * s, 0.03 * s, 0.1 * amplitude
            p = p0 + np.array([radius * (math.cos(w * t) - 1.0), radius * math.sin(w * t),
                               rise * math.sin(w * t / 4.0)])
            tilt = rotation_from_vector(np.array([0.3 * twist * math.sin(2 * w * t), 0.0, 0.0]))
            return p, _rot_z(twist * math.sin(w * t)) @ tilt @ R0
    return pose_at


def legs_for(model, position, quaternion) -> np.ndarray:
    """Leg lengths (config unit) of a pose, by the model's inverse kinematics."""
    return model.inverse_kinematics(model.variables_from_pose(position, quaternion))


def quaternion_angle(q1, q2) -> float:
    """Rotation angle (rad) between two unit quaternions [x, y, z, w], robust near 0."""
    a = np.asarray(q1, dtype=float)
    b = np.asarray(q2, dtype=float)
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    # relative rotation conj(a) * b: vector part and scalar part
    w = float(a @ b)
    v = a[3] * b[:3] - b[3] * a[:3] - np.cross(a[:3], b[:3])
    return 2.0 * math.atan2(float(np.linalg.norm(v)), abs(w))


# -- the run ---------------------------------------------------------------------------------------

@dataclass
class Sent:
    send_ns: int
    legs: np.ndarray         # config unit
    position_m: np.ndarray
    quaternion: np.ndarray


def _stats(values, scale: float = 1.0) -> dict:
    if not values:
        return {"p50": None, "p99": None, "max": None, "mean": None}
    arr = np.asarray(values, dtype=float) * scale
    p50, p99 = np.percentile(arr, [50, 99])
    return {"p50": float(p50), "p99": float(p99), "max": float(arr.max()), "mean": float(arr.mean())}


class PoseListener:
    """Takes ``pose_estimate`` (and the node's ``/diagnostics``) on a thread, with receive times."""

    def __init__(self, participant, depth: int):
        from glpma_ros.node.dds import endpoints
        from glpma_ros.node.dds.messages import DiagnosticArray, PoseStamped
        self.reader = participant.reader(endpoints.POSE_ESTIMATE, PoseStamped, depth)
        self.diag_reader = participant.reader(endpoints.DIAGNOSTICS, DiagnosticArray, depth)
        self.poses: list = []            # (recv_ns, stamp_ns, frame_id, position (3,), quaternion (4,))
        self.diagnostics: dict | None = None
        self.diagnostics_stamp_ns = 0
        self._stop = False
        self._waitset, self._guard = endpoints.reader_waitset(participant, [self.reader, self.diag_reader])
        self._thread = threading.Thread(target=self._run, name="mock-pose-listener", daemon=True)
        self._thread.start()

    def _run(self):
        from cyclonedds.util import duration

        from glpma_ros.node.dds.messages import DiagnosticArray, PoseStamped
        while not self._stop:
            self._waitset.wait(duration(milliseconds=100))
            samples = self.reader.take(256)
            recv_ns = time.time_ns()
            for s in samples:
                if isinstance(s, PoseStamped):
                    p, q = s.pose.position, s.pose.orientation
                    self.poses.append((recv_ns, s.header.stamp.to_ns(), s.header.frame_id,
                                       np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])))
            for d in self.diag_reader.take(64):
                if isinstance(d, DiagnosticArray) and d.status:
                    status = d.status[0]
                    self.diagnostics = {"level": int(status.level), "message": status.message,
                                        "values": {kv.key: kv.value for kv in status.values}}
                    self.diagnostics_stamp_ns = d.header.stamp.to_ns()

    def close(self):
        self._stop = True
        self._guard.set(True)
        self._thread.join(2.0)


def match_poses(model, sent: list[Sent], poses: list, window: int = 8) -> list[tuple[int, tuple]]:
    """Pair each pose with the input it answers: among the inputs sent just before its stamp,
    the one whose leg lengths the pose reproduces best.  Each input is matched at most once."""
    send_times = [s.send_ns for s in sent]
    matched: dict[int, tuple] = {}
    mpu = model.metres_per_unit
    for pose in poses:
        _, stamp_ns, _, position_m, quaternion = pose
        j = bisect.bisect_right(send_times, stamp_ns) - 1
        candidates = [i for i in range(max(0, j - window), min(len(sent), j + 2)) if i not in matched]
        if not candidates:
            continue
        try:
            legs = legs_for(model, position_m / mpu, quaternion)
        except Exception:  # noqa: BLE001 - a garbage pose: match by stamp alone
            legs = None
        if legs is None or not np.all(np.isfinite(legs)):
            best = min(candidates, key=lambda i: abs(i - j))
        else:
            best = min(candidates, key=lambda i: float(np.max(np.abs(legs - sent[i].legs))))
        matched[best] = pose
    return sorted(matched.items())


def run(config: str = "planar_3rpr_seed", rate_hz: float = 200.0, duration_s: float = 5.0, *,
        domain_id: int | None = None, qos_depth: int = 10, solution: int | None = None,
        amplitude: float = 1.0, connect_timeout_s: float = 30.0, settle_s: float = 0.3,
        tail_s: float = 1.0, diagnostics_wait_s: float = 1.5, progress=None, samples: bool = False,
        input_type: str = "float64_multi_array", joint_names=None, modes_period_s: float | None = None) -> dict:
    """Drive the node for ``duration_s`` at ``rate_hz`` and return the summary (a JSON-able dict).

    ``progress(i, n, summary_so_far)`` is called about once a second while sending, if given;
    ``summary_so_far`` has ``poses_received``, ``latency_p50_ms`` and ``position_error_max_m``.
    With ``samples=True`` the summary also holds the per-input series (``samples``: true and
    estimated positions in metres, latency in ms) for plotting.  With ``modes_period_s`` a
    ``~/request_assembly_modes`` is sent every so many seconds while streaming (the next once
    the previous is answered); the summary's ``assembly_modes`` has the answers and the pose
    latency of the inputs sent while a request was being answered.
    After sending, waits up to ``tail_s`` for the last poses and up to ``diagnostics_wait_s``
    for a ``/diagnostics`` report of the node that covers every input (``node_diagnostics``).
    ``input_type``: ``float64_multi_array`` (``leg_lengths``) or ``joint_state`` (``joint_states``,
    legs under ``joint_names`` among :data:`EXTRA_JOINTS`, shuffled, stamped with the send time).
    Raises :class:`TimeoutError` when no node answers within ``connect_timeout_s``."""
    from glpma_ros.node.dds import endpoints
    from glpma_ros.node.dds.messages import (Float64MultiArray, Header, JointState, MultiArrayDimension, MultiArrayLayout,
                               Time)

    if input_type not in INPUT_TYPES:
        raise ValueError(f"input_type must be one of {', '.join(INPUT_TYPES)}, got {input_type!r}")
    path = resolve_config(config)
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    mpu = model.metres_per_unit
    p0, R0 = start_pose(model, doc, solution)
    pose_at = trajectory(model, p0, R0, amplitude)
    joint_state = input_type == "joint_state"
    names = list(joint_names) if joint_names else [f"leg_{i + 1}" for i in range(model.n_legs)]
    if len(names) != model.n_legs:
        raise ValueError(f"joint_names must name the {model.n_legs} legs, got {len(names)} names")
    shuffle = np.random.default_rng(0)

    participant = endpoints.Participant(domain_id)
    if joint_state:
        writer = participant.writer(endpoints.JOINT_STATES, JointState, qos_depth)
    else:
        writer = participant.writer(endpoints.LEG_LENGTHS, Float64MultiArray, qos_depth)
    listener = PoseListener(participant, qos_depth)
    modes = None if modes_period_s is None else ModesClient(participant)
    try:
        if not endpoints.wait_for_match([writer, listener.reader] + ([] if modes is None else modes.endpoints),
                                        connect_timeout_s):
            raise TimeoutError(f"no glpma_fk node on ROS domain {participant.domain_id} within "
                               f"{connect_timeout_s:g} s (is it running with the same CYCLONEDDS_URI?)")
        time.sleep(settle_s)
        n = max(1, int(round(rate_hz * duration_s)))
        period = 1.0 / rate_hz
        layout = MultiArrayLayout(dim=[MultiArrayDimension(label="legs", size=model.n_legs, stride=model.n_legs)])
        sent: list[Sent] = []
        late = 0
        t_start = time.perf_counter()
        next_progress = t_start + 1.0
        for i in range(n):
            target = t_start + i * period
            delay = target - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            elif delay < -period:
                late += 1
            position, R = pose_at(i * period)
            quaternion = quaternion_from_matrix(R)
            legs = legs_for(model, position, quaternion)
            if joint_state:
                joints = list(zip(names, (float(v) * mpu for v in legs))) + list(EXTRA_JOINTS)
                order = shuffle.permutation(len(joints))
                send_ns = time.time_ns()
                msg = JointState(header=Header(stamp=Time.from_ns(send_ns), frame_id=""),
                                 name=[joints[k][0] for k in order], position=[joints[k][1] for k in order])
            else:
                msg = Float64MultiArray(layout=layout, data=[float(v) * mpu for v in legs])
                send_ns = time.time_ns()
            writer.write(msg)
            sent.append(Sent(send_ns, legs, position * mpu, quaternion))
            if modes is not None:
                modes.poll(send_ns, modes_period_s)
            if progress is not None and time.perf_counter() >= next_progress:
                next_progress += 1.0
                _, pos_err, _, latency = _compare(model, sent, list(listener.poses))
                progress(i + 1, n, {"poses_received": len(listener.poses),
                                    "latency_p50_ms": float(np.median(latency)) * 1e-6 if latency else math.nan,
                                    "position_error_max_m": max(pos_err) if pos_err else math.nan})
        deadline = time.monotonic() + tail_s
        while time.monotonic() < deadline and len(listener.poses) < len(sent):
            time.sleep(0.01)
        time.sleep(min(0.05, tail_s))
        # wait for a diagnostics report of the node issued after the last input
        deadline = time.monotonic() + diagnostics_wait_s
        while time.monotonic() < deadline and sent and listener.diagnostics_stamp_ns <= sent[-1].send_ns:
            time.sleep(0.02)
    finally:
        listener.close()

    pairs, pos_err, ang_err, latency = _compare(model, sent, list(listener.poses))
    frame_ids = sorted({p[2] for p in listener.poses})
    summary = {
        "manipulator": model.kind,
        "config": str(path),
        "solution": DEFAULT_SOLUTION[model.kind] if solution is None else int(solution),
        "input_type": input_type,
        "rate_hz": rate_hz,
        "duration_s": duration_s,
        "inputs_sent": len(sent),
        "poses_received": len(listener.poses),
        "poses_matched": len(pairs),
        "pose_ratio": len(pairs) / len(sent) if sent else 0.0,
        "late_sends": late,
        "frame_ids": frame_ids,
        "tracking_error": {"position_m": _stats(pos_err), "orientation_rad": _stats(ang_err)},
        "latency_ms": _stats(latency, 1e-6),
        "node_diagnostics": listener.diagnostics,
    }
    if modes is not None:
        modes.poll(time.time_ns(), None)
        busy = [lat for (i, _), lat in zip(pairs, latency) if modes.busy_at(sent[i].send_ns)]
        summary["assembly_modes"] = {"requests": modes.requested, "answers": len(modes.answers),
                                     "modes_per_answer": sorted({n for n, _ in modes.answers}),
                                     "answer_s": _stats([t for _, t in modes.answers]),
                                     "pose_latency_during_requests_ms": _stats(busy, 1e-6)}
    if samples:
        summary["samples"] = {
            "true_position_m": [[float(v) for v in s.position_m] for s in sent],
            "estimated_position_m": [[float(v) for v in pose[3]] for _, pose in pairs],
            "latency_ms": [v * 1e-6 for v in latency],
        }
    return summary


class ModesClient:
    """Sends ``~/request_assembly_modes`` one after the other (the next once the previous is
    answered and ``period_s`` has passed) and collects the ``~/assembly_modes`` answers."""

    def __init__(self, participant):
        from glpma_ros.node.dds import endpoints
        from glpma_ros.node.dds.messages import Empty, PoseArray
        self._empty = Empty
        self.writer = participant.writer(endpoints.REQUEST_ASSEMBLY_MODES, Empty, 1)
        self.reader = participant.reader(endpoints.ASSEMBLY_MODES, PoseArray, 1, transient_local=True)
        self.endpoints = [self.writer, self.reader]
        self.requested = 0
        self.pending_ns = None          # send time of the request being answered
        self.last_ns = 0
        self.answers = []               # (modes, seconds from request to answer)
        self.windows = []               # (request ns, answer ns)

    def poll(self, now_ns: int, period_s: float | None) -> None:
        for msg in self.reader.take(4):
            if hasattr(msg, "poses") and self.pending_ns is not None:
                done = time.time_ns()
                self.answers.append((len(msg.poses), (done - self.pending_ns) * 1e-9))
                self.windows.append((self.pending_ns, done))
                self.pending_ns = None
        if period_s is not None and self.pending_ns is None and now_ns - self.last_ns >= period_s * 1e9:
            self.writer.write(self._empty())
            self.requested += 1
            self.pending_ns = self.last_ns = now_ns

    def busy_at(self, t_ns: int) -> bool:
        return any(a <= t_ns <= b for a, b in self.windows)


def _compare(model, sent, poses):
    """Matched pairs, and per pair the position error (m), orientation error (rad), latency (ns)."""
    pairs = match_poses(model, sent, poses)
    pos_err, ang_err, latency = [], [], []
    for i, (recv_ns, _, _, position_m, quaternion) in pairs:
        pos_err.append(float(np.linalg.norm(position_m - sent[i].position_m)))
        ang_err.append(quaternion_angle(quaternion, sent[i].quaternion))
        latency.append(recv_ns - sent[i].send_ns)
    return pairs, pos_err, ang_err, latency


def format_summary(s: dict) -> str:
    """A few human-readable lines."""
    def fmt(d, unit, spec):
        if d["p50"] is None:
            return "n/a"
        return f"p50 {d['p50']:{spec}} / p99 {d['p99']:{spec}} / max {d['max']:{spec}} {unit}"
    te = s["tracking_error"]
    return "\n".join([
        f"{s['manipulator']} at {s['rate_hz']:g} Hz for {s['duration_s']:g} s: "
        f"{s['inputs_sent']} inputs sent, {s['poses_received']} poses received, "
        f"{s['poses_matched']} matched ({100 * s['pose_ratio']:.1f} %)",
        f"  tracking error position     {fmt(te['position_m'], 'm', '.3g')}",
        f"  tracking error orientation  {fmt(te['orientation_rad'], 'rad', '.3g')}",
        f"  end-to-end latency          {fmt(s['latency_ms'], 'ms', '.3f')}",
    ])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="mock_controller", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="planar_3rpr_seed",
                        help="manipulator YAML or shipped config name (the node's manipulator_config)")
    parser.add_argument("--rate", type=float, default=200.0, help="inputs per second (default 200)")
    parser.add_argument("--duration", type=float, default=5.0, help="seconds of sending (default 5)")
    parser.add_argument("--solution", type=int, default=None,
                        help="index of the config's known solution to move around")
    parser.add_argument("--amplitude", type=float, default=1.0, help="scale of the motion (default 1)")
    parser.add_argument("--qos-depth", type=int, default=10)
    parser.add_argument("--input", choices=INPUT_TYPES, default="float64_multi_array",
                        help="publish leg_lengths (default) or joint_states (legs among other joints, "
                             "shuffled; run the node with input_type:=joint_state)")
    parser.add_argument("--joint-names", nargs="+", default=None, metavar="NAME",
                        help="--input joint_state: the legs' joint names in leg order (default leg_1 .. leg_n)")
    parser.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for the node")
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object on stdout")
    args = parser.parse_args(argv)
    if args.rate <= 0 or args.duration <= 0:
        print("mock_controller: error: --rate and --duration must be positive", file=sys.stderr)
        return 2

    def progress(i, n, partial):
        print(f"sent {i}/{n}, poses received {partial['poses_received']}", file=sys.stderr, flush=True)

    try:
        summary = run(args.config, args.rate, args.duration, solution=args.solution, amplitude=args.amplitude,
                      qos_depth=args.qos_depth, connect_timeout_s=args.timeout,
                      progress=None if args.json else progress, input_type=args.input,
                      joint_names=args.joint_names)
    except (GlpmaError, TimeoutError, ValueError) as exc:
        print(f"mock_controller: error: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, GlpmaError) else 1
    print(json.dumps(summary) if args.json else format_summary(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())


#: seconds between two assembly-modes requests in the end-to-end benchmark's second run
MODES_PERIOD_S = 0.5
#: end-to-end benchmark rates (issue: 3-RPR at 1 kHz, hexapod at 500 Hz) and params files
END_TO_END = {"planar_3rpr": (1000.0, "params_3rpr.yaml"), "hexapod_66": (500.0, "params_hexapod.yaml")}


def bench_end_to_end(config: str, steps: int | None = None, quick: bool = False, duration_s: float = 10.0) -> dict:
    """Start a node process over DDS on a private domain, drive it at the issue's rate for the
    config's manipulator and return flat figures: input published -> pose received latency,
    inputs, poses, drops, the node's solve time, and its RSS after warm-up and after the run."""
    import os
    import tempfile

    from glpma_ros.config import config_dir
    from glpma_tools.sim.node_process import NodeProcess, node_environment

    model = model_from_dict(load_document(resolve_config(config)), str(config))
    rate, params = END_TO_END[model.kind]
    duration = 2.0 if quick else (steps / rate if steps else duration_s)
    domain = 233 - os.getpid() % 30
    with tempfile.TemporaryDirectory(prefix="glpma_e2e_") as logs:
        node = NodeProcess(["--params-file", str(config_dir() / params), "-p", f"manipulator_config:={config}"],
                           node_environment(domain), Path(logs))
        node.start()
        try:
            rss_before = node.rss_kb()
            summary = run(str(config), rate, duration, domain_id=domain)
            rss_after = node.rss_kb()
            with_modes = run(str(config), rate, duration, domain_id=domain, modes_period_s=MODES_PERIOD_S)
        finally:
            node.stop()
    lat, diag = summary["latency_ms"], (summary.get("node_diagnostics") or {}).get("values", {})

    def number(key):
        return float(diag[key]) if key in diag else None
    return {"rate_hz": rate, "duration_s": duration, "inputs": summary["inputs_sent"],
            "poses": summary["poses_matched"], "pose_ratio": summary["pose_ratio"],
            "p50_ms": lat["p50"], "p99_ms": lat["p99"], "max_ms": lat["max"],
            "dropped": number("inputs dropped"), "deadline_misses": number("deadline misses"),
            "node_solve_p99_ms": number("solve time p99 (ms)"),
            "position_error_max_m": summary["tracking_error"]["position_m"]["max"],
            "rss_after_warm_up_mb": rss_before / 1024, "rss_after_run_mb": rss_after / 1024,
            "rss_growth_mb": (rss_after - rss_before) / 1024,
            "assembly_modes": _modes_figures(with_modes)}


def _modes_figures(summary: dict) -> dict:
    m = summary["assembly_modes"]
    return {"requests answered": m["answers"], "modes per answer": ", ".join(map(str, m["modes_per_answer"])),
            "answer time p50 (s)": m["answer_s"]["p50"],
            "pose latency p99 while answering (ms)": m["pose_latency_during_requests_ms"]["p99"],
            "pose latency p99 whole run (ms)": summary["latency_ms"]["p99"]}
