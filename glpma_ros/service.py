"""The ``glpma_fk`` node without a transport.

:class:`FkService` owns the :class:`~glpma_ros.estimator.Estimator` and does
everything a transport should not have to know about: parameters and their
runtime changes, unit conversion (metres on topics, the config's unit inside),
input validation with a one-line reason, the publish decision (converged
only), statistics and the diagnostics report.  :class:`SolveLoop` is the
threading both transports share: the newest pending input is solved, an input
replaced before it was picked up counts as dropped.

A transport (``dds/node.py``, ``ros_node.py``) only converts messages:
``SolveLoop.submit(msg.data, arrival_ns)`` in, ``publish(PoseOutput)`` out,
``service.diagnostics()`` every ``diagnostics_period_s``.
"""
from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import params as P
from .config import load_manipulator, resolve_config
from .errors import InputError
from .estimator import Estimator

#: statistics cover the most recent inputs
WINDOW = 2000
#: distinct rejection reasons shown on /diagnostics (the rest are counted as "other")
MAX_REASONS = 16
#: a conditioning (reciprocal condition number) below this is reported as near-singular
NEAR_SINGULAR = 1e-4
#: seconds between two log lines of the same rejection reason
LOG_THROTTLE_S = 1.0

OK, WARN, ERROR, STALE = 0, 1, 2, 3   # diagnostic_msgs/DiagnosticStatus levels


@dataclass(frozen=True)
class PoseOutput:
    """A pose to publish: metres, unit quaternion [x, y, z, w], stamp = arrival of the legs."""

    stamp_ns: int
    frame_id: str
    position: tuple
    orientation: tuple


@dataclass
class Outcome:
    """What became of one input: a pose to publish, or the reason there is none."""

    pose: PoseOutput | None
    reason: str | None = None
    estimate: object = None     # the estimator's Estimate, when it ran
    latency_s: float = 0.0


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


class LogThrottle:
    """Lets one log line per key through every ``period_s`` and counts the rest."""

    def __init__(self, period_s: float = LOG_THROTTLE_S, clock=time.monotonic):
        self.period_s = period_s
        self.clock = clock
        self._last: dict = {}
        self._suppressed: Counter = Counter()

    def __call__(self, key) -> int | None:
        """``None`` to stay silent, else the number of lines suppressed since the last one."""
        now = self.clock()
        last = self._last.get(key)
        if last is not None and now - last < self.period_s:
            self._suppressed[key] += 1
            return None
        self._last[key] = now
        return self._suppressed.pop(key, 0)


def _percentiles_ms(samples) -> tuple[float, float, float]:
    if not samples:
        return (math.nan, math.nan, math.nan)
    arr = np.fromiter(samples, dtype=float) * 1e3
    p50, p99 = np.percentile(arr, [50, 99])
    return float(p50), float(p99), float(arr.max())


class Statistics:
    """Counters since start, and distributions over the last :data:`WINDOW` inputs.
    ``handled`` inputs went through :meth:`FkService.handle`; ``dropped`` ones were replaced
    by a newer input first; received = handled + dropped."""

    def __init__(self):
        self.handled = self.published = self.rejected = self.dropped = self.deadline_misses = 0
        self.dropped_reported = 0     # dropped count at the last diagnostics report
        self.reasons: Counter = Counter()
        self.starts: Counter = Counter()
        self.solve_s: deque = deque(maxlen=WINDOW)
        self.latency_s: deque = deque(maxlen=WINDOW)
        self.evaluations: deque = deque(maxlen=WINDOW)
        self.residual_m: deque = deque(maxlen=WINDOW)
        self.conditioning: deque = deque(maxlen=WINDOW)
        self.last_estimate = None
        self.last_reason = ""
        self.period = Counter()       # events since the last diagnostics report

    def count_reason(self, key: str) -> None:
        if key not in self.reasons and len(self.reasons) >= MAX_REASONS:
            key = "other"
        self.reasons[key] += 1


class FkService:
    """Leg lengths (metres) in, poses (metres) out, with the estimator's warm state in between."""

    def __init__(self, parameters: dict | None = None, *, logger=None, node_name: str = P.NODE_NAME):
        """``parameters``: name -> value (unknown names are an error, missing ones take their default);
        ``logger``: anything with ``debug/info/warning/error(str)`` (``logging.Logger``, an rclpy logger).
        Raises :class:`~glpma_ros.errors.ConfigError` or :class:`InputError` with a one-line reason."""
        self.log = logger or logging.getLogger(node_name)
        self.node_name = node_name
        values = P.defaults()
        for name, value in (parameters or {}).items():
            values[name] = P.coerce(name, value)
        self.model = load_manipulator(resolve_config(values["manipulator_config"]))
        self.metres_per_unit = float(self.model.metres_per_unit)
        self._initial_x = self._initial_variables(values["initial_pose"])
        # the estimator's warm-start state, mirrored so that a rebuilt estimator can keep it
        self._warm_x = self._initial_x
        self.estimator = self._build_estimator(values, self._warm_x)
        self.params = values
        self.stats = Statistics()
        self._throttle = LogThrottle()
        self._lock = threading.RLock()          # estimator, parameters, statistics
        self._drop_lock = threading.Lock()      # the dropped counters only

    # -- construction --------------------------------------------------------------------
    def _initial_variables(self, initial_pose):
        if not initial_pose:
            return None
        try:
            return self.model.check_variables(initial_pose)
        except InputError as exc:
            raise InputError(f"parameter 'initial_pose': {exc}") from None

    def _build_estimator(self, values: dict, warm_x) -> Estimator:
        def opt(name):           # 0 = the papers' setting
            return values[name] or None
        return Estimator(self.model, solver=values["solver"], time_budget_s=values["time_budget_ms"] * 1e-3,
                         tolerance=values["tolerance"], seed=values["seed"], polish=values["polish"],
                         initial_pose=warm_x, population=opt("population"),
                         local_population=opt("local_population"), ls_interval=opt("ls_interval"),
                         ls_intensity=opt("ls_intensity"))

    @property
    def deadline_s(self) -> float:
        return (self.params["deadline_ms"] or self.params["time_budget_ms"]) * 1e-3

    @property
    def frame_id(self) -> str:
        return self.params["frame_id"]

    def describe(self) -> str:
        m = self.model
        return (f"{m.kind} ({Path(str(getattr(m, 'source', ''))).name}, {m.n_legs} legs, config unit {m.unit}), "
                f"solver {self.params['solver']}, budget {self.params['time_budget_ms']:g} ms, "
                f"{'warm start from initial_pose' if self._initial_x is not None else 'cold start'}")

    def _warm_up_variables(self) -> np.ndarray:
        """A pose to warm up with: ``initial_pose``, or any pose clear of the base joints."""
        if self._initial_x is not None:
            return self._initial_x
        s = self.model.scale
        return self.model.variables_from_pose([0.25 * s, 0.25 * s, s], [0.0, 0.0, 0.0, 1.0])

    def warm_up(self, solvers=P.SOLVER_CHOICES, budget_ms: float = 50.0, max_tries: int = 5) -> float:
        """Run every path of each solver -- cold and warm start, with and without the
        refinement (without it the evolutionary loops run in the warm stages too) -- until it
        runs within its budget, so that Numba has compiled everything before the first real
        input.  The warm-start state and the statistics are left untouched.  Returns the
        seconds spent."""
        t0 = time.perf_counter()
        x = self._warm_up_variables()
        # not exactly x's legs: a warm start must then search, not stop at its first individual
        legs = self.model.inverse_kinematics(x) * (1.0 + 1e-3)
        if self.model.leg_limits is not None:
            legs = np.clip(legs, *self.model.leg_limits)
        with self._lock:
            for name in solvers:
                for start in (None, x):
                    for polish in (True, False):
                        values = dict(self.params, solver=name, time_budget_ms=budget_ms, polish=polish)
                        for _ in range(max_tries):
                            t = time.perf_counter()
                            try:
                                self._build_estimator(values, start).estimate(legs)
                            except Exception as exc:  # noqa: BLE001 - reported, not fatal
                                self.log.warning(f"warm-up with {name} failed: {exc}")
                                break
                            if time.perf_counter() - t < 3e-3 * budget_ms:
                                break
        return time.perf_counter() - t0

    # -- inputs -------------------------------------------------------------------------------
    def handle(self, legs_m, stamp_ns: int, arrival: float | None = None) -> Outcome:
        """Solve one input.  ``legs_m``: leg lengths in metres; ``stamp_ns``: its arrival time
        (the pose's header.stamp); ``arrival``: ``time.perf_counter()`` at arrival, for the
        latency and the deadline (default: now).  Never raises."""
        arrival = time.perf_counter() if arrival is None else arrival
        with self._lock:
            st = self.stats
            st.handled += 1
            try:
                with np.errstate(over="ignore", invalid="ignore"):
                    legs = np.asarray(legs_m, dtype=float).reshape(-1) / self.metres_per_unit
                estimate = self.estimator.estimate(legs)
            except InputError as exc:
                return self._reject(str(exc), str(exc), None, arrival)
            except Exception as exc:  # noqa: BLE001 - the node must survive anything
                self.log.error(f"internal error while solving: {exc!r}")
                return self._reject(f"internal error: {exc}", "internal error", None, arrival)
            st.last_estimate = estimate
            st.starts[estimate.start] += 1
            st.solve_s.append(estimate.elapsed_s)
            st.evaluations.append(estimate.evaluations)
            if not estimate.converged:
                return self._reject(f"{estimate.status}: {estimate.message}", estimate.status, estimate, arrival)
            st.conditioning.append(estimate.conditioning)
            st.residual_m.append(math.sqrt(estimate.fitness / self.model.n_res) * self.metres_per_unit)
            self._warm_x = np.array(estimate.x, dtype=float)
            pose = estimate.pose
            out = PoseOutput(int(stamp_ns), self.frame_id,
                             tuple(float(v) * self.metres_per_unit for v in pose.position),
                             tuple(float(v) for v in pose.orientation))
            st.published += 1
            return Outcome(out, None, estimate, self._finish(arrival))

    def _finish(self, arrival: float) -> float:
        latency = time.perf_counter() - arrival
        self.stats.latency_s.append(latency)
        if latency > self.deadline_s:
            self.stats.deadline_misses += 1
            self.stats.period["deadline_misses"] += 1
        return latency

    def _reject(self, reason: str, key: str, estimate, arrival: float) -> Outcome:
        st = self.stats
        st.rejected += 1
        st.period["rejected"] += 1
        st.count_reason(key)
        st.last_reason = reason
        suppressed = self._throttle(key)
        if suppressed is not None:
            more = f" (+{suppressed} similar suppressed)" if suppressed else ""
            self.log.warning(f"input rejected: {reason}{more}")
        return Outcome(None, reason, estimate, self._finish(arrival))

    def note_dropped(self, count: int = 1) -> None:
        """The transport replaced ``count`` pending inputs by newer ones before solving them.
        Does not wait for a solve in progress (the reader thread calls it)."""
        with self._drop_lock:
            self.stats.dropped += count

    # -- parameters -----------------------------------------------------------------------------
    def set_parameters(self, changes: dict) -> tuple[bool, str]:
        """Apply ``changes`` (name -> value) atomically.  Returns ``(True, "")`` or
        ``(False, reason)``; on failure nothing changes.  The warm-start state survives every
        change except a new ``initial_pose``, which restarts tracking from it."""
        with self._lock:
            values = dict(self.params)
            try:
                for name, value in changes.items():
                    value = P.coerce(name, value)
                    if P.SPECS[name].read_only and value != self.params[name]:
                        raise InputError(f"parameter '{name}' is read-only while the node runs "
                                         f"(restart the node to change it)")
                    values[name] = value
                initial_x = self._initial_variables(values["initial_pose"])
                warm_x = initial_x if values["initial_pose"] != self.params["initial_pose"] else self._warm_x
                estimator = self._build_estimator(values, warm_x)
            except InputError as exc:
                return False, str(exc)
            except (TypeError, ValueError) as exc:
                return False, f"invalid parameters: {exc}"
            changed = {k: v for k, v in values.items() if v != self.params[k]}
            self.params, self.estimator = values, estimator
            self._initial_x, self._warm_x = initial_x, warm_x
            if changed:
                self.log.info("parameters set: " + ", ".join(f"{k}={v!r}" for k, v in changed.items()))
            return True, ""

    # -- diagnostics ------------------------------------------------------------------------------
    def diagnostics(self) -> DiagnosticReport:
        """The current statistics as a DiagnosticStatus; starts a new reporting period."""
        with self._lock, self._drop_lock:
            st = self.stats
            period, st.period = st.period, Counter()
            period["dropped"], st.dropped_reported = st.dropped - st.dropped_reported, st.dropped
            solve = _percentiles_ms(st.solve_s)
            latency = _percentiles_ms(st.latency_s)
            last = st.last_estimate
            cond_last = last.conditioning if last is not None else math.nan
            values = [
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
            ]
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
            if last is not None and last.converged and cond_last < NEAR_SINGULAR:
                problems.append(f"near a singularity (conditioning {cond_last:.2g})")
            if problems:
                level, message = WARN, "; ".join(problems)
            elif st.handled + st.dropped == 0:
                level, message = OK, "waiting for leg_lengths"
            else:
                level, message = OK, "tracking"
            return DiagnosticReport(level, f"{self.node_name}: forward kinematics", message,
                                    f"{self.model.kind}:{Path(str(getattr(self.model, 'source', ''))).name}",
                                    [(k, str(v)) for k, v in values])

    def summary(self) -> str:
        """One line of totals, for the log at shutdown."""
        st = self.stats
        solve = _percentiles_ms(st.solve_s)
        return (f"received {st.handled + st.dropped}, solved {st.published}, rejected {st.rejected}, "
                f"dropped {st.dropped}, deadline misses {st.deadline_misses}, "
                f"solve time p50 {solve[0]:.3g} ms p99 {solve[1]:.3g} ms max {solve[2]:.3g} ms")


class LatestInput:
    """A one-slot mailbox: a new input replaces the pending one (which is then dropped)."""

    def __init__(self):
        self._cond = threading.Condition()
        self._item = None
        self._closed = False

    def put(self, item) -> bool:
        """Store ``item``; True when it replaced an input nobody had taken yet."""
        with self._cond:
            replaced = self._item is not None
            self._item = item
            self._cond.notify()
            return replaced

    def get(self, timeout: float | None = None):
        """The pending input, waiting up to ``timeout``; ``None`` on timeout or when closed."""
        with self._cond:
            if self._item is None and not self._closed:
                self._cond.wait(timeout)
            item, self._item = self._item, None
            return item

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()


class SolveLoop:
    """The worker thread both transports use: solve the newest input, publish its pose."""

    def __init__(self, service: FkService, publish, name: str = "glpma_fk-solver"):
        self.service = service
        self.publish = publish
        self.mailbox = LatestInput()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "SolveLoop":
        self._thread.start()
        return self

    def submit(self, legs_m, stamp_ns: int) -> None:
        """Called by the transport on arrival of leg lengths (metres)."""
        if self.mailbox.put((legs_m, int(stamp_ns), time.perf_counter())):
            self.service.note_dropped(1)

    def _run(self) -> None:
        while not self._stop.is_set():
            item = self.mailbox.get(timeout=0.1)
            if item is None:
                continue
            outcome = self.service.handle(*item)
            if outcome.pose is not None:
                try:
                    self.publish(outcome.pose)
                except Exception as exc:  # noqa: BLE001 - a failed publish must not stop the loop
                    self.service.log.error(f"publishing the pose failed: {exc!r}")

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        self.mailbox.close()
        self._thread.join(timeout)
