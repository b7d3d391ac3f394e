"""Which input each pose of the node answers, exactly, and how far it is from the truth.

Used by the tools (mock controller, stress test, benchmark) and by :mod:`glpma_ros.testing` for
users' launch tests; plain NumPy and the manipulator models, no ROS, no tools.

The node stamps a pose with the arrival time of its ``leg_lengths`` message, or with the
``header.stamp`` of its ``joint_states`` message.

* ``joint_state`` input: the controller stamps each message with its send time, unique per
  input, so a pose's stamp names its input.
* ``float64_multi_array`` input: the controller does not see the arrival time, but a correct pose
  reproduces its input's legs to round-off (inverse kinematics of the pose), and the simulated
  motion's legs repeat only a whole loop later (:mod:`glpma_tools.sim.trajectories`).  A pose is paired with the
  latest input, sent before its stamp, whose legs it reproduces to :data:`LEGS_MATCH_REL` of the
  scale; an input with the same legs from the loop before would have had to spend a whole period
  in transit, which a DDS keep-last history of a few samples cannot hold while inputs keep coming.
  (When the node runs on another machine whose clock disagrees, so that no such input was sent
  before the stamp, the one sent nearest the stamp.)

A pose that reproduces no input's legs, or a second pose for the same input, pairs with nothing:
it is wrong.  Poses are the tuples of :class:`.controller.PoseListener`: (receive time ns, stamp
ns, frame_id, position in metres (3,), quaternion [x, y, z, w] (4,)); an input ("sent") is anything
with ``send_ns``, ``legs`` (config unit), ``position_m`` and ``quaternion`` (:class:`glpma_tools.sim.controller.Sent`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: a pose pairs with an input whose legs it reproduces to this share of the geometry's scale:
#: far above the round-off of a converged solve (~1e-12) and far below the legs' change between
#: two inputs (~1e-5 of the scale in the stress test's burst)
LEGS_MATCH_REL = 1e-8
#: a pose is right when it is this close to the true pose (REP 103 units)
POSITION_TOL_M = 1e-6
ORIENTATION_TOL_RAD = 1e-6


def legs_for(model, position, quaternion) -> np.ndarray:
    """What the leg sensors read (config unit) at a pose (config unit, quaternion [x, y, z, w]): the
    inverse kinematics less the config's ``leg_offsets``, which the node adds back."""
    return model.sensors_from_legs(model.inverse_kinematics(model.variables_from_pose(position, quaternion)))


def quaternion_angle(q1, q2) -> float:
    """Rotation angle (rad) between two unit quaternions [x, y, z, w], robust near 0."""
    a = np.asarray(q1, dtype=float)
    b = np.asarray(q2, dtype=float)
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    # relative rotation conj(a) * b: vector part and scalar part
    w = float(a @ b)
    v = a[3] * b[:3] - b[3] * a[:3] - np.cross(a[:3], b[:3])
    return 2.0 * math.atan2(float(np.linalg.norm(v)), abs(w))


@dataclass
class Comparison:
    """Poses paired with their inputs; per pair (in input order) the input's index, the latency
    (input written -> pose received, ms), the distance to the true pose (m, rad) and the largest
    difference between the legs of the pose and its input (m)."""

    index: np.ndarray
    poses: list
    latency_ms: np.ndarray
    position_error_m: np.ndarray
    orientation_error_rad: np.ndarray
    legs_residual_m: np.ndarray
    unpaired: list = field(default_factory=list)

    @property
    def on_truth(self) -> np.ndarray:
        """Per pair: the pose is the true one (the input's assembly mode, to the tolerances)."""
        return (self.position_error_m <= POSITION_TOL_M) & (self.orientation_error_rad <= ORIENTATION_TOL_RAD)


def _pose_legs(model, pose) -> np.ndarray | None:
    try:
        with np.errstate(all="ignore"):
            legs = legs_for(model, np.asarray(pose[3]) / model.metres_per_unit, pose[4])
    except Exception:  # noqa: BLE001 - a garbage pose (NaN, zero quaternion) pairs with nothing
        return None
    return legs if np.all(np.isfinite(legs)) else None


def pair(model, sent: list, poses: list, by_stamp: bool = False, legs_of=None) -> tuple[list, list]:
    """``([(input index, pose, legs of the pose or None)], unpaired poses)``: each pose with the
    input it answers (see the module docstring); ``by_stamp`` for ``joint_state`` input.
    ``sent``: :class:`.controller.Sent`; ``legs_of(pose)``: the legs a pose stands for (config
    unit, None for none; default: by inverse kinematics of the pose)."""
    legs_of = legs_of or (lambda pose: _pose_legs(model, pose))
    if not sent:
        return [], list(poses)
    send_ns = np.array([s.send_ns for s in sent], dtype=np.int64)
    taken = np.zeros(len(sent), dtype=bool)
    pairs, unpaired = [], []
    if by_stamp:
        by_send = {int(t): i for i, t in enumerate(send_ns)}
        for pose in poses:
            i = by_send.get(int(pose[1]))
            if i is None or taken[i]:
                unpaired.append(pose)
            else:
                taken[i] = True
                pairs.append((i, pose, None))
        return sorted(pairs, key=lambda p: p[0]), unpaired
    legs_all = np.array([s.legs for s in sent], dtype=float)
    order = np.argsort(legs_all[:, 0], kind="stable")
    first = legs_all[order, 0]
    tol = LEGS_MATCH_REL * model.scale
    for pose in poses:
        legs = legs_of(pose)
        if legs is None:
            unpaired.append(pose)
            continue
        near = order[np.searchsorted(first, legs[0] - tol, "left"):np.searchsorted(first, legs[0] + tol, "right")]
        near = near[np.max(np.abs(legs_all[near] - legs), axis=1) <= tol] if near.size else near
        if near.size == 0:
            unpaired.append(pose)
            continue
        before = near[send_ns[near] <= pose[1]]
        # on one machine the input was sent before the node stamped its arrival: the latest such;
        # the clocks of two machines may disagree, and then the one sent nearest the stamp
        i = int(before.max()) if before.size else int(near[np.argmin(np.abs(send_ns[near] - pose[1]))])
        if taken[i]:
            unpaired.append(pose)
            continue
        taken[i] = True
        pairs.append((i, pose, legs))
    return sorted(pairs, key=lambda p: p[0]), unpaired


def compare(model, sent: list, poses: list, by_stamp: bool = False) -> Comparison:
    """:func:`pair`, then each pose against its input's true pose and legs."""
    pairs, unpaired = pair(model, sent, poses, by_stamp)
    mpu = float(model.metres_per_unit)
    lat, pos, ang, res = [], [], [], []
    for i, pose, legs in pairs:
        recv_ns, _, _, position_m, quaternion = pose
        lat.append((recv_ns - sent[i].send_ns) * 1e-6)
        pos.append(float(np.linalg.norm(np.asarray(position_m) - sent[i].position_m)))
        ang.append(quaternion_angle(quaternion, sent[i].quaternion))
        legs = _pose_legs(model, pose) if legs is None else legs
        res.append(math.inf if legs is None else float(np.max(np.abs(legs - sent[i].legs))) * mpu)
    return Comparison(np.array([i for i, _, _ in pairs], dtype=int), [p for _, p, _ in pairs], np.array(lat),
                      np.array(pos), np.array(ang), np.array(res), unpaired)


def split_at_stamp(sent: list, index, poses: list) -> tuple[np.ndarray, np.ndarray]:
    """For poses stamped with their input's arrival time at the node (``leg_lengths`` input, one
    clock) paired with ``sent[index]``: the latency split at the stamp, ``(written -> taken by
    the node, taken -> pose received)`` in ms per pose."""
    send_ns = np.array([sent[i].send_ns for i in index], dtype=np.int64)
    stamp_ns = np.array([p[1] for p in poses], dtype=np.int64)
    recv_ns = np.array([p[0] for p in poses], dtype=np.int64)
    return (stamp_ns - send_ns) * 1e-6, (recv_ns - stamp_ns) * 1e-6
