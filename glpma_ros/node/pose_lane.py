"""A ``leg_lengths`` message to its pose's message in one compiled call: the node's everyday input.

Between an input's bytes and its pose's bytes the node's work is small (a warm Levenberg-Marquardt of a few
microseconds), but done in Python step by step -- the message read, the readings converted and checked, the
estimator's decision, an ``Estimate`` and a ``PoseOutput`` built, the pose packed -- it cost several times the
compiled work, the more so when the caches are cold between two inputs at 1 kHz (measured: BENCHMARKS.md,
"Extra outputs and the transport path", part 4).  :func:`pose_message_kernel` does it all in one compiled call: it
reads the ``std_msgs/Float64MultiArray`` (CDR_LE, no layout: what a controller sends), converts the readings
(:func:`~glpma_ros.models.base.lengths_from_readings`), runs the warm stage
(:func:`~glpma_ros.estimation.estimator.warm_readings_kernel`), decides whether it is the estimate
(:func:`~glpma_ros.estimation.estimator.warm_accepted`, the estimator's own rule) and, when it is, writes the
``geometry_msgs/PoseStamped`` into a message whose frame id is already in place.  The pose goes out; the
``Estimate`` and ``PoseOutput`` the statistics and the extra outputs read are built after it
(:meth:`FkService.account <glpma_ros.node.service.FkService.account>`).

Whatever the kernel does not take (another layout or encoding, another count, a reading outside the plausible
band or not a number) it leaves untouched (:data:`NOT_APPLICABLE`), and the node decodes the message and
solves it the long way, which names the problem; a warm stage the rule declines (:data:`SEARCH`) goes on to the
estimator's search.  The byte layouts are those of :mod:`glpma_ros.node.dds.cdr` (XCDR1, little endian), which
also builds the pose's message.  No ROS import.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..estimation.estimator import warm_accepted, warm_readings_kernel
from .dds import cdr

#: the kernel took nothing: decode the message and solve it the long way
NOT_APPLICABLE = -1
#: the warm stage ran but is not the estimate: the estimator's search goes on from its output
SEARCH = 0
#: the warm stage is the estimate and the pose's message is written
ACCEPTED = 1

#: the encapsulation's first two bytes, CDR_LE (XCDR1, little endian): what the kernel reads
ENCAPSULATION_0, ENCAPSULATION_1 = cdr.CDR_LE[0], cdr.CDR_LE[1]
#: Float64MultiArray without a layout: the layout's dimension count (uint32), then data_offset (uint32), the
#: data's count (uint32) and, aligned to 8 from the payload's start, the doubles (byte offsets in the message)
DIM_COUNT_AT = cdr.HEADER_SIZE
DATA_COUNT_AT = cdr.HEADER_SIZE + 8
DATA_AT = cdr.HEADER_SIZE + 16
#: PoseStamped: header.stamp (int32 sec, uint32 nanosec) first, position and orientation (7 doubles) last
STAMP_AT = cdr.HEADER_SIZE
POSE_DOUBLES = 3 + 4
DOUBLE_SIZE = 8
NS_PER_S = 1_000_000_000


@njit(cache=True, nogil=True)
def _u32(data, at):
    return np.int64(data[at]) | np.int64(data[at + 1]) << 8 | np.int64(data[at + 2]) << 16 | \
        np.int64(data[at + 3]) << 24


@njit(cache=True, nogil=True)
def _put_u32(message, at, value):
    for k in range(4):
        message[at + k] = (value >> (8 * k)) & 0xFF


@njit(cache=True, nogil=True)
def read_float64_multi_array(data, n, scratch) -> bool:
    """The ``n`` doubles of a ``Float64MultiArray`` message ``data`` (bytes, CDR_LE, no layout) copied into
    ``scratch`` (bytes of an 8-aligned buffer: read as doubles from its start); False when the message is not
    that (another encoding, a layout, another count, too short)."""
    if len(data) < DATA_AT + DOUBLE_SIZE * n or data[0] != ENCAPSULATION_0 or data[1] != ENCAPSULATION_1:
        return False
    if _u32(data, DIM_COUNT_AT) != 0 or _u32(data, DATA_COUNT_AT) != n:
        return False
    for k in range(DOUBLE_SIZE * n):
        scratch[k] = data[DATA_AT + k]
    return True


@njit(cache=True, nogil=True)
def write_pose_stamped(message, stamp_ns, out, n_vars, metres_per_unit, scratch) -> None:
    """Stamp ``stamp_ns`` and the pose of the warm stage's output ``out`` (position in the config's unit,
    times ``metres_per_unit``; the unit quaternion) into ``message``, a ``PoseStamped`` whose frame id is in
    place (:meth:`PoseLane.message`); ``scratch``: bytes of an 8-aligned buffer of at least 7 doubles."""
    sec = stamp_ns // NS_PER_S
    _put_u32(message, STAMP_AT, sec)
    _put_u32(message, STAMP_AT + 4, stamp_ns - sec * NS_PER_S)
    pose = scratch[:DOUBLE_SIZE * POSE_DOUBLES].view(np.float64)
    for k in range(3):
        pose[k] = out[n_vars + k] * metres_per_unit
    for k in range(3, POSE_DOUBLES):
        pose[k] = out[n_vars + k]
    at = message.shape[0] - DOUBLE_SIZE * POSE_DOUBLES
    for k in range(DOUBLE_SIZE * POSE_DOUBLES):
        message[at + k] = scratch[k]


@njit(cache=True, nogil=True)
def pose_message_kernel(data, divisor, lo, hi, offsets, buf, x0, legs_ref, near_floor, legs, out, scratch,
                        message, stamp_ns, metres_per_unit) -> int:
    """A ``leg_lengths`` message ``data`` to its pose's ``message`` (see the module's docstring).  The readings
    (``divisor``, band ``[lo, hi]``, ``offsets``: :attr:`InputConverter.readings
    <glpma_ros.node.inputs.InputConverter.readings>`) into ``legs``; the warm stage from ``x0`` / ``legs_ref``
    (``buf``, ``near_floor``: :meth:`Estimator.warm_lane <glpma_ros.estimation.estimator.Estimator.warm_lane>`)
    into ``out``.  Returns :data:`ACCEPTED`, :data:`SEARCH` or :data:`NOT_APPLICABLE`."""
    n = legs.shape[0]
    if not read_float64_multi_array(data, n, scratch):
        return NOT_APPLICABLE
    readings = scratch[:DOUBLE_SIZE * n].view(np.float64)
    if not warm_readings_kernel(readings, divisor, lo, hi, offsets, buf, x0, legs_ref, legs, out):
        return NOT_APPLICABLE
    n_vars = x0.shape[0]
    if not warm_accepted(out, n_vars, near_floor):
        return SEARCH
    write_pose_stamped(message, stamp_ns, out, n_vars, metres_per_unit, scratch)
    return ACCEPTED


class PoseLane:
    """The buffers of :func:`pose_message_kernel` for a manipulator of ``n_legs`` legs and ``n_out`` warm-stage
    outputs (:attr:`LocalSolver.n_out <glpma_ros.solvers.local.LocalSolver.n_out>`); the pose's message per
    frame id.  One solving thread at a time (the node's solve loop)."""

    def __init__(self, n_legs: int, n_out: int):
        self.n_legs, self.n_out = int(n_legs), int(n_out)
        # doubles, seen as bytes: the readings and the pose pass through it 8-aligned
        self._scratch = np.zeros(max(self.n_legs, POSE_DOUBLES)).view(np.uint8)
        self._frame_id = None
        self._message = None

    def message(self, frame_id: str) -> np.ndarray:
        """The ``PoseStamped`` the kernel writes into (its frame id in place), built again when it changes."""
        if frame_id != self._frame_id:
            template = cdr.Encoder().pose_stamped(0, frame_id, (0.0,) * 3, (0.0,) * 4)
            self._message, self._frame_id = np.frombuffer(bytearray(template), dtype=np.uint8), frame_id
        return self._message

    def run(self, data, stamp_ns: int, readings, warm, frame_id: str, metres_per_unit: float):
        """:func:`pose_message_kernel` on ``data``: ``(code, legs, out)``, and with :data:`ACCEPTED` the pose's
        message in :meth:`message` (``frame_id``'s).  ``readings``: ``(divisor, lo, hi, offsets)``; ``warm``:
        :meth:`Estimator.warm_lane <glpma_ros.estimation.estimator.Estimator.warm_lane>`'s tuple.  Only
        ``bytes`` are read (what both transports take)."""
        if type(data) is not bytes:
            return NOT_APPLICABLE, None, None
        legs, out = np.empty(self.n_legs), np.empty(self.n_out)
        code = pose_message_kernel(data, *readings, *warm, legs, out, self._scratch, self.message(frame_id),
                                   int(stamp_ns), float(metres_per_unit))
        return code, legs, out

