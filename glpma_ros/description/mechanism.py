"""The loop-cut tree of a parallel manipulator and the state of every one of its joints at a pose.

URDF describes trees, and a parallel manipulator is a closed chain: every leg joins the base to
the platform.  The usual way to show one with ``robot_state_publisher`` (PI's hexapod driver,
``joint_state_transformer``) is to cut the loops: each leg is a serial chain of its joints from
the base, the platform hangs from the end of one leg (the *cut leg*, leg 1) by a fixed joint,
and the passive joints' positions are computed from the platform's pose (the forward kinematics'
answer) so that every other leg's chain ends where its platform joint is.  This module is that
tree and that computation; :mod:`glpma_ros.description.urdf` writes it as a URDF.

The legs as they are built (``P`` = prefix, ``i`` = leg number from 1, in config order):

* hexapod (``hexapod_66``; shared joints and redundant legs too: every leg has its own chain):
  ``Pleg<i>_u1`` (revolute about the base's x axis at the base joint A_i) and ``Pleg<i>_u2``
  (revolute about the y axis it has turned): the universal joint, zero with the leg along the
  base's +z axis; ``Pleg<i>_actuator`` (prismatic along the leg, position = leg length |B_i - A_i|
  in metres); ``Pleg<i>_s1``, ``Pleg<i>_s2``, ``Pleg<i>_s3`` (revolute about the x, y, z axes in
  turn at the platform joint B_i): the spherical joint, zero with the platform's axes along the
  leg's (the end link then has the platform's orientation);
* planar 3-RPR (and more RPR legs): ``Pleg<i>_base`` (revolute about z at A_i, zero with the leg
  along the base's +x axis), ``Pleg<i>_actuator`` (prismatic along the leg, the leg length in
  metres), ``Pleg<i>_platform`` (revolute about z at B_i: the platform's angle minus the leg's).
* actuated spatial families (``delta``, ``rus_6``; :mod:`glpma_ros.models.actuated`): ``Pleg<i>_actuator``
  (revolute about the leg's ``axis`` at its ``origin``, position = the motor's angle in radians: the
  reading plus the config's ``actuator_offsets``, zero without; link ``Pleg<i>_crank``, its frame the
  base's turned by that angle), ``Pleg<i>_u1``, ``Pleg<i>_u2`` (the rod's universal joint at the crank
  tip, about the crank frame's x axis and the y axis it has turned, zero with the rod along the crank
  frame's +z axis; link ``Pleg<i>_rod``, the rod along its +z axis), ``Pleg<i>_s1``, ``Pleg<i>_s2``,
  ``Pleg<i>_s3`` (a spherical joint at the platform joint, ``rod`` along the rod, as the hexapod's).
  The Delta's parallelogram forearm is one rod here (its position kinematics is that of a rod between
  the crank tip and the platform joint): universal at the crank tip, spherical -- not universal -- at
  the platform, since only three rotations bring the rod's frame back to the platform's (which only
  translates) whatever the arm's angle;
* actuated planar families (``planar_3rrr``): ``Pleg<i>_actuator`` (revolute about z at ``origin``,
  the crank's angle), ``Pleg<i>_elbow`` (revolute about z at the crank tip, the rod's angle minus the
  crank's: zero with the rod along the crank frame's +x axis), ``Pleg<i>_platform`` (revolute about z
  at B_i, ``rod`` along the rod: the platform's angle minus the rod's).
* rail-driven families (``linear_delta``, ``pus_6``, ``planar_3prr``): as the crank-driven ones with the
  crank replaced by a carriage: ``Pleg<i>_actuator`` is prismatic along the rail's ``axis`` from its
  ``origin`` (position = the carriage's place on the rail in metres, the reading plus the offset; link
  ``Pleg<i>_carriage``, the base's orientation), the rod's joints at the carriage (no crank tip offset).

Each leg's last link ``Pleg<i>_end`` sits at its platform joint B_i with the platform's
orientation; ``Pplatform_link`` is fixed to ``Pleg1_end`` (joint ``Pplatform_mount``, origin
-CB_1), so it is at the pose.  Velocities: each leg's joint rates are those that move its end
link with the platform (the twist), the leg's chain Jacobian solved (six joints, six
components; planar: three, three).  The actuated families' actuator angles come from the model's
inverse kinematics (the branch of :func:`~glpma_ros.models.legs.choose_root`, the one the readings are
solved with), their passive joints from the rod's direction as above.

No ROS import here: plain NumPy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..models.legs import PRISMATIC as PRISMATIC_ACTUATOR
from ..models.legs import REVOLUTE as REVOLUTE_ACTUATOR
from ..models.legs import actuator_roots, choose_root
from ..models.rotations import cross_rows, matrix_from_quaternion
from .limits import wrap

REVOLUTE, PRISMATIC, FIXED = "revolute", "prismatic", "fixed"
#: the leg whose chain carries the platform (the loop cut): leg 1, index 0
CUT_LEG = 0
#: a leg's universal / spherical joint at this angle (rad) off its middle joint's zero is at the
#: Euler angles' gimbal lock: the joint rates are then undetermined (the positions are not)
GIMBAL_MARGIN = 1e-9


@dataclass(frozen=True)
class JointSpec:
    """One joint of the tree: name, type, parent and child link, origin (metres, in the parent's
    frame, no rotation), axis (in the joint's frame) and limits (metres or radians; None: none)."""

    name: str
    type: str
    parent: str
    child: str
    origin: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)
    limits: tuple | None = None
    leg: int = -1              # 0-based leg index, -1 for the platform mount
    role: str = ""             # u1 u2 actuator s1 s2 s3 / base actuator platform / elbow / mount


class Mechanism:
    """The loop-cut tree of a manipulator model and its joint states at a pose.

    ``model``: a :class:`~glpma_ros.models.base.Manipulator` from a config (its ``metres_per_unit``
    and ``leg_limits`` used); ``prefix``: put before every link and joint name (e.g. ``left_``);
    ``passive_limits``: a :class:`~glpma_ros.description.limits.PassiveLimits` (or None) whose
    ranges become the URDF's limits of the passive joints."""

    def __init__(self, model, prefix: str = "", passive_limits=None):
        #: an actuated family: the legs are crank + rod (:mod:`glpma_ros.models.actuated`)
        self.actuated = bool(getattr(model, "actuated", False))
        self.rails = False
        if self.actuated:
            kinds = np.asarray(model.actuators)
            #: a rail-driven family (every actuator prismatic): carriages instead of cranks
            self.rails = bool(np.all(kinds == PRISMATIC_ACTUATOR))
            if not (self.rails or np.all(kinds == REVOLUTE_ACTUATOR)):
                raise InputError(f"no URDF for {model.kind} with mixed actuators (known: all revolute, all "
                                 f"prismatic)")
        elif model.kind not in ("hexapod_66", "planar_3rpr"):
            raise InputError(f"no URDF for manipulator kind {model.kind!r} (known: hexapod_66, planar_3rpr, "
                             f"the actuated families: delta, rus_6, planar_3rrr, linear_delta, pus_6, planar_3prr)")
        self.model = model
        self.prefix = str(prefix)
        self.planar = model.kind == "planar_3rpr" or (self.actuated and int(model.dim) == 2)
        self.metres = float(getattr(model, "metres_per_unit", 1.0))
        self.n_legs = int(model.n_legs)
        pts = np.asarray(model.base, dtype=float) * self.metres
        self.base_m = np.hstack((pts, np.zeros((self.n_legs, 1)))) if self.planar else pts
        pts = np.asarray(model.platform, dtype=float) * self.metres
        self.platform_m = np.hstack((pts, np.zeros((self.n_legs, 1)))) if self.planar else pts
        self.scale_m = float(model.scale) * self.metres
        self.passive_limits = passive_limits
        if self.actuated:
            self._actuated_geometry()
        self.joints = self._build()
        self.moving = tuple(j for j in self.joints if j.type != FIXED)
        #: names of the joints a JointState carries, in the order of :meth:`positions`
        self.joint_names = tuple(j.name for j in self.moving)
        self.per_leg = len(self.moving) // self.n_legs
        k = self.per_leg
        #: every leg's joints' origins and axes (n, per_leg, 3), each in its parent link's frame
        self._chains = tuple(np.array([[getattr(j, key) for j in self.moving[i * k:(i + 1) * k]]
                                       for i in range(self.n_legs)], dtype=float) for key in ("origin", "axis"))

    # -- names ----------------------------------------------------------------------------
    def name(self, text: str) -> str:
        return f"{self.prefix}{text}"

    @property
    def base_link(self) -> str:
        return self.name("base_link")

    @property
    def platform_link(self) -> str:
        return self.name("platform_link")

    def leg_link(self, leg: int, part: str) -> str:
        """Link ``part`` of leg ``leg`` (0-based): e.g. ``leg3_end``."""
        return self.name(f"leg{leg + 1}_{part}")

    # -- the tree -------------------------------------------------------------------------
    def _build(self) -> list:
        joints = []
        for i in range(self.n_legs):
            joints += self._leg_joints(i)
        mount = tuple(float(-v) for v in self.platform_m[CUT_LEG])
        joints.append(JointSpec(self.name("platform_mount"), FIXED, self.leg_link(CUT_LEG, "end"),
                                self.platform_link, mount, role="mount"))
        return joints

    def _actuator_limits(self) -> tuple:
        from ..config import plausible_band
        lo, hi = plausible_band(self.model)
        return (lo * self.metres, hi * self.metres)

    def _actuated_geometry(self) -> None:
        """The actuated legs' crank (3-D, metres), axis (planar: +z), rod (metres), offsets and limits."""
        m, n = self.model, self.n_legs
        crank = np.asarray(m.crank, dtype=float) * self.metres
        self.crank_m = np.hstack((crank, np.zeros((n, 1)))) if self.planar else crank
        axis = np.asarray(m.axis, dtype=float)
        if self.planar and self.rails:           # a planar rail's direction, in the plane
            self.axis_3d = np.hstack((axis, np.zeros((n, 1))))
        else:
            self.axis_3d = np.tile([0.0, 0.0, 1.0], (n, 1)) if self.planar else axis
        self.rods_m = np.asarray(m.rods, dtype=float) * self.metres
        self.offsets = np.zeros(n) if m.actuator_offsets is None else np.asarray(m.actuator_offsets, dtype=float)
        #: the motors' angle ranges as the model turns them (the readings' limits plus the offsets; config unit
        #: for rails)
        self.model_limits = (None if m.actuator_limits is None
                             else np.asarray(m.actuator_limits, dtype=float) + self.offsets[:, None])
        #: the actuator joints' positions in the joint states per model unit (rails: metres per config unit)
        self.actuator_scale = self.metres if self.rails else 1.0

    def _actuated_leg_joints(self, i: int) -> list:
        base, leg = self.base_link, lambda part: self.leg_link(i, part)
        a = tuple(float(v) for v in self.base_m[i])
        tip = tuple(float(v) for v in self.crank_m[i])
        full = (-math.pi, math.pi)
        if self.model_limits is None:
            motor = (-self.scale_m, self.scale_m) if self.rails else full
        else:
            motor = tuple(float(v) * self.actuator_scale for v in self.model_limits[i])

        def joint(part, parent, child, origin=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), limits=full):
            return JointSpec(self.name(f"leg{i + 1}_{part}"), REVOLUTE, parent, child, origin, axis, limits, i, part)
        arm = leg("carriage") if self.rails else leg("crank")
        actuator = JointSpec(self.name(f"leg{i + 1}_actuator"), PRISMATIC if self.rails else REVOLUTE, base, arm, a,
                             tuple(float(v) for v in self.axis_3d[i]), motor, i, "actuator")
        rod = float(self.rods_m[i])
        if self.planar:
            return [actuator, joint("elbow", arm, leg("rod"), tip),
                    joint("platform", leg("rod"), leg("end"), (rod, 0.0, 0.0))]
        half = 0.5 * math.pi
        return [actuator,
                joint("u1", arm, leg("u_cross"), tip, (1.0, 0.0, 0.0)),
                joint("u2", leg("u_cross"), leg("rod"), axis=(0.0, 1.0, 0.0), limits=(-half, half)),
                joint("s1", leg("rod"), leg("s_cross1"), (0.0, 0.0, rod), (1.0, 0.0, 0.0)),
                joint("s2", leg("s_cross1"), leg("s_cross2"), axis=(0.0, 1.0, 0.0), limits=(-half, half)),
                joint("s3", leg("s_cross2"), leg("end"))]

    def _leg_joints(self, i: int) -> list:
        if self.actuated:
            return self._actuated_leg_joints(i)
        base, leg, lim = self.base_link, lambda part: self.leg_link(i, part), self._limit
        a = tuple(float(v) for v in self.base_m[i])
        actuator, stroke = self.name(f"leg{i + 1}_actuator"), self._actuator_limits()
        if self.planar:
            return [
                JointSpec(self.name(f"leg{i + 1}_base"), REVOLUTE, base, leg("cylinder"), a, (0.0, 0.0, 1.0),
                          lim(i, "base", (-math.pi, math.pi)), i, "base"),
                JointSpec(actuator, PRISMATIC, leg("cylinder"), leg("rod"), axis=(1.0, 0.0, 0.0), limits=stroke,
                          leg=i, role="actuator"),
                JointSpec(self.name(f"leg{i + 1}_platform"), REVOLUTE, leg("rod"), leg("end"), axis=(0.0, 0.0, 1.0),
                          limits=lim(i, "platform", (-math.pi, math.pi)), leg=i, role="platform"),
            ]
        half = 0.5 * math.pi
        return [
            JointSpec(self.name(f"leg{i + 1}_u1"), REVOLUTE, base, leg("u_cross"), a, (1.0, 0.0, 0.0),
                      lim(i, "u1", (-math.pi, math.pi)), i, "u1"),
            JointSpec(self.name(f"leg{i + 1}_u2"), REVOLUTE, leg("u_cross"), leg("cylinder"), axis=(0.0, 1.0, 0.0),
                      limits=lim(i, "u2", (-half, half)), leg=i, role="u2"),
            JointSpec(actuator, PRISMATIC, leg("cylinder"), leg("rod"), axis=(0.0, 0.0, 1.0), limits=stroke,
                      leg=i, role="actuator"),
            JointSpec(self.name(f"leg{i + 1}_s1"), REVOLUTE, leg("rod"), leg("s_cross1"), axis=(1.0, 0.0, 0.0),
                      limits=lim(i, "s1", (-math.pi, math.pi)), leg=i, role="s1"),
            JointSpec(self.name(f"leg{i + 1}_s2"), REVOLUTE, leg("s_cross1"), leg("s_cross2"), axis=(0.0, 1.0, 0.0),
                      limits=lim(i, "s2", (-half, half)), leg=i, role="s2"),
            JointSpec(self.name(f"leg{i + 1}_s3"), REVOLUTE, leg("s_cross2"), leg("end"), axis=(0.0, 0.0, 1.0),
                      limits=(-math.pi, math.pi), leg=i, role="s3"),
        ]

    def _limit(self, leg: int, role: str, default: tuple) -> tuple:
        """A passive joint's range: from the config's ``passive_joint_limits`` where it bounds this
        joint (a cone angle bounds both joints of a universal joint and the first two of a spherical
        one: the cone lies inside that box), else ``default``."""
        if self.passive_limits is None:
            return default
        bound = self.passive_limits.joint_range(leg, role)
        if bound is None:
            return default
        return (max(default[0], bound[0]), min(default[1], bound[1]))

    # -- joint states ---------------------------------------------------------------------
    def legs_at(self, position_m, orientation):
        """``(R, B, d, L)``: the platform's rotation matrix, the platform joints B_i (base frame,
        metres), the leg vectors d_i = B_i - A_i and their lengths."""
        R = matrix_from_quaternion(orientation)
        p = np.asarray(position_m, dtype=float)
        B = p + self.platform_m @ R.T
        d = B - self.base_m
        return R, B, d, np.sqrt((d * d).sum(axis=1))

    def positions(self, position_m, orientation) -> np.ndarray:
        """Every moving joint's position (radians, metres; order :attr:`joint_names`) with the
        platform at ``position_m`` (metres) / ``orientation`` (unit quaternion x, y, z, w, platform
        to base).  Raises :class:`InputError` for a leg of zero length (its direction is undefined).
        Every leg at once (NumPy over the legs: the extras thread computes this for every pose)."""
        if self.actuated:
            return self._actuated_positions(position_m, orientation)
        R, _, d, L = self.legs_at(position_m, orientation)
        if np.any(L <= 0.0):
            raise InputError("a leg has zero length: its joints are undefined")
        q = np.empty((self.n_legs, self.per_leg))
        if self.planar:
            phi = np.arctan2(d[:, 1], d[:, 0])
            theta = math.atan2(R[1, 0], R[0, 0])
            q[:, 0], q[:, 1] = phi, L
            q[:, 2] = wrap(theta - phi)
            return q.ravel()
        u = d / L[:, None]
        q[:, 0] = np.arctan2(-u[:, 1], u[:, 2])                       # universal joint: u = Rx(q1) Ry(q2) e_z
        q[:, 1] = np.arctan2(u[:, 0], np.hypot(u[:, 1], u[:, 2]))
        q[:, 2] = L
        M = np.einsum("nji,jk->nik", self._rod_rotations(q[:, 0], q[:, 1]), R)   # end link relative to the rod
        q[:, 3] = np.arctan2(-M[:, 1, 2], M[:, 2, 2])                 # spherical joint: M = Rx(s1) Ry(s2) Rz(s3)
        q[:, 4] = np.arctan2(M[:, 0, 2], np.hypot(M[:, 0, 0], M[:, 0, 1]))
        q[:, 5] = np.arctan2(-M[:, 0, 1], M[:, 0, 0])
        return q.ravel()

    def motor_angles(self, B) -> np.ndarray:
        """The actuated legs' motor angles (radians, as the model turns them: reading + offset) that put
        each rod's end at the platform joint ``B`` (base frame, metres): the model's inverse kinematics
        per leg (:func:`~glpma_ros.models.legs.actuator_roots`, the branch of ``choose_root``)."""
        m = self.model
        distal = np.asarray(B, dtype=float)[:, :int(m.dim)] / self.metres
        out = np.empty(self.n_legs)
        for i in range(self.n_legs):
            roots = actuator_roots(int(m.actuators[i]), m.origin[i], m.axis[i], m.crank[i], float(m.rods[i]),
                                   distal[i])
            root = choose_root(roots, None if self.model_limits is None else self.model_limits[i])
            if root is None:
                raise InputError(f"leg {i + 1} cannot reach the pose within its actuator limits")
            out[i] = root
        return out

    def _crank_rotations(self, angles) -> np.ndarray:
        """Rot(axis_i, angle_i) for every leg, shape (n, 3, 3): the crank links' orientations (a carriage keeps
        the base's)."""
        if self.rails:
            return np.broadcast_to(np.eye(3), (self.n_legs, 3, 3))
        return _axis_rotations(self.axis_3d, angles)

    def _actuated_positions(self, position_m, orientation) -> np.ndarray:
        R, B, _, _ = self.legs_at(position_m, orientation)
        qa = self.motor_angles(B)
        Rc = self._crank_rotations(qa)
        if self.rails:                                                      # the carriages; the joint in metres
            qa = qa * self.actuator_scale
            P = self.base_m + qa[:, None] * self.axis_3d
        else:
            P = self.base_m + np.einsum("nij,nj->ni", Rc, self.crank_m)    # the crank tips
        e = B - P
        L = np.sqrt((e * e).sum(axis=1))
        if np.any(L <= 0.0):
            raise InputError("a rod has zero length: its joints are undefined")
        q = np.empty((self.n_legs, self.per_leg))
        q[:, 0] = qa
        if self.planar:
            phi = np.arctan2(e[:, 1], e[:, 0])
            theta = math.atan2(R[1, 0], R[0, 0])
            q[:, 1] = wrap(phi - (0.0 if self.rails else qa))
            q[:, 2] = wrap(theta - phi)
            return q.ravel()
        u = np.einsum("nji,nj->ni", Rc, e) / L[:, None]                      # the rod in the crank's frame
        q[:, 1] = np.arctan2(-u[:, 1], u[:, 2])                               # u = Rx(u1) Ry(u2) e_z
        q[:, 2] = np.arctan2(u[:, 0], np.hypot(u[:, 1], u[:, 2]))
        rod = np.einsum("nij,njk->nik", Rc, self._rod_rotations(q[:, 1], q[:, 2]))
        M = np.einsum("nji,jk->nik", rod, R)                                  # end link relative to the rod
        q[:, 3] = np.arctan2(-M[:, 1, 2], M[:, 2, 2])                         # M = Rx(s1) Ry(s2) Rz(s3)
        q[:, 4] = np.arctan2(M[:, 0, 2], np.hypot(M[:, 0, 0], M[:, 0, 1]))
        q[:, 5] = np.arctan2(-M[:, 0, 1], M[:, 0, 0])
        return q.ravel()

    def _actuated_velocities(self, q, B, v_B, w):
        """The actuated legs' joint rates: each leg's chain Jacobian (revolute joint at o with axis a:
        (a x (B - o), a); planar: its x, y and z rows) solved for its end link's twist (v_B, w).  The
        chain's frames are composed joint by joint, every leg at once."""
        n, k = self.n_legs, self.per_leg
        rows = [0, 1, 5] if self.planar else list(range(6))
        origins, axes = self._chains
        J = np.empty((n, len(rows), k))
        Ri, o = np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3))
        for c in range(k):
            o = o + np.einsum("nij,nj->ni", Ri, origins[:, c])
            a = np.einsum("nij,nj->ni", Ri, axes[:, c])
            if c == 0 and self.rails:              # the carriage: prismatic along a, (a, 0); it moves o along a
                J[:, :, c] = np.hstack((a, np.zeros_like(a)))[:, rows]
                o = o + q[:, c][:, None] * a
                continue
            J[:, :, c] = np.hstack((np.cross(a, B - o), a))[:, rows]
            Ri = np.einsum("nij,njk->nik", Ri, _axis_rotations(axes[:, c], q[:, c]))
        rhs = np.hstack((v_B, np.broadcast_to(w, v_B.shape)))[:, rows]
        return self._solve(J, rhs)

    @staticmethod
    def _rod_rotations(a, b) -> np.ndarray:
        """Rx(a) Ry(b) for arrays of angles, shape (n, 3, 3): the rods' orientations after the universal joints."""
        ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        out = np.empty((len(a), 3, 3))
        out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = cb, 0.0, sb
        out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = sa * sb, ca, -sa * cb
        out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = -ca * sb, sa, ca * cb
        return out

    def velocities(self, position_m, orientation, linear, angular, positions=None):
        """Every moving joint's rate (rad/s, m/s) for the platform's twist (``linear``: velocity of
        the platform frame's origin, ``angular``: angular velocity, both in the base frame), or
        None where a leg's joint rates are undetermined (a universal or spherical joint at its
        gimbal lock).  Per leg: the chain Jacobian (revolute joint at o with axis a: (a x (B - o),
        a); prismatic along u: (u, 0)) times the rates = the end link's twist (v + w x R CB_i, w);
        the joints at B_i move no point of B_i, so the universal joint and the actuator follow from
        B_i's velocity, then the spherical joint from the angular velocity left (two 3x3 solves)."""
        R, B, d, L = self.legs_at(position_m, orientation)
        q = (self.positions(position_m, orientation) if positions is None
             else np.asarray(positions, dtype=float)).reshape(self.n_legs, self.per_leg)
        v, w = np.asarray(linear, dtype=float), np.asarray(angular, dtype=float)
        w_rows = np.broadcast_to(w, B.shape)
        vB = v + cross_rows(w_rows, B - np.asarray(position_m, dtype=float))   # each platform joint's velocity
        if self.actuated:
            return self._actuated_velocities(q, B, vB, w)
        u = d / L[:, None]
        n = self.n_legs
        if self.planar:
            J = np.zeros((n, 3, 3))
            J[:, 0, 0], J[:, 1, 0], J[:, 2, 0] = -d[:, 1], d[:, 0], 1.0        # base revolute: e_z x d, 1
            J[:, 0, 1], J[:, 1, 1] = u[:, 0], u[:, 1]                         # actuator
            J[:, 2, 2] = 1.0                                                  # platform revolute
            rhs = np.stack((vB[:, 0], vB[:, 1], np.full(n, w[2])), axis=1)
            return self._solve(J, rhs)
        if np.any(np.abs(np.abs(q[:, [1, 4]]) - 0.5 * math.pi) < GIMBAL_MARGIN):
            return None
        ex = np.array([1.0, 0.0, 0.0])
        a1 = np.zeros((n, 3))                                                 # u2's axis: Rx(q1) e_y
        a1[:, 1], a1[:, 2] = np.cos(q[:, 0]), np.sin(q[:, 0])
        J = np.empty((n, 3, 3))
        J[:, 0, 0], J[:, 1, 0], J[:, 2, 0] = 0.0, -d[:, 2], d[:, 1]          # e_x x d
        J[:, :, 1] = cross_rows(a1, d)
        J[:, :, 2] = u
        lower = self._solve(J, vB)                                            # q1', q2', L'
        if lower is None:
            return None
        lower = lower.reshape(n, 3)
        rod = self._rod_rotations(q[:, 0], q[:, 1])
        c3, s3 = np.cos(q[:, 3]), np.sin(q[:, 3])
        K = np.empty((n, 3, 3))
        K[:, :, 0] = rod[:, :, 0]                                             # s1: the rod's x axis
        K[:, :, 1] = rod[:, :, 1] * c3[:, None] + rod[:, :, 2] * s3[:, None]  # s2: Rrod Rx(s1) e_y
        K[:, :, 2] = R[:, 2]                                                  # s3: the end link's z = platform's
        left = w - lower[:, [0]] * ex - lower[:, [1]] * a1                    # angular velocity past the rod
        upper = self._solve(K, left)
        if upper is None:
            return None
        return np.hstack((lower, upper.reshape(n, 3))).ravel()

    @staticmethod
    def _solve(A, b):
        """``A x = b`` for a stack of square systems, flattened; None when one is singular."""
        try:
            return np.linalg.solve(A, b[..., None])[..., 0].ravel()
        except np.linalg.LinAlgError:
            return None


def _axis_rotations(axes, angles) -> np.ndarray:
    """The rotations by ``angles`` (n,) about the unit ``axes`` (n, 3), shape (n, 3, 3) (Rodrigues' formula
    ``I + sin(t) K + (1 - cos(t)) K^2``, ``K`` the cross-product matrix of the axis)."""
    a = np.asarray(axes, dtype=float)
    t = np.asarray(angles, dtype=float)
    K = np.zeros((len(a), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -a[:, 2], a[:, 1], -a[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = a[:, 2], -a[:, 1], a[:, 0]
    return np.eye(3) + np.sin(t)[:, None, None] * K + (1.0 - np.cos(t))[:, None, None] * (K @ K)
