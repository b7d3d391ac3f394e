"""One node process over Cyclone DDS, the controller that talks to it and the trajectory
clock shared by the phases (each phase continues where the previous one stopped), and what every
phase measures: the node's counters over the phase and each pose against its input."""
from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

from glpma_ros.node.ros_args import node_values
from glpma_ros.testing.matching import compare
from glpma_tools.sim.controller import Controller, counters, diff, starts
from glpma_tools.sim.domains import claim_domain
from glpma_tools.sim.node_process import NodeProcess, node_environment
from glpma_tools.sim.trajectories import Plan
from glpma_tools.stats import distribution

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_PARAMS = REPO_ROOT / "config" / "params_3rpr.yaml"
#: inputs per second of the overload
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
#: a pose on the trajectory's assembly mode is this close to the true pose (metres)
ON_MODE_M = 1e-6
#: the node reports often, so that a phase ends soon after its last input
DIAGNOSTICS_PERIOD_S = 0.2
#: seconds to wait for the node's endpoints, and for it to report idle after a phase
MATCH_TIMEOUT_S = 60.0
SETTLE_TIMEOUT_S = 15.0


def analyse(model, sent: list, poses: list, earlier: list = ()) -> dict:
    """Each pose paired with its input (:mod:`glpma_ros.testing.matching`) among ``earlier + sent``:
    latency (write -> pose received, ms), how many answer no input (wrong), how well they reproduce
    the legs (m), how many are on the trajectory's assembly mode, and the first input of ``sent``
    answered.  ``earlier``: the inputs sent before ``sent`` in the session (:attr:`Session.history`);
    a pose that answers one of them (it came late, from a backlog) is counted as ``late``: it is
    neither wrong nor an answer to ``sent``."""
    c = compare(model, [*earlier, *sent], poses)
    mine = c.index >= len(earlier)
    index, latency = c.index[mine] - len(earlier), c.latency_ms[mine]
    first = int(index[0]) if index.size else None
    residual = c.legs_residual_m[mine]
    return {"poses": len(poses), "matched": int(mine.sum()), "late": int((~mine).sum()),
            "unpaired": len(c.unpaired), "latency_ms": distribution(latency),
            "residual_max_m": float(residual.max()) if residual.size else None,
            "on_trajectory_mode": int((c.position_error_m[mine] <= ON_MODE_M).sum()),
            "first_answered": first, "first_latency_ms": float(latency[0]) if first is not None else None}


def node_latency(values: dict) -> dict:
    """The node's own latency figures (arrival -> solved) from a ``/diagnostics`` report."""
    def num(key):
        try:
            v = float(values.get(key, "nan"))
        except ValueError:
            return None
        return v if math.isfinite(v) else None
    return {"p50": num("latency p50 (ms)"), "p99": num("latency p99 (ms)"), "max": num("latency max (ms)")}


class Session:
    """One node process, the controller talking to it, and the trajectory clock."""

    def __init__(self, params_file=DEFAULT_PARAMS, extra_args=(), domain_id: int | None = None,
                 log_dir: Path | None = None, say=None):
        # a domain of its own unless one is given (held while this process runs)
        self._claim = None if domain_id is not None else claim_domain()
        self.domain_id = int(domain_id) if self._claim is None else self._claim.domain_id
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
        self.history: list = []          # every input sent in the session, in order

    def start(self) -> "Session":
        self.say(f"starting the node (domain {self.domain_id}; it compiles or loads its solvers first)")
        self.startup_s.append(self.node.start())
        self.controller = self.new_controller()
        return self

    def new_controller(self) -> Controller:
        c = Controller(self.model, self.domain_id, depth=self.params["qos_depth"])
        c.wait_for_node(MATCH_TIMEOUT_S)
        time.sleep(0.3)
        return c

    def close(self) -> None:
        if self.controller is not None:
            self.controller.close()
            self.controller = None
        self.node.stop()

    def send(self, n: int, rate_hz: float | None, plan: Plan | None = None, stop=None, dt: float | None = None):
        """Write ``n`` inputs along the plan from the session's trajectory time, and advance it."""
        dt = dt or 1.0 / (rate_hz or RATE_HZ)
        sent, late = self.controller.send(plan or self.plan, self.t, n, rate_hz, dt, stop)
        self.t += len(sent) * dt
        self.history.extend(sent)
        return sent, late

    def settle(self, after_ns: int | None = None) -> dict:
        """The node's report once it reported after ``after_ns`` (default: now) and is idle."""
        time.sleep(0.1)
        values = self.controller.diagnostics_after(time.time_ns() if after_ns is None else after_ns,
                                                   SETTLE_TIMEOUT_S)
        if values is None:
            raise TimeoutError(f"no stable /diagnostics report within {SETTLE_TIMEOUT_S:g} s")
        return values

    def poses_since(self, k0: int) -> list:
        return list(self.controller.listener.poses[k0:])


__all__ = ["Session", "analyse", "counters", "diff", "node_latency", "starts"]
