"""What the node publishes for a solved input besides the pose, transport-free.

For every pose published on ``pose_estimate`` (each switchable by a parameter):

* ``publish_tf``: the transform ``frame_id`` -> ``child_frame_id`` on ``/tf`` -- the pose itself,
  same stamp, same numbers;
* ``publish_covariance``: ``pose_estimate_cov``, the pose with the 6x6 covariance of
  :class:`~glpma_ros.estimation.covariance.PoseJacobian` for leg noise ``leg_noise_std``;
* ``publish_twist``: ``twist_estimate``, from the ``joint_states`` velocities by the forward
  velocity kinematics when the input carries them, else the finite difference
  (:mod:`glpma_ros.estimation.velocity`) of this pose and the previous one;
* ``publish_markers``: ``~/markers``, at most one every ``markers_period_s`` (by the stamps);
* ``publish_joint_states``: ``~/mechanism_joint_states``, every joint of the manipulator's URDF
  (:mod:`glpma_ros.description`) at the pose, with the joints' rates when the twist is computed
  (``publish_twist``; then even without a subscriber to ``twist_estimate``).

:class:`OutputBuilder` turns an :class:`~glpma_ros.node.service.Outcome` into
:class:`ExtraOutputs`; the transports turn those into messages.  One builder per service,
called by the one thread that solves at a time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from ..description.mechanism import Mechanism
from ..estimation.covariance import PoseJacobian
from ..estimation.velocity import finite_difference_twist
from ..models.rotations import matrix_from_quaternion

#: ``twist_estimate`` sources, as /diagnostics names them
TWIST_FROM_VELOCITIES = "joint_states velocities (forward velocity kinematics)"
TWIST_FROM_POSES = "finite difference of consecutive poses"
#: a finite difference over a longer gap between two poses is no velocity (tracking was interrupted)
TWIST_MAX_GAP_S = 1.0
#: the extra outputs, named as ``subscribed()`` names them, and the parameter switching each
OUTPUT_PARAMS = {"tf": "publish_tf", "covariance": "publish_covariance", "twist": "publish_twist",
                 "markers": "publish_markers", "joint_states": "publish_joint_states"}

#: visualization_msgs/Marker types and action used here
SPHERE_LIST, LINE_STRIP, LINE_LIST = 7, 4, 5
ADD = 0
#: marker sizes relative to the manipulator's size (its ``scale``): joint spheres, line widths
JOINT_SIZE = 0.04
LINE_WIDTH = 0.01
#: colours (r, g, b, a)
BASE_COLOUR = (0.55, 0.55, 0.6, 1.0)
PLATFORM_COLOUR = (0.95, 0.65, 0.1, 1.0)
SHORT_LEG_COLOUR = (0.1, 0.35, 1.0, 1.0)     # the shortest leg length of the colour range
LONG_LEG_COLOUR = (1.0, 0.15, 0.1, 1.0)      # the longest


@dataclass(frozen=True)
class MarkerOutput:
    """One ``visualization_msgs/Marker`` (ADD, identity pose, points in the header's frame, metres)."""

    ns: str
    id: int
    type: int
    scale: tuple
    color: tuple
    points: tuple = ()
    colors: tuple = ()
    action: int = ADD


@dataclass(slots=True)          # built for every pose: no frozen-dataclass overhead
class ExtraOutputs:
    """The further messages of one published pose; a field is None when its output is off
    (or, for the twist, not available yet)."""

    stamp_ns: int
    frame_id: str
    position: tuple                  # metres, as on pose_estimate
    orientation: tuple
    child_frame_id: str | None = None     # /tf when set
    covariance: tuple | None = None       # 36 numbers, row-major, m^2 / rad^2
    covariance_capped: bool = False
    twist: tuple | None = None            # ((vx, vy, vz), (wx, wy, wz)), m/s and rad/s, base frame
    twist_source: str | None = None
    markers: tuple | None = None          # MarkerOutput, ...
    joint_names: tuple | None = None      # ~/mechanism_joint_states when set: the URDF's moving joints,
    joint_positions: tuple = ()           # their positions (rad, m) and
    joint_velocities: tuple = ()          # rates (rad/s, m/s; empty without a twist)
    publish_twist: bool = True            # False: the twist was computed for the joints' rates only

    @property
    def any(self) -> bool:
        return (self.child_frame_id is not None or self.covariance is not None or self.twist_out
                or self.markers is not None or self.joint_names is not None)

    @property
    def twist_out(self) -> bool:
        """Whether ``twist_estimate`` goes out."""
        return self.twist is not None and self.publish_twist


def polygon_order(points: np.ndarray) -> list:
    """Indices of ``points`` (n, 2 or 3) by angle about their centroid in their best-fit plane."""
    centred = points - points.mean(axis=0)
    if centred.shape[1] == 2:
        u, v = centred[:, 0], centred[:, 1]
    else:
        _, _, vt = np.linalg.svd(centred)
        u, v = centred @ vt[0], centred @ vt[1]
    return [int(i) for i in np.argsort(np.arctan2(v, u))]


def _as_3d(points: np.ndarray) -> np.ndarray:
    return np.hstack((points, np.zeros((points.shape[0], 1)))) if points.shape[1] == 2 else points


def _blend(a: tuple, b: tuple, t: float) -> tuple:
    return tuple(float(x + (y - x) * t) for x, y in zip(a, b))


class OutputBuilder:
    """Builds :class:`ExtraOutputs` for the poses of one manipulator."""

    def __init__(self, model, urdf_prefix: str = ""):
        self.model = model
        self.mechanism = Mechanism(model, prefix=urdf_prefix, passive_limits=getattr(model, "passive_limits", None))
        self.passive_limits = getattr(model, "passive_limits", None)
        self.limit_poses = 0             # poses with a passive joint beyond its limit, so far
        self.last_violation = None       # the joints of the last such pose, as text
        self.metres_per_unit = float(model.metres_per_unit)
        self.jacobian = PoseJacobian(model)
        #: an actuated family (:mod:`glpma_ros.models.actuated`): legs drawn as crank + rod
        self.actuated = bool(getattr(model, "actuated", False))
        self._without: dict = {}         # redundant legs: leg left out -> the Jacobian of the others
        self.size_m = float(model.scale) * self.metres_per_unit
        self.base_m = _as_3d(model.base) * self.metres_per_unit
        self.platform_m = _as_3d(model.platform) * self.metres_per_unit
        self._base_points = tuple(tuple(float(v) for v in a) for a in self.base_m)
        self._base_loop = [int(i) for i in polygon_order(model.base)]
        self._platform_loop = [int(i) for i in polygon_order(model.platform)]
        limits = model.leg_limits
        self._leg_range = ((limits[0] * self.metres_per_unit, limits[1] * self.metres_per_unit)
                           if limits is not None else None)
        self.reset()

    def reset(self) -> None:
        """Forget the previous pose (no finite difference across a restart of tracking) and the
        colour range of the legs seen so far."""
        self.reset_previous()
        self._last_markers_ns = None
        self._seen = [math.inf, -math.inf]
        self.capped = 0                  # covariances capped at a singularity so far
        self.twist_source = None         # of the last twist published

    def reset_previous(self) -> None:
        """Forget the previous pose: the next twist by finite difference waits for two poses."""
        self._previous = None            # (stamp_ns, position (m), orientation)

    def build(self, outcome, params: dict, twist_for_joints: bool = False) -> ExtraOutputs:
        """The outputs for ``outcome`` (a published pose) under ``params``; ``twist_for_joints``: compute
        the twist (as ``publish_twist`` would) for the joints' rates even though ``publish_twist`` is off
        here (no subscriber to ``twist_estimate``)."""
        twist_only_for_joints = twist_for_joints and not params["publish_twist"]
        if twist_only_for_joints:
            params = {**params, "publish_twist": True}
        pose, estimate = outcome.pose, outcome.estimate
        stamp_ns = pose.stamp_ns
        rates = outcome.leg_rates_m if params["publish_twist"] else None
        covariance = capped = None
        left_out = getattr(estimate, "excluded_leg", None)
        jacobian = self._jacobian_without(left_out)
        if rates is not None and left_out is not None:
            rates = np.delete(rates, left_out)
        if params["publish_covariance"] or rates is not None:
            # an actuated family: the Jacobian of its actuators at this input's proximal points, each
            # actuator with its own noise (revolute: actuator_noise_std, rad; prismatic: leg_noise_std, m)
            capped = jacobian.solve(estimate.pose.position, estimate.pose.orientation,
                                    params["leg_noise_std"], rates, self.metres_per_unit,
                                    outcome.legs if self.actuated else None, params["actuator_noise_std"])
            if params["publish_covariance"]:
                covariance = tuple(jacobian.covariance.ravel().tolist())
                self.capped += bool(capped)
        twist = source = None
        if rates is not None:
            t = jacobian.twist.tolist()
            twist, source = (tuple(t[:3]), tuple(t[3:])), TWIST_FROM_VELOCITIES
        elif params["publish_twist"] and self._previous is not None:
            t0, p0, q0 = self._previous
            if 0 < stamp_ns - t0 <= TWIST_MAX_GAP_S * 1e9:
                twist = finite_difference_twist(p0, q0, pose.position, pose.orientation, (stamp_ns - t0) * 1e-9)
                source = TWIST_FROM_POSES
        if source is not None:
            self.twist_source = source
        self._previous = (stamp_ns, pose.position, pose.orientation)
        markers = None
        if params["publish_markers"] and (self._last_markers_ns is None or
                                          stamp_ns - self._last_markers_ns >= params["markers_period_s"] * 1e9):
            markers = self.markers(pose.position, pose.orientation, outcome.legs * self.metres_per_unit)
            self._last_markers_ns = stamp_ns
        out = ExtraOutputs(stamp_ns, pose.frame_id, pose.position, pose.orientation,
                           params["child_frame_id"] if params["publish_tf"] else None,
                           covariance, bool(capped), twist, source, markers, publish_twist=not twist_only_for_joints)
        if params.get("publish_joint_states"):
            self.joint_states(out)
        return out

    def check_limits(self, outcome) -> None:
        """Count ``outcome``'s pose when a passive joint is beyond the config's limits (and name them)."""
        if self.passive_limits is None or outcome.pose is None:
            return
        found = self.passive_limits.violations(self.mechanism, outcome.pose.position, outcome.pose.orientation)
        if found:
            self.limit_poses += 1
            self.last_violation = "; ".join(str(v) for v in found)

    def joint_states(self, out: ExtraOutputs) -> None:
        """Fill ``out``'s joint fields: every moving joint of the URDF at ``out``'s pose, with rates
        from ``out.twist`` when there is one (and the legs are clear of a gimbal lock)."""
        mech = self.mechanism
        q = mech.positions(out.position, out.orientation)
        rates = None
        if out.twist is not None:
            rates = mech.velocities(out.position, out.orientation, out.twist[0], out.twist[1], q)
        out.joint_names = mech.joint_names
        out.joint_positions = tuple(q.tolist())
        out.joint_velocities = () if rates is None else tuple(rates.tolist())

    def _jacobian_without(self, leg):
        """The leg Jacobian of the legs a pose used: every leg, or all but ``leg`` (redundant legs, the
        faulty one left out of the pose: its covariance and twist are those of the other legs)."""
        if leg is None:
            return self.jacobian
        if leg not in self._without:
            m = self.model
            keep = [i for i in range(m.n_legs) if i != leg]
            self._without[leg] = PoseJacobian(SimpleNamespace(base=m.base[keep], platform=m.platform[keep],
                                                              metres_per_unit=self.metres_per_unit, scale=m.scale,
                                                              n_legs=len(keep)))
        return self._without[leg]

    def markers(self, position_m, orientation, legs_m) -> tuple:
        """Base joints, platform joints, the legs (coloured by length: blue = short, red = long,
        over ``leg_limits`` when the config has them, else over the lengths seen so far), the
        base and platform polygons -- all in the base frame, metres."""
        R = matrix_from_quaternion(orientation)
        joints = np.asarray(position_m, dtype=float) + self.platform_m @ R.T          # B_i
        platform_points = tuple(tuple(float(v) for v in b) for b in joints)
        leg_points, leg_colours = [], []
        if self.actuated:        # each leg: the crank (actuated joint to proximal point), then the rod
            n = self.model.n_legs
            proximal = _as_3d(np.asarray(legs_m[n:], dtype=float).reshape(n, -1))
            for a, p, b in zip(self._base_points, proximal, platform_points):
                p = tuple(float(v) for v in p)
                leg_points += (a, p, p, b)
                leg_colours += (BASE_COLOUR, BASE_COLOUR, LONG_LEG_COLOUR, LONG_LEG_COLOUR)
        else:
            lo, hi = self._leg_range if self._leg_range is not None else self._seen_range(legs_m)
            for a, b, length in zip(self._base_points, platform_points, legs_m):
                t = min(max((float(length) - lo) / (hi - lo), 0.0), 1.0) if hi > lo else 0.5
                colour = _blend(SHORT_LEG_COLOUR, LONG_LEG_COLOUR, t)
                leg_points += (a, b)
                leg_colours += (colour, colour)
        joint = (JOINT_SIZE * self.size_m,) * 3
        line = (LINE_WIDTH * self.size_m, 0.0, 0.0)
        return (
            MarkerOutput("base_joints", 0, SPHERE_LIST, joint, BASE_COLOUR, self._base_points),
            MarkerOutput("platform_joints", 1, SPHERE_LIST, joint, PLATFORM_COLOUR, platform_points),
            MarkerOutput("legs", 2, LINE_LIST, line, LONG_LEG_COLOUR, tuple(leg_points), tuple(leg_colours)),
            MarkerOutput("base", 3, LINE_STRIP, line, BASE_COLOUR,
                         tuple(self._base_points[i] for i in self._base_loop + self._base_loop[:1])),
            MarkerOutput("platform", 4, LINE_STRIP, line, PLATFORM_COLOUR,
                         tuple(platform_points[i] for i in self._platform_loop + self._platform_loop[:1])),
        )

    def _seen_range(self, legs_m) -> tuple:
        self._seen[0] = min(self._seen[0], float(np.min(legs_m)))
        self._seen[1] = max(self._seen[1], float(np.max(legs_m)))
        return self._seen[0], self._seen[1]
