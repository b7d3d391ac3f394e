"""The actuated families: parallel manipulators whose actuators move the proximal end of a rod of fixed length
(the one leg model of :mod:`.legs`).

* :class:`DeltaTranslation` -- a platform that only translates (``platform_motion: translation``): the rotary
  Delta (Clavel 1990: three revolute actuators, parallelogram forearms) and the linear Delta (3-PUU, rails).
  Solver variables ``x = (x, y, z)``, the platform origin; residuals ``|p + B_i - P_i| - rod_i``; the
  refinement's Jacobian rows are the unit rod vectors ``u_i``.  With three legs the forward kinematics has
  a closed form, the intersection of the three spheres of centre ``P_i - B_i`` and radius ``rod_i``
  (:meth:`DeltaTranslation.closed_form`; two solutions, mirror images through the plane of the centres).
* :class:`ActuatedSpatial` -- full pose (6-RUS rotary hexapods, 6-PUS rail hexapods): the hexapod's
  9-variable model and pose-space refinement (:mod:`.hexapod_66`) with the crank tips / carriages as base
  joints and the rods as leg lengths.
* :class:`ActuatedPlanar` -- planar full pose (3-RRR, 3-PRR): the 3-RPR model (:mod:`.planar_3rpr`) likewise.

Every model here takes the leg vector ``w = (rod_1..rod_n, P_1, .., P_n)`` where today's models take leg
lengths: :meth:`ActuatedLegs.legs_from_sensors` turns the actuator positions into it (once per input),
:meth:`ActuatedLegs.inverse_kinematics` returns it for a pose, :meth:`ActuatedLegs.actuator_positions` the
actuator positions.  No ROS import here: this is the core.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .base import Manipulator, Pose, number_vector
from .hexapod_66 import Hexapod66
from .legs import (
    LENGTH,
    PRISMATIC,
    REVOLUTE,
    actuator_from_point,
    actuator_roots,
    choose_root,
    leg_vector_into,
    readings_into,
)
from .planar_3rpr import Planar3RPR
from .residuals import KIND_ACTUATED_PLANAR, KIND_ACTUATED_SPATIAL, KIND_ACTUATED_TRANSLATION

#: the unit of each actuator kind's position, for messages (prismatic and length: the config's unit)
ACTUATOR_UNIT = {REVOLUTE: "rad"}


class ActuatedLegs:
    """The leg description shared by the actuated models (a mixin beside :class:`~.base.Manipulator`).

    ``actuators`` (n,) kinds of :mod:`.legs`; ``origin``, ``axis`` (unit), ``crank`` (n, dim); ``rods`` (n,);
    ``actuator_limits`` (n, 2) or None; ``actuator_offsets`` (n,) or None: the model's actuator position is
    the reading plus its offset (a zero error, identified by calibration)."""

    actuated = True
    actuator_names: tuple = ()
    actuator_limits: np.ndarray | None = None
    actuator_offsets: np.ndarray | None = None

    def __init__(self, kind, actuators, origin, axis, crank, rods, platform, unit="mm", actuator_limits=None):
        """The legs, then the pose model this mixin precedes (built on the actuators' origins as base joints),
        then the compiled kernels' data (:meth:`_actuated_data`) and the cold start's box
        (:meth:`_initial_range` of :meth:`reach_box`), both the family's own."""
        self.kind = kind
        self._set_legs(actuators, origin, axis, crank, rods, actuator_limits)
        super().__init__(self.origin, platform, unit, None)
        self.data = self._actuated_data()
        self.initial_range = self._initial_range(*self.reach_box())

    def _actuated_data(self) -> tuple:
        """The model's data as the compiled kernels take it (:meth:`~.base.Manipulator._make_data`)."""
        raise NotImplementedError

    def _initial_range(self, lo, hi) -> tuple:
        """The uniform initial range of a cold start's variables, from the platform origin's reach box."""
        raise NotImplementedError

    def _set_legs(self, actuators, origin, axis, crank, rods, actuator_limits=None):
        self.actuators = np.ascontiguousarray(actuators, dtype=np.int64)
        self.origin = np.ascontiguousarray(origin, dtype=float)
        axis = np.asarray(axis, dtype=float)
        self.axis = np.ascontiguousarray(axis / np.linalg.norm(axis, axis=1)[:, None])
        self.crank = np.ascontiguousarray(crank, dtype=float)
        self.rods = np.ascontiguousarray(rods, dtype=float)
        self.actuator_limits = None if actuator_limits is None else np.asarray(actuator_limits, dtype=float)
        self.dim = self.origin.shape[1]
        n = self.origin.shape[0]
        # the limits as the compiled check takes them (none: the whole real line)
        self._lo = np.full(n, -np.inf) if actuator_limits is None else np.ascontiguousarray(self.actuator_limits[:, 0])
        self._hi = np.full(n, np.inf) if actuator_limits is None else np.ascontiguousarray(self.actuator_limits[:, 1])
        self._no_offsets = np.zeros(n)
        self._unit_divisor = np.ones(n)          # readings in the model's units (legs_from_sensors)
        self._si = (None, None)                  # (metres_per_unit, divisor) of readings in SI (legs_from_si)

    # -- the leg vector --------------------------------------------------------------------------
    @property
    def leg_vector_size(self) -> int:
        return self.n_legs * (1 + self.dim)

    def leg_vector(self, q) -> np.ndarray:
        """``w = (rod_1..rod_n, P_1(q_1), .., P_n(q_n))`` of the model's actuator positions ``q`` (offsets included)."""
        out = np.empty(self.leg_vector_size)
        leg_vector_into(self.actuators, self.origin, self.axis, self.crank, self.rods,
                        np.ascontiguousarray(q, dtype=float), out)
        return out

    def rods_of(self, legs) -> np.ndarray:
        return np.asarray(legs, dtype=float)[:self.n_legs]

    def proximal_points(self, legs) -> np.ndarray:
        """The proximal points ``P_i`` (n, dim) of a leg vector."""
        return np.asarray(legs, dtype=float)[self.n_legs:].reshape(self.n_legs, self.dim)

    def _unit(self, i) -> str:
        return ACTUATOR_UNIT.get(int(self.actuators[i]), self.unit)

    def check_actuators(self, q) -> np.ndarray:
        """Validated actuator positions (one per leg, radians or config unit, as read), or :class:`InputError`."""
        arr = number_vector(q, "actuator positions")
        if arr.size != self.n_legs:
            raise InputError(f"expected {self.n_legs} actuator positions for {self.kind}, got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise InputError("actuator positions must be finite (got NaN or inf)")
        if self.actuator_limits is not None:
            lo, hi = self.actuator_limits[:, 0], self.actuator_limits[:, 1]
            bad = np.flatnonzero((arr < lo) | (arr > hi))
            if bad.size:
                i = int(bad[0])
                raise InputError(f"actuator {i + 1} at {arr[i]:g} {self._unit(i)} is outside its limits "
                                 f"[{lo[i]:g}, {hi[i]:g}] {self._unit(i)}")
        return arr

    def _readings(self, q, divisor) -> np.ndarray | None:
        """The leg vector of readings ``q / divisor`` (contiguous, one per leg) by one compiled call, or None
        when a reading is not finite or outside its limits (the caller's checks then name the problem)."""
        out = np.empty(self.leg_vector_size)
        offsets = self._no_offsets if self.actuator_offsets is None else self.actuator_offsets
        if readings_into(self.actuators, self.origin, self.axis, self.crank, self.rods, self._lo, self._hi, offsets,
                         divisor, q, out) == -1:
            return out
        return None

    def legs_from_sensors(self, measured) -> np.ndarray:
        """The leg vector of the actuators' readings ``measured`` (validated: count, finite, limits; the
        config's ``actuator_offsets`` added)."""
        try:
            q = np.asarray(measured, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            q = None
        if q is not None and q.size == self.n_legs:     # the usual input: checked and converted compiled
            out = self._readings(np.ascontiguousarray(q), self._unit_divisor)
            if out is not None:
                return out
        self.check_actuators(measured)                    # raises with the reason
        raise InputError("actuator positions rejected")   # not reached: the check above names the problem

    def legs_from_si(self, values) -> np.ndarray:
        """:meth:`legs_from_sensors` of :meth:`readings_from_si` (the node's input: radians, metres for
        prismatic actuators), the usual input converted and checked in one compiled call."""
        try:
            q = np.ascontiguousarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            q = None
        if q is not None and q.size == self.n_legs:
            mpu, divisor = self._si
            if mpu != self.metres_per_unit:         # built on first use (the config sets metres_per_unit)
                mpu = self.metres_per_unit
                divisor = np.where(self.actuators == PRISMATIC, mpu, 1.0)
                self._si = (mpu, divisor)
            out = self._readings(q, divisor)
            if out is not None:
                return out
        return self.legs_from_sensors(self.readings_from_si(values))   # raises with the reason

    def sensors_from_legs(self, legs) -> np.ndarray:
        """What the actuators read for leg vector ``legs``: the inverse of :meth:`legs_from_sensors`."""
        legs = np.asarray(legs, dtype=float)
        points = self.proximal_points(legs)
        q = np.array([legs[i] if k == LENGTH else actuator_from_point(k, self.origin[i], self.axis[i],
                                                                        self.crank[i], points[i])
                      for i, k in enumerate(self.actuators)])
        return q if self.actuator_offsets is None else q - self.actuator_offsets

    def check_legs(self, legs) -> np.ndarray:
        """A leg vector (validated), or actuator readings turned into one (:meth:`legs_from_sensors`)."""
        arr = number_vector(legs, "actuator positions")
        if arr.size != self.leg_vector_size:
            return self.legs_from_sensors(arr)
        if not np.all(np.isfinite(arr)):
            raise InputError("the leg vector must be finite (got NaN or inf)")
        if np.any(arr[:self.n_legs] <= 0.0):
            raise InputError("rod lengths must be positive")
        return arr

    # -- inverse kinematics --------------------------------------------------------------------------
    def distal_points(self, x) -> np.ndarray:
        """The platform joints in the base frame (n, dim) for solver variables ``x``."""
        return self.joints(x)

    def actuator_positions(self, x) -> np.ndarray:
        """The actuators' readings for the pose ``x`` (inverse kinematics, the branch of
        :func:`~.legs.choose_root`); ``ValueError`` when a leg cannot reach it within its limits."""
        distal = self.distal_points(x)
        q = np.empty(self.n_legs)
        for i, k in enumerate(self.actuators):
            limits = None if self.actuator_limits is None else self.actuator_limits[i]
            off = 0.0 if self.actuator_offsets is None else float(self.actuator_offsets[i])
            model_limits = None if limits is None else (limits[0] + off, limits[1] + off)
            roots = actuator_roots(k, self.origin[i], self.axis[i], self.crank[i], self.rods[i], distal[i])
            root = choose_root(roots, model_limits)
            if root is None:
                raise ValueError(f"leg {i + 1} cannot reach the pose within its actuator limits")
            q[i] = root - off
        return q

    def inverse_kinematics(self, x) -> np.ndarray:
        """The leg vector of the pose ``x`` (its actuators at :meth:`actuator_positions`)."""
        return self.legs_from_sensors(self.actuator_positions(x))

    def readings_from_si(self, values) -> np.ndarray:
        """Actuator readings in SI (radians; metres for prismatic actuators, as on the topics) in the
        config's units (radians; the config unit)."""
        arr = number_vector(values, "actuator positions", copy=True)     # scaled in place below
        if arr.size == self.n_legs:
            prismatic = self.actuators == PRISMATIC
            with np.errstate(over="ignore", invalid="ignore"):
                arr[prismatic] = arr[prismatic] / self.metres_per_unit
        return arr

    def readings_to_si(self, values) -> np.ndarray:
        """The inverse of :meth:`readings_from_si`: config units to radians / metres."""
        arr = np.array(values, dtype=float).reshape(-1)
        prismatic = self.actuators == PRISMATIC
        arr[prismatic] = arr[prismatic] * self.metres_per_unit
        return arr

    def reference_legs(self) -> np.ndarray:
        """The leg vector of the actuators at mid-range (zero without limits): an input the kernels accept,
        whether or not it has an assembly (for measuring the solvers before any input)."""
        q = np.zeros(self.n_legs) if self.actuator_limits is None else self.actuator_limits.mean(axis=1)
        return self.legs_from_sensors(q)

    def home_variables(self) -> np.ndarray | None:
        """A pose inside the workspace (warm-ups, demos): the config's first known solution, else the working
        mode at the actuators' mid-range (zero without limits) by the closed form; None where that needs a
        solve of :meth:`reference_legs` (:func:`~glpma_ros.runtime.precompile.warm_up_pose` does it)."""
        known = getattr(self, "known_solutions", None)
        if known is not None:
            return np.array(known[0], dtype=float)
        closed = getattr(self, "closed_form", None)
        xs = closed(self.reference_legs()) if closed is not None else None
        return self.preferred_order(xs)[0] if xs else None

    def reach_box(self) -> tuple[np.ndarray, np.ndarray]:
        """A box holding every platform joint's reachable region shifted to the platform origin: the
        intersection over the legs of the boxes of the balls of centre ``origin_i - B_i`` and radius
        ``rod_i`` plus the proximal point's reach (the crank's length; a rail's farthest limit)."""
        lows, highs = [], []
        for i, k in enumerate(self.actuators):
            if k == PRISMATIC:
                limits = self.actuator_limits[i] if self.actuator_limits is not None else (-self.scale, self.scale)
                reach = float(max(abs(limits[0]), abs(limits[1])))
            else:
                reach = float(np.linalg.norm(self.crank[i]))
            centre = self.origin[i] - self.platform[i]
            r = self.rods[i] + reach
            lows.append(centre - r)
            highs.append(centre + r)
        return np.max(lows, axis=0), np.min(highs, axis=0)


class DeltaTranslation(ActuatedLegs, Manipulator):
    """A platform that only translates (module docstring); ``kind`` is the config's family name."""

    min_legs = 3
    n_vars = 3
    n_pose = 3
    variable_names = ("x", "y", "z")
    kind_id = KIND_ACTUATED_TRANSLATION
    settings_like = "planar_3rpr"        # the papers' population sizes for three variables

    def _actuated_data(self) -> tuple:
        self.n_res = self.n_legs
        self.pose_column_scale = np.ones(3)
        return self._make_data(self.platform, self.platform)

    def _initial_range(self, lo, hi) -> tuple:
        return lo, hi

    def joints(self, x) -> np.ndarray:
        return np.asarray(x, dtype=float)[:3] + self.platform

    def pose(self, x) -> Pose:
        return Pose(np.array(x[:3], dtype=float), np.array([0.0, 0.0, 0.0, 1.0]))

    def variables_from_pose(self, position, orientation) -> np.ndarray:
        return np.array(position, dtype=float)[:3]

    def pose_state(self, x):
        return (np.eye(3), np.array(x[:3], dtype=float))

    def pose_residuals_jacobian(self, state, legs):
        _, p = state
        e = p + self.platform - self.proximal_points(legs)
        n = np.sqrt((e * e).sum(axis=1))
        return n - self.rods_of(legs), e / n[:, None]

    def pose_retract(self, state, step):
        R, p = state
        return R, p + step[:3]

    def pose_variables(self, state) -> np.ndarray:
        return np.array(state[1], dtype=float)

    def spread_vector(self, length: float) -> np.ndarray:
        return np.full(3, float(length))

    def canonical(self, x) -> np.ndarray:
        return np.array(x, dtype=float)

    def distance(self, x1, x2) -> float:
        return float(np.linalg.norm(np.asarray(x1, dtype=float) - np.asarray(x2, dtype=float)))

    def preferred_order(self, xs) -> list:
        """Modes in order of preference for a solve without a previous pose: the platform below its arms
        first (the base frame's z up: the smaller z), the Delta's working mode."""
        return sorted(xs, key=lambda x: float(x[2]))

    def closed_form(self, legs) -> list:
        """Every real solution of three legs (sorted by variables): the intersection of the spheres of centre
        ``C_i = P_i - B_i`` and radius ``rod_i`` (trilateration: in the frame ``e_x`` along ``C_1 C_2``,
        ``e_y`` in the centres' plane, ``p = C_1 + a e_x + b e_y +- c e_z``).  None for more legs (no closed
        form is used for redundant legs); an empty list when the spheres do not meet."""
        if self.n_legs != 3:
            return None
        legs = self.check_legs(legs)
        C = self.proximal_points(legs) - self.platform
        r = self.rods_of(legs)
        d12 = C[1] - C[0]
        d = float(np.linalg.norm(d12))
        ex = d12 / d
        i = float(ex @ (C[2] - C[0]))
        ey = C[2] - C[0] - i * ex
        j = float(np.linalg.norm(ey))
        ey = ey / j
        ez = np.cross(ex, ey)
        a = (r[0] ** 2 - r[1] ** 2 + d * d) / (2.0 * d)
        b = (r[0] ** 2 - r[2] ** 2 + i * i + j * j) / (2.0 * j) - (i / j) * a
        c2 = r[0] ** 2 - a * a - b * b
        if c2 < 0.0:
            return []
        c = math.sqrt(c2)
        centre = C[0] + a * ex + b * ey
        roots = [centre - c * ez] if c == 0.0 else [centre - c * ez, centre + c * ez]
        return sorted(roots, key=lambda v: tuple(np.round(v, 6)))


class ActuatedSpatial(ActuatedLegs, Hexapod66):
    """Full pose with actuated proximal points (6-RUS, 6-PUS): the hexapod's model with per-input base joints."""

    kind_id = KIND_ACTUATED_SPATIAL
    settings_like = "hexapod_66"

    def _actuated_data(self) -> tuple:
        return self._make_data(self.abc, self.platform, self.d0sq)

    def _initial_range(self, lo, hi) -> tuple:
        arm = float(np.linalg.norm(self.frame, axis=1).max())     # a frame joint is this far from the origin
        return np.tile(lo - arm, 3), np.tile(hi + arm, 3)

    def pose_residuals_jacobian(self, state, legs):
        R, p = state
        w = self.platform @ R.T
        e = p + w - self.proximal_points(legs)
        n = np.sqrt((e * e).sum(axis=1))
        u = e / n[:, None]
        return n - self.rods_of(legs), np.hstack((u, np.cross(w, u)))


class ActuatedPlanar(ActuatedLegs, Planar3RPR):
    """Planar full pose with actuated proximal points (3-RRR, 3-PRR): the 3-RPR model with per-input base joints."""

    kind_id = KIND_ACTUATED_PLANAR
    settings_like = "planar_3rpr"

    def _actuated_data(self) -> tuple:
        return self._make_data(self.platform, self.platform)

    def _initial_range(self, lo, hi) -> tuple:
        arm = float(np.linalg.norm(self.platform, axis=1).max())   # a platform joint is this far from its origin
        return (np.array([lo[0] - arm, lo[1] - arm, -math.pi]),
                np.array([hi[0] + arm, hi[1] + arm, math.pi]))

    def pose_residuals_jacobian(self, state, legs):
        c, s = math.cos(state[2]), math.sin(state[2])
        rot = self.platform @ np.array([[c, s], [-s, c]])
        e = state[:2] + rot - self.proximal_points(legs)
        n = np.sqrt((e * e).sum(axis=1))
        J = np.empty((self.n_legs, 3))
        J[:, :2] = e / n[:, None]
        J[:, 2] = J[:, 1] * rot[:, 0] - J[:, 0] * rot[:, 1]
        return n - self.rods_of(legs), J
