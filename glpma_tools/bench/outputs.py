"""Cost of the node's extra outputs and of its DDS transport path, for BENCHMARKS.md.

``python -m glpma_tools.bench.outputs [--inputs N] [--e2e-seconds S] [--rate HZ] [--markdown PATH]``

1. **Extra outputs, per input** -- a :class:`~glpma_ros.node.dds.node.DdsNode` in this process,
   its readers not started, fed through :meth:`SolveLoop.offer` (the path its reader threads
   take) with warm inputs along the mock controller's trajectory, a subscriber process taking
   every topic.  For each output alone (``/tf``, ``pose_estimate_cov``, ``twist_estimate`` from
   poses and from ``joint_states`` velocities, ``~/markers`` with every pose) and for all of them,
   the time the node spends on the extra messages of one pose -- building, encoding, writing
   (``/diagnostics``' ``extra outputs time``) -- p50 and p99, beside the time of the pose's own
   encoding and write and of the solve.
2. **Legs written -> pose read** -- the node as a process (``glpma_ros.node.dds.node``, shipped
   params file, every default output on), a client writing ``leg_lengths`` at ``--rate`` for
   ``--e2e-seconds`` and taking ``pose_estimate``: latency p50/p99/max split at the pose's stamp
   (the node's arrival time, same clock): *written -> taken by the node* (DDS delivery, the
   reader's wake-up, take and decode) and *taken -> pose read* (solve, encode, write, the
   client's wake-up); node CPU and inputs dropped.
3. **The rclpy adapter** (where rclpy is importable): the same from an rclpy client, for the
   shipped executor set-up (``SingleThreadedExecutor``, the newest input solved in the
   subscription callback) and two alternatives (a hand-off to a solver thread; a two-thread
   ``MultiThreadedExecutor`` with a reentrant group).

Writes a ``## Extra outputs and the transport path`` section into ``--markdown`` (default
BENCHMARKS.md; other sections kept) and prints it.  Timings are wall clock on a shared machine.
"""
from __future__ import annotations

import argparse
import os
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

HEADING = "## Extra outputs and the transport path"
ROOT = Path(__file__).resolve().parents[2]
CONFIGS = (("planar_3rpr_seed", "params_3rpr.yaml"), ("hexapod_66_rolland", "params_hexapod.yaml"))
#: the output configurations of part 1: name -> parameters
CASES = (
    ("none", {}),
    ("/tf", {"publish_tf": True}),
    ("pose_estimate_cov", {"publish_covariance": True}),
    ("twist_estimate (poses)", {"publish_twist": True}),
    ("twist_estimate (velocities)", {"publish_twist": True, "input_type": "joint_state"}),
    ("~/markers (every pose)", {"publish_markers": True, "markers_period_s": 0.0}),
    ("all (defaults + markers 10 Hz)", {"publish_tf": True, "publish_covariance": True, "publish_twist": True,
                                        "publish_markers": True}),
)
OFF = {"publish_tf": False, "publish_covariance": False, "publish_twist": False, "publish_markers": False}
#: seconds between two inputs of part 1 (the subscriber keeps up; the inputs stay warm)
PACE_S = 1e-3
SUBSCRIBER = r"""
import sys, time
from glpma_ros.node.dds import cdr, endpoints
from glpma_ros.node.dds.messages import PoseStamped, TFMessage, PoseWithCovarianceStamped, TwistStamped, MarkerArray
p = endpoints.Participant()
readers = [p.reader(t, m, 100) for t, m in ((endpoints.POSE_ESTIMATE, PoseStamped), (endpoints.TF, TFMessage),
           (endpoints.POSE_ESTIMATE_COV, PoseWithCovarianceStamped), (endpoints.TWIST_ESTIMATE, TwistStamped),
           (endpoints.MARKERS, MarkerArray))]
ws, guard = endpoints.reader_waitset(p, readers)
from cyclonedds.util import duration
print("ready", flush=True)
while True:
    ws.wait(duration(milliseconds=100))
    for r in readers:
        cdr.take_raw(r, 1000)
"""


def _percentiles_us(values) -> tuple[float, float]:
    arr = np.asarray(values, dtype=float) * 1e6
    return float(np.percentile(arr, 50)), float(np.percentile(arr, 99))


def _env(domain: int) -> dict:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    env.setdefault("CYCLONEDDS_URI", (ROOT / "config" / "cyclonedds-localhost.xml").as_uri())
    return env


def _legs_along_trajectory(config: str, n: int, period_s: float):
    from glpma_ros.config import load_document, model_from_dict, resolve_config
    from glpma_ros.models.rotations import quaternion_from_matrix
    try:                                    # the shared trajectories' module, where it exists
        from glpma_tools.sim.trajectories import legs_for, start_pose, trajectory
    except ImportError:
        from glpma_tools.mock_controller import legs_for, start_pose, trajectory
    path = resolve_config(config)
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    p0, R0 = start_pose(model, doc)
    at = trajectory(model, p0, R0)
    legs = []
    for i in range(n + 1):
        p, R = at(i * period_s)
        legs.append(legs_for(model, p, quaternion_from_matrix(R)) * model.metres_per_unit)
    return model, np.array(legs)


def output_costs(n_inputs: int, domain: int, pace_s: float = PACE_S) -> list[dict]:
    """Part 1: per configuration and manipulator, p50/p99 of the extras, pose publish and solve."""
    import yaml

    from glpma_ros.node.dds import endpoints
    from glpma_ros.node.dds.node import DdsNode
    from glpma_ros.node.params import resolve
    from glpma_ros.node.service import FkService, JointStateInput

    os.environ.update({k: v for k, v in _env(domain).items() if k in ("ROS_DOMAIN_ID", "CYCLONEDDS_URI")})
    sub = subprocess.Popen([sys.executable, "-c", SUBSCRIBER], stdout=subprocess.PIPE, text=True, env=_env(domain))
    rows = []
    try:
        sub.stdout.readline()
        participant = endpoints.Participant(domain)
        for config, params_file in CONFIGS:
            file_params = yaml.safe_load((ROOT / "config" / params_file).read_text())["glpma_fk"]["ros__parameters"]
            model, legs = _legs_along_trajectory(config, n_inputs, PACE_S)
            for name, case in CASES:
                values, _ = resolve({**file_params, **OFF, **case})
                service = FkService(values)
                service.warm_up(solvers=(values["solver"],))
                node = DdsNode(service, participant, modes_solve=lambda *a: [])
                pose_s, pose_cpu, extras_cpu, build_cpu, current = [], [], [], [], [0, 0]
                publish, build, publish_extras = node._publish_pose, service.extras, node.loop.publish_extras

                def timed_pose(pose, publish=publish, pose_s=pose_s, pose_cpu=pose_cpu):
                    t, c = time.perf_counter(), time.thread_time_ns()
                    publish(pose)
                    pose_cpu.append((time.thread_time_ns() - c) * 1e-9)
                    pose_s.append(time.perf_counter() - t)

                def timed(function, slot, current=current):
                    def call(arg):
                        c = time.thread_time_ns()
                        try:
                            return function(arg)
                        finally:
                            current[slot] += time.thread_time_ns() - c
                    return call
                node.loop.publish = timed_pose
                service.extras = timed(build, 0)                    # TF, covariance, twist, markers
                node.loop.publish_extras = timed(publish_extras, 1)  # their encoding and DDS writes
                names = tuple(f"leg_{i + 1}" for i in range(model.n_legs))
                rates = np.gradient(legs, PACE_S, axis=0)
                time.sleep(0.5)                     # discovery of the subscriber
                for i in range(n_inputs):
                    stamp = 1_795_000_000 * 10**9 + int(i * PACE_S * 1e9)
                    if values["input_type"] == "joint_state":
                        item = JointStateInput(names, tuple(legs[i]), tuple(rates[i]))
                    else:
                        item = tuple(legs[i])
                    current[:] = [0, 0]
                    node.loop.offer(item, stamp)
                    extras_cpu.append(sum(current) * 1e-9)
                    build_cpu.append(current[0] * 1e-9)
                    if pace_s:
                        time.sleep(pace_s)
                st = service.stats
                extras = _percentiles_us(st.extras_s) if st.extras_s else (0.0, 0.0)
                rows.append({"manipulator": model.kind, "outputs": name, "inputs": n_inputs,
                             "published": st.published, "extras_us": extras, "pose_us": _percentiles_us(pose_s),
                             "extras_cpu_us": _percentiles_us(extras_cpu), "pose_cpu_us": _percentiles_us(pose_cpu),
                             "build_cpu_us": _percentiles_us(build_cpu),
                             "solve_us": _percentiles_us(st.solve_s)})
    finally:
        sub.kill()
        sub.wait()
    return rows


def end_to_end(seconds: float, rate_hz: float, domain: int, node_root: Path = ROOT, label: str = "",
               extra_args=()) -> list[dict]:
    """Part 2: legs written -> pose read, with the node as a process (from the checkout ``node_root``;
    ``extra_args``: more ``--ros-args``)."""
    from cyclonedds.util import duration

    from glpma_ros.node.dds import cdr, endpoints
    from glpma_ros.node.dds.messages import Float64MultiArray, MultiArrayDimension, MultiArrayLayout, PoseStamped

    rows = []
    for k, (config, params_file) in enumerate(CONFIGS):
        env = _env(domain + 1 + k)
        env["PYTHONPATH"] = str(node_root)
        os.environ.update({key: env[key] for key in ("ROS_DOMAIN_ID", "CYCLONEDDS_URI")})
        err = tempfile.TemporaryFile(mode="w+")
        node = subprocess.Popen([sys.executable, "-m", "glpma_ros.node.dds.node", "--ros-args", "--params-file",
                                 str(ROOT / "config" / params_file), *extra_args], stdout=subprocess.PIPE,
                                stderr=err, text=True, env=env, cwd=node_root)
        try:
            node.stdout.readline()
            model, legs = _legs_along_trajectory(config, int(seconds * rate_hz), 1.0 / rate_hz)
            part = endpoints.Participant(domain + 1 + k)
            writer = part.writer(endpoints.LEG_LENGTHS, Float64MultiArray, 10)
            reader = part.reader(endpoints.POSE_ESTIMATE, PoseStamped, 100)
            waitset, guard = endpoints.reader_waitset(part, [reader])
            received, stop = [], threading.Event()

            def listen():
                while not stop.is_set():
                    waitset.wait(duration(milliseconds=100))
                    for data, _ in cdr.take_raw(reader, 256):
                        t = time.time_ns()
                        sec, nanosec = struct.unpack_from("<iI", data, 4)
                        received.append((sec * 1_000_000_000 + nanosec, t))
            listener = threading.Thread(target=listen, daemon=True)
            listener.start()
            if not endpoints.wait_for_match([writer, reader], 120):
                raise TimeoutError("the node did not come up")
            time.sleep(0.5)
            layout = MultiArrayLayout(dim=[MultiArrayDimension(label="legs", size=model.n_legs, stride=model.n_legs)])
            raw = [Float64MultiArray(layout=layout, data=[float(v) for v in row]).serialize() for row in legs]
            out = cdr.RawWriter(writer)
            sent = []
            cpu0, wall0 = _cpu_s(node.pid), time.monotonic()
            t0 = time.perf_counter()
            for i, data in enumerate(raw):
                delay = t0 + i / rate_hz - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                sent.append(time.time_ns())
                out.write(data)
            time.sleep(1.0)
            cpu = (_cpu_s(node.pid) - cpu0) / (time.monotonic() - wall0)
            stop.set()
            guard.set(True)
            listener.join()
        finally:
            node.send_signal(signal.SIGINT)
            node.wait(30)
        err.seek(0)
        summary = [ln for ln in err.read().splitlines() if "stopped:" in ln]
        sent_ns = np.array(sent)
        total, to_node, in_node = [], [], []
        for stamp, t in received:
            j = int(np.searchsorted(sent_ns, stamp)) - 1
            if j >= 0:
                total.append((t - sent_ns[j]) * 1e-6)
                to_node.append((stamp - sent_ns[j]) * 1e-6)
                in_node.append((t - stamp) * 1e-6)

        def stats(v):
            a = np.asarray(v)
            return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max())
        rows.append({"manipulator": model.kind + label, "rate_hz": rate_hz, "seconds": seconds, "sent": len(sent),
                     "poses": len(received), "total_ms": stats(total), "to_node_ms": stats(to_node),
                     "in_node_ms": stats(in_node), "cpu": cpu, "node": summary[-1].split("stopped: ")[-1] if summary
                     else ""})
    return rows


RCLPY_CLIENT = r"""
import sys, time, threading
import numpy as np, rclpy
from std_msgs.msg import Float64MultiArray
from geometry_msgs.msg import PoseStamped
from rclpy.executors import SingleThreadedExecutor
config, rate, seconds = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
from glpma_tools.bench.outputs import _legs_along_trajectory
model, legs = _legs_along_trajectory(config, int(rate * seconds), 1.0 / rate)
rclpy.init()
node = rclpy.create_node("glpma_fk_bench_client")
received = []
node.create_subscription(PoseStamped, "pose_estimate", lambda m: received.append(
    (m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec, time.time_ns())), 100)
pub = node.create_publisher(Float64MultiArray, "leg_lengths", 10)
executor = SingleThreadedExecutor()
executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
while pub.get_subscription_count() == 0:
    time.sleep(0.1)
time.sleep(1.0)
sent, t0 = [], time.perf_counter()
for i, row in enumerate(legs[:-1]):
    delay = t0 + i / rate - time.perf_counter()
    if delay > 0:
        time.sleep(delay)
    sent.append(time.time_ns())
    pub.publish(Float64MultiArray(data=[float(v) for v in row]))
time.sleep(1.0)
s = np.array(sent)
lat = [(t - s[np.searchsorted(s, st) - 1]) * 1e-6 for st, t in received if np.searchsorted(s, st) > 0]
print(len(sent), len(received), np.percentile(lat, 50), np.percentile(lat, 99), flush=True)
"""
#: rclpy adapter variants of part 3: the shipped one, and two alternatives that were measured
RCLPY_VARIANTS = (
    ("SingleThreadedExecutor, newest input solved in the callback (shipped)", "shipped"),
    ("SingleThreadedExecutor, hand-off to a solver thread", "submit"),
    ("MultiThreadedExecutor(2), reentrant group, solve in the callback", "multi"),
)


def rclpy_variants(seconds: float, rate_hz: float, domain: int) -> list[dict]:
    """Part 3 (where rclpy is importable): legs published by an rclpy client process -> pose received,
    for the adapter as shipped and two alternatives (3-RPR, shipped params)."""
    import yaml
    import rclpy
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from std_msgs.msg import Float64MultiArray

    from glpma_ros.node.ros_node import FkNode
    config, params_file = CONFIGS[0]
    values = yaml.safe_load((ROOT / "config" / params_file).read_text())["glpma_fk"]["ros__parameters"]
    rows = []
    for k, (label, variant) in enumerate(RCLPY_VARIANTS):
        env = _env(domain + 10 + k)
        os.environ.update({key: env[key] for key in ("ROS_DOMAIN_ID", "CYCLONEDDS_URI")})
        rclpy.init()
        node = FkNode(parameter_overrides=[Parameter(n, value=v) for n, v in values.items() if v != []])
        if variant != "shipped":
            node.destroy_subscription(node.input_sub)
            if variant == "submit":
                node.loop.start()
                callback = lambda msg: node.loop.submit(tuple(msg.data), node.get_clock().now().nanoseconds)  # noqa
            else:
                callback = lambda msg: node.loop.offer(tuple(msg.data), node.get_clock().now().nanoseconds)  # noqa
            node.create_subscription(Float64MultiArray, "leg_lengths", callback, values["qos_depth"],
                                     callback_group=ReentrantCallbackGroup() if variant == "multi" else None)
        executor = MultiThreadedExecutor(2) if variant == "multi" else SingleThreadedExecutor()
        executor.add_node(node)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        try:
            out = subprocess.run([sys.executable, "-c", RCLPY_CLIENT, config, str(rate_hz), str(seconds)], env=env,
                                 capture_output=True, text=True, timeout=seconds + 300, cwd=ROOT)
            sent, poses, p50, p99 = out.stdout.split()
            st = node.service.stats
            rows.append({"variant": label, "sent": int(sent), "poses": int(poses), "p50": float(p50),
                         "p99": float(p99), "received": st.handled + st.dropped, "dropped": st.dropped})
        finally:
            executor.shutdown()
            spinner.join()
            node.stop()
            node.destroy_node()
            rclpy.try_shutdown()
    return rows


def _cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def section(costs: list[dict], e2e: list[dict], pace_s: float = PACE_S, ros: list | None = None) -> list[str]:
    pace = f"one every {pace_s * 1e3:g} ms" if pace_s else "back to back"
    out = [HEADING, "",
           "`python -m glpma_tools.bench.outputs` (issue 12: each extra output costs at most 20 us per input at "
           "p50; issue 11: where the time between legs written and pose read goes). Wall clock on a shared "
           "2-core machine.", "",
           "Per input, the node's time on the extra messages of one published pose (build, encode, write; "
           "`extra outputs time` on `/diagnostics`), beside the pose's own encoding and write and the solve "
           f"({costs[0]['inputs'] if costs else 0} warm inputs per row, {pace}, a subscriber process on every "
           "topic):", "",
           "| manipulator | outputs on | extra outputs, CPU p50 / p99 (us) | of which building them, CPU p50 (us) | "
           "extra outputs, wall p50 / p99 (us) | pose encode + write, CPU / wall p50 (us) | solve, wall p50 (us) |",
           "|---|---|---|---|---|---|---|"]
    for r in costs:
        out.append(f"| {r['manipulator']} | {r['outputs']} | "
                   f"{r['extras_cpu_us'][0]:.1f} / {r['extras_cpu_us'][1]:.1f} | {r['build_cpu_us'][0]:.1f} | "
                   f"{r['extras_us'][0]:.1f} / {r['extras_us'][1]:.1f} | "
                   f"{r['pose_cpu_us'][0]:.1f} / {r['pose_us'][0]:.1f} | {r['solve_us'][0]:.0f} |")
    out += ["", "CPU = the solving thread's CPU time (`time.thread_time`), which preemption by other processes "
            "does not inflate; wall = `perf_counter`. Reading: an extra output costs what the node does to build "
            "it (the *building* column: the compiled Jacobian, covariance and twist, the finite difference, "
            "the markers' geometry) plus one struct-packed encoding and one Cyclone DDS write; the write to a "
            "reader in another process is most of it, as the pose's own write in the last column shows. An "
            "output nobody subscribes to costs its building and a write without readers; one switched off "
            "costs nothing. `~/markers` are built at most every `markers_period_s` (0.1 s), so at 1 kHz the "
            "median input builds none."]
    out += ["", "Legs written -> pose read, the node as a process with the shipped params file (all default "
            "outputs on, then off; a baseline checkout's node if given), split at the pose's stamp (the node's "
            "arrival time):", "",
            "| manipulator | rate | sent / poses | written -> pose read p50 / p99 / max (ms) | "
            "written -> taken by the node p50 / p99 (ms) | taken -> pose read p50 / p99 (ms) | node CPU | "
            "node summary |",
            "|---|---|---|---|---|---|---|---|"]
    for r in e2e:
        t, a, b = r["total_ms"], r["to_node_ms"], r["in_node_ms"]
        out.append(f"| {r['manipulator']} | {r['rate_hz']:g} Hz, {r['seconds']:g} s | {r['sent']} / {r['poses']} | "
                   f"{t[0]:.3f} / {t[1]:.3f} / {t[2]:.2f} | {a[0]:.3f} / {a[1]:.3f} | {b[0]:.3f} / {b[1]:.3f} | "
                   f"{100 * r['cpu']:.0f} % | {r['node']} |")
    if ros:
        out += ["", "The rclpy adapter (ROS 2 Jazzy, rmw_cyclonedds_cpp), 3-RPR: legs published by an rclpy client "
                "process -> pose received. *received* = inputs that reached the node's callback (the rest were "
                "lost in the middleware's keep-last queue while the executor was busy, uncounted):", "",
                "| executor | sent / received / poses | dropped (newest wins) | latency p50 / p99 (ms) |",
                "|---|---|---|---|"]
        for r in ros:
            out.append(f"| {r['variant']} | {r['sent']} / {r['received']} / {r['poses']} | {r['dropped']} | "
                       f"{r['p50']:.3f} / {r['p99']:.3f} |")
    return out + [""]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m glpma_tools.bench.outputs", description=__doc__.split("\n\n")[0])
    parser.add_argument("--inputs", type=int, default=3000, help="inputs per row of part 1 (default 3000)")
    parser.add_argument("--e2e-seconds", type=float, default=60.0, help="seconds of part 2 (default 60)")
    parser.add_argument("--rate", type=float, default=1000.0, help="input rate of part 2 (default 1000 Hz)")
    parser.add_argument("--domain", type=int, default=150 + os.getpid() % 50, help="first ROS_DOMAIN_ID used")
    parser.add_argument("--pace", type=float, default=PACE_S,
                        help="seconds between two inputs of part 1 (default 0.001; 0 = back to back)")
    parser.add_argument("--rclpy-seconds", type=float, default=10.0,
                        help="seconds per rclpy variant of part 3 (default 10; 0 = skip; needs rclpy)")
    parser.add_argument("--rclpy-rate", type=float, default=500.0, help="input rate of part 3 (default 500 Hz)")
    parser.add_argument("--baseline", type=Path, default=None, metavar="CHECKOUT",
                        help="part 2 also with the node of another checkout (e.g. the transport before this one)")
    parser.add_argument("--markdown", type=Path, default=ROOT / "BENCHMARKS.md")
    parser.add_argument("--no-markdown", action="store_true")
    args = parser.parse_args(argv)
    costs = output_costs(args.inputs, args.domain, args.pace)
    e2e = []
    if args.e2e_seconds > 0:
        e2e = end_to_end(args.e2e_seconds, args.rate, args.domain)
        off = ("-p", "publish_tf:=false", "-p", "publish_covariance:=false", "-p", "publish_twist:=false")
        e2e += end_to_end(args.e2e_seconds, args.rate, args.domain, label=", extra outputs off", extra_args=off)
        if args.baseline is not None:
            e2e += end_to_end(args.e2e_seconds, args.rate, args.domain, args.baseline.resolve(),
                              f", baseline node from {args.baseline}")
    ros = None
    if args.rclpy_seconds > 0:
        try:
            import rclpy  # noqa: F401 - only whether it imports
        except ImportError:
            print("rclpy not importable (source ROS 2 Jazzy): part 3 skipped", file=sys.stderr)
        else:
            ros = rclpy_variants(args.rclpy_seconds, args.rclpy_rate, args.domain)
    lines = section(costs, e2e, args.pace, ros)
    print("\n".join(lines))
    if not args.no_markdown:
        text = args.markdown.read_text() if args.markdown.exists() else ""
        args.markdown.write_text(splice(text, lines))
    return 0


def splice(text: str, section_lines: list[str]) -> str:
    """``text`` with its :data:`HEADING` section (up to the next ``## ``) replaced by
    ``section_lines``, or with them appended."""
    lines = text.splitlines()
    start = next((i for i, ln in enumerate(lines) if ln.strip() == HEADING), None)
    new = "\n".join(section_lines).rstrip().splitlines()
    if start is None:
        body = text.rstrip()
        return (body + "\n\n" if body else "") + "\n".join(new) + "\n"
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
    rest = lines[end:]
    return "\n".join(lines[:start] + new + ([""] + rest if rest else [])).rstrip() + "\n"


if __name__ == "__main__":
    sys.exit(main())
