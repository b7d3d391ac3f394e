"""``glpma-fk stress``: the ``glpma_fk`` node under overload, bursts, restarts and deadlines.

Starts a real node process over Cyclone DDS (``python -m glpma_ros.node.dds.node``,
cold start, ``/diagnostics`` every 0.2 s) and drives it from this process as a
controller would, along the mock controller's trajectory:

* **overload**: leg lengths at 1 kHz for 60 s.  The node keeps the newest input
  and counts the ones it replaced (dropped); its memory must not grow (RSS from
  ``/proc/<pid>/status`` after a warm-up traffic and after the run).
* **burst**: 10,000 messages written as fast as the writer can.
* **restarts**: the controller restarts mid-trajectory (a new DDS participant);
  the node restarts mid-trajectory (SIGINT, started again while the controller
  keeps sending: its first answer is a cold start, the next ones warm, as
  ``/diagnostics`` must say); a large jump of the legs to another assembly mode
  (the trajectory around the config's next known solution): the estimator must
  recover.
* **deadline**: in-process :class:`~glpma_ros.estimator.Estimator` solves with
  budgets of 1, 2 and 5 ms on legs without a real assembly (cold, and from a
  warm state so that all three stages run), which use the whole budget.

Counts come from the node's ``/diagnostics`` (differences of its counters over
each phase); "lost in transport" is what the controller wrote and the node never
received (DDS keep-last history of ``qos_depth`` on both sides); latency is end to
end, controller write -> pose received, for the inputs that got a pose.

Run: ``python -m glpma_tools.stress [--quick] [--json] [--markdown [BENCHMARKS.md]]``;
exit status 0 when every check passed, 1 when one failed, 2 for bad arguments.
"""
from __future__ import annotations

import argparse
import gc
import json
import math
import os
import shlex
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from glpma_tools.sim.node_process import NodeProcess, node_environment

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_PARAMS = REPO_ROOT / "config" / "params_3rpr.yaml"
SECTIONS = ("overload", "burst", "restarts", "deadline")
#: (full, --quick)
DEFAULTS = {"duration_s": (60.0, 3.0), "burst": (10_000, 2_000), "deadline_solves": (10_000, 300),
            "phase_s": (2.0, 1.0)}
RATE_HZ = 1000.0
#: inputs per second of the restart and jump phases
PHASE_RATE_HZ = 200.0
#: seconds of traffic before the RSS baseline (fills the node's statistics windows and DDS buffers)
WARMUP_S = 2.0
#: share of paced inputs that may be lost in transport: the node's reader thread shares the GIL with
#: the solver and the CPU with other processes; a stall longer than qos_depth inputs overwrites samples
LOST_SLACK = 0.05
#: allowed RSS growth of the node over a run
RSS_SLACK_MB = 5.0
#: "on time" = within budget + this
DEADLINE_MARGIN_MS = 0.5
DEADLINE_BUDGETS_MS = (1.0, 2.0, 5.0)
#: a pose reproduces its input's legs to this (metres)
RESIDUAL_MAX_M = 1e-6
DIAGNOSTICS_PERIOD_S = 0.2
RELIABILITY_HEADING = "## Reliability"

COUNTERS = {"received": "inputs received", "solved": "inputs solved", "rejected": "inputs rejected",
            "dropped": "inputs dropped", "deadline_misses": "deadline misses"}


# -- the controller side ---------------------------------------------------------------------------

class Plan:
    """A trajectory of the config's manipulator around one of its known solutions, sampled on a
    clock shared by the phases (each phase continues where the previous one stopped)."""

    def __init__(self, config, solution: int | None = None, amplitude: float = 1.0):
        from glpma_ros.config import load_document, model_from_dict, resolve_config
        from glpma_tools.mock_controller import DEFAULT_SOLUTION, start_pose, trajectory
        path = resolve_config(config)
        self.doc = load_document(path)
        self.model = model_from_dict(self.doc, str(path))
        self.mpu = float(self.model.metres_per_unit)
        self.solution = DEFAULT_SOLUTION[self.model.kind] if solution is None else int(solution)
        p0, R0 = start_pose(self.model, self.doc, self.solution)
        self.pose_at = trajectory(self.model, p0, R0, amplitude)

    def other_solution(self) -> int:
        """The index of another known solution (another assembly mode) of the config."""
        n = len(self.doc.get("real_solutions") or self.doc.get("published_solutions") or [])
        return (self.solution + 1) % max(n, 1)

    def sample(self, t: float):
        """(legs in the config's unit, position m, quaternion) at trajectory time ``t``."""
        from glpma_tools.mock_controller import legs_for
        from glpma_ros.models.rotations import quaternion_from_matrix
        position, R = self.pose_at(t)
        q = quaternion_from_matrix(R)
        return legs_for(self.model, position, q), position * self.mpu, q


class Controller:
    """One DDS participant: a ``leg_lengths`` writer and a listener of poses and ``/diagnostics``."""

    def __init__(self, model, domain_id: int, depth: int = 10, listen_depth: int = 1000):
        from glpma_ros.node.dds import endpoints
        from glpma_ros.node.dds.messages import Float64MultiArray, MultiArrayDimension, MultiArrayLayout
        from glpma_tools.mock_controller import PoseListener
        self.model = model
        self.mpu = float(model.metres_per_unit)
        self.participant = endpoints.Participant(domain_id)
        self.writer = self.participant.writer(endpoints.LEG_LENGTHS, Float64MultiArray, depth)
        self.listener = PoseListener(self.participant, listen_depth)
        self._msg = Float64MultiArray
        self._layout = MultiArrayLayout(dim=[MultiArrayDimension(label="legs", size=model.n_legs,
                                                                 stride=model.n_legs)])

    def wait_for_node(self, timeout: float = 60.0) -> float:
        """Seconds until the node's endpoints matched ours; raises TimeoutError."""
        from glpma_ros.node.dds import endpoints
        t0 = time.monotonic()
        if not endpoints.wait_for_match([self.writer, self.listener.reader, self.listener.diag_reader], timeout):
            raise TimeoutError(f"no glpma_fk node matched within {timeout:g} s")
        return time.monotonic() - t0

    def message(self, legs):
        return self._msg(layout=self._layout, data=[float(v) * self.mpu for v in legs])

    def send(self, plan: Plan, t0: float, n: int, rate_hz: float | None, stop: threading.Event | None = None,
             dt: float | None = None):
        """Write ``n`` samples of ``plan`` from trajectory time ``t0``, ``dt`` apart in trajectory time
        (default 1 / rate_hz); paced at ``rate_hz`` in wall time, or as fast as possible when ``rate_hz``
        is None (the messages are then prepared beforehand).  Returns ([Sent], late sends)."""
        from glpma_tools.mock_controller import Sent
        dt = dt or 1.0 / (rate_hz or RATE_HZ)
        sent, late = [], 0
        if rate_hz is None:
            samples = [plan.sample(t0 + i * dt) for i in range(n)]
            msgs = [self.message(s[0]) for s in samples]
            for (legs, pos, q), msg in zip(samples, msgs):
                send_ns = time.time_ns()
                self.writer.write(msg)
                sent.append(Sent(send_ns, legs, pos, q))
            return sent, 0
        start = time.perf_counter()
        for i in range(n):
            if stop is not None and stop.is_set():
                break
            delay = start + i / rate_hz - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            elif delay < -1.0 / rate_hz:
                late += 1
            legs, pos, q = plan.sample(t0 + i * dt)
            msg = self.message(legs)
            send_ns = time.time_ns()
            self.writer.write(msg)
            sent.append(Sent(send_ns, legs, pos, q))
        return sent, late

    def diagnostics_after(self, t_ns: int, timeout: float = 10.0, stable: bool = True) -> dict:
        """Values of the first ``/diagnostics`` report stamped after ``t_ns`` -- with ``stable``, of
        the first two consecutive such reports with the same counters (the node is idle)."""
        deadline = time.monotonic() + timeout
        last_stamp, previous = t_ns, None
        while time.monotonic() < deadline:
            stamp, diag = self.listener.diagnostics_stamp_ns, self.listener.diagnostics
            if stamp > last_stamp and diag is not None:
                last_stamp = stamp
                values = diag["values"]
                if not stable:
                    return values
                if previous is not None and counters(previous) == counters(values):
                    return values
                previous = values
            time.sleep(0.01)
        raise TimeoutError(f"no (stable) /diagnostics report within {timeout:g} s")

    def close(self) -> None:
        """Delete the participant and everything in it (a controller that goes away)."""
        self.listener.close()
        from cyclonedds.core import Entity
        refs = [e._ref for e in (self.writer, self.listener.reader, self.listener.diag_reader,
                                 self.participant.dp)]
        self.writer = self.listener = self.participant = None
        gc.collect()
        left = [r for r in refs if r in Entity._entities]
        for ref in left:             # still referenced somewhere: delete explicitly
            entity = Entity._entities.get(ref)
            if entity is not None:
                entity.__del__()


def counters(values: dict) -> dict:
    return {k: int(values.get(key, 0)) for k, key in COUNTERS.items()}


def starts(values: dict) -> dict:
    warm, widened, cold = (int(v) for v in values.get("starts warm/widened/cold", "0/0/0").split("/"))
    return {"warm": warm, "widened": widened, "cold": cold}


def _diff(after: dict, before: dict | None) -> dict:
    return {k: v - (before or {}).get(k, 0) for k, v in after.items()}


def _ms_stats(values_ms) -> dict:
    a = np.asarray(values_ms, dtype=float)
    if a.size == 0:
        return {"p50": None, "p99": None, "max": None}
    return {"p50": float(np.percentile(a, 50)), "p99": float(np.percentile(a, 99)), "max": float(a.max())}


#: inputs written before a pose's stamp among which its input is looked for (a burst has thousands
#: in flight when the node's reader thread takes a sample) ...
MATCH_WINDOW = 4096
#: ... and written at most this long before it (the trajectory repeats its legs every loop)
MATCH_WINDOW_NS = 1_000_000_000


def match(model, sent: list, poses: list, window: int = MATCH_WINDOW) -> list:
    """``[(input index, pose, max leg residual in the config's unit)]``: each pose paired with the
    input whose legs it reproduces best among the ``window`` written before its stamp (the input's
    arrival at the node) and the next one; each input at most once."""
    from glpma_tools.mock_controller import legs_for
    if not sent:
        return []
    send_ns = np.array([s.send_ns for s in sent], dtype=np.int64)
    legs_all = np.array([s.legs for s in sent], dtype=float)
    taken = np.zeros(len(sent), dtype=bool)
    mpu = float(model.metres_per_unit)
    out = []
    for pose in poses:
        j = int(np.searchsorted(send_ns, pose[1], side="right")) - 1
        lo = max(0, j - window, int(np.searchsorted(send_ns, pose[1] - MATCH_WINDOW_NS)))
        hi = min(len(sent), j + 2)
        if lo >= hi:
            continue
        try:
            legs = legs_for(model, pose[3] / mpu, pose[4])
            diff = np.max(np.abs(legs_all[lo:hi] - legs), axis=1)
        except Exception:  # noqa: BLE001 - a garbage pose: the nearest by time
            diff = np.abs(np.arange(lo, hi) - j).astype(float) + 1e300
        free = ~taken[lo:hi]
        if not free.any():
            continue
        diff = np.where(free, np.nan_to_num(diff, nan=np.inf), np.inf)
        best = float(np.min(diff))
        if math.isfinite(best):         # the latest of equally good candidates (the node solves the newest)
            k = int(np.flatnonzero(diff <= best + 1e-9 * model.scale)[-1])
        else:                           # every free candidate is non-finite: a garbage pose
            k = int(np.flatnonzero(free)[-1])
        taken[lo + k] = True
        out.append((lo + k, pose, float(diff[k])))
    return sorted(out, key=lambda t: t[0])


def analyse(model, sent: list, poses: list) -> dict:
    """Match poses to inputs; latency (write -> pose received, ms), how well each pose reproduces
    its input's legs (m), and whether it is the trajectory's assembly mode."""
    matched = match(model, sent, poses)
    pairs = [(i, pose) for i, pose, _ in matched]
    mpu = float(model.metres_per_unit)
    latency, residual, on_mode, first = [], [], 0, None
    for (i, (recv_ns, _, _, position_m, q)), (_, _, res) in zip(pairs, matched):
        latency.append((recv_ns - sent[i].send_ns) * 1e-6)
        residual.append(res * mpu)
        on_mode += float(np.linalg.norm(position_m - sent[i].position_m)) <= RESIDUAL_MAX_M
        first = i if first is None else min(first, i)
    return {"poses": len(poses), "matched": len(pairs), "latency_ms": _ms_stats(latency),
            "residual_max_m": max(residual) if residual else None, "on_trajectory_mode": on_mode,
            "first_answered": first, "first_latency_ms": None if first is None else
            next(lat for (i, _), lat in zip(pairs, latency) if i == first)}


def _node_latency(values: dict) -> dict:
    def num(key):
        try:
            v = float(values.get(key, "nan"))
            return v if math.isfinite(v) else None
        except ValueError:
            return None
    return {"p50": num("latency p50 (ms)"), "p99": num("latency p99 (ms)"), "max": num("latency max (ms)")}


# -- the scenarios -------------------------------------------------------------------------------------

class Session:
    """One node process, the controller talking to it, and the trajectory clock."""

    def __init__(self, params_file=DEFAULT_PARAMS, extra_args=(), domain_id: int | None = None,
                 log_dir: Path | None = None, say=None):
        from glpma_ros.node.ros_args import node_values
        self.domain_id = 150 + os.getpid() % 50 if domain_id is None else int(domain_id)
        self.ros_args = ["--params-file", str(params_file), "-p", "initial_pose:=[]",
                         "-p", f"diagnostics_period_s:={DIAGNOSTICS_PERIOD_S}", *extra_args]
        values, _, _ = node_values(["--ros-args", *self.ros_args])
        self.params = values
        self.plan = Plan(values["manipulator_config"])
        self.model = self.plan.model
        self.log_dir = Path(log_dir or tempfile.mkdtemp(prefix="glpma_stress_"))
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.node = NodeProcess(self.ros_args, node_environment(self.domain_id), self.log_dir)
        self.controller: Controller | None = None
        self.t = 0.0                    # trajectory time
        self.say = say or (lambda msg: None)
        self.startup_s: list[float] = []

    def start(self) -> "Session":
        self.say(f"starting the node (domain {self.domain_id}; it compiles or loads its solvers first)")
        self.startup_s.append(self.node.start())
        self.controller = self.new_controller()
        return self

    def new_controller(self) -> Controller:
        c = Controller(self.model, self.domain_id, depth=self.params["qos_depth"])
        c.wait_for_node(60.0)
        time.sleep(0.3)
        return c

    def close(self) -> None:
        if self.controller is not None:
            self.controller.close()
            self.controller = None
        self.node.stop()

    def send(self, n: int, rate_hz: float | None, plan: Plan | None = None, stop=None, dt: float | None = None):
        dt = dt or 1.0 / (rate_hz or RATE_HZ)
        sent, late = self.controller.send(plan or self.plan, self.t, n, rate_hz, stop, dt)
        self.t += len(sent) * dt
        return sent, late

    def settle(self, after_ns: int | None = None) -> dict:
        """Wait until the node reported after ``after_ns`` (default: now) and is idle."""
        time.sleep(0.1)
        return self.controller.diagnostics_after(time.time_ns() if after_ns is None else after_ns, 15.0)

    # -- (a) and (b): overload and burst ------------------------------------------------------------
    def flood(self, name: str, n: int, rate_hz: float | None, warmup_s: float = WARMUP_S,
              dt: float | None = None) -> dict:
        ctl = self.controller
        if warmup_s > 0:
            self.send(int(warmup_s * (rate_hz or RATE_HZ)), rate_hz or RATE_HZ)
        before = self.settle()
        rss0 = self.node.rss_kb()
        k0 = len(ctl.listener.poses)
        self.say(f"{name}: {n} inputs " + (f"at {rate_hz:g} Hz" if rate_hz else "as fast as possible"))
        t0 = time.perf_counter()
        sent, late = self.send(n, rate_hz, dt=dt)
        send_s = time.perf_counter() - t0
        after = self.settle(sent[-1].send_ns)
        time.sleep(0.2)
        rss1 = self.node.rss_kb()
        poses = list(ctl.listener.poses[k0:])
        counts = _diff(counters(after), counters(before))
        res = {"inputs": len(sent), "send_s": send_s, "send_rate_hz": len(sent) / send_s if send_s > 0 else None,
               "late_sends": late, **counts, "lost_in_transport": len(sent) - counts["received"],
               "rss_before_mb": rss0 / 1024, "rss_after_mb": rss1 / 1024, "rss_growth_mb": (rss1 - rss0) / 1024,
               "node_latency_ms": _node_latency(after), "starts": _diff(starts(after), starts(before))}
        a = analyse(self.model, sent, poses)
        res.update(poses=a["poses"], matched=a["matched"], latency_ms=a["latency_ms"],
                   residual_max_m=a["residual_max_m"], on_trajectory_mode=a["on_trajectory_mode"])
        res["checks"] = {
            "node alive": self.node.alive(),
            "every received input accounted for (solved + rejected + dropped)":
                counts["received"] == counts["solved"] + counts["rejected"] + counts["dropped"],
            "one pose per solved input": a["poses"] == counts["solved"],
            f"RSS growth <= {RSS_SLACK_MB:g} MB": res["rss_growth_mb"] <= RSS_SLACK_MB,
            f"every pose reproduces its legs to {RESIDUAL_MAX_M:g} m":
                a["residual_max_m"] is not None and a["residual_max_m"] <= RESIDUAL_MAX_M,
        }
        if rate_hz:
            res["checks"][f"transport lost <= {100 * LOST_SLACK:g} % of inputs"] = \
                res["lost_in_transport"] <= LOST_SLACK * len(sent)
        return res

    def overload(self, duration_s: float, rate_hz: float = RATE_HZ) -> dict:
        res = self.flood("overload", int(round(duration_s * rate_hz)), rate_hz)
        res.update(rate_hz=rate_hz, duration_s=duration_s)
        return res

    def burst(self, n: int) -> dict:
        # within less than half a loop of the trajectory, so that no two inputs of the burst have the
        # same legs (the pose <-> input matching goes by the legs)
        from glpma_tools.mock_controller import PERIOD_S
        return self.flood("burst", n, None, warmup_s=0.0, dt=min(1.0 / RATE_HZ, 0.4 * PERIOD_S / n))

    # -- (c) restarts and a jump ----------------------------------------------------------------------
    def controller_restart(self, phase_s: float) -> dict:
        self.say("controller restart: a new participant continues the trajectory")
        n = int(phase_s * PHASE_RATE_HZ)
        before = self.settle()
        sent_a, _ = self.send(n, PHASE_RATE_HZ)
        t_close = time.monotonic()
        self.controller.close()
        t_new = time.monotonic()
        self.controller = Controller(self.model, self.domain_id, depth=self.params["qos_depth"])
        self.controller.wait_for_node(60.0)
        match_s = time.monotonic() - t_new
        time.sleep(0.3)
        gap_s = time.monotonic() - t_close
        self.t += gap_s                                  # the robot moved on meanwhile
        k0 = len(self.controller.listener.poses)
        mid = self.settle()
        sent_b, _ = self.send(n, PHASE_RATE_HZ)
        after = self.settle(sent_b[-1].send_ns)
        a = analyse(self.model, sent_b, list(self.controller.listener.poses[k0:]))
        counts_b = _diff(counters(after), counters(mid))
        st = _diff(starts(after), starts(mid))
        res = {"inputs_before": len(sent_a), "inputs_after": len(sent_b), "gap_s": gap_s, "discovery_s": match_s,
               "after": counts_b, "starts_after": st, "poses_after": a["matched"],
               "first_pose_latency_ms": a["first_latency_ms"], "residual_max_m": a["residual_max_m"],
               "last_start": after.get("last start"), "totals": _diff(counters(after), counters(before))}
        res["checks"] = {
            "node alive": self.node.alive(),
            "new controller answered (>= 95 % of its inputs)": a["matched"] >= 0.95 * len(sent_b),
            "tracking stays warm (no cold start)": st["cold"] == 0 and after.get("last start") == "warm",
            # a rejection here can only be a solve the budget cut short (a preempted node)
            "rejected <= 5 % of the inputs": counts_b["rejected"] <= 0.05 * len(sent_b),
            "poses reproduce the legs": a["residual_max_m"] is not None and a["residual_max_m"] <= RESIDUAL_MAX_M,
        }
        return res

    def large_jump(self, phase_s: float) -> dict:
        other = Plan(self.params["manipulator_config"], solution=self.plan.other_solution())
        self.say(f"large jump: to the trajectory around known solution {other.solution}")
        n = int(phase_s * PHASE_RATE_HZ)
        ctl = self.controller
        k0 = len(ctl.listener.poses)
        sent_a, _ = self.send(n, PHASE_RATE_HZ)
        before = self.settle()
        a_before = analyse(self.model, sent_a, list(ctl.listener.poses[k0:]))
        k0 = len(ctl.listener.poses)
        # jump to the point of the other trajectory whose legs are farthest from the last ones sent
        from glpma_tools.mock_controller import PERIOD_S
        last_legs = self.plan.sample(self.t - 1.0 / PHASE_RATE_HZ)[0]
        self.t = max(np.linspace(0.0, PERIOD_S, 200, endpoint=False),
                     key=lambda t: float(np.max(np.abs(other.sample(t)[0] - last_legs))))
        jump_legs = other.sample(self.t)[0]
        sent, _ = self.send(n, PHASE_RATE_HZ, plan=other)
        after = self.settle(sent[-1].send_ns)
        a = analyse(self.model, sent, list(ctl.listener.poses[k0:]))
        counts = _diff(counters(after), counters(before))
        st = _diff(starts(after), starts(before))
        jump = float(np.max(np.abs(jump_legs - last_legs)))
        step = float(np.max(np.abs(sent_a[-1].legs - sent_a[-2].legs)))
        res = {"to_solution": other.solution, "jump_legs_max": jump, "step_legs_max": step,
               "jump_relative": jump / self.model.scale,
               "unit": self.model.unit, "inputs": len(sent), **counts, "starts": st,
               "inputs_until_first_pose": a["first_answered"], "first_pose_latency_ms": a["first_latency_ms"],
               "poses_on_requested_mode": a["on_trajectory_mode"], "poses": a["matched"],
               "before": {"inputs": len(sent_a), "poses": a_before["matched"],
                          "on_trajectory_mode": a_before["on_trajectory_mode"]},
               "residual_max_m": a["residual_max_m"], "last_start": after.get("last start")}
        res["checks"] = {
            "node alive": self.node.alive(),
            "recovered: poses again within 10 inputs": a["first_answered"] is not None and a["first_answered"] < 10,
            ">= 90 % of the inputs answered": a["matched"] >= 0.9 * len(sent),
            "poses reproduce the legs": a["residual_max_m"] is not None and a["residual_max_m"] <= RESIDUAL_MAX_M,
            "tracking warm again": after.get("last start") == "warm",
        }
        # go back to the trajectory the session follows
        self.plan = other
        return res

    def node_restart(self, phase_s: float) -> dict:
        """SIGINT the node while the controller streams; start it again; the controller keeps sending."""
        self.say("node restart: SIGINT mid-trajectory, start again, the controller keeps sending")
        ctl = self.controller
        stop = threading.Event()
        out = {}

        def stream():
            out["sent"], _ = self.send(10**9, PHASE_RATE_HZ, stop=stop)

        k0 = len(ctl.listener.poses)
        thread = threading.Thread(target=stream, name="stress-stream", daemon=True)
        thread.start()
        time.sleep(phase_s)
        old_rss = self.node.rss_kb()
        t_kill = time.monotonic()
        kill_ns = time.time_ns()
        status = self.node.stop()
        stopped = self.node.stopped_line()
        try:
            startup = self.node.start()
        except RuntimeError:
            stop.set()
            thread.join(5)
            raise
        self.startup_s.append(startup)
        ready_ns = self.node.ready_ns
        # the first report of the new node that has an answer, then its first with most answers
        first = None
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and first is None:
            d = ctl.listener.diagnostics
            if ctl.listener.diagnostics_stamp_ns > ready_ns and d and int(d["values"]["inputs solved"]) >= 1:
                first = dict(d["values"])
            time.sleep(0.005)
        t_first = time.monotonic()
        time.sleep(phase_s)
        stop.set()
        thread.join(10)
        sent = out.get("sent", [])
        after = self.settle(sent[-1].send_ns if sent else None)
        poses = list(ctl.listener.poses[k0:])
        new_poses = [p for p in poses if p[1] > ready_ns]
        old_poses = [p for p in poses if p[1] <= kill_ns]
        sent_new = [s for s in sent if s.send_ns > ready_ns - int(5e9)]
        a = analyse(self.model, sent_new, new_poses)
        first_pose_s = (min(p[0] for p in new_poses) - ready_ns) * 1e-9 if new_poses else None
        s_first = starts(first) if first else None
        s_end = starts(after)
        c_end = counters(after)
        res = {"exit_status": status, "stopped": stopped, "rss_old_mb": old_rss / 1024,
               "downtime_s": t_first - t_kill, "startup_s": startup, "first_pose_after_ready_s": first_pose_s,
               "poses_before": len(old_poses), "poses_after": len(new_poses), "inputs_sent": len(sent),
               "first_report": {"starts": s_first, "last start": first.get("last start") if first else None,
                                "solved": int(first["inputs solved"]) if first else 0},
               "final": {"starts": s_end, "last start": after.get("last start"), **c_end},
               "residual_max_m": a["residual_max_m"], "poses_on_trajectory_mode": a["on_trajectory_mode"]}
        res["checks"] = {
            "node stopped cleanly on SIGINT (status 0)": status == 0,
            "restarted node answers": bool(new_poses),
            "first answer cold (the restarted node has no warm state)":
                s_first is not None and s_first["cold"] >= 1,
            "then warm: no cold start after the first answer":
                s_first is not None and s_end["cold"] == s_first["cold"] and after.get("last start") == "warm",
            "poses reproduce the legs": a["residual_max_m"] is not None and a["residual_max_m"] <= RESIDUAL_MAX_M,
        }
        return res


# -- (d) deadlines, in process ---------------------------------------------------------------------------

def infeasible_legs(model) -> np.ndarray:
    """Leg lengths with no real assembly (the platform cannot reach the base joints)."""
    if model.kind == "planar_3rpr":
        return np.array([10.0, 10.0, 400.0])
    return np.full(model.n_legs, 100.0)


def _warm_up(est, legs, budget_ms: float, reset: bool, quiet: int = 20, max_calls: int = 500) -> None:
    """Solve until ``quiet`` calls in a row return on time (Numba compiles each path on first use)."""
    in_row = 0
    for _ in range(max_calls):
        if reset:
            est.reset()
        t0 = time.perf_counter()
        est.estimate(legs)
        in_row = in_row + 1 if (time.perf_counter() - t0) * 1e3 <= budget_ms + DEADLINE_MARGIN_MS else 0
        if in_row >= quiet:
            return


def deadlines(model, budgets_ms=DEADLINE_BUDGETS_MS, n: int = 10_000, seed_x=None, say=None) -> list[dict]:
    """``n`` Estimator solves per budget and case on legs without a real assembly and without an
    evaluation cap: each runs until its deadline (after a warm-up until the solves run on time).
    Cases: cold (state reset before each solve), warm (a warm state the failures keep, so the warm,
    widened and cold stages all run).  Each call is flagged when another process preempted it or
    Python's garbage collector ran during it."""
    legs = infeasible_legs(model)
    rows = []
    collections = [0]

    def on_gc(phase, info):
        if phase == "start":
            collections[0] += 1

    gc.callbacks.append(on_gc)
    try:
        for case in ("cold", "warm"):
            for b in budgets_ms:
                rows.append(_deadline_cell(model, legs, case, b, n, seed_x, collections, say))
    finally:
        gc.callbacks.remove(on_gc)
    return rows


def _deadline_cell(model, legs, case: str, b: float, n: int, seed_x, collections: list, say) -> dict:
    from glpma_tools.bench.common import involuntary_switches
    from glpma_ros.estimator import Estimator
    if say:
        say(f"deadline: {n} Estimator solves, {case}, {b:g} ms")
    # no evaluation cap: only the deadline stops a search
    est = Estimator(model, time_budget_s=b * 1e-3, initial_pose=seed_x if case == "warm" else None,
                    max_evals=10**9)
    _warm_up(est, legs, b, reset=case == "cold")
    gc.collect()
    elapsed = np.empty(n)
    preempted = np.zeros(n, dtype=bool)
    collected = np.zeros(n, dtype=bool)
    statuses = {}
    for k in range(n):
        if case == "cold":
            est.reset()
        c0, g0 = involuntary_switches(), collections[0]
        t0 = time.perf_counter()
        e = est.estimate(legs)
        elapsed[k] = time.perf_counter() - t0
        preempted[k] = involuntary_switches() > c0
        collected[k] = collections[0] > g0
        statuses[e.status] = statuses.get(e.status, 0) + 1
    over = elapsed * 1e3 - b
    quiet = over[~(preempted | collected)]
    return {"case": case, "budget_ms": b, "solves": n,
            "on_time_pct": 100.0 * float(np.mean(over <= DEADLINE_MARGIN_MS)),
            "elapsed_p50_ms": float(np.percentile(elapsed, 50) * 1e3),
            "elapsed_p99_ms": float(np.percentile(elapsed, 99) * 1e3),
            "worst_overrun_ms": float(over.max()), "preempted": int(preempted.sum()),
            "gc": int(collected.sum()),
            "on_time_undisturbed_pct": 100.0 * float(np.mean(quiet <= DEADLINE_MARGIN_MS)) if quiet.size else None,
            "worst_overrun_undisturbed_ms": float(quiet.max()) if quiet.size else None,
            "statuses": statuses}


# -- the whole run ---------------------------------------------------------------------------------------

def run(sections=SECTIONS, quick: bool = False, duration_s: float | None = None, rate_hz: float = RATE_HZ,
        burst_n: int | None = None, deadline_solves: int | None = None, phase_s: float | None = None,
        params_file=DEFAULT_PARAMS, extra_args=(), domain_id: int | None = None, log_dir=None,
        budgets_ms=DEADLINE_BUDGETS_MS, say=None) -> dict:
    """Every requested section; a JSON-able dict of figures and checks."""
    from glpma_tools.bench.common import git_revision, machine

    def pick(value, name):
        return DEFAULTS[name][1 if quick else 0] if value is None else value

    say = say or (lambda msg: None)
    t_start = time.perf_counter()
    res = {"date": time.strftime("%Y-%m-%d %H:%M %Z"), "quick": quick, "revision": git_revision(),
           "machine": machine(), "load_average_start": os.getloadavg(), "sections": {}}
    node_sections = [s for s in sections if s != "deadline"]
    session = None
    if node_sections:
        session = Session(params_file, extra_args, domain_id, log_dir, say)
        res["node"] = {"command": shlex.join(["python", "-m", "glpma_ros.node.dds.node", "--ros-args",
                                              *session.ros_args]),
                       "domain": session.domain_id, "manipulator": session.model.kind,
                       "time_budget_ms": session.params["time_budget_ms"], "qos_depth": session.params["qos_depth"],
                       "log_dir": str(session.log_dir)}
        try:
            session.start()
            if "overload" in sections:
                d = pick(duration_s, "duration_s")
                res["sections"]["overload"] = session.overload(d, rate_hz)
            if "burst" in sections:
                res["sections"]["burst"] = session.burst(pick(burst_n, "burst"))
            if "restarts" in sections:
                p = pick(phase_s, "phase_s")
                res["sections"]["controller_restart"] = session.controller_restart(p)
                res["sections"]["large_jump"] = session.large_jump(p)
                res["sections"]["node_restart"] = session.node_restart(p)
            res["node"]["startup_s"] = session.startup_s
        finally:
            session.close()
    if "deadline" in sections:
        plan = session.plan if session else Plan(_manipulator(params_file, extra_args))
        seed_x = _known_solution(plan)
        res["sections"]["deadline"] = {
            "manipulator": plan.model.kind,
            "rows": deadlines(plan.model, budgets_ms, pick(deadline_solves, "deadline_solves"), seed_x, say)}
    res["load_average_end"] = os.getloadavg()
    res["wall_s"] = time.perf_counter() - t_start
    res["passed"] = all(all(s.get("checks", {}).values()) for s in res["sections"].values())
    return res


def _manipulator(params_file, extra_args) -> str:
    from glpma_ros.node.ros_args import node_values
    values, _, _ = node_values(["--ros-args", "--params-file", str(params_file), *extra_args])
    return values["manipulator_config"]


def _known_solution(plan: Plan) -> np.ndarray:
    """Solver variables of the trajectory's start (a known solution of the config)."""
    from glpma_ros.models.rotations import quaternion_from_matrix
    position, R = plan.pose_at(0.0)
    return plan.model.variables_from_pose(position, quaternion_from_matrix(R))


# -- output ---------------------------------------------------------------------------------------------

def _f(v, spec=".3g"):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return f"{v:,}"
    return f"{v:{spec}}"


def _lat(d) -> str:
    if not d or d.get("p50") is None:
        return "—"
    return f"{d['p50']:.3f} / {d['p99']:.3f} / {d['max']:.3f}"


def _flood_rows(secs: dict) -> tuple[list[str], list[list[str]]]:
    keys = [k for k in ("overload", "burst") if k in secs]
    head = ["quantity"] + [("overload, " + f"{secs[k]['rate_hz']:g} Hz for {secs[k]['duration_s']:g} s")
                           if k == "overload" else f"burst of {secs[k]['inputs']:,}" for k in keys]

    def row(label, fn):
        return [label] + [fn(secs[k]) for k in keys]

    rows = [
        row("inputs written", lambda s: _f(s["inputs"])),
        row("write rate achieved (Hz)", lambda s: _f(s["send_rate_hz"], ",.0f")),
        row("received by the node", lambda s: _f(s["received"])),
        row("lost in transport (DDS keep-last)", lambda s: _f(s["lost_in_transport"])),
        row("solved (pose published)", lambda s: _f(s["solved"])),
        row("dropped (replaced by a newer input)", lambda s: _f(s["dropped"])),
        row("rejected", lambda s: _f(s["rejected"])),
        row("deadline misses", lambda s: _f(s["deadline_misses"])),
        row("starts warm / widened / cold", lambda s: "{warm} / {widened} / {cold}".format(**s["starts"])),
        row("poses received", lambda s: _f(s["poses"])),
        row("latency write -> pose p50 / p99 / max (ms)", lambda s: _lat(s["latency_ms"])),
        row("node latency arrival -> solved p50 / p99 / max (ms)", lambda s: _lat(s["node_latency_ms"])),
        row("max leg residual of a pose (m)", lambda s: _f(s["residual_max_m"], ".1e")),
        row("poses on the trajectory's assembly mode", lambda s: _f(s["on_trajectory_mode"])),
        row("node RSS before / after (MB)", lambda s: f"{s['rss_before_mb']:.1f} / {s['rss_after_mb']:.1f}"),
        row("RSS growth (MB)", lambda s: f"{s['rss_growth_mb']:+.2f}"),
    ]
    return head, rows


def _restart_rows(secs: dict) -> list[list[str]]:
    rows = []
    if "controller_restart" in secs:
        s = secs["controller_restart"]
        rows.append(["controller restart (new participant)",
                     f"{s['inputs_before']} inputs, participant deleted, new one matched in {s['discovery_s']:.2f} s; "
                     f"{s['poses_after']} poses for its {s['inputs_after']} inputs, first in "
                     f"{_f(s['first_pose_latency_ms'])} ms; starts warm/widened/cold "
                     "{warm}/{widened}/{cold}".format(**s["starts_after"]) +
                     f"; rejected {s['after']['rejected']}; residual max {_f(s['residual_max_m'], '.1e')} m",
                     _ok(s)])
    if "large_jump" in secs:
        s = secs["large_jump"]
        rows.append([f"large jump (to known solution {s['to_solution']})",
                     f"before: {s['before']['on_trajectory_mode']} of {s['before']['poses']} poses on the mode "
                     f"of the trajectory followed; legs jump {s['jump_legs_max']:.3g} {s['unit']} "
                     f"({100 * s['jump_relative']:.0f} % of the scale, one step is "
                     f"~{s['step_legs_max']:.2g} {s['unit']}); "
                     f"first pose after {s['inputs_until_first_pose']} inputs "
                     f"({_f(s['first_pose_latency_ms'])} ms); {s['poses']} poses for {s['inputs']} inputs, "
                     f"{s['rejected']} rejected, {s['dropped']} dropped; starts warm/widened/cold "
                     "{warm}/{widened}/{cold}".format(**s["starts"]) +
                     f"; {s['poses_on_requested_mode']} poses on the requested mode; "
                     f"residual max {_f(s['residual_max_m'], '.1e')} m; last start {s['last_start']}", _ok(s)])
    if "node_restart" in secs:
        s = secs["node_restart"]
        fr, fi = s["first_report"], s["final"]
        rows.append(["node restart (SIGINT mid-trajectory, started again)",
                     f"exit status {s['exit_status']}; back in {s['downtime_s']:.1f} s "
                     f"(start-up {s['startup_s']:.1f} s, "
                     f"first pose {_f(s['first_pose_after_ready_s'])} s after ready); first report with an answer: "
                     + ("starts warm/widened/cold {warm}/{widened}/{cold}".format(**fr["starts"])
                        if fr["starts"] else "none")
                     + f"; at the end {fi['solved']} solved, starts warm/widened/cold "
                     "{warm}/{widened}/{cold}".format(**fi["starts"]) +
                     f", last start {fi['last start']}; {s['poses_on_trajectory_mode']} of {s['poses_after']} poses "
                     f"on the trajectory's mode; residual max {_f(s['residual_max_m'], '.1e')} m", _ok(s)])
    return rows


def _ok(section) -> str:
    failed = [k for k, v in section.get("checks", {}).items() if not v]
    return "pass" if not failed else "FAIL: " + "; ".join(failed)


def _deadline_rows(rows) -> list[list[str]]:
    def pct(v):
        return "—" if v is None else f"{v:.2f} %"

    def ms(v):
        return "—" if v is None else f"{v:+.3f}"
    return [[r["case"], f"{r['budget_ms']:g}", f"{r['solves']:,}", pct(r["on_time_pct"]),
             f"{r['elapsed_p50_ms']:.3f}", f"{r['elapsed_p99_ms']:.3f}", ms(r["worst_overrun_ms"]),
             f"{r['preempted']:,}", f"{r.get('gc', 0):,}", pct(r.get("on_time_undisturbed_pct")),
             ms(r.get("worst_overrun_undisturbed_ms")),
             ", ".join(f"{k} {v}" for k, v in sorted(r["statuses"].items()))] for r in rows]


DEADLINE_HEAD = ["start", "budget ms", "solves", f"within budget + {DEADLINE_MARGIN_MS} ms", "p50 elapsed ms",
                 "p99 elapsed ms", "worst overrun ms", "preempted", "GC ran", "within, undisturbed",
                 "worst overrun, undisturbed", "statuses"]


def _text_table(head, rows) -> str:
    widths = [max(len(str(r[i])) for r in [head, *rows]) for i in range(len(head))]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(head, widths))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(lines)


def format_table(res: dict) -> str:
    """The figures as plain-text tables."""
    secs = res["sections"]
    out = []
    if "node" in res:
        startup = ", ".join(f"{v:.1f}" for v in res["node"].get("startup_s", []))
        out.append(f"node: {res['node']['manipulator']}, budget {res['node']['time_budget_ms']:g} ms, "
                   f"qos depth {res['node']['qos_depth']}, start-up {startup} s")
    if "overload" in secs or "burst" in secs:
        head, rows = _flood_rows(secs)
        out += ["", _text_table(head, rows)]
        for k in ("overload", "burst"):
            if k in secs:
                out.append(f"{k}: {_ok(secs[k])}")
    r = _restart_rows(secs)
    if r:
        out += [""] + [f"{name}: {result}\n  {text}" for name, text, result in r]
    if "deadline" in secs:
        out += ["", f"deadline ({secs['deadline']['manipulator']}, in-process Estimator, legs without a real "
                    "assembly):", _text_table(DEADLINE_HEAD, _deadline_rows(secs["deadline"]["rows"]))]
    out += ["", f"{'all checks passed' if res['passed'] else 'SOME CHECKS FAILED'} "
                f"({res['wall_s'] / 60:.1f} min; load average {res['load_average_start'][0]:.2f} at the start, "
                f"{res['load_average_end'][0]:.2f} at the end, {res['machine']['cores']} cores)"]
    return "\n".join(out)


def _md_table(head, rows) -> str:
    return "\n".join(["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
                     + ["| " + " | ".join(str(c) for c in r) + " |" for r in rows])


def reliability_section(res: dict) -> list[str]:
    """The ``## Reliability`` section of BENCHMARKS.md, as lines."""
    secs = res["sections"]
    m = res["machine"]
    out = [RELIABILITY_HEADING, "",
           f"Generated by `{res.get('command') or 'glpma-fk stress'}` (`python -m glpma_tools.stress`) on "
           f"{res['date']} (run took {res['wall_s'] / 60:.1f} min), revision {res['revision']}; {m['cpu']}, "
           f"{m['cores']} cores; load average {res['load_average_start'][0]:.2f} at the start and "
           f"{res['load_average_end'][0]:.2f} at the end (the machine is shared: timings are noisy). "
           f"Checks: {'all passed' if res['passed'] else 'some failed (see below)'}.", ""]
    if res.get("quick"):
        out += ["> **--quick run**: short phases; the figures are indicative only.", ""]
    if "node" in res:
        n = res["node"]
        out += [f"A real node process over Cyclone DDS on loopback (`{n['command']}`: "
                f"{n['manipulator']}, time budget {n['time_budget_ms']:g} ms, keep-last depth {n['qos_depth']}, "
                f"cold start), driven from another process along the mock controller's trajectory. Counts are "
                "differences of the node's `/diagnostics` counters over each phase; *lost in transport* = written "
                "but never received by the node (the DDS keep-last history overflowed); latency is write -> pose "
                "received, over the inputs that got a pose. RSS from `/proc/<pid>/status` after "
                f"{WARMUP_S:g} s of warm-up traffic and after the phase.", ""]
    if "overload" in secs or "burst" in secs:
        head, rows = _flood_rows(secs)
        out += [_md_table(head, rows), ""]
        for k in ("overload", "burst"):
            if k in secs:
                out.append(f"- {k}: {_ok(secs[k])}")
        out += ["", "Nothing queues: the node holds one pending input (a newer one replaces it and counts as "
                "dropped) and DDS a keep-last history of `qos_depth` samples per endpoint (older samples are "
                "overwritten: lost in transport). Checks: every received input is solved, rejected or dropped; "
                "one pose per solved input; RSS growth within "
                f"{RSS_SLACK_MB:g} MB; every pose reproduces its legs to {RESIDUAL_MAX_M:g} m; at 1 kHz at most "
                f"{100 * LOST_SLACK:g} % lost in transport.", ""]
    rows = _restart_rows(secs)
    if rows:
        out += ["### Restarts and a jump", "", _md_table(["scenario", "what happened", "checks"], rows), "",
                "Leg lengths alone do not tell the assembly modes apart: the estimator keeps the solution nearest "
                "its previous pose, so after the jump it follows the branch continuous with the mode it was on "
                "(valid poses, the legs reproduced), not the trajectory's own mode; a restarted node starts cold "
                "and may pick either real assembly of the first legs it gets. `initial_pose` selects the mode.",
                ""]
    if "deadline" in secs:
        d = secs["deadline"]
        out += ["### Deadlines (in-process Estimator)", "",
                f"{d['manipulator']}, legs without a real assembly and no evaluation cap, so every solve runs until "
                "its deadline (after a warm-up until 20 solves in a row are on time: Numba compiles on first use); "
                "*cold*: state reset before each solve; *warm*: a warm state (which failures keep), so the warm, "
                "widened and cold stages all run. Elapsed = wall clock around `Estimator.estimate`; *preempted* = "
                "calls during which the thread had an involuntary context switch (another process took the CPU); "
                "*GC ran* = calls during which Python's garbage collector ran; *undisturbed* = neither. On a "
                "shared machine these explain most overruns.", "",
                _md_table(DEADLINE_HEAD, _deadline_rows(d["rows"])), ""]
    return out


def splice_section(text: str, section_lines: list[str], heading: str = RELIABILITY_HEADING) -> str:
    """``text`` with its ``heading`` section (up to the next ``## ``) replaced by ``section_lines``,
    or with them appended when it has none."""
    lines = text.splitlines()
    start = next((i for i, ln in enumerate(lines) if ln.strip() == heading), None)
    new = [ln for ln in "\n".join(section_lines).rstrip().splitlines()]
    if start is None:
        body = "\n".join(lines).rstrip()
        return (body + "\n\n" if body else "") + "\n".join(new) + "\n"
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
    rest = lines[end:]
    return "\n".join(lines[:start] + new + ([""] + rest if rest else [])).rstrip() + "\n"


def extract_section(text: str, heading: str = RELIABILITY_HEADING) -> list[str]:
    """The lines of the ``heading`` section of ``text`` (empty if none)."""
    lines = text.splitlines()
    start = next((i for i, ln in enumerate(lines) if ln.strip() == heading), None)
    if start is None:
        return []
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
    return lines[start:end]


def write_markdown(path: Path, res: dict) -> None:
    path = Path(path)
    text = path.read_text() if path.exists() else ""
    path.write_text(splice_section(text, reliability_section(res)))


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    if isinstance(o, Path):
        return str(o)
    return str(o)


class _OneLineParser(argparse.ArgumentParser):
    def error(self, message):
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    p = _OneLineParser(prog="glpma-fk stress", description=__doc__.split("\n\n")[0].split(": ", 1)[1]
                       .replace("``", ""))
    p.add_argument("--quick", action="store_true", help="a few seconds per section")
    p.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS),
                   help="run only these sections (default: all)")
    p.add_argument("--duration", type=float, help="seconds of overload (default 60; --quick 3)")
    p.add_argument("--rate", type=float, default=RATE_HZ, help="overload input rate, Hz (default 1000)")
    p.add_argument("--burst", type=int, help="messages in the burst (default 10000; --quick 2000)")
    p.add_argument("--phase", type=float, help="seconds of each restart/jump phase (default 2; --quick 1)")
    p.add_argument("--deadline-solves", type=int, help="Estimator solves per budget and case (default 10000)")
    p.add_argument("--budgets-ms", type=float, nargs="+", default=list(DEADLINE_BUDGETS_MS),
                   help="time budgets of the deadline section, ms")
    p.add_argument("--params-file", type=Path, default=DEFAULT_PARAMS, help="the node's parameters")
    p.add_argument("-p", dest="params", action="append", default=[], metavar="NAME:=VALUE",
                   help="more node parameters (as after --ros-args -p)")
    p.add_argument("--domain", type=int, help="ROS_DOMAIN_ID (default 150 + pid %% 50)")
    p.add_argument("--log-dir", type=Path, help="where the node's stdout/stderr go (default a temporary directory)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument("--markdown", type=Path, nargs="?", const=REPO_ROOT / "BENCHMARKS.md", default=None,
                   help="write the figures as the '## Reliability' section of this file (default BENCHMARKS.md)")
    p.add_argument("--from-json", type=Path, metavar="FILE",
                   help="run nothing: print (and with --markdown write) the figures of an earlier --json output")
    return p


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return 0 if exc.code in (0, None) else 2
    for name in ("duration", "phase"):
        v = getattr(args, name)
        if v is not None and not (math.isfinite(v) and v > 0):
            print(f"glpma-fk stress: error: --{name} must be positive", file=sys.stderr)
            return 2
    for name in ("burst", "deadline_solves"):
        v = getattr(args, name)
        if v is not None and v < 1:
            print(f"glpma-fk stress: error: --{name.replace('_', '-')} must be at least 1", file=sys.stderr)
            return 2
    if not (math.isfinite(args.rate) and args.rate > 0) or not all(b > 0 for b in args.budgets_ms):
        print("glpma-fk stress: error: --rate and --budgets-ms must be positive", file=sys.stderr)
        return 2
    if args.domain is not None and not 0 <= args.domain <= 232:
        print("glpma-fk stress: error: --domain must be in [0, 232]", file=sys.stderr)
        return 2
    if not args.params_file.exists():
        print(f"glpma-fk stress: error: no params file {args.params_file}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()

    def say(msg):
        print(f"[stress {time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    if args.from_json:
        try:
            res = json.loads(args.from_json.read_text())
        except (OSError, ValueError) as exc:
            print(f"glpma-fk stress: error: cannot read {args.from_json}: {exc}", file=sys.stderr)
            return 2
        if args.markdown:
            write_markdown(args.markdown, res)
        print(json.dumps(res) if args.json else format_table(res))
        return 0 if res.get("passed") else 1
    extra = [a for p in args.params for a in ("-p", p)]
    try:
        res = run(args.sections, args.quick, args.duration, args.rate, args.burst, args.deadline_solves,
                  args.phase, args.params_file, extra, args.domain, args.log_dir, tuple(args.budgets_ms), say)
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # noqa: BLE001 - one line, not a traceback
        print(f"glpma-fk stress: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    res["command"] = shlex.join(["glpma-fk", "stress", *argv])
    if args.markdown:
        write_markdown(args.markdown, res)
        say(f"wrote the Reliability section of {args.markdown}")
    print(json.dumps(res, default=_json_default) if args.json else format_table(res))
    return 0 if res["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
