"""The measurements of ``glpma-fk calibrate``: a CSV file or a rosbag2 directory, read into
:class:`~glpma_ros.calibration.identify.Measurements` (config unit), with one-line errors.

CSV: a header row naming the columns, ``leg_1 .. leg_n`` (the sensors' readings: leg lengths in the
config unit; an actuated family's actuator positions, radians for revolute and the config unit for
prismatic actuators) and the measured pose in the base frame, planar ``x y theta`` (config unit,
radians), spatial ``x y z qx qy qz qw`` (config unit, unit quaternion platform -> base), a platform that
only translates (Delta) ``x y z`` (the quaternion columns optional: its orientation is the base's, a
measured one must be within :data:`MAX_TRANSLATION_TILT_DEG` of it); the columns in any order, one
measurement per row, commas between values.

rosbag2 (MCAP or SQLite3, read with ``rosbags``): leg readings on ``--legs-topic`` as the node takes
them -- ``std_msgs/msg/Float64MultiArray`` (metres, leg order; its time is the bag's log time, as the
node stamps a pose with its arrival) or ``sensor_msgs/msg/JointState`` (joints ``leg_1 .. leg_n``,
metres; its header.stamp; an actuated family's actuator positions, radians / metres) -- and the
reference ``geometry_msgs/msg/PoseStamped`` on ``--pose-topic``
(metres; its header.stamp).  A pose and a leg reading are a measurement when each is the other's
nearest in time and they are at most ``--max-dt`` apart, so every message is used at most once
whatever the two rates.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..models.actuated import DeltaTranslation
from ..models.rotations import matrix_from_quaternion, quaternion_from_matrix
from ..node.dds.rosbag import (
    FLOAT64_MULTI_ARRAY,
    JOINT_STATE,
    NS_PER_S,
    POSE_STAMPED,
    decode_float64_multi_array,
    decode_joint_state,
    open_bag,
)
from .identify import Geometry, Measurements

#: a quaternion whose norm is farther than this from 1 is refused (a unit quaternion written with
#: 6 decimals is within 1e-6; anything far off is a wrong column, not rounding); the rest are normalised
QUATERNION_NORM_TOL = 1e-3
#: default --max-dt (s): a pose and a leg reading more than 5 ms apart are no measurement (a
#: calibration holds the platform still while the instrument measures; 5 ms is half a period at 100 Hz)
MAX_DT_S = 0.005
#: a platform that only translates: a measured orientation farther than this from the base's (degrees) is
#: refused -- an instrument aligned with the base frame reports it within its noise (a tracker: below
#: 0.01 degree), so a degree off is a frame not aligned with the base, not noise
MAX_TRANSLATION_TILT_DEG = 1.0
#: the orientation columns of a spatial pose
QUATERNION_COLUMNS = ("qx", "qy", "qz", "qw")


def geometry_of(model) -> Geometry:
    """The calibration's view of a loaded manipulator (:class:`~.parameters.Geometry`): a length-actuated
    model's base and platform joints and ``leg_offsets``; an actuated family's legs (one actuator kind for
    every leg) and ``actuator_offsets``."""
    n = model.base.shape[0]
    if not getattr(model, "actuated", False):
        return Geometry(model.base.copy(), model.platform.copy(),
                        np.zeros(n) if model.leg_offsets is None else model.leg_offsets.copy())
    offsets = np.zeros(n) if model.actuator_offsets is None else np.array(model.actuator_offsets, dtype=float)
    return Geometry(model.origin.copy(), np.array(model.platform, dtype=float), offsets, int(model.actuators[0]),
                    model.crank.copy(), model.axis.copy(), model.rods.copy(), isinstance(model, DeltaTranslation))


def rotation_2d(theta) -> np.ndarray:
    """(m, 2, 2) rotations of angles ``theta`` (m,)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack((np.stack((c, -s), -1), np.stack((s, c), -1)), -2)


def pose_columns(dim: int, translation: bool = False) -> tuple:
    """The pose columns of a calibration CSV: planar ``x y theta``, spatial ``x y z qx qy qz qw``, a
    platform that only translates ``x y z``."""
    if dim == 2:
        return ("x", "y", "theta")
    return ("x", "y", "z") if translation else ("x", "y", "z", *QUATERNION_COLUMNS)


def pose_values(position, rotation, translation: bool = False) -> np.ndarray:
    """Rows of the pose columns for poses (m, d) / (m, d, d)."""
    if translation:
        return np.asarray(position, dtype=float)
    if position.shape[1] == 2:
        return np.column_stack((position, np.arctan2(rotation[:, 1, 0], rotation[:, 0, 0])))
    return np.column_stack((position, np.array([quaternion_from_matrix(R) for R in rotation])))


def rotations_from_values(values) -> np.ndarray:
    """Rotations (m, d, d) from the orientation columns: planar theta (m,), spatial quaternions (m, 4)."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        return rotation_2d(values)
    return np.array([matrix_from_quaternion(q) for q in values])


def leg_columns(n_legs: int) -> list:
    return [f"leg_{i + 1}" for i in range(n_legs)]


def _check_pose_values(values: np.ndarray, dim: int, where) -> np.ndarray:
    """Orientation values of the rows (planar theta; quaternions normalised), or InputError."""
    if dim == 2:
        return values
    norm = np.linalg.norm(values, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_NORM_TOL)
    if bad.size:
        raise InputError(f"{where(bad[0])}: the quaternion qx qy qz qw has norm {norm[bad[0]]:.6g}, "
                         f"not 1 (a unit quaternion platform -> base)")
    return values / norm[:, None]


def _translation_rotations(quaternion, where) -> np.ndarray:
    """Identity rotations (m, 3, 3) of a platform that only translates, after checking that the measured
    orientations ``quaternion`` (m, 4; unit, or None when not measured) are the base's (MAX_TRANSLATION_TILT_DEG)."""
    if quaternion is not None and len(quaternion):
        angle = np.degrees(2.0 * np.arccos(np.minimum(np.abs(quaternion[:, 3]), 1.0)))
        bad = np.flatnonzero(angle > MAX_TRANSLATION_TILT_DEG)
        if bad.size:
            raise InputError(f"{where(bad[0])}: the platform only translates, but the measured orientation is "
                             f"{angle[bad[0]]:.3g} degrees from the base's (more than {MAX_TRANSLATION_TILT_DEG:g}): "
                             f"align the instrument's frame with the base, or leave the orientation out")
    m = 0 if quaternion is None else len(quaternion)
    return np.broadcast_to(np.eye(3), (m, 3, 3)).copy()


def read_csv(path: Path, n_legs: int, dim: int, unit: str, actuated: bool = False,
             translation: bool = False) -> Measurements:
    """The measurements of a calibration CSV for ``n_legs`` legs in ``dim`` dimensions (``actuated``: the
    readings are actuator positions, any sign; ``translation``: a platform that only translates)."""
    want = leg_columns(n_legs) + list(pose_columns(dim, translation))
    optional = list(QUATERNION_COLUMNS) if translation else []
    try:
        with open(path, newline="") as f:
            rows = [(k + 1, row) for k, row in enumerate(csv.reader(f)) if row and any(c.strip() for c in row)]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    except csv.Error as exc:
        raise InputError(f"{path}: not a CSV file ({exc})") from None
    if not rows:
        raise InputError(f"{path} is empty; expected a header row ({' '.join(want)}) and one row per measurement")
    line0, header = rows[0]
    header = [h.strip() for h in header]
    unknown = [h for h in header if h not in want + optional]
    if unknown:
        raise InputError(f"{path} line {line0}: unknown column {unknown[0]!r}; expected the columns "
                         f"{' '.join(want)} (a header row first)")
    missing = [w for w in want if w not in header]
    if missing:
        raise InputError(f"{path} line {line0}: no column {missing[0]!r}; expected the columns {' '.join(want)}")
    if len(set(header)) < len(header):
        twice = next(h for h in header if header.count(h) > 1)
        raise InputError(f"{path} line {line0}: column {twice!r} appears twice")
    given = [o for o in optional if o in header]
    if given and len(given) < len(optional):
        raise InputError(f"{path} line {line0}: the orientation needs all of {' '.join(optional)} (or none of them)")
    want = want + given
    order = [header.index(w) for w in want]
    table = np.empty((len(rows) - 1, len(want)))
    lines = np.array([line for line, _ in rows[1:]], dtype=int)
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputError(f"{path} line {line}: {len(row)} values, expected {len(header)} (one per column)")
        for c, k in enumerate(order):
            try:
                table[r, c] = float(row[k])
            except ValueError:
                raise InputError(f"{path} line {line}, column {want[c]}: {row[k].strip()!r} is not a number") from None
    bad = np.argwhere(~np.isfinite(table))
    if bad.size:
        r, c = bad[0]
        raise InputError(f"{path} line {lines[r]}, column {want[c]}: not a finite number")
    legs = table[:, :n_legs]
    bad = np.argwhere(legs <= 0.0)
    if bad.size and not actuated:
        r, c = bad[0]
        raise InputError(f"{path} line {lines[r]}, column {want[c]}: leg lengths must be positive ({unit})")
    if translation:
        quaternion = _check_pose_values(table[:, n_legs + 3:], 3, lambda r: f"{path} line {lines[r]}") \
            if given else None
        rotation = _translation_rotations(quaternion, lambda r: f"{path} line {lines[r]}")
        return Measurements(legs, table[:, n_legs:n_legs + 3], rotation if given else
                            np.broadcast_to(np.eye(3), (len(legs), 3, 3)).copy())
    orientation = _check_pose_values(table[:, n_legs + dim:] if dim == 3 else table[:, n_legs + 2],
                                     dim, lambda r: f"{path} line {lines[r]}")
    return Measurements(legs, table[:, n_legs:n_legs + dim], rotations_from_values(orientation))


@dataclass
class BagInfo:
    """What a bag held: the topics used, their message counts and the measurements paired."""

    legs_topic: str
    pose_topic: str
    legs_messages: int
    pose_messages: int
    paired: int

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def _pick_topic(by_topic: dict, given: str | None, types, option: str, path) -> str:
    if given is not None:
        topic = "/" + given.lstrip("/")
        if topic not in by_topic:
            listed = ", ".join(f"{t} ({'/'.join(sorted(ts))})" for t, ts in sorted(by_topic.items())) or "none"
            raise InputError(f"{path} has no topic {topic} (topics: {listed})")
        other = by_topic[topic] - set(types)
        if other:
            raise InputError(f"topic {topic} has type {', '.join(sorted(other))}, expected {' or '.join(types)}")
        return topic
    found = sorted(t for t, ts in by_topic.items() if ts & set(types))
    if len(found) != 1:
        what = "none" if not found else ", ".join(found)
        raise InputError(f"{path}: {len(found)} topics of type {' or '.join(types)} ({what}); choose one with {option}")
    return found[0]


def nearest_pairs(t_legs: np.ndarray, t_pose: np.ndarray, max_dt_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices (legs, poses) of the pairs that are each other's nearest in time and at most
    ``max_dt_ns`` apart; both time arrays sorted ascending."""
    if not len(t_legs) or not len(t_pose):
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)

    def nearest(t, ref):
        """Index of the element of ``ref`` nearest to each of ``t`` (the earlier one on a tie)."""
        k = np.searchsorted(ref, t)
        lo, hi = np.clip(k - 1, 0, len(ref) - 1), np.clip(k, 0, len(ref) - 1)
        return np.where(np.abs(ref[lo] - t) <= np.abs(ref[hi] - t), lo, hi)
    leg_of_pose = nearest(t_pose, t_legs)
    pose_of_leg = nearest(t_legs, t_pose)
    poses = np.arange(len(t_pose))
    mutual = pose_of_leg[leg_of_pose] == poses
    close = np.abs(t_legs[leg_of_pose] - t_pose) <= max_dt_ns
    keep = mutual & close
    return leg_of_pose[keep], poses[keep]


def read_bag(path: Path, n_legs: int, dim: int, metres_per_unit: float, legs_topic: str | None,
             pose_topic: str | None, max_dt_s: float, readings_from_si=None,
             translation: bool = False) -> tuple[Measurements, BagInfo]:
    """The measurements of a rosbag2 (config unit), paired as the module docstring says.
    ``readings_from_si``: an actuated family's readings (m, n) in SI to the config's units (default: leg
    lengths, metres to the config unit; the readings of an actuated family may have any sign)."""
    from rosbags.typesys import Stores, get_typestore  # the bag extra: optional, imported where used

    ts = get_typestore(Stores.ROS2_JAZZY)
    reader = open_bag(Path(path))
    try:
        by_topic: dict = {}
        for c in reader.connections:
            by_topic.setdefault(c.topic, set()).add(c.msgtype)
        legs_topic = _pick_topic(by_topic, legs_topic, (FLOAT64_MULTI_ARRAY, JOINT_STATE), "--legs-topic", path)
        pose_topic = _pick_topic(by_topic, pose_topic, (POSE_STAMPED,), "--pose-topic", path)
        names = leg_columns(n_legs)
        legs_t, legs_v, pose_t, pose_v = [], [], [], []
        conns = [c for c in reader.connections if c.topic in (legs_topic, pose_topic)]
        for c, t, raw in reader.messages(connections=conns):
            try:
                if c.topic == pose_topic:
                    msg = ts.deserialize_cdr(raw, POSE_STAMPED)
                elif c.msgtype == JOINT_STATE:
                    joints, positions, stamp_ns = decode_joint_state(raw, ts)
                else:
                    data = decode_float64_multi_array(raw, ts)
            except Exception as exc:  # noqa: BLE001 - a corrupt message: named, one line
                raise InputError(f"{path}: cannot decode a {c.msgtype} on {c.topic} at log time {t} ns "
                                 f"({type(exc).__name__})") from None
            if c.topic == pose_topic:
                s = msg.header.stamp
                p, q = msg.pose.position, msg.pose.orientation
                pose_t.append(s.sec * NS_PER_S + s.nanosec)
                pose_v.append((p.x, p.y, p.z, q.x, q.y, q.z, q.w))
            elif c.msgtype == JOINT_STATE:
                pos = dict(zip(joints, positions))
                missing = [n for n in names if n not in pos]
                if missing:
                    raise InputError(f"{path}: a JointState on {legs_topic} has no joint {missing[0]!r} (the legs "
                                     f"are the joints {' '.join(names)})")
                legs_t.append(stamp_ns)
                legs_v.append([pos[n] for n in names])
            else:
                if data.size != n_legs:
                    raise InputError(f"{path}: a Float64MultiArray on {legs_topic} at log time {t} ns has "
                                     f"{data.size} values, expected {n_legs} leg lengths")
                legs_t.append(t)
                legs_v.append(np.array(data, dtype=float))
    finally:
        reader.close()
    legs_t, pose_t = np.array(legs_t, dtype=np.int64), np.array(pose_t, dtype=np.int64)
    lo, po = np.argsort(legs_t, kind="stable"), np.argsort(pose_t, kind="stable")
    li, pi = nearest_pairs(legs_t[lo], pose_t[po], int(round(max_dt_s * NS_PER_S)))
    info = BagInfo(legs_topic, pose_topic, len(legs_t), len(pose_t), len(li))
    legs = np.array(legs_v, dtype=float).reshape(-1, n_legs)[lo][li]
    legs = legs / metres_per_unit if readings_from_si is None else readings_from_si(legs)
    poses = np.array(pose_v, dtype=float).reshape(-1, 7)[po][pi]
    where = lambda r: f"{path}: the pose on {pose_topic} stamped {pose_t[po][pi][r]} ns"  # noqa: E731
    if not np.all(np.isfinite(legs)) or not np.all(np.isfinite(poses)):
        raise InputError(f"{path}: a paired leg reading or pose is not finite")
    if readings_from_si is None and np.any(legs <= 0.0):
        raise InputError(f"{path}: a leg reading on {legs_topic} is not positive")
    position = poses[:, :dim] / metres_per_unit
    quaternion = _check_pose_values(poses[:, 3:], 3, where)
    if translation:
        return Measurements(legs, position, _translation_rotations(quaternion, where)), info
    if dim == 2:
        # a planar pose: rotation about z, theta = 2 atan2(qz, qw)
        orientation = 2.0 * np.arctan2(quaternion[:, 2], quaternion[:, 3])
    else:
        orientation = quaternion
    return Measurements(legs, position, rotations_from_values(orientation)), info


def is_bag(path: Path) -> bool:
    """A rosbag2: a directory (with metadata.yaml) or a single .mcap / .db3 file."""
    return path.is_dir() or path.suffix in (".mcap", ".db3")
