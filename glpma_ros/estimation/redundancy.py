"""Redundant legs: is the least-squares pose consistent with the leg noise, and which leg is at fault.

With ``m`` legs and ``d`` degrees of freedom (3-RPR 3, hexapod 6) the forward kinematics is the
least-squares pose ``argmin sum r_i^2`` (:mod:`glpma_ros.solvers.lm`).  Two classical tests of
geodetic adjustment decide what it is worth (Baarda 1968, "A testing procedure for use in geodetic
networks"; Teunissen 2000, *Testing theory*, sections 3-4):

* **Consistency (overall model test).**  With independent leg errors ``N(0, sigma^2)`` the weighted
  sum of squared residuals at the least-squares pose, ``T = sum r_i^2 / sigma^2``, follows a
  chi-square law with ``m - d`` degrees of freedom (to first order).  The legs are consistent when
  ``T <= chi2_{m-d}(CONSISTENCY_LEVEL)``: a false alarm in ``1 - CONSISTENCY_LEVEL`` of the inputs of a
  healthy manipulator.  ``sigma`` (``leg_noise_std``) and the residuals are in the same unit, so the
  decision is the same in mm, cm or m.
* **Isolation (leave one out).**  A single leg with a gross error ``b`` (much larger than ``sigma``)
  is found by solving without each leg in turn: without the faulty one the other legs are consistent
  again.  With two or more redundant legs that is decidable from the input alone: the leg whose
  removal leaves the smallest ``T`` (below the chi-square limit with one degree of freedom less) is
  the most likely at fault (Baarda's data snooping, done exactly instead of linearised).  With a single
  redundant leg every leave-one-out pose fits its legs exactly, so the input alone cannot tell the
  legs apart (Baarda: the legs' tests are then all the same); the pose history can -- the pose
  without the faulty leg continues the motion, the others jump by the effect of ``b``.  The leg
  whose leave-one-out pose is nearest the pose predicted from the last two estimates (constant
  velocity) is then the most likely at fault, and the isolation is accepted when that pose is more
  than ``ISOLATION_MARGIN`` times nearer than every other.

No ROS import: this is the core.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..models.base import Pose
from ..solvers.common import BUDGET_EXHAUSTED
from ..solvers.local import LocalSolver
from ..units import UNIT_TO_METRES

#: confidence of the consistency test: a healthy manipulator gets ``inconsistent_legs`` for one
#: input in a thousand (a false alarm costs little: the pose without the "faulty" leg is published)
CONSISTENCY_LEVEL = 0.999
#: standard deviation of the leg measurements (m) when none is given: the node's ``leg_noise_std``
#: default (a good linear encoder or string pot)
DEFAULT_LEG_NOISE_M = 1e-5
#: one redundant leg: the leave-one-out pose nearest the predicted pose must be this many times
#: nearer than the next for the isolation to hold (otherwise the fault is named, not isolated)
ISOLATION_MARGIN = 3.0
#: iteration cap of a leave-one-out solve (it starts at the previous pose: a few iterations)
LEAVE_ONE_OUT_MAX_ITER = 50
#: starts per compiled call of a leave-one-out solve without history: the deadline is looked at between
#: two calls, so one call must be short (a few starts, tens of microseconds)
LEAVE_ONE_OUT_CHUNK = 4
#: the expected time of one start of a leave-one-out solve (the longest seen) forgets this share of itself
#: per start that measures less, so that a one-off delay does not hold it high for good
EXPECTED_DECAY = 0.01
#: the status of legs that no pose explains within the leg noise
STATUS_INCONSISTENT = "inconsistent_legs"


def chi2_limit(dof: int, level: float = CONSISTENCY_LEVEL) -> float:
    """The ``level`` quantile of the chi-square law with ``dof`` degrees of freedom (0 for ``dof`` 0:
    an exactly determined pose has no residual to test).  SciPy is imported only here: a manipulator
    without redundant legs never needs it."""
    if dof <= 0:
        return 0.0
    from scipy.special import chdtri
    return float(chdtri(dof, 1.0 - level))


def leg_noise(model, leg_noise_std=None) -> float:
    """``sigma`` of the tests in the config's unit: ``leg_noise_std`` (config unit), or
    :data:`DEFAULT_LEG_NOISE_M` converted when it is None; :class:`InputError` unless positive."""
    mpu = getattr(model, "metres_per_unit", UNIT_TO_METRES.get(model.unit, 1.0))
    sigma = float(DEFAULT_LEG_NOISE_M / mpu if leg_noise_std is None else leg_noise_std)
    if not (math.isfinite(sigma) and sigma > 0.0):
        raise InputError(f"leg_noise_std must be positive, got {leg_noise_std!r}")
    return sigma


@dataclass
class Isolation:
    """The leg most likely at fault (0-based) and, when the isolation holds, the pose without it."""

    leg: int | None               # None: no leave-one-out solve converged
    isolated: bool                # the other legs determine the pose consistently
    result: object = None         # LocalResult of the pose without ``leg`` (full model's variables)
    statistic: float = math.nan   # T of the legs without ``leg``
    evaluations: int = 0
    reason: str = ""
    cut: bool = False             # the deadline came before every leave-one-out solve it needed had run


class FaultIsolator:
    """The leave-one-out solves of one redundant model (a sub-model and a local solver per leg, built
    once).  A sub-model's solver variables may be other joints than the full model's (its frame joints
    when a frame joint's leg is left out): poses cross between them as position + quaternion.

    Under a deadline each compiled call (a leave-one-out solve from the previous pose, or
    :data:`LEAVE_ONE_OUT_CHUNK` of the fixed starts) starts only when its expected time (``start_s`` per
    start, the longest seen in the thread's CPU time) still ends before it; an isolation cut there is
    reported as such (``Isolation.cut``)."""

    def __init__(self, model):
        self.model = model
        self.dof_left = model.redundancy - 1
        self.limit_left = chi2_limit(self.dof_left)
        self._subs: dict = {}
        self.start_s = 0.0            # expected CPU time (s) of one start of a leave-one-out solve

    def expected_s(self, n_starts: int) -> float:
        """The expected time (s) of a whole isolation: every leg left out in turn, each from ``n_starts``
        starts (1 from the previous pose, the fixed starts' count without history)."""
        return self.model.n_legs * n_starts * self.start_s

    def _fits(self, n_starts: int, deadline) -> bool:
        return deadline is None or time.perf_counter() + n_starts * self.start_s < deadline

    def _note(self, seconds: float, n_starts: int) -> None:
        self.start_s = max(seconds / max(n_starts, 1), (1.0 - EXPECTED_DECAY) * self.start_s)

    def calibrate(self, legs, start) -> None:
        """A first measure of a leave-one-out solve's time: leg 1 left out of ``legs`` from ``start``
        (solver variables), twice (the first loads the code)."""
        for _ in range(2):
            c = time.thread_time()
            self.solve_without(0, np.ascontiguousarray(legs, dtype=float), start)
            self._note(time.thread_time() - c, 1)

    def _sub(self, leg: int):
        if leg not in self._subs:
            m = self.model
            keep = [i for i in range(m.n_legs) if i != leg]
            try:
                sub = type(m)(m.base[keep], m.platform[keep], unit=m.unit, leg_limits=m.leg_limits)
                self._subs[leg] = (keep, sub, LocalSolver(sub))
            except ValueError:      # the other legs' joints leave the pose undetermined
                self._subs[leg] = None
        return self._subs[leg]

    def solve_without(self, leg: int, legs, start_x, starts=None, ftol=math.inf, deadline=None):
        """``(LocalResult in the full model's variables, T * sigma^2)`` of the legs without ``leg``
        from the full model's variables ``start_x`` -- or, without a start (no history), from the rows of
        ``starts``, :data:`LEAVE_ONE_OUT_CHUNK` per compiled call, until one converges with a leg fitness below
        ``ftol``; None when that sub-model is undetermined; False when the ``deadline`` (a
        ``time.perf_counter`` value) came before a call that was needed (a partial result is kept only if
        it converged)."""
        entry = self._sub(leg)
        if entry is None:
            return None
        keep, sub, solver = entry
        m = self.model
        mine = np.ascontiguousarray(legs[keep])
        if start_x is None:
            r, nfev, nit = None, 0, 0
            for k in range(0, len(starts), LEAVE_ONE_OUT_CHUNK):
                chunk = starts[k:k + LEAVE_ONE_OUT_CHUNK]
                if not self._fits(len(chunk), deadline):
                    return False
                c = time.thread_time()
                part = solver.multistart(chunk, mine, max_iter=LEAVE_ONE_OUT_MAX_ITER, ftol=ftol)
                self._note(time.thread_time() - c, len(chunk))
                if part is None:
                    return None
                nfev, nit = nfev + part.nfev, nit + part.nit
                if r is None or part.converged or part.leg_fitness < r.leg_fitness:
                    r = part
                if part.converged:
                    break
            r = r._replace(nfev=nfev, nit=nit)
        else:
            if not self._fits(1, deadline):
                return False
            pose = m.pose(start_x)
            x0 = np.ascontiguousarray(sub.variables_from_pose(pose.position, pose.orientation))
            c = time.thread_time()
            r = solver.solve(x0, mine, max_iter=LEAVE_ONE_OUT_MAX_ITER)
            self._note(time.thread_time() - c, 1)
        if r is None:
            return None
        x = m.variables_from_pose(r.position, r.orientation)
        return r._replace(x=x), r.leg_fitness

    def isolate(self, legs, start_x, sigma: float, predicted=None, near: float = math.inf,
                first: int | None = None, starts=None, deadline=None) -> Isolation:
        """The most likely faulty leg of ``legs`` (config unit) whose least-squares pose failed the
        consistency test.  ``start_x``: where the leave-one-out solves start (the previous pose), or
        None without history: then each solve tries the rows of ``starts`` (fixed starts over the
        pose space) until it finds a pose consistent with its legs; ``predicted``: the pose expected
        from the history (full model's variables) or None; ``near``: the largest distance from it a
        continuing pose may have; ``first``: the leg left out last time, tried first (a leg that stays
        faulty is left out again without solving for the others); ``deadline``: no compiled call starts
        unless it is expected to end before it (a ``time.perf_counter`` value; an isolation cut there is
        ``cut``, no leg named)."""
        m = self.model
        s2 = sigma * sigma
        if start_x is None and self.dof_left <= 0:
            return Isolation(None, False, None, math.nan, 0,
                             "one redundant leg and no previous pose: the faulty leg cannot be told")
        ftol = self.limit_left * s2
        order = list(range(m.n_legs))
        if first is not None:
            order.remove(first)
            order.insert(0, first)
        tried = []                  # (leg, result, T)
        nfev = 0
        for leg in order:
            out = self.solve_without(leg, legs, start_x, starts, ftol, deadline)
            if out is False:
                return Isolation(None, False, None, math.nan, nfev, "finding the faulty leg did not fit in the budget",
                                 cut=True)
            if out is None:
                continue
            r, fit = out
            nfev += r.nfev
            if not r.converged:
                continue
            T = fit / s2
            tried.append((leg, r, T))
            if leg == first and self._consistent(T) and self._continues(r, predicted, near):
                return Isolation(leg, True, r, T, nfev, "left out again")
        if not tried:
            return Isolation(None, False, None, math.nan, nfev, "no leave-one-out pose converged")
        if self.dof_left > 0:
            tried.sort(key=lambda t: t[2])
            leg, r, T = tried[0]
            ok = self._consistent(T) and (len(tried) < 2 or not self._consistent(tried[1][2]))
            why = "" if ok else ("the other legs are not consistent either" if not self._consistent(T)
                                 else "several legs could be at fault")
            return Isolation(leg, ok, r, T, nfev, why)
        if predicted is None:
            return Isolation(None, False, None, math.nan, nfev,
                             "one redundant leg and no previous pose: the faulty leg cannot be told")
        dist = [m.distance(r.x, predicted) for _, r, _ in tried]
        ranked = np.argsort(dist)
        leg, r, T = tried[ranked[0]]
        best = dist[ranked[0]]
        second = dist[ranked[1]] if len(ranked) > 1 else math.inf
        ok = best <= near and second > ISOLATION_MARGIN * best
        why = "" if ok else "the poses without each leg are alike: the faulty leg is uncertain"
        return Isolation(leg, ok, r, T, nfev, why)

    def _consistent(self, T: float) -> bool:
        return self.dof_left <= 0 or T <= self.limit_left

    def _continues(self, r, predicted, near) -> bool:
        """The pose ``r`` continues the motion: within ``near`` of the predicted pose (if any)."""
        return predicted is None or self.model.distance(r.x, predicted) <= near


class RedundantLegs:
    """The estimator's policy for redundant legs (more legs than degrees of freedom): the consistency
    test of a converged least-squares pose and, when it fails, the isolation of the faulty leg with
    the pose from the others.  Keeps what the policy needs of the history: the estimate before the
    last one (for the constant-velocity prediction), the inputs since the last pose and the leg left
    out last time.  The estimator keeps the warm state itself and asks :meth:`judge` what to advance
    it to.

    ``leg_noise_std``: sigma of the tests (config unit; default :data:`DEFAULT_LEG_NOISE_M` in the
    config's unit); ``exclude_faulty_leg``: publish the pose without the isolated leg; ``starts``: the
    fixed starts of leave-one-out solves without history."""

    def __init__(self, model, leg_noise_std=None, exclude_faulty_leg=True, starts=None):
        self.model = model
        self.leg_noise_std = leg_noise(model, leg_noise_std)
        self.exclude_faulty_leg = bool(exclude_faulty_leg)
        self.consistency_limit = chi2_limit(model.redundancy)
        self.isolator = FaultIsolator(model) if model.redundancy > 0 else None
        #: the largest sum of squared leg residuals (config unit squared) of a consistent pose
        self.consistent_fitness = self.consistency_limit * self.leg_noise_std ** 2 if model.redundancy else math.inf
        self.starts = starts
        self.reset()

    @property
    def active(self) -> bool:
        """The model has redundant legs (otherwise every method is a no-op)."""
        return self.isolator is not None

    def reset(self) -> None:
        self.prev_x = None                  # the estimate before the last one
        self.inputs = self.advanced_at = 0  # inputs seen, and when the last estimate was set
        self.excluded = None                # the leg left out of the last pose

    def note_input(self) -> None:
        self.inputs += 1

    @property
    def isolation_s(self) -> float:
        """The expected time (s) of the longest isolation (no history: every leg left out, from every fixed
        start); 0 without redundant legs."""
        if not self.active:
            return 0.0
        return self.isolator.expected_s(1 if self.starts is None else len(self.starts))

    def consistent(self, leg_fitness: float) -> bool:
        """A converged point with this leg fitness passes the consistency test (always without redundant legs)."""
        return leg_fitness <= self.consistent_fitness

    def advanced(self, old_x) -> None:
        """The warm state moved on from ``old_x`` (the estimate before the new one)."""
        self.prev_x = old_x
        self.advanced_at = self.inputs

    def judge(self, e, legs, leg_fitness: float, last_x, near: float, deadline=None):
        """Test the converged least-squares estimate ``e`` (changed in place: its consistency, and for
        inconsistent legs its status, message, suspect and, when isolated, the pose without the faulty
        leg).  ``last_x``: the warm state (None: no history); ``near``: the largest distance a
        continuing pose may have from the prediction; ``deadline``: the isolation's (a ``time.perf_counter``
        value; when the isolation does not fit before it the status is ``budget_exhausted``).  Returns the
        variables the warm state should advance to, or None."""
        T = leg_fitness / self.leg_noise_std ** 2
        e.consistency, e.consistency_limit = T, self.consistency_limit
        if T <= self.consistency_limit:
            self.excluded = None
            e.message += f", legs consistent (chi-square {T:.3g} <= {self.consistency_limit:.3g})"
            return e.x
        predicted = None
        if last_x is not None:
            # constant velocity per input from the last two estimates, over the inputs since the last one
            # (an input that gave no pose leaves the history behind by one more step)
            steps = max(self.inputs - self.advanced_at, 1)
            predicted = last_x if self.prev_x is None else last_x + steps * (last_x - self.prev_x)
        iso = self.isolator.isolate(legs, last_x, self.leg_noise_std, predicted, near, first=self.excluded,
                                    starts=self.starts, deadline=deadline)
        e.status, e.suspect_leg = (BUDGET_EXHAUSTED if iso.cut else STATUS_INCONSISTENT), iso.leg
        e.evaluations += iso.evaluations
        head = f"legs inconsistent (chi-square {e.consistency:.3g} > {e.consistency_limit:.3g})"
        x_ls, advance = e.x, None
        e.pose = None
        if iso.leg is None:
            e.message = f"{head}; {iso.reason}"
        elif not iso.isolated:
            e.message = f"{head}; leg {iso.leg + 1} most likely at fault ({iso.reason})"
        else:
            r = iso.result
            self.excluded = iso.leg
            advance = r.x
            if self.exclude_faulty_leg:
                e.x, e.pose, e.excluded_leg = r.x, Pose(r.position, r.orientation), iso.leg
                e.conditioning, e.max_residual = r.conditioning, r.max_residual
                e.fitness = r.fitness          # the papers' fitness of the legs the pose used
                e.message = (f"{head}; leg {iso.leg + 1} most likely at fault, left out: pose from the other "
                             f"{self.model.n_legs - 1} legs")
            else:
                e.message = f"{head}; leg {iso.leg + 1} most likely at fault (exclude_faulty_leg off: no pose)"
        if e.pose is None:
            e.x = x_ls
        return advance
