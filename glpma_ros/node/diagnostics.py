"""The ``glpma_fk`` node's diagnostics: the ``diagnostic_msgs/DiagnosticStatus`` levels, a
transport-free status (:class:`DiagnosticReport`) and the report built from the service's statistics
(:class:`DiagnosticsMixin`, a base of :class:`~glpma_ros.node.service.FkService`: one key-value pair per
figure, the level WARN with the problems of the last reporting period, and the shutdown summary)."""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import params as P
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



class DiagnosticsMixin:
    """:meth:`diagnostics` and :meth:`summary` of :class:`~glpma_ros.node.service.FkService` (they read
    its ``stats``, ``params``, ``model``, ``outputs``, ``estimator`` state under its locks)."""

    def diagnostics(self) -> DiagnosticReport:
        """The current statistics as a DiagnosticStatus; starts a new reporting period."""
        with self._lock, self._drop_lock:
            st = self.stats
            period, st.period = st.period, Counter()
            period["dropped"], st.dropped_reported = st.dropped - st.dropped_reported, st.dropped
            solve = percentiles_ms(st.solve_s)
            latency = percentiles_ms(st.latency_s)
            extras = percentiles_ms(st.extras_s)
            handoff = percentiles_ms(st.extras_handoff_s)
            last = st.last_estimate
            cond_last = last.conditioning if last is not None else math.nan
            with self._modes_lock:
                modes = [("assembly modes requests", st.modes_requests),
                         ("assembly modes published", st.modes_published),
                         ("assembly modes failed", st.modes_failed),
                         ("assembly modes coalesced", st.modes_coalesced),
                         ("assembly modes last", st.modes_last or "none"),
                         ("assembly modes last starts", st.modes_last_starts)]
                if st.modes_last_failure:
                    modes.append(("assembly modes last failure", st.modes_last_failure))
            values = [
                ("input", "joint_states (" + ", ".join(self.joint_names) + ")"
                 if self.input_type == P.INPUT_JOINT_STATE else "leg_lengths"),
                ("inputs received", st.handled + st.dropped),
                ("inputs solved", st.published),
                ("inputs rejected", st.rejected),
                ("inputs dropped", st.dropped),
                ("deadline misses", st.deadline_misses),
                ("solver", self.params["solver"]),
                ("last start", last.start if last is not None else "none"),
                ("warm state", "yes" if self._warm_x is not None else "no (cold start next)"),
                ("starts warm/widened/cold",
                 f"{st.starts['warm']}/{st.starts['widened']}/{st.starts['cold']}"),
                ("solve time p50 (ms)", f"{solve[0]:.4g}"),
                ("solve time p99 (ms)", f"{solve[1]:.4g}"),
                ("solve time max (ms)", f"{solve[2]:.4g}"),
                ("latency p50 (ms)", f"{latency[0]:.4g}"),
                ("latency p99 (ms)", f"{latency[1]:.4g}"),
                ("latency max (ms)", f"{latency[2]:.4g}"),
                ("residual RMS last (m)", f"{st.residual_m[-1]:.3g}" if st.residual_m else "nan"),
                ("residual RMS max (m)", f"{max(st.residual_m):.3g}" if st.residual_m else "nan"),
                ("fitness last", f"{last.fitness:.3g}" if last is not None else "nan"),
                ("evaluations last", last.evaluations if last is not None else 0),
                ("evaluations mean", f"{np.mean(st.evaluations):.1f}" if st.evaluations else "nan"),
                ("conditioning last", f"{cond_last:.3g}"),
                ("conditioning min", f"{min(st.conditioning):.3g}" if st.conditioning else "nan"),
                ("time budget (ms)", f"{self.params['time_budget_ms']:g}"),
                ("tolerance", f"{self.params['tolerance']:g}"),
                ("manipulator", f"{self.model.kind} ({self.model.unit})"),
                ("frame_id", self.frame_id),
                ("outputs", ", ".join(name for name, on in (
                    ("pose_estimate", True), ("/tf", self.params["publish_tf"]),
                    ("pose_estimate_cov", self.params["publish_covariance"]),
                    ("twist_estimate", self.params["publish_twist"]),
                    ("~/markers", self.params["publish_markers"])) if on)),
                ("child_frame_id", self.params["child_frame_id"]),
                ("leg noise std (m)", f"{self.params['leg_noise_std']:g}"),
                ("covariance capped (singular pose)", self.outputs.capped),
                ("twist source", self.outputs.twist_source or "none yet"),
                ("extra outputs time p50 (ms)", f"{extras[0]:.4g}"),
                ("extra outputs time p99 (ms)", f"{extras[1]:.4g}"),
                ("extra outputs hand-off p50 (ms)", f"{handoff[0]:.4g}"),
                ("extra outputs hand-off p99 (ms)", f"{handoff[1]:.4g}"),
                ("extra outputs dropped (backlog)", st.extras_dropped),
            ]
            values += modes
            legs, leg_problems = self.leg_health.report(self.joint_names)
            values += legs
            values += [(f"rejected: {reason}", n) for reason, n in st.reasons.most_common()]
            if st.last_reason:
                values.append(("last rejection", st.last_reason))
            problems = []
            if period["rejected"]:
                problems.append(f"{period['rejected']} inputs rejected")
            if period["deadline_misses"]:
                problems.append(f"{period['deadline_misses']} deadline misses")
            if period["dropped"]:
                problems.append(f"{period['dropped']} inputs dropped")
            if period["modes_failed"]:
                problems.append(f"{period['modes_failed']} assembly-modes requests failed")
            if last is not None and last.converged and last.near_singular:
                problems.append(f"near a singularity (conditioning {cond_last:.2g})")
            if self.outputs.capped > st.capped_reported:
                problems.append(f"pose at a singularity: covariance capped "
                                f"({self.outputs.capped - st.capped_reported} times)")
            st.capped_reported = self.outputs.capped
            problems += leg_problems
            if problems:
                level, message = WARN, "; ".join(problems)
            elif st.handled + st.dropped == 0:
                level, message = OK, ("waiting for joint_states" if self.input_type == P.INPUT_JOINT_STATE
                                      else "waiting for leg_lengths")
            else:
                level, message = OK, "tracking"
            return DiagnosticReport(level, f"{self.node_name}: forward kinematics", message,
                                    f"{self.model.kind}:{Path(str(getattr(self.model, 'source', ''))).name}",
                                    [(k, str(v)) for k, v in values])

    def summary(self) -> str:
        """One line of totals, for the log at shutdown."""
        st = self.stats
        solve = percentiles_ms(st.solve_s)
        times = (f"solve time p50 {solve[0]:.3g} ms p99 {solve[1]:.3g} ms max {solve[2]:.3g} ms" if st.solve_s
                 else "no solve yet")
        return (f"received {st.handled + st.dropped}, solved {st.published}, rejected {st.rejected}, "
                f"dropped {st.dropped}, deadline misses {st.deadline_misses}, {times}")
