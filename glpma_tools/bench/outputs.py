"""The ``outputs`` section of ``glpma-fk bench`` (prose: ``templates/outputs.md``): what the node's extra
outputs cost per input (part 1), legs written -> pose read over DDS against the transport floor (part 2), the
write and wake-up figures the node's design cites (part 3) and the rclpy adapter's executors (part 4)."""
from __future__ import annotations

import contextlib
import queue
import threading
import time

import numpy as np
from cyclonedds.util import duration

from glpma_ros.node.dds import cdr, endpoints
from glpma_ros.node.dds.messages import MarkerArray, PoseStamped, PoseWithCovarianceStamped, TFMessage, TwistStamped
from glpma_ros.node.dds.node import DdsNode
from glpma_ros.node.params import resolve
from glpma_ros.node.service import FkService, JointStateInput, default_joint_names
from glpma_tools.sim.controller import Controller
from glpma_tools.sim.domains import claim_domain
from glpma_tools.sim.node_process import node_environment
from glpma_tools.sim.trajectories import Plan
from glpma_tools.stats import distribution
from glpma_tools.tables import MISSING, table

from .markdown import md_blocks, prose
from .scenarios import END_TO_END_TARGET_MS, LABEL
from .transport import ECHO, OFF, SHIPPED_ON, TARGETS, match, node_process, params_of, path_latency
from .waits import timed

HEADING = "## Extra outputs and the transport path"
#: the outputs the shipped params files switch on: the row judged against :data:`EXTRAS_TARGET_US`
SHIPPED = "shipped (/tf, covariance, twist)"
#: the per-input cost at p50 (µs) the shipped extra outputs are held to
EXTRAS_TARGET_US = 20.0
#: the output configurations of part 1: name -> parameters; the first, none, is the reference
CASES = (("none", {}), ("/tf", {"publish_tf": True}), ("pose_estimate_cov", {"publish_covariance": True}),
         ("twist_estimate (poses)", {"publish_twist": True}),
         ("twist_estimate (velocities)", {"publish_twist": True, "input_type": "joint_state"}),
         ("~/markers (every pose)", {"publish_markers": True, "markers_period_s": 0.0}), (SHIPPED, SHIPPED_ON),
         ("all (shipped + markers 10 Hz)", {**SHIPPED_ON, "publish_markers": True}))
#: seconds between two timed calls of parts 1 and 3 (the subscriber keeps up, the inputs stay warm)
PACE_S = 1e-3
#: the stamp of part 1's first input (ns)
FIRST_STAMP_NS = 1_795_000_000 * 10**9
#: part 4's targets: with the extra outputs subscribed the rclpy node stays within this multiple of the echo
#: floor at p50 and p99, and answers at least this share of the inputs in every run
RCLPY_FLOOR_FACTOR = 1.5
RCLPY_ANSWERED = 0.995
#: the name of the node's extras thread (``ExtrasLoop``'s default), whose CPU clock part 1 reads
EXTRAS_THREAD = "glpma_fk-extras"


def _cpu_wall(call, items) -> dict:
    """CPU and wall time (µs) of ``call(*item)`` per item of ``items``, :data:`PACE_S` apart."""
    wall, cpu, _ = timed(call, items, PACE_S)
    return {"cpu_us": distribution(cpu, 1e6), "wall_us": distribution(wall, 1e6)}


def main() -> None:
    """The subscriber process of part 1: takes every output of the node, raw, until SIGINT."""

    p = endpoints.Participant()
    readers = [p.reader(t, m, 100) for t, m in ((endpoints.POSE_ESTIMATE, PoseStamped), (endpoints.TF, TFMessage),
               (endpoints.POSE_ESTIMATE_COV, PoseWithCovarianceStamped), (endpoints.TWIST_ESTIMATE, TwistStamped),
               (endpoints.MARKERS, MarkerArray))]
    waitset, _ = endpoints.reader_waitset(p, readers)
    print("ready", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        while True:
            waitset.wait(duration(milliseconds=100))
            for r in readers:
                cdr.take_raw(r, 1000)


def output_costs(scenarios, n_inputs: int, domain: int) -> list[dict]:
    """Part 1: per manipulator and output configuration, from outside the node: the solving thread's CPU
    and wall time around each ``offer`` (µs), the extras thread's CPU per pose from its own clock (the
    thread starts with the first pose), and the node's own wall figures (solve, hand-off, extras)."""

    rows = []
    with node_process(domain, module=__name__):
        participant = endpoints.Participant(domain)
        for sc in scenarios:
            plan = Plan(sc.path)
            legs = np.array([plan.sample(i * PACE_S)[0] * plan.mpu for i in range(n_inputs + 1)])
            rates = np.gradient(legs, PACE_S, axis=0)
            for name, case in CASES:
                values, _ = resolve({**params_of(plan.model.kind), "manipulator_config": sc.path, **OFF, **case})
                names = tuple(values["joint_names"] or default_joint_names(plan.model.n_legs))
                inputs = [(JointStateInput(names, tuple(q), tuple(v)) if values["input_type"] == "joint_state"
                           else tuple(q), FIRST_STAMP_NS + int(i * PACE_S * 1e9))
                          for i, (q, v) in enumerate(zip(legs[:n_inputs], rates))]
                service = FkService(values)
                service.warm_up(solvers=(values["solver"],))
                node = DdsNode(service, participant, modes_solve=lambda *a: [])
                match([node.pose_writer], "the subscriber")           # then the other topics' discovery
                offer = _cpu_wall(node.loop.offer, inputs)
                node.loop.extras.flush()
                clocks = [time.pthread_getcpuclockid(t.ident) for t in threading.enumerate() if t.name == EXTRAS_THREAD]
                extras_cpu_s = sum(map(time.clock_gettime, clocks)) if clocks else None     # before the thread ends
                node.loop.stop()
                st = service.stats
                rows.append({"manipulator": sc.label, "outputs": name, "inputs": n_inputs, **offer,
                             "extras_dropped": st.extras_dropped, "extras_thread_cpu_us":
                             None if extras_cpu_s is None else extras_cpu_s / max(st.published, 1) * 1e6,
                             **{key: distribution(window.values(), 1e6) for key, window in (("solve_us", st.solve_s),
                                ("handoff_us", st.extras_handoff_s), ("extras_us", st.extras_s))}})
    return rows


def micro_profile(sc, n: int, domain: int) -> dict:
    """Part 3: ``n`` paced writes of one of ``sc``'s inputs without a reader and with the echo's reader in
    another process, and ``n`` thread wake-up round trips (wall µs): this thread puts into a
    ``queue.SimpleQueue`` (what the node's extras thread is woken with) another thread waits on, which puts
    into one this thread waits on."""

    plan = Plan(sc.path)
    node_environment(domain)                    # this process's participant discovers as the echo's does
    with contextlib.closing(Controller(plan.model, domain)) as ctl:
        writes = [ctl.encoded(plan.sample(0.0)[0])[:1]] * n
        out = {"write_alone": _cpu_wall(ctl.raw_writer.write, writes)}
        with node_process(domain, module=TARGETS[ECHO][0]):
            match([ctl.writer], "the echo")
            out["write_remote"] = _cpu_wall(ctl.raw_writer.write, writes)
    ping, pong = queue.SimpleQueue(), queue.SimpleQueue()

    def answer():
        for _ in range(n):
            pong.put(ping.get())
    other = threading.Thread(target=answer, daemon=True)
    other.start()
    out["wake_us"] = _cpu_wall(lambda: (ping.put(True), pong.get()), [()] * n)["wall_us"]
    other.join()
    return {**out, "samples": n}


def measure(scenarios, inputs: int, seconds: float, profile_samples: int, rclpy_seconds: float, say=print,
            rclpy_runs: int = 1) -> dict:
    """Every part for the bench: ``res["outputs"]``.  ``inputs``: per row of part 1, ``seconds``: per
    run of part 2, ``profile_samples``: writes and round trips of part 3, ``rclpy_seconds``: per variant
    of part 4 (needs rclpy; ``rclpy_runs``: runs of its floor beside the shipped node); 0 skips a part.
    Each part runs on a ROS domain of its own."""
    res = {"keys": [sc.key for sc in scenarios], "costs": [], "paths": [], "profile": None, "rclpy": None}
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
                from . import rclpy_client  # needs rclpy (a sourced ROS 2): optional, imported here
            except ImportError as exc:
                res["rclpy"] = f"{exc.name or 'rclpy'} does not import in the Python that ran the bench"
            else:
                say(f"{scenarios[0].label}: the rclpy adapter's executors")
                res["rclpy"] = rclpy_client.variants(scenarios[0], rclpy_seconds, domain, rclpy_runs)
    return res


# -- the report ------------------------------------------------------------------------------------------
def _q(d, digits=3, keys=("p50", "p99")) -> str:
    """``keys`` of the distribution ``d`` (default ``p50 / p99``), or of the number ``d``."""
    values = [d] if not isinstance(d, dict) else [d.get(k) for k in keys]
    return " / ".join(MISSING if v is None else f"{v:.{digits}f}" for v in values)


def _verdict(measured: float, target: float, unit="ms", digits=3) -> str:
    """``met`` or by how much ``measured`` misses ``target``."""
    return "met" if measured <= target else f"missed by {measured - target:.{digits}f} {unit}, {measured / target:.1f}×"


def _against_floor(row) -> str:
    """``row``'s latency p50 / p99 as multiples of the floor measured beside it (the echo's rows: none)."""
    if row.get("floor_p50") is None:
        return MISSING
    return " / ".join(f"{row[q] / row['floor_' + q]:.2f}×" for q in ("p50", "p99"))


def _costs(rows) -> list:
    """Part 1's table, each row's hand-off judged against the target."""
    none = {r["manipulator"]: r["cpu_us"]["p50"] for r in rows if r["outputs"] == CASES[0][0]}
    body = [[r["manipulator"], r["outputs"], _q(r["cpu_us"], 1), f"{r['cpu_us']['p50'] - none[r['manipulator']]:+.1f}",
             _q(r["wall_us"], 1), _q(r["solve_us"], 1, ("p50",)), _q(r["handoff_us"], 1),
             MISSING if r["handoff_us"]["p50"] is None else
             _verdict(r["handoff_us"]["p50"], EXTRAS_TARGET_US, "µs", 1),
             _q(r["extras_thread_cpu_us"], 1), _q(r["extras_us"], 1), r["extras_dropped"]] for r in rows]
    return [prose("outputs", "costs", inputs=rows[0]["inputs"], pace=f"{1e3 * PACE_S:g}"),
            table(["manipulator", "outputs on", "solving thread per input, CPU p50 / p99 (µs)",
                   "CPU p50 above none (µs)", "solving thread per input, wall p50 / p99 (µs)",
                   "of which solve, wall p50 (µs)", "of which hand-off, wall p50 / p99 (µs)",
                   "hand-off against the target", "extras thread, CPU per pose (µs)",
                   "extras thread, wall per pose p50 / p99 (µs)", "extras dropped"], body),
            prose("outputs", "costs_target", shipped=SHIPPED, target=f"{EXTRAS_TARGET_US:g}"),
            prose("outputs", "costs_reading")]


def _paths(rows) -> list:
    """Part 2's table, each row against the targets and the floor (the echo's row)."""
    floor = {r["manipulator"]: r["total_ms"] for r in rows if r["target"] == ECHO}

    def against(d, targets) -> str:
        return " / ".join("no target" if t is None else MISSING if d.get(q) is None
                          else f"{100 * d[q] / t:.0f} % ({_verdict(d[q], t)})" for q, t in zip(("p50", "p99"), targets))

    def above(d, f) -> str:
        return " / ".join(MISSING if f is None or None in (d.get(q), f.get(q)) else f"{d[q] - f[q]:+.3f}"
                          for q in ("p50", "p99"))
    body = [[r["manipulator"], r["target"], f"{r['rate_hz']:g} Hz, {r['seconds']:g} s",
             f"{r['sent']:,} / {r['paired']:,}", r["wrong"], f"{_q(r['total_ms'])} / {_q(r['total_ms'], 2, ('max',))}",
             against(r["total_ms"], END_TO_END_TARGET_MS[r["key"]]),
             above(r["total_ms"], floor.get(r["manipulator"])),
             _q(r["to_node_ms"]), _q(r["in_node_ms"]), f"{r['cpu_percent']:.0f} %", r["summary"]] for r in rows]
    return [prose("outputs", "paths"),
            table(["manipulator", "process", "rate", "sent / poses", "wrong", "written -> read p50 / p99 / max (ms)",
                   "p50 / p99 against the targets", "above the floor p50 / p99 (ms)", "written -> taken p50 / p99 (ms)",
                   "taken -> read p50 / p99 (ms)", "process CPU", "process summary"], body),
            prose("outputs", "targets")]


def section(res, md_path=None) -> list[str]:
    """The section of BENCHMARKS.md from ``res["outputs"]`` (nothing when it did not run)."""
    o = res.get("outputs")
    if not o:
        return []
    targets = "; ".join(f"{LABEL[key]} " + " and ".join(f"{q} ≤ {v:g} ms" for q, v in zip(("p50", "p99"), pair)
                                                         if v is not None)
                        for key, pair in END_TO_END_TARGET_MS.items() if key in o["keys"])
    out = [prose("outputs", extras_target=f"{EXTRAS_TARGET_US:g}", e2e_targets=targets)]
    out += _costs(o["costs"]) if o["costs"] else []
    out += _paths(o["paths"]) if o["paths"] else []
    if p := o["profile"]:
        body = [*[[f"one Cyclone DDS write, {what}", _q(p[key]["cpu_us"], 1), _q(p[key]["wall_us"], 1)]
                  for key, what in (("write_alone", "no reader"), ("write_remote", "a reader in another process"))],
                ["Python thread wake-up round trip (`queue.SimpleQueue`)", MISSING, _q(p["wake_us"], 1)]]
        out += [prose("outputs", "profile", samples=p["samples"]),
                table(["step", "CPU µs (p50 / p99)", "wall µs (p50 / p99)"], body),
                prose("outputs", "profile_reading")]
    if isinstance(o["rclpy"], str):
        out.append(prose("outputs", "rclpy_not_run", reason=o["rclpy"]))
    elif o["rclpy"]:
        setup, rows = o["rclpy"]
        body = [[r["variant"], MISSING if r.get("run") is None else r["run"],
                 f"{r['sent']} / {r['received']} / {r['poses']}", f"{100 * r['answered']:.1f} %",
                 r["dropped"], r["wrong"], f"{r['p50']:.3f} / {r['p99']:.3f}", _against_floor(r),
                 f"{r['cpu_us_per_input']:.0f}", r.get("client_late", MISSING),
                 MISSING if r.get("steal_ms") is None else f"{r['steal_ms']:.0f}"] for r in rows]
        out += [prose("outputs", "rclpy", manipulator=setup["manipulator"], rate=f"{setup['rate']:g}",
                      seconds=f"{setup['seconds']:g}", runs=setup.get("runs", 1),
                      target=f"{RCLPY_FLOOR_FACTOR:g}", answered=f"{100 * RCLPY_ANSWERED:g}"),
                table(["variant", "run", "sent / received / poses", "answered", "dropped (newest wins)", "wrong",
                       "latency p50 / p99 (ms)", "against the floor p50 / p99", "node CPU µs per input",
                       "client late", "host steal ms"], body),
                "load" in setup and prose("outputs", "rclpy_load", start=f"{setup['load'][0]:.1f}",
                                          end=f"{setup['load'][1]:.1f}", policy=setup["policy"])]
    return md_blocks(HEADING, *out)


if __name__ == "__main__":
    main()
