"""Every assembly mode of the last input, on request (``~/request_assembly_modes`` ->
``~/assembly_modes``): the output record (:class:`PoseArrayOutput`) and the service side
(:class:`AssemblyModes`, held by :class:`~glpma_ros.node.service.FkService` as ``modes``): the last input
received, checked and converted to the config's unit, the modes solved by
:func:`~glpma_ros.node.modes_worker.find_modes` or a :class:`~glpma_ros.node.modes_worker.ModesWorker`
process, and the requests counted under a lock of its own."""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .input_topic import input_topic, model_is_actuated
from .modes_worker import ModesWorker, find_modes

#: ``last_input`` argument: the last input received so far
CURRENT = object()


@dataclass(frozen=True)
class PoseArrayOutput:
    """Every real assembly mode of one input: ``poses`` = ((x, y, z) metres, (qx, qy, qz, qw)) each,
    ``stamp_ns`` = time of the request, ``input_stamp_ns`` = stamp of the input they solve."""

    stamp_ns: int
    frame_id: str
    poses: tuple
    input_stamp_ns: int = 0
    elapsed_s: float = 0.0
    starts: int = 0          # local solves the search used (0: not reported by ``solve``)



class AssemblyModes:
    """Every assembly mode of the last input received, on request, and the requests' counters.

    ``to_config_unit(input)``: an input (metres, or a JointState) as leg lengths in the config's unit,
    :class:`InputError` when it cannot be; ``params()``: the service's current parameters (the
    request's ``assembly_modes_runs``, ``seed``, ``frame_id``, ``input_type``)."""

    def __init__(self, model, config_path, to_config_unit, params, warm_legs=None):
        self.model = model
        self.config_path = config_path
        self.metres_per_unit = float(model.metres_per_unit)
        self._to_config_unit = to_config_unit
        self._params = params
        self._warm_legs = warm_legs
        self._last_input = None          # (input, stamp_ns) last received
        self._lock = threading.Lock()    # the counters below
        self._requests = self._published = self._failed = self._coalesced = self._period_failed = 0
        self._last = self._last_failure = ""
        self._last_starts = 0

    def note_input(self, raw, stamp_ns: int) -> None:
        """Remember the last input received (whatever becomes of it); one assignment, no lock."""
        self._last_input = (raw, int(stamp_ns))

    @property
    def last_input(self):
        """``(input, stamp_ns)`` of the last input received, None before the first."""
        return self._last_input

    def request_input(self, last_input=CURRENT) -> tuple:
        """``(legs in the config's unit, input stamp_ns, runs, seed)`` of the last input received
        (or of ``last_input`` = (input, stamp_ns), None = nothing received); :class:`InputError`
        when there is none or it is not a valid set of leg lengths."""
        last_input = self._last_input if last_input is CURRENT else last_input
        params = self._params()
        if last_input is None:
            source = input_topic(params["input_type"], model_is_actuated(self.model))
            raise InputError(f"no input received yet on {source}")
        raw, stamp_ns = last_input
        try:
            legs = self.model.check_legs(self._to_config_unit(raw))
        except (InputError, TypeError, ValueError) as exc:
            raise InputError(f"the last input is invalid: {exc}") from None
        return legs, stamp_ns, params["assembly_modes_runs"], params["seed"]

    def compute(self, stamp_ns: int, last_input=CURRENT, solve=None) -> PoseArrayOutput:
        """Every real assembly mode of the last input received (or ``last_input``), stamped
        ``stamp_ns`` (the time of the request).  ``solve(legs, runs, seed, leg_noise_std)`` (config unit:
        parameter ``leg_noise_std``, the noise of a redundant leg's consistency test) returns the solver
        variables of each mode, as a list or a :class:`~glpma_ros.node.modes_worker.Modes` that also
        says how many starts it used (default: the multistart of
        :func:`~glpma_ros.node.modes_worker.find_modes` in this thread;
        the node passes a :class:`~glpma_ros.node.modes_worker.ModesWorker`).  Holds no lock of the
        service while solving.  :class:`InputError` with the reason on failure."""
        t0 = time.perf_counter()
        legs, input_stamp_ns, runs, seed = self.request_input(last_input)
        leg_noise_std = self._params()["leg_noise_std"] / self.metres_per_unit
        xs = (solve or self._solve_here)(legs, runs, seed, leg_noise_std)
        poses = []
        for x in xs:
            pose = self.model.pose(np.asarray(x, dtype=float))
            poses.append((tuple(float(v) * self.metres_per_unit for v in pose.position),
                          tuple(float(v) for v in pose.orientation)))
        return PoseArrayOutput(int(stamp_ns), self._params()["frame_id"], tuple(poses), int(input_stamp_ns),
                               time.perf_counter() - t0, int(getattr(xs, "starts", 0)))

    def worker(self):
        """A :class:`~glpma_ros.node.modes_worker.ModesWorker` (not started) for this manipulator."""
        return ModesWorker(self.config_path, warm_legs=self._warm_legs)

    def _solve_here(self, legs, runs, seed, leg_noise_std) -> list:
        return find_modes(self.model, legs, runs, seed, leg_noise_std)

    def note(self, result: PoseArrayOutput | None = None, failure: str | None = None, coalesced: int = 0) -> None:
        """Count a request: answered with ``result``, failed with ``failure``, or ``coalesced``
        requests merged into the next computation."""
        with self._lock:
            self._coalesced += coalesced
            if result is not None:
                self._requests += 1
                self._published += 1
                self._last = f"{len(result.poses)} modes in {result.elapsed_s:.3g} s"
                self._last_starts = result.starts
            elif failure is not None:
                self._requests += 1
                self._failed += 1
                self._period_failed += 1
                self._last_failure = failure

    @property
    def failed(self) -> int:
        """Requests that failed since start."""
        return self._failed

    def snapshot(self, new_period: bool = False) -> tuple[list, int]:
        """``([(key, value)] for /diagnostics, requests failed in the period)``; with ``new_period``
        a new period starts."""
        with self._lock:
            values = [("assembly modes requests", self._requests),
                      ("assembly modes published", self._published),
                      ("assembly modes failed", self._failed),
                      ("assembly modes coalesced", self._coalesced),
                      ("assembly modes last", self._last or "none"),
                      ("assembly modes last starts", self._last_starts)]
            if self._last_failure:
                values.append(("assembly modes last failure", self._last_failure))
            failed = self._period_failed
            if new_period:
                self._period_failed = 0
            return values, failed
