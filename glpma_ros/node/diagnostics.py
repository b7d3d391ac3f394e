"""The ``glpma_fk`` node's diagnostics: the ``diagnostic_msgs/DiagnosticStatus`` levels, a
transport-free status (:class:`DiagnosticReport`) and :class:`Diagnostics`, the reporter a
:class:`~glpma_ros.node.service.FkService` holds, handed the collaborators it reads: one
key-value pair per figure, the level WARN with the problems of the last reporting period, and the
shutdown summary.

A report is built from snapshots (:meth:`Statistics.snapshot <glpma_ros.node.stats.Statistics.snapshot>`,
:meth:`AssemblyModes.snapshot <glpma_ros.node.assembly_modes.AssemblyModes.snapshot>`) taken in
microseconds; its percentiles and its formatting happen afterwards in the caller's thread (the
transports call it from a thread of its own, :class:`~glpma_ros.node.loops.ReportLoop`), holding no
lock of the service, so that no input waits for a report.  That thread still holds the interpreter
(the GIL) while it computes, and a solving thread that needs it meanwhile waits: the report is
therefore built in stages of a few tens of microseconds, with ``pause()`` (the report thread
sleeps, releasing the interpreter) between them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from . import params as P
from .input_topic import input_topic, model_is_actuated
from .stats import percentiles_ms

OK, WARN, ERROR, STALE = 0, 1, 2, 3   # diagnostic_msgs/DiagnosticStatus levels


@dataclass
class DiagnosticReport:
    """A transport-free ``diagnostic_msgs/DiagnosticStatus``."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: list = field(default_factory=list)   # [(key, value)] strings

    def as_dict(self) -> dict:
        return dict(self.values)


def _g(value: float, digits: str = ".4g") -> str:
    return format(value, digits)


class Diagnostics:
    """The /diagnostics report and the shutdown summary of a :class:`~glpma_ros.node.service.FkService`,
    from its collaborators: ``params()`` the current parameter values, ``inputs`` the
    :class:`~glpma_ros.node.inputs.InputConverter` (joint names), ``stats``
    (:class:`~glpma_ros.node.stats.Statistics`), ``modes`` (:class:`~glpma_ros.node.assembly_modes.AssemblyModes`),
    ``leg_health`` (:class:`~glpma_ros.node.leg_health.LegHealth`), ``outputs``
    (:class:`~glpma_ros.node.outputs.OutputBuilder`) and ``warm_state()``: whether the estimator
    has a warm start for the next input."""

    def __init__(self, node_name: str, model, params, inputs, stats, modes, leg_health, outputs, warm_state):
        self.node_name = node_name
        self.model = model
        self.params = params
        self.inputs = inputs
        self.stats = stats
        self.modes = modes
        self.leg_health = leg_health
        self.outputs = outputs
        self.warm_state = warm_state
        self._capped_reported = 0     # covariances capped at a singularity, at the last report
        self._limits_reported = 0     # poses beyond a passive-joint limit, at the last report

    def report(self, pause=lambda: None) -> DiagnosticReport:
        """The current statistics as a DiagnosticStatus; starts a new reporting period.
        ``pause()`` is called between the stages of the work (default: nothing)."""
        st = self.stats.snapshot(new_period=True, pause=pause)
        pause()
        modes, modes_failed = self.modes.snapshot(new_period=True)
        params, model, outputs = self.params(), self.model, self.outputs
        joint_state = params["input_type"] == P.INPUT_JOINT_STATE
        topic = input_topic(params["input_type"], model_is_actuated(model))
        capped, self._capped_reported = outputs.capped - self._capped_reported, outputs.capped
        beyond, self._limits_reported = outputs.limit_poses - self._limits_reported, outputs.limit_poses
        tails = []                    # p50, p99, max (ms) of each timed window
        for name in ("solve_s", "latency_s", "extras_s", "extras_handoff_s"):
            pause()
            tails.append(percentiles_ms(st.window(name)))
        solve, latency, extras, handoff = tails
        pause()
        residual, evaluations, conditioning = (st.window(n) for n in ("residual_m", "evaluations", "conditioning"))
        last = st.last_estimate
        cond_last = last.conditioning if last is not None else math.nan
        pause()
        values = [
            ("input", "joint_states (" + ", ".join(self.inputs.joint_names) + ")"
             if joint_state else topic),
            ("inputs received", st.received),
            ("inputs solved", st.published),
            ("inputs rejected", st.rejected),
            ("inputs dropped", st.dropped),
            ("deadline misses", st.deadline_misses),
            ("solver", params["solver"]),
            ("last start", last.start if last is not None else "none"),
            ("warm state", "yes" if self.warm_state() else "no (cold start next)"),
            ("starts warm/widened/cold", "/".join(str(st.starts.get(k, 0)) for k in ("warm", "widened", "cold"))),
        ]
        pause()
        values += [
            ("solve time p50 (ms)", _g(solve[0])),
            ("solve time p99 (ms)", _g(solve[1])),
            ("solve time max (ms)", _g(solve[2])),
            ("latency p50 (ms)", _g(latency[0])),
            ("latency p99 (ms)", _g(latency[1])),
            ("latency max (ms)", _g(latency[2])),
        ]
        pause()
        values += [
            ("residual RMS last (m)", _g(residual[-1], ".3g") if residual.size else "nan"),
            ("residual RMS max (m)", _g(residual.max(), ".3g") if residual.size else "nan"),
            ("fitness last", _g(last.fitness, ".3g") if last is not None else "nan"),
            ("evaluations last", last.evaluations if last is not None else 0),
            ("evaluations mean", _g(evaluations.mean(), ".1f") if evaluations.size else "nan"),
            ("conditioning last", _g(cond_last, ".3g")),
            ("conditioning min", _g(conditioning.min(), ".3g") if conditioning.size else "nan"),
            ("time budget (ms)", _g(params["time_budget_ms"], "g")),
            ("tolerance", _g(params["tolerance"], "g")),
        ]
        pause()
        values += [
            ("manipulator", f"{model.kind} ({model.unit})"),
            ("frame_id", params["frame_id"]),
            ("outputs", ", ".join(name for name, on in (
                ("pose_estimate", True), ("/tf", params["publish_tf"]),
                ("pose_estimate_cov", params["publish_covariance"]),
                ("twist_estimate", params["publish_twist"]),
                ("~/markers", params["publish_markers"]),
                ("~/mechanism_joint_states", params["publish_joint_states"])) if on)),
            ("child_frame_id", params["child_frame_id"]),
            ("leg noise std (m)", _g(params["leg_noise_std"], "g")),
            *((("actuator noise std (rad)", _g(params["actuator_noise_std"], "g")),)
              if model_is_actuated(model) else ()),
            ("covariance capped (singular pose)", outputs.capped),
            ("twist source", outputs.twist_source or "none yet"),
        ]
        if outputs.passive_limits is not None:
            values += [("poses beyond a joint limit", outputs.limit_poses),
                       ("joint limit", outputs.last_violation or "none")]
        pause()
        values += [
            ("extra outputs time p50 (ms)", _g(extras[0])),
            ("extra outputs time p99 (ms)", _g(extras[1])),
            ("extra outputs hand-off p50 (ms)", _g(handoff[0])),
            ("extra outputs hand-off p99 (ms)", _g(handoff[1])),
            ("extra outputs dropped (backlog)", st.extras_dropped),
            *modes,
        ]
        legs, leg_problems = self.leg_health.report(self.inputs.joint_names)     # redundant legs' health
        values += [*legs, *((f"rejected: {reason}", n) for reason, n in st.reasons)]
        if st.last_reason:
            values.append(("last rejection", st.last_reason))
        pause()
        problems = [f"{n} {what}" for n, what in ((st.period.get("rejected", 0), "inputs rejected"),
                                                  (st.period.get("deadline_misses", 0), "deadline misses"),
                                                  (st.period.get("dropped", 0), "inputs dropped"),
                                                  (modes_failed, "assembly-modes requests failed")) if n]
        if last is not None and last.converged and last.near_singular:
            problems.append(f"near a singularity (conditioning {cond_last:.2g})")
        if capped:
            problems.append(f"pose at a singularity: covariance capped ({capped} times)")
        if beyond:
            problems.append(f"joint_limit: {outputs.last_violation} ({beyond} poses beyond a passive joint's limit)")
        problems += leg_problems
        if problems:
            level, message = WARN, "; ".join(problems)
        elif st.received == 0:
            level, message = OK, f"waiting for {topic}"
        else:
            level, message = OK, "tracking"
        return DiagnosticReport(level, f"{self.node_name}: forward kinematics", message,
                                f"{model.kind}:{Path(str(getattr(model, 'source', ''))).name}",
                                [(k, v if isinstance(v, str) else str(v)) for k, v in values])

    def summary(self) -> str:
        """One line of totals, for the log at shutdown."""
        st = self.stats.snapshot()
        solve_s = st.window("solve_s")
        solve = percentiles_ms(solve_s)
        times = (f"solve time p50 {solve[0]:.3g} ms p99 {solve[1]:.3g} ms max {solve[2]:.3g} ms"
                 if solve_s.size else "no solve yet")
        return (f"received {st.received}, solved {st.published}, rejected {st.rejected}, "
                f"dropped {st.dropped}, deadline misses {st.deadline_misses}, {times}")
