"""The ``glpma_fk`` node without a transport.

:class:`FkService` owns the :class:`~glpma_ros.estimation.estimator.Estimator` and does
everything a transport should not have to know about: parameters and their
runtime changes, unit conversion (metres on topics, the config's unit inside),
input validation with a one-line reason, the publish decision (converged, or -- redundant legs --
inconsistent with the faulty leg left out), and the collaborators it holds: the statistics
(``stats``, :mod:`.stats`), the legs' health (``leg_health``, :mod:`.leg_health`), the diagnostics
report built from their snapshots (:mod:`.diagnostics`) and the assembly modes on request
(``modes``, :mod:`.assembly_modes`), each with its own lock.  The threads both
transports share are in :mod:`.loops`.

A transport (``dds/node.py``, ``ros_node.py``) only converts messages:
``SolveLoop.offer(legs_m, arrival_ns)`` (``input_type`` float64_multi_array) or
``SolveLoop.offer(JointStateInput(...), msg.header.stamp)`` (``joint_state``) in,
``publish(PoseOutput)`` out -- then, from the extras thread,
``publish_extras(service.extras(outcome, ...))``: TF, covariance, twist and markers
(:mod:`.outputs`) -- ``service.diagnostics()`` every ``diagnostics_period_s`` from a
:class:`~glpma_ros.node.loops.ReportLoop`, and ``AssemblyModesLoop.request(arrival_ns)`` on
``~/request_assembly_modes`` with
``publish(PoseArrayOutput)`` on ``~/assembly_modes``.  Every assembly mode of the last input
received is computed by :func:`~glpma_ros.modes.multistart.solve_all` in a worker process
(:mod:`glpma_ros.node.modes_worker`), so that the real-time solve loop keeps its latency.
"""
from __future__ import annotations

import gc
import logging
import math
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import check_units, load_manipulator, plausible_band, resolve_config
from ..errors import InputError
from ..estimation.estimator import Estimator
from ..runtime.compat import check_numba
from ..runtime.precompile import cache_counts, describe_cache_use, warm_up_pose
from . import params as P
from .assembly_modes import AssemblyModes
from .diagnostics import DiagnosticReport, Diagnostics
from .input_topic import input_topic, model_is_actuated
from .leg_health import LegHealth
from .outputs import OUTPUT_PARAMS, OutputBuilder
from .stats import LogThrottle, Statistics

#: solvers warmed up at start (with the configured one): the papers' real-time solvers
WARM_UP_SOLVERS = ("glpma", "g3pcx", "rcga")


def default_joint_names(n_legs: int) -> list:
    """``leg_1`` .. ``leg_n``: the joint names when parameter ``joint_names`` is empty."""
    return [f"leg_{i + 1}" for i in range(n_legs)]


@dataclass(frozen=True)
class PoseOutput:
    """A pose to publish: metres, unit quaternion [x, y, z, w], stamp = arrival of the legs."""

    stamp_ns: int
    frame_id: str
    position: tuple
    orientation: tuple


@dataclass(frozen=True)
class JointStateInput:
    """A ``sensor_msgs/JointState`` as far as the node reads it: joint names, positions (metres)
    and velocities (m/s; empty when the message has none)."""

    names: tuple
    positions: tuple
    velocities: tuple = ()

@dataclass
class Outcome:
    """What became of one input: a pose to publish, or the reason there is none."""

    pose: PoseOutput | None
    reason: str | None = None
    estimate: object = None     # the estimator's Estimate, when it ran
    latency_s: float = 0.0
    legs: np.ndarray | None = None         # the input's leg lengths, config unit
    leg_rates_m: np.ndarray | None = None  # their rates (m/s) from a JointState's velocities, if any


class FkService:
    """Leg lengths (metres) in, poses (metres) out, with the estimator's warm state in between."""

    def __init__(self, parameters: dict | None = None, *, logger=None, node_name: str = P.NODE_NAME):
        """``parameters``: name -> value (unknown names are an error, missing ones take their default);
        ``logger``: anything with ``debug/info/warning/error(str)`` (``logging.Logger``, an rclpy logger).
        Raises :class:`~glpma_ros.errors.ConfigError` or :class:`InputError` with a one-line reason."""
        self.log = logger or logging.getLogger(node_name)
        self.node_name = node_name
        check_numba()
        values = P.defaults()
        for name, value in (parameters or {}).items():
            values[name] = P.coerce(name, value)
        self.config_path = resolve_config(values["manipulator_config"])
        self.model = load_manipulator(self.config_path)
        self.metres_per_unit = float(self.model.metres_per_unit)
        #: leg lengths (m) below this divide by metres_per_unit without overflow
        self._overflow_m = sys.float_info.max * min(self.metres_per_unit, 1.0)
        self._initial_x = self._initial_variables(values["initial_pose"])
        # the estimator's warm-start state, mirrored so that a rebuilt estimator can keep it
        self._warm_x = self._initial_x
        self.estimator = self._build_estimator(values, self._warm_x)
        self.params = values
        self.stats = Statistics()
        self._check_joint_names(values["joint_names"])
        self._check_frames(values)
        self.leg_health = LegHealth(self.model)
        self.outputs = OutputBuilder(self.model, values["urdf_prefix"])
        self.log_throttle = LogThrottle()    # one log line a second per rejection reason
        self._lock = threading.RLock()          # estimator and parameters (statistics and modes: their own)
        self._warmed: set = set()               # solvers warm_up() has run
        self.modes = AssemblyModes(self.model, self.config_path, self.to_config_unit, lambda: self.params,
                                   warm_legs=self.model.inverse_kinematics(self._warm_up_variables()))
        self._diagnostics = Diagnostics(self)

    # -- construction --------------------------------------------------------------------
    def _initial_variables(self, initial_pose):
        if not initial_pose:
            return None
        try:
            return self.model.check_variables(initial_pose)
        except InputError as exc:
            raise InputError(f"parameter 'initial_pose': {exc}") from None

    def _check_joint_names(self, names) -> None:
        if names and len(names) != self.model.n_legs:
            raise InputError(f"parameter 'joint_names' must name the {self.model.n_legs} legs in order "
                             f"(or be empty for {', '.join(default_joint_names(self.model.n_legs))}), "
                             f"got {len(names)} names")

    @staticmethod
    def _check_frames(values: dict) -> None:
        if values["child_frame_id"] == values["frame_id"]:
            raise InputError(f"parameters 'frame_id' and 'child_frame_id' must differ (a transform from "
                             f"'{values['frame_id']}' to itself), got both {values['frame_id']!r}")

    def _build_estimator(self, values: dict, warm_x) -> Estimator:
        def opt(name):           # 0 = the papers' setting
            return values[name] or None
        return Estimator(self.model, solver=values["solver"], time_budget_s=values["time_budget_ms"] * 1e-3,
                         tolerance=values["tolerance"], seed=values["seed"], polish=values["polish"],
                         initial_pose=warm_x, population=opt("population"),
                         local_population=opt("local_population"), ls_interval=opt("ls_interval"),
                         ls_intensity=opt("ls_intensity"),
                         leg_noise_std=values["leg_noise_std"] / self.metres_per_unit,
                         exclude_faulty_leg=values["exclude_faulty_leg"])

    @property
    def deadline_s(self) -> float:
        return (self.params["deadline_ms"] or self.params["time_budget_ms"]) * 1e-3

    @property
    def warm_x(self):
        """The solver variables the next input starts from (None: a cold start)."""
        return self._warm_x

    @property
    def warmed_up(self) -> frozenset:
        """The solvers :meth:`warm_up` has run."""
        return frozenset(self._warmed)

    @property
    def frame_id(self) -> str:
        return self.params["frame_id"]

    @property
    def input_type(self) -> str:
        return self.params["input_type"]

    @property
    def input_topic(self) -> str:
        """The input topic's name (:mod:`glpma_ros.node.input_topic`): ``joint_states``, ``leg_lengths``, or
        ``actuator_positions`` for an actuated family."""
        return input_topic(self.input_type, model_is_actuated(self.model))

    @property
    def joint_names(self) -> list:
        """The legs' joint names in leg order (``joint_names``, or ``leg_1`` .. ``leg_n``)."""
        return list(self.params["joint_names"]) or default_joint_names(self.model.n_legs)

    def describe(self) -> str:
        m = self.model
        if self.input_type == P.INPUT_JOINT_STATE:
            source = f"input joint_states ({', '.join(self.joint_names)})"
        else:
            source = f"input {self.input_topic}"
        offsets = "" if m.leg_offsets is None else \
            f", leg_offsets [{', '.join(f'{v:g}' for v in m.leg_offsets)}] {m.unit} added to the legs"
        name = Path(str(getattr(m, "source", ""))).name
        return (f"{m.kind} ({name}, {m.n_legs} legs, config unit {m.unit}{offsets}), "
                f"{source}, solver {self.params['solver']}, budget {self.params['time_budget_ms']:g} ms, "
                f"{'warm start from initial_pose' if self._initial_x is not None else 'cold start'}")

    def _warm_up_variables(self) -> np.ndarray:
        """A pose to warm up with: ``initial_pose``, or any pose clear of the base joints."""
        if self._initial_x is not None:
            return self._initial_x
        return warm_up_pose(self.model)

    def warm_up(self, solvers=None, budget_ms: float = 50.0, max_tries: int = 5) -> float:
        """Run every path of each solver -- cold and warm start, with and without the
        refinement (without it the evolutionary loops run in the warm stages too) -- until it
        runs within its budget, so that Numba has compiled everything before the first real
        input.  ``solvers``: default :data:`WARM_UP_SOLVERS` and the configured one; a switch
        to another solver at runtime warms that one up first (:meth:`set_parameters`).
        The warm-start state and the statistics are left untouched (the service lock is not
        held: inputs are solved meanwhile).  Returns the seconds spent."""
        t0 = time.perf_counter()
        with self._lock:
            params = dict(self.params)
        if solvers is None:
            solvers = tuple(dict.fromkeys((*WARM_UP_SOLVERS, params["solver"])))
        x = self._warm_up_variables()
        # not exactly x's legs: a warm start must then search, not stop at its first individual
        legs = self.model.inverse_kinematics(x) * (1.0 + 1e-3)
        if self.model.leg_limits is not None:
            legs = np.clip(legs, *self.model.leg_limits)
        for k, name in enumerate(solvers, 1):
            t_solver = time.perf_counter()
            counts = cache_counts()
            for start in (None, x):
                for polish in (True, False):
                    values = dict(params, solver=name, time_budget_ms=budget_ms, polish=polish)
                    for _ in range(max_tries):
                        t = time.perf_counter()
                        try:
                            self._build_estimator(values, start).estimate(legs)
                        except Exception as exc:  # noqa: BLE001 - reported, not fatal
                            self.log.warning(f"warm-up with {name} failed: {exc}")
                            break
                        if time.perf_counter() - t < 3e-3 * budget_ms:
                            break
            self._warmed.add(name)
            loaded, compiled = (after - before for after, before in zip(cache_counts(), counts))
            self._log_warm_up(name, k, len(solvers), time.perf_counter() - t_solver, loaded, compiled)
        # everything loaded so far lives as long as the node: keep it out of the cyclic
        # collector's scans, whose pauses would otherwise land in the real-time path
        from ..estimation.covariance import warm_up as warm_up_covariance
        warm_up_covariance()
        gc.collect()
        gc.freeze()
        return time.perf_counter() - t0

    def _log_warm_up(self, name: str, k: int, n: int, took_s: float, loaded: int, compiled: int) -> None:
        """One line per solver warmed up: what Numba compiled (first start after an install) or
        loaded from its cache, counted (:func:`~glpma_ros.runtime.precompile.cache_counts`), not guessed."""
        how = describe_cache_use(loaded, compiled)
        if compiled:
            how += " (first start; `glpma-fk precompile` does this ahead)"
        self.log.info(f"warm-up [{k}/{n}] {name}: {how} in {took_s:.1f} s")

    # -- inputs -------------------------------------------------------------------------------
    def _leg_indices(self, names, positions) -> list:
        """Where each leg of :attr:`joint_names` is in a JointState's ``names``."""
        names = list(names)
        if len(names) != len(positions):
            raise InputError(f"joint_states has {len(names)} names but {len(positions)} positions")
        index: dict = {}
        for i, name in enumerate(names):
            index.setdefault(name, []).append(i)
        found_at = []
        for leg in self.joint_names:
            found = index.get(leg)
            if not found:
                raise InputError(f"joint_states has no joint '{leg}'")
            if len(found) > 1:
                raise InputError(f"joint_states names joint '{leg}' {len(found)} times")
            found_at.append(found[0])
        return found_at

    def legs_from_joint_state(self, names, positions) -> list:
        """The leg lengths (metres, leg order) in a JointState's ``names`` / ``positions``: each
        leg by its name in :attr:`joint_names`, in any order; other joints are ignored.
        :class:`InputError` with the reason when a leg is missing or named twice, or when there
        are not as many positions as names."""
        positions = list(positions)
        return [positions[i] for i in self._leg_indices(names, positions)]

    def leg_rates_from_joint_state(self, js: JointStateInput):
        """The legs' rates (m/s, leg order) from a JointState's velocities, or None when it has
        none (``velocity`` empty, as the message allows) or they are not finite."""
        if not js.velocities or len(js.velocities) != len(js.names):
            return None
        try:
            rates = np.array([js.velocities[i] for i in self._leg_indices(js.names, js.positions)], dtype=float)
        except (InputError, TypeError, ValueError):
            return None
        return rates if np.all(np.isfinite(rates)) else None

    def _legs_m(self, legs_m):
        """An input (leg lengths in metres, or a :class:`JointStateInput`) as leg lengths in metres."""
        if isinstance(legs_m, JointStateInput):
            return self.legs_from_joint_state(legs_m.names, legs_m.positions)
        return legs_m

    def handle_joint_state(self, names, positions, stamp_ns: int, arrival: float | None = None,
                           velocities=()) -> Outcome:
        """Solve one ``sensor_msgs/JointState``: ``names``, ``positions`` (metres), ``velocities``
        (m/s, may be empty) and its ``header.stamp`` (ns), which goes on the pose.  Same path as
        :meth:`handle`."""
        return self.handle(JointStateInput(tuple(names), tuple(positions), tuple(velocities)), stamp_ns, arrival)

    def to_config_unit(self, raw) -> np.ndarray:
        """An input's leg lengths (metres, or a :class:`JointStateInput`) in the config's unit, with the
        config's ``leg_offsets`` added: the lengths |B_i - A_i| the estimator solves for."""
        if model_is_actuated(self.model):       # actuator positions: radians, or metres for prismatic ones
            return self.model.legs_from_sensors(self.model.readings_from_si(self._legs_m(raw)))
        try:
            legs_m = np.asarray(self._legs_m(raw), dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError("leg lengths are not numbers") from None
        if legs_m.size == self.model.n_legs:
            # the usual input, every leg within the plausible band (finite, no unit mistake possible):
            # the checks below would pass; deciding it on Python floats saves their NumPy calls
            given = legs_m.tolist()
            if -self._overflow_m < min(given) and max(given) < self._overflow_m:
                legs = legs_m / self.metres_per_unit
                values = legs.tolist()
                lo, hi = plausible_band(self.model)
                if lo <= min(values) and max(values) <= hi:
                    return self.model.legs_from_sensors(legs)      # the config's leg_offsets added
        with np.errstate(over="ignore", invalid="ignore"):
            legs = legs_m / self.metres_per_unit
        if legs.size == self.model.n_legs and np.all(np.isfinite(legs_m)) and not np.all(np.isfinite(legs)):
            raise InputError(f"leg lengths too large to express in {self.model.unit}")
        if legs.size == self.model.n_legs:   # e.g. millimetres sent on the topic: a reason naming units
            check_units(self.model, legs, "m", "topics are in metres (REP 103)")
        return self.model.legs_from_sensors(legs)      # the config's leg_offsets added

    def handle(self, legs_m, stamp_ns: int, arrival: float | None = None) -> Outcome:
        """Solve one input.  ``legs_m``: leg lengths in metres, or a :class:`JointStateInput`;
        ``stamp_ns``: the pose's header.stamp (the arrival time of a leg_lengths message, the
        header.stamp of a JointState); ``arrival``: ``time.perf_counter()`` at arrival, for the
        latency and the deadline (default: now).  Never raises."""
        arrival = time.perf_counter() if arrival is None else arrival
        st = self.stats
        with self._lock:
            st.record_handled()
            try:
                legs = self.to_config_unit(legs_m)
                estimate = self.estimator.estimate(legs)
            except InputError as exc:
                return self._reject(str(exc), str(exc), None, arrival)
            except Exception as exc:  # noqa: BLE001 - the node must survive anything
                self.log.error(f"internal error while solving: {exc!r}")
                return self._reject(f"internal error: {exc}", "internal error", None, arrival)
            st.record_estimate(estimate)
            self.leg_health.note(estimate)
            if not estimate.publishable:
                return self._reject(f"{estimate.status}: {estimate.message}", estimate.status, estimate, arrival)
            st.record_published(estimate.conditioning,
                                math.sqrt(estimate.fitness / self.model.n_res) * self.metres_per_unit)
            self._warm_x = np.array(estimate.x, dtype=float)
            pose = estimate.pose
            out = PoseOutput(int(stamp_ns), self.frame_id,
                             tuple((np.asarray(pose.position, dtype=float) * self.metres_per_unit).tolist()),
                             tuple(np.asarray(pose.orientation, dtype=float).tolist()))
            rates = self.leg_rates_from_joint_state(legs_m) if isinstance(legs_m, JointStateInput) else None
            return Outcome(out, None, estimate, self._finish(arrival), legs, rates)

    def extras(self, outcome: Outcome, params: dict | None = None, subscribed=None):
        """TF, covariance, twist and markers (:class:`~glpma_ros.node.outputs.ExtraOutputs`) of a
        published pose, as the ``publish_*`` parameters (``params``, default the current ones)
        ask and, when ``subscribed`` (names of :data:`~glpma_ros.node.outputs.OUTPUT_PARAMS`) is
        given, only those with a subscriber; None when none is left.  Called for the poses in
        their order (by the :class:`~glpma_ros.node.loops.ExtrasLoop` thread), after each went out."""
        params = self.params if params is None else params
        if outcome.pose is None:
            return None
        self.outputs.check_limits(outcome)      # the config's passive-joint limits, for /diagnostics
        wanted = {name: params[key] and (subscribed is None or name in subscribed)
                  for name, key in OUTPUT_PARAMS.items()}
        if not any(wanted.values()):
            self.outputs.reset_previous()      # no finite difference across a time it was off
            return None
        # the joints' rates come from the twist: computed for them when publish_twist is on
        twist_for_joints = wanted["joint_states"] and params["publish_twist"]
        if not all(wanted[name] == params[key] for name, key in OUTPUT_PARAMS.items()):
            params = {**params, **{OUTPUT_PARAMS[name]: on for name, on in wanted.items()}}
        extras = self.outputs.build(outcome, params, twist_for_joints)
        return extras if extras.any else None

    def extras_on(self) -> bool:
        """Whether any extra output is switched on or the config has passive-joint limits to check (else no
        pose is handed to the extras thread)."""
        params = self.params
        return self.outputs.passive_limits is not None or any(params[key] for key in OUTPUT_PARAMS.values())

    def note_extras_time(self, seconds: float) -> None:
        """Time the extras thread spent on the extra outputs of one pose: building, converting, writing."""
        self.stats.record_extras_time(seconds)

    def note_extras_handoff(self, seconds: float) -> None:
        """Time the solving thread spent handing a pose over to the extras thread."""
        self.stats.record_extras_handoff(seconds)

    def note_extras_dropped(self, count: int) -> None:
        """Poses whose extra outputs were dropped: the extras thread was ``EXTRAS_BACKLOG`` behind."""
        self.stats.record_extras_dropped(count)

    def _finish(self, arrival: float) -> float:
        latency = time.perf_counter() - arrival
        self.stats.record_latency(latency, latency > self.deadline_s)
        return latency

    def _reject(self, reason: str, key: str, estimate, arrival: float) -> Outcome:
        self.stats.record_rejected(key, reason)
        suppressed = self.log_throttle(key)
        if suppressed is not None:
            more = f" (+{suppressed} similar suppressed)" if suppressed else ""
            self.log.warning(f"input rejected: {reason}{more}")
        return Outcome(None, reason, estimate, self._finish(arrival))

    def note_dropped(self, count: int = 1) -> None:
        """The transport replaced ``count`` pending inputs by newer ones before solving them.
        Does not wait for a solve in progress (the reader thread calls it)."""
        self.stats.record_dropped(count)

    # -- reports --------------------------------------------------------------------------------
    def diagnostics(self, pause=lambda: None) -> DiagnosticReport:
        """The current statistics as a DiagnosticStatus (:class:`~glpma_ros.node.diagnostics.Diagnostics`);
        starts a new reporting period.  Holds no lock of the service: call it from any thread;
        ``pause()`` runs between the stages of the work (:class:`~glpma_ros.node.loops.ReportLoop`
        sleeps there)."""
        return self._diagnostics.report(pause)

    def summary(self) -> str:
        """One line of totals, for the log at shutdown."""
        return self._diagnostics.summary()

    # -- parameters -----------------------------------------------------------------------------
    def set_parameters(self, changes: dict) -> tuple[bool, str]:
        """Apply ``changes`` (name -> value) atomically.  Returns ``(True, "")`` or
        ``(False, reason)``; on failure nothing changes.  The warm-start state survives every
        change except a new ``initial_pose``, which restarts tracking from it.  A solver that
        was not warmed up yet is warmed up first (Numba loads or compiles it; seconds), without
        holding up the solve loop."""
        solver = changes.get("solver")
        if isinstance(solver, str) and solver in P.SOLVER_CHOICES and solver not in self._warmed:
            self.log.info(f"warming up solver {solver} before switching to it")
            self.warm_up(solvers=(solver,))
        with self._lock:
            values = dict(self.params)
            try:
                for name, value in changes.items():
                    value = P.coerce(name, value)
                    if P.SPECS[name].read_only and value != self.params[name]:
                        raise InputError(f"parameter '{name}' is read-only while the node runs "
                                         f"(restart the node to change it)")
                    values[name] = value
                self._check_joint_names(values["joint_names"])
                self._check_frames(values)
                initial_x = self._initial_variables(values["initial_pose"])
                warm_x = initial_x if values["initial_pose"] != self.params["initial_pose"] else self._warm_x
                estimator = self._build_estimator(values, warm_x)
            except InputError as exc:
                return False, str(exc)
            except (TypeError, ValueError) as exc:
                return False, f"invalid parameters: {exc}"
            changed = {k: v for k, v in values.items() if v != self.params[k]}
            if "initial_pose" in changed:
                self.outputs.reset()        # tracking restarts: no velocity across the jump
            self.params, self.estimator = values, estimator
            self._initial_x, self._warm_x = initial_x, warm_x
            if changed:
                self.log.info("parameters set: " + ", ".join(f"{k}={v!r}" for k, v in changed.items()))
            return True, ""
