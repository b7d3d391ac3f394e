"""Every assembly mode of the last input, on request (``~/request_assembly_modes`` ->
``~/assembly_modes``): the output record (:class:`PoseArrayOutput`) and the service side
(:class:`AssemblyModesMixin`, a base of :class:`~glpma_ros.node.service.FkService`): the last input checked
and converted to the config's unit, the modes solved by :func:`~glpma_ros.node.modes_worker.find_modes` or a
:class:`~glpma_ros.node.modes_worker.ModesWorker` process, and the requests counted."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from . import params as P
from ..errors import InputError

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



class AssemblyModesMixin:
    """The assembly-modes methods of :class:`~glpma_ros.node.service.FkService` (they use its ``model``,
    ``params``, ``stats``, locks, ``_last_input`` and ``_config_unit``)."""

    def assembly_modes_input(self, last_input=CURRENT) -> tuple:
        """``(legs in the config's unit, input stamp_ns, runs, seed)`` of the last input received
        (or of ``last_input`` = (input, stamp_ns), None = nothing received); :class:`InputError`
        when there is none or it is not a valid set of leg lengths."""
        last_input = self._last_input if last_input is CURRENT else last_input
        if last_input is None:
            source = "joint_states" if self.input_type == P.INPUT_JOINT_STATE else "leg_lengths"
            raise InputError(f"no input received yet on {source}")
        raw, stamp_ns = last_input
        try:
            legs = self.model.check_legs(self._config_unit(raw))
        except InputError as exc:
            raise InputError(f"the last input is invalid: {exc}") from None
        except (TypeError, ValueError) as exc:
            raise InputError(f"the last input is invalid: {exc}") from None
        with self._lock:
            runs, seed = self.params["assembly_modes_runs"], self.params["seed"]
        return legs, stamp_ns, runs, seed

    def assembly_modes(self, stamp_ns: int, last_input=CURRENT, solve=None) -> PoseArrayOutput:
        """Every real assembly mode of the last input received (or ``last_input``), stamped
        ``stamp_ns`` (the time of the request).  ``solve(legs, runs, seed)`` returns the solver
        variables of each mode, as a list or a :class:`~glpma_ros.node.modes_worker.Modes` that also
        says how many starts it used (default: the multistart of
        :func:`~glpma_ros.node.modes_worker.find_modes` in this thread;
        the node passes a :class:`~glpma_ros.node.modes_worker.ModesWorker`).  Does not hold the
        service lock while solving.  :class:`InputError` with the reason on failure."""
        t0 = time.perf_counter()
        legs, input_stamp_ns, runs, seed = self.assembly_modes_input(last_input)
        if solve is None:
            solve = self._solve_all_here
        xs = solve(legs, runs, seed)
        poses = []
        for x in xs:
            pose = self.model.pose(np.asarray(x, dtype=float))
            poses.append((tuple(float(v) * self.metres_per_unit for v in pose.position),
                          tuple(float(v) for v in pose.orientation)))
        with self._lock:
            frame_id = self.frame_id
        return PoseArrayOutput(int(stamp_ns), frame_id, tuple(poses), int(input_stamp_ns),
                               time.perf_counter() - t0, int(getattr(xs, "starts", 0)))

    def modes_worker(self):
        """A :class:`~glpma_ros.node.modes_worker.ModesWorker` (not started) for this manipulator."""
        from .modes_worker import ModesWorker
        return ModesWorker(self.config_path, warm_legs=self.model.inverse_kinematics(self._warm_up_variables()))

    def _solve_all_here(self, legs, runs, seed) -> list:
        from .modes_worker import find_modes
        return find_modes(self.model, legs, runs, seed)

    def note_assembly_modes(self, result: PoseArrayOutput | None = None, failure: str | None = None,
                            coalesced: int = 0) -> None:
        """Count a request: answered with ``result``, failed with ``failure``, or ``coalesced``
        requests merged into the next computation."""
        with self._modes_lock:
            st = self.stats
            st.modes_coalesced += coalesced
            if result is not None:
                st.modes_requests += 1
                st.modes_published += 1
                st.modes_last = f"{len(result.poses)} modes in {result.elapsed_s:.3g} s"
                st.modes_last_starts = result.starts
            elif failure is not None:
                st.modes_requests += 1
                st.modes_failed += 1
                st.modes_last_failure = failure
                st.period["modes_failed"] += 1
