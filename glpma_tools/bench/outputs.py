"""The ``outputs`` section of ``glpma-fk bench``: what the node's extra outputs cost per input,
and where the time between legs written and pose read goes over DDS.

1. :func:`output_costs` -- a :class:`~glpma_ros.node.dds.node.DdsNode` in this process fed through
   ``SolveLoop.offer`` with warm inputs, a subscriber process taking every topic: per output
   configuration, the solving thread's hand-off to the extras thread and that thread's work.
2. :func:`path_latency` -- the simulated controller against the node, the node with its extra
   outputs off and the echo (the transport floor), latency split at the pose's stamp.
3. :func:`micro_profile` -- one DDS write without and with a remote reader, a thread wake-up round
   trip, decoding an input and encoding a pose.
4. :func:`rclpy_variants` (where ``rclpy`` imports) -- the rclpy adapter's executor set-ups.

:func:`measure` runs them; :func:`section` renders them (prose in ``templates/outputs.md``)."""
from __future__ import annotations

import contextlib
import subprocess
import sys
import tempfile
import threading
import time
import timeit
from pathlib import Path

import numpy as np

from glpma_tools.sim.domains import claim_domain
from glpma_tools.stats import distribution
from glpma_tools.tables import MISSING, fmt, table

HEADING = "## Extra outputs and the transport path"
#: the outputs the shipped params files switch on: the row judged against :data:`EXTRAS_TARGET_US`
SHIPPED = "shipped (/tf, covariance, twist)"
#: per-input cost of the shipped extra outputs at p50 (µs) that issue 12 asks for
EXTRAS_TARGET_US = 20.0
#: the output configurations of part 1: name -> parameters
CASES = (
    ("none", {}),
    ("/tf", {"publish_tf": True}),
    ("pose_estimate_cov", {"publish_covariance": True}),
    ("twist_estimate (poses)", {"publish_twist": True}),
    ("twist_estimate (velocities)", {"publish_twist": True, "input_type": "joint_state"}),
    ("~/markers (every pose)", {"publish_markers": True, "markers_period_s": 0.0}),
    (SHIPPED, {"publish_tf": True, "publish_covariance": True, "publish_twist": True}),
    ("all (shipped + markers 10 Hz)", {"publish_tf": True, "publish_covariance": True, "publish_twist": True,
                                       "publish_markers": True}),
)
OFF = {"publish_tf": False, "publish_covariance": False, "publish_twist": False, "publish_markers": False}
#: seconds between two inputs of part 1 (the subscriber keeps up; the inputs stay warm)
PACE_S = 1e-3
#: the processes part 2 drives: label -> (module, extra --ros-args)
NODE, NODE_OFF, ECHO = "node", "node, extra outputs off", "echo (transport floor)"
TARGETS = {NODE: ("glpma_ros.node.dds.node", ()),
           NODE_OFF: ("glpma_ros.node.dds.node", tuple(a for k in OFF for a in ("-p", f"{k}:=false"))),
           ECHO: ("glpma_tools.sim.echo_node", ())}
#: seconds to wait for the controller's endpoints to match the process's, and to let it settle
CONNECT_S = 60.0
SETTLE_S = 0.5
#: seconds to wait for the last poses after the last input
TAIL_S = 1.0
#: the micro-profile's pace (s between two writes or round trips) and repetitions of the pure-CPU steps
PROFILE_PACE_S = 1e-3
PROFILE_CPU_REPEATS = 5000


def _us(values) -> dict:
    return distribution(values, 1e6)


# -- part 1: the extra outputs, per input ---------------------------------------------------------------
def subscribe_outputs() -> None:
    """A subscriber process of part 1: takes every output of the node, raw, until killed."""
    from cyclonedds.util import duration

    from glpma_ros.node.dds import cdr, endpoints
    from glpma_ros.node.dds.messages import MarkerArray, PoseStamped, PoseWithCovarianceStamped, TFMessage, TwistStamped
    p = endpoints.Participant()
    readers = [p.reader(t, m, 100) for t, m in ((endpoints.POSE_ESTIMATE, PoseStamped), (endpoints.TF, TFMessage),
               (endpoints.POSE_ESTIMATE_COV, PoseWithCovarianceStamped), (endpoints.TWIST_ESTIMATE, TwistStamped),
               (endpoints.MARKERS, MarkerArray))]
    waitset, _ = endpoints.reader_waitset(p, readers)
    print("ready", flush=True)
    while True:
        waitset.wait(duration(milliseconds=100))
        for r in readers:
            cdr.take_raw(r, 1000)


def _params_file(kind: str) -> dict:
    """The parameters of the shipped params file of ``kind`` (the node reads them so)."""
    from glpma_ros.config import config_dir
    from glpma_ros.node.ros_args import load_params_file

    from .dds import END_TO_END
    return load_params_file(str(config_dir() / END_TO_END[kind][1]))


def _timed(function, sink: list):
    """``function``, also appending ``(CPU s of the calling thread, wall s)`` of each call to ``sink``."""
    def call(*args):
        c, t = time.thread_time_ns(), time.perf_counter_ns()
        try:
            return function(*args)
        finally:
            sink.append(((time.thread_time_ns() - c) * 1e-9, (time.perf_counter_ns() - t) * 1e-9))
    return call


def output_costs(scenarios, n_inputs: int, domain: int, pace_s: float = PACE_S) -> list[dict]:
    """Part 1: per manipulator and output configuration (µs): on the solving thread the solve,
    the pose's encoding and write and the hand-off of the pose to the extras thread; on the
    extras thread the building and writing of the extra outputs of one pose."""
    from glpma_ros.node.dds import endpoints
    from glpma_ros.node.dds.node import DdsNode
    from glpma_ros.node.params import resolve
    from glpma_ros.node.service import FkService, JointStateInput, default_joint_names
    from glpma_tools.sim.node_process import node_environment
    from glpma_tools.sim.trajectories import Plan

    env = node_environment(domain)
    sub = subprocess.Popen([sys.executable, "-c", "from glpma_tools.bench.outputs import subscribe_outputs; "
                            "subscribe_outputs()"], stdout=subprocess.PIPE, text=True, env=env)
    rows = []
    try:
        sub.stdout.readline()
        participant = endpoints.Participant(domain)
        for sc in scenarios:
            plan = Plan(sc.path)
            file_params = _params_file(plan.model.kind)
            legs = np.array([plan.sample(i * pace_s)[0] * plan.mpu for i in range(n_inputs + 1)])
            rates = np.gradient(legs, pace_s, axis=0)
            for name, case in CASES:
                values, _ = resolve({**file_params, "manipulator_config": sc.path, **OFF, **case})
                service = FkService(values)
                service.warm_up(solvers=(values["solver"],))
                node = DdsNode(service, participant, modes_solve=lambda *a: [])
                loop, extras = node.loop, node.loop.extras
                names = tuple(values["joint_names"] or default_joint_names(plan.model.n_legs))
                pose, handoff, thread, build = [], [], [], []
                loop.publish = _timed(loop.publish, pose)                # solving thread: encode + write the pose
                extras.put = _timed(extras.put, handoff)                 # solving thread: the hand-off
                extras.publish = _timed(extras.publish, thread)          # extras thread: one pose's extras
                service.extras = _timed(service.extras, build)           # extras thread: building them
                if not endpoints.wait_for_match([node.pose_writer], CONNECT_S):
                    raise TimeoutError(f"the subscriber did not match within {CONNECT_S:g} s")
                time.sleep(SETTLE_S)                                     # the other topics' discovery
                for i in range(n_inputs):
                    stamp = 1_795_000_000 * 10**9 + int(i * pace_s * 1e9)
                    if values["input_type"] == "joint_state":
                        item = JointStateInput(names, tuple(legs[i]), tuple(rates[i]))
                    else:
                        item = tuple(legs[i])
                    loop.offer(item, stamp)
                    if pace_s:
                        time.sleep(pace_s)
                extras.flush()
                loop.stop()
                st = service.stats
                rows.append({"manipulator": sc.label, "outputs": name, "inputs": n_inputs, "published": st.published,
                             "solve_us": _us(st.solve_s.values()), "pose_cpu_us": _us([c for c, _ in pose]),
                             "pose_us": _us([w for _, w in pose]), "handoff_cpu_us": _us([c for c, _ in handoff]),
                             "handoff_us": _us(st.extras_handoff_s.values()), "extras_cpu_us": _us([c for c, _ in thread]),
                             "build_cpu_us": _us([c for c, _ in build]), "extras_us": _us(st.extras_s.values()),
                             "extras_dropped": st.extras_dropped})
    finally:
        sub.kill()
        sub.wait()
    return rows


# -- part 2: legs written -> pose read ------------------------------------------------------------------
def answers(plan, sent, poses, echo: bool) -> tuple[list, list, int]:
    """(the index of the input each paired pose answers, those poses, the poses that answer no input or
    lie off its true pose); an echo's poses carry the legs they answer (part 2 and the rclpy client)."""
    from glpma_tools.sim.echo_node import legs_of
    from glpma_tools.sim.matching import compare, pair
    if echo:
        pairs, unpaired = pair(plan.model, sent, poses,
                               legs_of=lambda pose: np.array(legs_of(pose, plan.model.n_legs)) / plan.mpu)
        return [i for i, _, _ in pairs], [p for _, p, _ in pairs], len(unpaired)
    c = compare(plan.model, sent, poses)
    return list(c.index), c.poses, len(c.unpaired) + int(np.sum(~c.on_truth))


def path_latency(sc, target: str, seconds: float, domain: int) -> dict:
    """Part 2: the simulated controller drives ``target`` (a key of :data:`TARGETS`) for
    ``seconds`` at the DDS section's rate; latency split at the pose's stamp (ms), the
    process's CPU share while driven, poses that answer no input or a wrong one."""
    from glpma_ros.config import config_dir
    from glpma_ros.node.dds import endpoints
    from glpma_tools.sim.controller import Controller
    from glpma_tools.sim.matching import split_at_stamp
    from glpma_tools.sim.node_process import NodeProcess, node_environment
    from glpma_tools.sim.trajectories import Plan

    from .dds import END_TO_END

    plan = Plan(sc.path)
    rate, params = END_TO_END[plan.model.kind]
    module, extra = TARGETS[target]
    with tempfile.TemporaryDirectory(prefix="glpma_outputs_") as logs:
        proc = NodeProcess(["--params-file", str(config_dir() / params), "-p", f"manipulator_config:={sc.path}",
                            *extra], node_environment(domain), Path(logs), module=module)
        proc.start()
        try:
            ctl = Controller(plan.model, domain, listen_depth=1000)
            try:
                if not endpoints.wait_for_match([ctl.writer, ctl.listener.reader], CONNECT_S):
                    raise TimeoutError(f"{target} did not match the controller within {CONNECT_S:g} s")
                time.sleep(SETTLE_S)
                cpu0, wall0 = proc.cpu_s(), time.perf_counter()
                sent, late = ctl.send(plan, 0.0, max(1, round(rate * seconds)), rate, 1.0 / rate)
                cpu_share = (proc.cpu_s() - cpu0) / (time.perf_counter() - wall0)
                deadline = time.monotonic() + TAIL_S
                while time.monotonic() < deadline and len(ctl.listener.poses) < len(sent):
                    time.sleep(0.01)
                poses = list(ctl.listener.poses)
            finally:
                ctl.close()
        finally:
            proc.stop()
        summary = proc.stopped_line()
    index, paired, wrong = answers(plan, sent, poses, echo=target == ECHO)
    to_node, in_node = split_at_stamp(sent, index, paired)
    return {"manipulator": sc.label, "key": sc.key, "target": target, "rate_hz": rate,
            "seconds": seconds, "sent": len(sent), "poses": len(poses), "paired": len(paired), "wrong": wrong,
            "late_sends": late, "total_ms": distribution(to_node + in_node), "to_node_ms": distribution(to_node),
            "in_node_ms": distribution(in_node), "cpu_percent": 100.0 * cpu_share, "summary": summary}


# -- part 3: the micro-profile -------------------------------------------------------------------------
def _paced(call, n: int) -> dict:
    """CPU and wall time (µs) of ``n`` calls ``call()``, :data:`PROFILE_PACE_S` apart."""
    cpu, wall = [], []
    for _ in range(n):
        c, t = time.thread_time_ns(), time.perf_counter_ns()
        call()
        wall.append((time.perf_counter_ns() - t) * 1e-3)
        cpu.append((time.thread_time_ns() - c) * 1e-3)
        time.sleep(PROFILE_PACE_S)
    return {"cpu_us": distribution(cpu), "wall_us": distribution(wall)}


def wake_round_trip(n: int) -> dict:
    """A Python thread wake-up round trip (wall µs): this thread sets an ``Event`` another waits on,
    which sets one this thread waits on."""
    ping, pong = threading.Event(), threading.Event()

    def answer():
        for _ in range(n):
            ping.wait()
            ping.clear()
            pong.set()

    def round_trip():
        ping.set()
        pong.wait()
        pong.clear()
    other = threading.Thread(target=answer, daemon=True)
    other.start()
    out = _paced(round_trip, n)["wall_us"]
    other.join()
    return out


def micro_profile(sc, n: int, domain: int) -> dict:
    """Part 3, on ``sc``'s inputs: decoding one input and encoding one pose (µs, back to back),
    ``n`` paced writes of an input without a reader and with the echo's reader in another process,
    and ``n`` thread wake-up round trips."""
    from glpma_ros.node.dds import cdr, endpoints
    from glpma_tools.sim.controller import Controller
    from glpma_tools.sim.node_process import NodeProcess, node_environment
    from glpma_tools.sim.trajectories import Plan

    plan = Plan(sc.path)
    env = node_environment(domain)
    ctl = Controller(plan.model, domain)
    try:
        data, _ = ctl.encoded(plan.sample(0.0)[0])
        encoder, position, orientation = cdr.Encoder(), (0.1, 0.2, 0.0), (0.0, 0.0, 0.0, 1.0)

        def mean_us(call):          # CPU-bound steps back to back (timeit: the garbage collector off)
            return timeit.timeit(call, number=PROFILE_CPU_REPEATS) / PROFILE_CPU_REPEATS * 1e6
        out = {"decode_us": mean_us(lambda: cdr.float64_multi_array_data(data)),
               "encode_us": mean_us(lambda: encoder.pose_stamped(time.time_ns(), "base", position, orientation)),
               "write_alone": _paced(lambda: ctl.raw_writer.write(data), n)}
        with tempfile.TemporaryDirectory(prefix="glpma_outputs_") as logs:
            echo = NodeProcess([], env, Path(logs), module=TARGETS[ECHO][0])
            echo.start()
            try:
                if not endpoints.wait_for_match([ctl.writer], CONNECT_S):
                    raise TimeoutError(f"the echo did not match within {CONNECT_S:g} s")
                time.sleep(SETTLE_S)
                out["write_remote"] = _paced(lambda: ctl.raw_writer.write(data), n)
            finally:
                echo.stop()
    finally:
        ctl.close()
    out["wake_us"] = wake_round_trip(n)
    out["samples"] = n
    return out


# -- part 4: the rclpy adapter ---------------------------------------------------------------------------
#: a process that keeps one core busy (the "one core busy" rows)
BUSY_LOOP = "while True:\n    pass\n"


class RclpyEcho:
    """The transport floor on rclpy: ``leg_lengths`` taken raw, the newest read with ``struct``, a
    ``pose_estimate`` carrying its legs published as bytes -- the rclpy node's path without the solve
    (:mod:`glpma_tools.sim.echo_node` on Cyclone DDS)."""

    def __init__(self, depth: int, frame_id: str):
        import time as _time

        from geometry_msgs.msg import PoseStamped
        from rclpy.node import Node
        from std_msgs.msg import Float64MultiArray

        from glpma_ros.node.dds import cdr
        from glpma_tools.sim.echo_node import POSE_NUMBERS
        self.node = Node("glpma_fk")
        self.received = self.dropped = 0
        encode, pub = cdr.Encoder(), self.node.create_publisher(PoseStamped, "pose_estimate", depth)

        def on_legs(data):
            sub, newest = self.sub, data
            while True:
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                newest, self.dropped = taken[0], self.dropped + 1
            self.received += 1
            numbers = (cdr.float64_multi_array_data(newest) + (0.0,) * POSE_NUMBERS)[:POSE_NUMBERS]
            pub.publish(encode.pose_stamped(_time.time_ns(), frame_id, numbers[:3], numbers[3:]))

        self.sub = self.node.create_subscription(Float64MultiArray, "leg_lengths", on_legs, depth, raw=True)
#: rclpy adapter variants of part 4: (label, variant, /tf + covariance subscribed, one core busy) --
#: the echo floor and the shipped node with the usual subscribers, idle and with one core busy, then
#: the shipped node alone and two alternative executor set-ups
RCLPY_VARIANTS = (
    ("echo (the floor: no solve), /tf + cov subscribed", "echo", True, False),
    ("shipped, /tf + cov subscribed", "shipped", True, False),
    ("echo (the floor), /tf + cov subscribed, one core busy", "echo", True, True),
    ("shipped, /tf + cov subscribed, one core busy", "shipped", True, True),
    ("SingleThreadedExecutor, newest input solved in the callback (shipped), nothing else subscribed",
     "shipped", False, False),
    ("SingleThreadedExecutor, hand-off to a solver thread", "submit", False, False),
    ("MultiThreadedExecutor(2), reentrant group, solve in the callback", "multi", False, False),
)


def rclpy_variants(sc, seconds: float, rate_hz: float, domain) -> list[dict]:
    """Part 4 (where rclpy imports): legs published by an rclpy client process -> pose received,
    for the adapter as shipped and two alternatives (``sc``'s shipped params); ``domain()`` claims a
    fresh ROS domain for each."""
    import rclpy
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from std_msgs.msg import Float64MultiArray

    from glpma_ros.node.ros_node import FkNode
    from glpma_tools.sim.node_process import PACKAGE_PARENT, node_environment
    values = {**_params_file(sc.model.kind), "manipulator_config": sc.path}
    rows = []
    for label, variant, extras, busy in RCLPY_VARIANTS:
        env = node_environment(domain())
        rclpy.init()
        if variant == "echo":
            node = RclpyEcho(values["qos_depth"], values["frame_id"])
        else:
            node = FkNode(parameter_overrides=[Parameter(n, value=v) for n, v in values.items() if v != []])
        if variant in ("submit", "multi"):
            node.destroy_subscription(node.input_sub)
            if variant == "submit":
                node.loop.start()
                callback = lambda msg: node.loop.submit(tuple(msg.data), node.get_clock().now().nanoseconds)  # noqa
            else:
                callback = lambda msg: node.loop.offer(tuple(msg.data), node.get_clock().now().nanoseconds)  # noqa
            node.create_subscription(Float64MultiArray, "leg_lengths", callback, values["qos_depth"],
                                     callback_group=ReentrantCallbackGroup() if variant == "multi" else None)
        executor = MultiThreadedExecutor(2) if variant == "multi" else SingleThreadedExecutor()
        executor.add_node(node.node if variant == "echo" else node)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        hog = subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) if busy else None
        cpu0 = time.process_time()
        try:
            out = subprocess.run([sys.executable, "-m", "glpma_tools.bench.rclpy_client", sc.path, str(rate_hz),
                                  str(seconds), "extras" if extras else "-", "echo" if variant == "echo" else "-"],
                                 env=env,
                                 capture_output=True, text=True, timeout=seconds + 300, cwd=PACKAGE_PARENT)
            cpu_s = time.process_time() - cpu0          # this process = the node under test
            sent, poses, p50, p99, wrong = out.stdout.split()
            if variant == "echo":
                received, dropped = node.received + node.dropped, node.dropped
            else:
                st = node.service.stats
                received, dropped = st.handled + st.dropped, st.dropped
            rows.append({"variant": label, "sent": int(sent), "poses": int(poses), "p50": float(p50),
                         "p99": float(p99), "wrong": int(wrong), "received": received, "dropped": dropped,
                         "answered": int(poses) / max(int(sent), 1), "cpu_us_per_input": cpu_s / max(int(sent), 1) * 1e6,
                         "extras": extras, "busy": busy, "echo": variant == "echo"})
        finally:
            if hog is not None:
                hog.kill()
                hog.wait()
            executor.shutdown()
            spinner.join()
            if variant != "echo":
                node.stop()
            (node.node if variant == "echo" else node).destroy_node()
            rclpy.try_shutdown()
    return rows


# -- the bench's entry and the report ------------------------------------------------------------------
def measure(scenarios, inputs: int, seconds: float, profile_samples: int, rclpy_seconds: float, say=print) -> dict:
    """Every part for the bench: ``res["outputs"]``.  ``inputs``: per row of part 1, ``seconds``: per
    run of part 2, ``profile_samples``: writes and round trips of part 3, ``rclpy_seconds``: per variant
    of part 4 (needs rclpy); 0 skips a part.  Each part runs on a ROS domain of its own."""
    res = {"keys": [sc.key for sc in scenarios], "pace_s": PACE_S, "costs": [], "paths": [], "profile": None,
           "rclpy": None, "rclpy_reason": None}
    with contextlib.ExitStack() as claims:
        def domain() -> int:
            return claims.enter_context(claim_domain()).domain_id
        if inputs > 0:
            say(f"extra outputs: {inputs} inputs per configuration")
            res["costs"] = output_costs(scenarios, inputs, domain())
        for sc in scenarios if seconds > 0 else ():
            for target in TARGETS:
                say(f"{sc.label}: legs written -> pose read, {target}, {seconds:g} s")
                res["paths"].append(path_latency(sc, target, seconds, domain()))
        if profile_samples > 0:
            say(f"micro-profile: {profile_samples} writes and thread round trips")
            res["profile"] = micro_profile(scenarios[0], profile_samples, domain())
        if rclpy_seconds > 0:
            try:
                import rclpy  # noqa: F401 - only whether it imports
            except ImportError:
                res["rclpy_reason"] = "rclpy does not import in the Python that ran the bench"
            else:
                from .dds import END_TO_END
                sc = scenarios[0]
                say(f"{sc.label}: the rclpy adapter's executors")
                rate = END_TO_END[sc.model.kind][0]
                res["rclpy_setup"] = {"manipulator": sc.label, "rate": rate, "seconds": rclpy_seconds}
                res["rclpy"] = rclpy_variants(sc, rclpy_seconds, rate, domain)
    return res


def _p(d, key="p50", digits=3) -> str:
    return MISSING if not d or d.get(key) is None else f"{d[key]:.{digits}f}"


def _pair(d, digits=3) -> str:
    return f"{_p(d, 'p50', digits)} / {_p(d, 'p99', digits)}"


def _verdict(measured: float, target: float, unit="ms", digits=3, ratio="{}, {:.1f}×") -> str:
    """``met`` or by how much ``measured`` misses ``target``."""
    return "met" if measured <= target else ratio.format(f"missed by {measured - target:.{digits}f} {unit}",
                                                         measured / target)


def section(res, md_path=None) -> list[str]:
    """The section of BENCHMARKS.md from ``res["outputs"]`` (nothing when it did not run)."""
    from .report import prose
    from .scenarios import END_TO_END_TARGET_MS, LABEL
    o = res.get("outputs")
    if not o:
        return []
    targets = "; ".join(f"{LABEL[key]} " + " and ".join(f"{q} ≤ {v:g} ms" for q, v in zip(("p50", "p99"), pair)
                                                         if v is not None)
                        for key, pair in END_TO_END_TARGET_MS.items() if key in o["keys"])
    out = [HEADING, "", prose("outputs", extras_target=f"{EXTRAS_TARGET_US:g}", e2e_targets=targets), ""]
    if o["costs"]:
        body = [[r["manipulator"], r["outputs"], _pair(r["handoff_cpu_us"], 1), _pair(r["handoff_us"], 1),
                 _pair(r["extras_cpu_us"], 1), _p(r["build_cpu_us"], digits=1), _pair(r["extras_us"], 1),
                 r["extras_dropped"], f"{_p(r['pose_cpu_us'], digits=1)} / {_p(r['pose_us'], digits=1)}",
                 _p(r["solve_us"], digits=0)] for r in o["costs"]]
        out += [prose("outputs", "costs", inputs=o["costs"][0]["inputs"], pace=f"{1e3 * o['pace_s']:g}"), "",
                table(["manipulator", "outputs on", "solving thread: hand-off, CPU p50 / p99 (µs)",
                       "hand-off, wall p50 / p99 (µs)", "extras thread: build + write, CPU p50 / p99 (µs)",
                       "of which building, CPU p50 (µs)", "extras thread, wall p50 / p99 (µs)", "extras dropped",
                       "pose encode + write, CPU / wall p50 (µs)", "solve, wall p50 (µs)"], body), ""]
        out += ["- " + prose("outputs", "costs_target", manipulator=r["manipulator"],
                             handoff=f"{r['handoff_cpu_us']['p50']:.1f}", handoff_wall=_p(r["handoff_us"], digits=1),
                             target=f"{EXTRAS_TARGET_US:g}", thread=_p(r["extras_cpu_us"], digits=1),
                             verdict=_verdict(r["handoff_cpu_us"]["p50"], EXTRAS_TARGET_US, "µs", 1, "{} ({:.1f}×)"),
                             build=_p(r["build_cpu_us"], digits=1)) for r in o["costs"] if r["outputs"] == SHIPPED]
        out += ["", prose("outputs", "costs_reading"), ""]
    if o["paths"]:
        body = [[r["manipulator"], r["target"], f"{r['rate_hz']:g} Hz, {r['seconds']:g} s",
                 f"{r['sent']:,} / {r['paired']:,}", r["wrong"], f"{_pair(r['total_ms'])} / {_p(r['total_ms'], 'max', 2)}",
                 _pair(r["to_node_ms"]), _pair(r["in_node_ms"]), f"{r['cpu_percent']:.0f} %", r["summary"]]
                for r in o["paths"]]
        out += [prose("outputs", "paths"), "",
                table(["manipulator", "process", "rate", "sent / poses", "wrong", "written -> read p50 / p99 / max (ms)",
                       "written -> taken p50 / p99 (ms)", "taken -> read p50 / p99 (ms)", "process CPU",
                       "process summary"], body), ""]
        for label in dict.fromkeys(r["manipulator"] for r in o["paths"]):
            rows = {r["target"]: r for r in o["paths"] if r["manipulator"] == label}
            node, floor, off = rows.get(NODE), rows.get(ECHO), rows.get(NODE_OFF)
            if node is None or floor is None:
                continue
            (t50, t99), n, f = END_TO_END_TARGET_MS[node["key"]], node["total_ms"], floor["total_ms"]
            out.append("- " + prose(
                "outputs", "targets", manipulator=label,
                **{q: f"{n[q]:.3f} ms" + (f" (target ≤ {t:g}: {_verdict(n[q], t)})" if t is not None else "")
                   for q, t in (("p50", t50), ("p99", t99))},
                off=_pair(off["total_ms"]) if off else MISSING, floor=_pair(f),
                floor_to_node=_pair(floor["to_node_ms"]), floor_in_node=_pair(floor["in_node_ms"]),
                above_p50=f"{n['p50'] - f['p50']:+.3f}", above_p99=f"{n['p99'] - f['p99']:+.3f}",
                floor_share=(f"{100 * f['p50'] / t50:.0f} % of the p50 target and " if t50 else "")
                + f"{100 * f['p99'] / t99:.0f} % of the p99 target"))
        out.append("")
    p = o.get("profile")
    if p:
        none = [r for r in o["costs"] if r["outputs"] == "none"]
        body = [["decode one `leg_lengths` sample (`struct`)", fmt(p["decode_us"]), MISSING],
                ["encode one `PoseStamped` (`struct`)", fmt(p["encode_us"]), MISSING],
                *[[f"one Cyclone DDS write, {what}", _pair(p[key]["cpu_us"], 1), _pair(p[key]["wall_us"], 1)]
                  for key, what in (("write_alone", "no reader"), ("write_remote", "a reader in another process"))],
                ["Python thread wake-up round trip (`threading.Event`)", MISSING, _pair(p["wake_us"], 1)],
                *[[f"{r['manipulator']}: warm solve (part 1, p50)", MISSING, fmt(r["solve_us"]["p50"])] for r in none],
                *[[f"{r['manipulator']}: pose encode + write with a subscriber (part 1, CPU p50)",
                   fmt(r["pose_cpu_us"]["p50"]), MISSING] for r in none]]
        out += [prose("outputs", "profile", samples=p["samples"]), "",
                table(["step", "CPU µs (p50 / p99, or mean)", "wall µs (p50 / p99)"], body), "",
                prose("outputs", "profile_reading", write_remote=_p(p["write_remote"]["cpu_us"], digits=1),
                      write_alone=_p(p["write_alone"]["cpu_us"], digits=1), wake=_p(p["wake_us"], digits=1),
                      decode=fmt(p["decode_us"]), encode=fmt(p["encode_us"])), ""]
    if o.get("rclpy"):
        body = [[r["variant"], f"{r['sent']} / {r['received']} / {r['poses']}",
                 f"{100 * r['answered']:.1f} %" if "answered" in r else MISSING, r["dropped"], r["wrong"],
                 f"{r['p50']:.3f} / {r['p99']:.3f}",
                 f"{r['cpu_us_per_input']:.0f}" if "cpu_us_per_input" in r else MISSING] for r in o["rclpy"]]
        setup = o["rclpy_setup"]
        out += [prose("outputs", "rclpy", manipulator=setup["manipulator"], rate=f"{setup['rate']:g}",
                      seconds=f"{setup['seconds']:g}"), "",
                table(["variant", "sent / received / poses", "answered", "dropped (newest wins)", "wrong",
                       "latency p50 / p99 (ms)", "node CPU µs per input"], body), ""]
    elif o.get("rclpy_reason"):
        out += [prose("outputs", "rclpy_not_run", reason=o["rclpy_reason"]), ""]
    return out
