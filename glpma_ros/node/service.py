"""The ``glpma_fk`` node without a transport.

:class:`FkService` owns the :class:`~glpma_ros.estimation.estimator.Estimator` and does
everything a transport should not have to know about: parameters and their
runtime changes, the publish decision (converged, or -- redundant legs --
inconsistent with the faulty leg left out), and the collaborators it holds: the input conversion
(``inputs``, :mod:`.inputs`: JointState decoding, metres on topics, the config's unit inside,
a one-line reason for a bad input), the warm-up (``warming``, :mod:`.warm_up`), the statistics
(``stats``, :mod:`.stats`), the legs' health (``leg_health``, :mod:`.leg_health`), the diagnostics
report built from their snapshots (``reporter``, :mod:`.diagnostics`) and the assembly modes on request
(``modes``, :mod:`.assembly_modes`), each with its own lock.  The threads both
transports share are in :mod:`.loops`.

A transport (``dds/node.py``, ``ros_node.py``) only converts messages:
``SolveLoop.offer_message(data, arrival_ns)`` (a ``leg_lengths`` message's bytes: solved and its pose's message
written in one compiled call, :mod:`.pose_lane`, where that applies) or ``SolveLoop.offer(legs_m, arrival_ns)``
(``input_type`` float64_multi_array) or ``SolveLoop.offer(JointStateInput(...), msg.header.stamp)``
(``joint_state``) in, ``publish(PoseOutput)`` (or an :class:`EncodedPose`: the message's bytes) out -- then, from
the extras thread,
``publish_extras(service.extras(outcome, ...))``: TF, covariance, twist and markers
(:mod:`.outputs`) -- ``service.diagnostics()`` every ``diagnostics_period_s`` from a
:class:`~glpma_ros.node.loops.ReportLoop`, and ``AssemblyModesLoop.request(arrival_ns)`` on
``~/request_assembly_modes`` with
``publish(PoseArrayOutput)`` on ``~/assembly_modes``.  Every assembly mode of the last input
received is computed by :func:`~glpma_ros.modes.multistart.solve_all` in a worker process
(:mod:`glpma_ros.node.modes_worker`), so that the real-time solve loop keeps its latency.
"""
from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import load_manipulator, resolve_config
from ..errors import InputError
from ..estimation.estimator import Estimator
from ..runtime.compat import check_numba
from . import params as P
from .assembly_modes import AssemblyModes
from .diagnostics import DiagnosticReport, Diagnostics
from .input_topic import input_topic, model_is_actuated
from .inputs import InputConverter, JointStateInput, default_joint_names
from .leg_health import LegHealth
from .outputs import OUTPUT_PARAMS, OutputBuilder
from .pose_lane import ACCEPTED, NOT_APPLICABLE, PoseLane
from .stats import LogThrottle, Statistics
from .warm_up import WarmUp, warm_up_variables


@dataclass(frozen=True)
class PoseOutput:
    """A pose to publish: metres, unit quaternion [x, y, z, w], stamp = arrival of the legs."""

    stamp_ns: int
    frame_id: str
    position: tuple
    orientation: tuple


@dataclass(frozen=True)
class EncodedPose:
    """A pose to publish as its ``geometry_msgs/PoseStamped`` message's bytes (CDR_LE), written by the
    one-call way (:mod:`.pose_lane`); its :class:`PoseOutput` is built after the write
    (:meth:`FkService.account`)."""

    message: bytes


@dataclass
class Outcome:
    """What became of one input: a pose to publish, or the reason there is none."""

    pose: PoseOutput | EncodedPose | None
    reason: str | None = None
    estimate: object = None     # the estimator's Estimate, when it ran (the one-call way: built by account)
    latency_s: float = 0.0
    legs: np.ndarray | None = None         # the input's leg lengths, config unit
    leg_rates_m: np.ndarray | None = None  # their rates (m/s) from a JointState's velocities, if any
    arrival: float | None = None           # perf_counter() at arrival, until FkService.account took it
    #: the one-call way's warm-stage output, elapsed seconds, stamp, frame id and metres per unit, from which
    #: account builds the estimate and the PoseOutput once the EncodedPose is out (None otherwise)
    warm: tuple | None = None


class FkService:
    """Leg lengths (metres) in, poses (metres) out: the parameters, the estimator (which keeps its
    warm state; the service reads it through :attr:`Estimator.warm_x
    <glpma_ros.estimation.estimator.Estimator.warm_x>`) and the publish decision; the input
    conversion (:class:`~glpma_ros.node.inputs.InputConverter`) and the warm-up
    (:class:`~glpma_ros.node.warm_up.WarmUp`) are collaborators of their own."""

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
        self._initial_x = self._initial_variables(values["initial_pose"])
        self.estimator = self._build_estimator(values, self._initial_x)
        self.params = values
        self.stats = Statistics()
        self._check_joint_names(values["joint_names"])
        self._check_frames(values)
        self.inputs = InputConverter(self.model, values["joint_names"])
        # a leg_lengths message in one compiled call (pose_lane); not for an actuated family's readings
        self._lane = None if self.inputs.readings is None else PoseLane(self.model.n_legs,
                                                                        self.estimator.warm_output_size)
        self.leg_health = LegHealth(self.model)
        self.outputs = OutputBuilder(self.model, values["urdf_prefix"])
        self.log_throttle = LogThrottle()    # one log line a second per rejection reason
        self._lock = threading.RLock()          # estimator and parameters (statistics and modes: their own)
        self.warming = WarmUp(self.model, self._build_estimator, self.log)
        self.modes = AssemblyModes(self.model, self.config_path, self.inputs.to_config_unit, lambda: self.params,
                                   warm_legs=self.model.inverse_kinematics(self._warm_up_variables()))
        self.reporter = Diagnostics(node_name, self.model, lambda: self.params, self.inputs, self.stats,
                                    self.modes, self.leg_health, self.outputs,
                                    warm_state=lambda: self.estimator.warm_x is not None)

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
        """The solver variables the next input starts from (None: a cold start): the estimator's."""
        return self.estimator.warm_x

    @property
    def warmed_up(self) -> frozenset:
        """The solvers :meth:`warm_up` has run."""
        return self.warming.warmed

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
        return self.inputs.joint_names

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
        return warm_up_variables(self.model, self._initial_x)

    def warm_up(self, solvers=None, budget_ms: float = 50.0, max_tries: int = 5) -> float:
        """Numba's compiled code of ``solvers`` (default
        :data:`~glpma_ros.node.warm_up.WARM_UP_SOLVERS` and the configured
        one) loaded before the first real input (:meth:`WarmUp.run <glpma_ros.node.warm_up.WarmUp.run>`);
        a switch to another solver at runtime warms that one up first (:meth:`set_parameters`).
        The warm-start state and the statistics are left untouched (the service lock is not
        held: inputs are solved meanwhile).  Returns the seconds spent."""
        with self._lock:
            params = dict(self.params)
        return self.warming.run(params, self._warm_up_variables(), solvers, budget_ms, max_tries)

    # -- inputs -------------------------------------------------------------------------------
    def legs_from_joint_state(self, names, positions) -> list:
        """The leg lengths (metres, leg order) in a JointState's ``names`` / ``positions``
        (:meth:`InputConverter.legs_from_joint_state <glpma_ros.node.inputs.InputConverter.legs_from_joint_state>`)."""
        return self.inputs.legs_from_joint_state(names, positions)

    def handle_joint_state(self, names, positions, stamp_ns: int, arrival: float | None = None,
                           velocities=()) -> Outcome:
        """Solve one ``sensor_msgs/JointState``: ``names``, ``positions`` (metres), ``velocities``
        (m/s, may be empty) and its ``header.stamp`` (ns), which goes on the pose.  Same path as
        :meth:`handle`."""
        return self.handle(JointStateInput(tuple(names), tuple(positions), tuple(velocities)), stamp_ns, arrival)

    def to_config_unit(self, raw) -> np.ndarray:
        """An input's leg lengths (metres, or a :class:`JointStateInput`) in the config's unit, with the
        config's ``leg_offsets`` added (:class:`~glpma_ros.node.inputs.InputConverter`)."""
        return self.inputs.to_config_unit(raw)

    def handle(self, legs_m, stamp_ns: int, arrival: float | None = None) -> Outcome:
        """Solve one input and account for it (:meth:`solve`, then :meth:`account`).  ``legs_m``: leg lengths in
        metres, or a :class:`JointStateInput`; ``stamp_ns``: the pose's header.stamp (the arrival time of a
        leg_lengths message, the header.stamp of a JointState); ``arrival``: ``time.perf_counter()`` at arrival,
        for the latency and the deadline (default: now).  Never raises."""
        outcome = self.solve(legs_m, stamp_ns, arrival)
        self.account(outcome)
        return outcome

    def solve(self, legs_m, stamp_ns: int, arrival: float | None = None) -> Outcome:
        """What :meth:`handle` does before the pose can go out: the input converted, the estimate, the publish
        decision and the pose; a rejection is accounted for at once.  A pose's statistics, the legs' health
        and the latency are left to :meth:`account`, which a transport calls once the pose is written (the
        solve loop: :class:`~glpma_ros.node.loops.SolveLoop`).  Never raises."""
        arrival = time.perf_counter() if arrival is None else arrival
        with self._lock:
            return self._settle(self._estimate_input, (legs_m,), legs_m, stamp_ns, arrival)

    def solve_message(self, data, stamp_ns: int, arrival: float | None = None) -> Outcome | None:
        """:meth:`solve` for a ``std_msgs/Float64MultiArray`` message's bytes (``data``, as taken) in one compiled
        call (:mod:`.pose_lane`): when the warm stage is the estimate, the outcome's pose is an
        :class:`EncodedPose`, written before anything else is built (:meth:`account` builds the rest); a
        declined warm stage goes on to the search as in :meth:`solve`.  None when the one-call way does not apply
        (an actuated family, no warm start, redundant legs, another layout or encoding, a reading outside the
        plausible band): nothing was done, and the caller decodes the message and calls :meth:`solve`."""
        lane = self._lane
        if lane is None:
            return None
        arrival = time.perf_counter() if arrival is None else arrival
        with self._lock:
            estimator = self.estimator
            warm = estimator.warm_lane()
            if warm is None:
                return None
            t0 = time.perf_counter()
            frame_id, metres_per_unit = self.frame_id, self.metres_per_unit
            code, legs, out = lane.run(data, stamp_ns, self.inputs.readings, warm, frame_id, metres_per_unit)
            if code == ACCEPTED:
                estimator.advance(legs, out)
                return Outcome(EncodedPose(lane.message(frame_id).tobytes()), legs=legs, arrival=arrival,
                               warm=(out, time.perf_counter() - t0, int(stamp_ns), frame_id, metres_per_unit))
            if code == NOT_APPLICABLE:
                return None
            return self._settle(self._finish_warm, (legs, out, t0), None, stamp_ns, arrival)

    def _estimate_input(self, legs_m):
        """``(legs, estimate)`` of an input (raises :class:`InputError`)."""
        # a message's floats, when the everyday conditions hold: converted and solved warm in one
        # compiled call (Estimator.estimate_readings), else (None) converted and checked the long way
        done = self.estimator.estimate_readings(legs_m, *self.inputs.readings) \
            if type(legs_m) is tuple and self.inputs.readings is not None else None
        if done is not None:
            return done
        legs = self.inputs.to_config_unit(legs_m)
        return legs, self.estimator.estimate(legs)

    def _finish_warm(self, legs, out, t0: float):
        """``(legs, estimate)`` after a warm stage the one-call way ran and its rule declined."""
        return legs, self.estimator.finish_warm(legs, out, t0)

    def _settle(self, work, args, legs_m, stamp_ns: int, arrival: float) -> Outcome:
        """The outcome of ``work(*args)`` -> ``(legs, estimate)`` for input ``legs_m`` (None: a message's bytes):
        the publish decision and the pose, or the rejection (accounted for).  Called with the lock held."""
        try:
            legs, estimate = work(*args)
        except InputError as exc:
            return self._reject(str(exc), str(exc), None, arrival)
        except Exception as exc:  # noqa: BLE001 - the node must survive anything
            self.log.error(f"internal error while solving: {exc!r}")
            return self._reject(f"internal error: {exc}", "internal error", None, arrival)
        if not estimate.publishable:
            return self._reject(f"{estimate.status}: {estimate.message}", estimate.status, estimate, arrival)
        out = self._pose_output(estimate, int(stamp_ns), self.frame_id, self.metres_per_unit)
        rates = self.inputs.leg_rates_from_joint_state(legs_m) if isinstance(legs_m, JointStateInput) else None
        return Outcome(out, None, estimate, 0.0, legs, rates, arrival)

    @staticmethod
    def _pose_output(estimate, stamp_ns: int, frame_id: str, metres_per_unit: float) -> PoseOutput:
        pose = estimate.pose
        position = np.asarray(pose.position, dtype=float) * metres_per_unit
        return PoseOutput(stamp_ns, frame_id, tuple(position.tolist()),
                          tuple(np.asarray(pose.orientation, dtype=float).tolist()))

    def account(self, outcome: Outcome) -> None:
        """The statistics of a pose :meth:`solve` returned (once; a rejection's were recorded by :meth:`solve`):
        the input handled, its estimate, the legs' health, the latency from its arrival to now."""
        if outcome.arrival is None:
            return
        arrival, outcome.arrival = outcome.arrival, None
        if outcome.warm is not None:        # the one-call way's pose is out: its estimate and PoseOutput now
            out, elapsed_s, stamp_ns, frame_id, metres_per_unit = outcome.warm
            outcome.warm = None
            outcome.estimate = self.estimator.warm_estimate(out, elapsed_s)
            outcome.pose = self._pose_output(outcome.estimate, stamp_ns, frame_id, metres_per_unit)
        estimate, st = outcome.estimate, self.stats
        st.record_handled()
        st.record_estimate(estimate)
        self.leg_health.note(estimate)
        st.record_published(estimate.conditioning,
                            math.sqrt(estimate.fitness / self.model.n_res) * self.metres_per_unit)
        outcome.latency_s = self._finish(arrival)

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
        self.stats.record_handled()
        if estimate is not None:
            self.stats.record_estimate(estimate)
            self.leg_health.note(estimate)
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
        return self.reporter.report(pause)

    def summary(self) -> str:
        """One line of totals, for the log at shutdown."""
        return self.reporter.summary()

    # -- parameters -----------------------------------------------------------------------------
    def set_parameters(self, changes: dict) -> tuple[bool, str]:
        """Apply ``changes`` (name -> value) atomically.  Returns ``(True, "")`` or
        ``(False, reason)``; on failure nothing changes.  The warm-start state survives every
        change except a new ``initial_pose``, which restarts tracking from it.  A solver that
        was not warmed up yet is warmed up first (Numba loads or compiles it; seconds), without
        holding up the solve loop."""
        solver = changes.get("solver")
        if isinstance(solver, str) and solver in P.SOLVER_CHOICES and solver not in self.warming.warmed:
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
                warm_x = initial_x if values["initial_pose"] != self.params["initial_pose"] else self.warm_x
                estimator = self._build_estimator(values, warm_x)
            except InputError as exc:
                return False, str(exc)
            except (TypeError, ValueError) as exc:
                return False, f"invalid parameters: {exc}"
            changed = {k: v for k, v in values.items() if v != self.params[k]}
            if "initial_pose" in changed:
                self.outputs.reset()        # tracking restarts: no velocity across the jump
            self.params, self.estimator = values, estimator
            self._initial_x = initial_x
            self.inputs.joint_names = values["joint_names"]
            if changed:
                self.log.info("parameters set: " + ", ".join(f"{k}={v!r}" for k, v in changed.items()))
            return True, ""
