"""The node's hot messages in and out of their wire form (XCDR1, little endian), with ``struct``.

Cyclone DDS's Python binding serializes an ``IdlStruct`` field by field in Python: 20-50 us for
a ``PoseStamped``, over a millisecond for a ``MarkerArray``, more than the solve itself.  Every
message the node sends for each input has a fixed layout once its strings are known, so this
module builds a ``struct.Struct`` per layout (cached by the strings and sequence lengths) and
packs the values in one call; the input messages (``Float64MultiArray``, ``JointState``) are
read with ``struct.unpack_from``.  The bytes are those of the binding's own serializer (the
tests compare them for every message), i.e. what ``rmw_cyclonedds_cpp`` sends and expects:
a 4-byte encapsulation header (``CDR_LE``), then the fields in ``.msg`` order, each primitive
aligned to its size (at most 8) from the start of the payload, a string as ``uint32`` length
(with the terminating NUL) + bytes + NUL, a sequence as ``uint32`` count + elements.

:class:`RawWriter` / :func:`take_raw` pass the bytes to and from Cyclone DDS
(``cyclonedds._clayer``, the calls ``DataWriter.write`` and ``DataReader.take`` make after
their own serialization).  Input in another encoding (big endian, XCDR2) goes through the
binding's generic deserializer.  The codec itself needs no Cyclone DDS (it is imported on first use
of :class:`RawWriter` / :func:`take_raw`): the rclpy node publishes the same bytes with
``Publisher.publish(bytes)`` and reads its inputs raw (:mod:`glpma_ros.node.ros_node`).
"""
from __future__ import annotations

import struct
from types import SimpleNamespace

#: encapsulation identifier CDR_LE (XCDR1, little endian) and options
CDR_LE = b"\x00\x01\x00\x00"
HEADER_SIZE = len(CDR_LE)
SIZES = {"b": 1, "B": 1, "?": 1, "i": 4, "I": 4, "f": 4, "d": 8}
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")


class Layout:
    """A ``struct`` format built field by field with XCDR1 alignment (offsets from the payload)."""

    def __init__(self):
        self.parts = ["<"]
        self.offset = 0

    def _align(self, size: int) -> None:
        pad = -self.offset % size
        if pad:
            self.parts.append(f"{pad}x")
            self.offset += pad

    def prim(self, code: str, count: int = 1) -> "Layout":
        if count == 0:                  # an empty sequence's elements: no alignment either
            return self
        size = SIZES[code]
        self._align(size)
        self.parts.append(f"{count}{code}")
        self.offset += size * count
        return self

    def string(self, text: bytes) -> "Layout":
        """A string field (its value is passed as ``len(text) + 1, text``)."""
        self.prim("I")
        self.parts.append(f"{len(text) + 1}s")
        self.offset += len(text) + 1
        return self

    def header(self, frame_id: bytes) -> "Layout":
        return self.prim("i").prim("I").string(frame_id)

    def struct(self) -> struct.Struct:
        pad = -self.offset % 4          # DataWriter.write pads the payload to a multiple of 4
        if pad:
            self.parts.append(f"{pad}x")
        return struct.Struct("".join(self.parts))


def _split(stamp_ns: int) -> tuple[int, int]:
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return sec, nanosec


class Encoder:
    """Packs the node's outputs; one cached ``struct.Struct`` per distinct layout."""

    def __init__(self):
        self._cache: dict = {}

    def _layout(self, key, build) -> struct.Struct:
        st = self._cache.get(key)
        if st is None:
            st = self._cache[key] = build()
        return st

    def float64_multi_array(self, data) -> bytes:
        """``std_msgs/Float64MultiArray`` without a layout (no dimension, data_offset 0): what a controller
        sends on ``leg_lengths``."""
        data = tuple(float(v) for v in data)
        st = self._layout(("Float64MultiArray", len(data)), lambda: Layout().prim("I", 3).prim("d", len(data)).struct())
        return CDR_LE + st.pack(0, 0, len(data), *data)

    def pose(self, pose) -> bytes:
        """The ``PoseStamped`` of a pose to publish: a :class:`~glpma_ros.node.service.PoseOutput` packed, or an
        :class:`~glpma_ros.node.service.EncodedPose`'s message as it is."""
        message = getattr(pose, "message", None)
        if message is not None:
            return message
        return self.pose_stamped(pose.stamp_ns, pose.frame_id, pose.position, pose.orientation)

    def pose_stamped(self, stamp_ns: int, frame_id: str, position, orientation) -> bytes:
        """``geometry_msgs/PoseStamped``."""
        frame = frame_id.encode()
        st = self._layout(("PoseStamped", frame), lambda: Layout().header(frame).prim("d", 7).struct())
        return CDR_LE + st.pack(*_split(stamp_ns), len(frame) + 1, frame, *position, *orientation)

    def tf_message(self, stamp_ns: int, frame_id: str, child_frame_id: str, translation, rotation) -> bytes:
        """``tf2_msgs/TFMessage`` with one ``geometry_msgs/TransformStamped``."""
        frame, child = frame_id.encode(), child_frame_id.encode()
        st = self._layout(("TFMessage", frame, child),
                          lambda: Layout().prim("I").header(frame).string(child).prim("d", 7).struct())
        return CDR_LE + st.pack(1, *_split(stamp_ns), len(frame) + 1, frame, len(child) + 1, child,
                                *translation, *rotation)

    def pose_with_covariance_stamped(self, stamp_ns: int, frame_id: str, position, orientation,
                                     covariance) -> bytes:
        """``geometry_msgs/PoseWithCovarianceStamped``; ``covariance``: 36 numbers, row-major."""
        frame = frame_id.encode()
        st = self._layout(("PoseWithCovarianceStamped", frame),
                          lambda: Layout().header(frame).prim("d", 7).prim("d", 36).struct())
        return CDR_LE + st.pack(*_split(stamp_ns), len(frame) + 1, frame, *position, *orientation, *covariance)

    def twist_stamped(self, stamp_ns: int, frame_id: str, linear, angular) -> bytes:
        """``geometry_msgs/TwistStamped``."""
        frame = frame_id.encode()
        st = self._layout(("TwistStamped", frame), lambda: Layout().header(frame).prim("d", 6).struct())
        return CDR_LE + st.pack(*_split(stamp_ns), len(frame) + 1, frame, *linear, *angular)

    def marker_array(self, stamp_ns: int, frame_id: str, markers) -> bytes:
        """``visualization_msgs/MarkerArray`` of :class:`~glpma_ros.node.outputs.MarkerOutput`
        (all with this header; every field a ``MarkerOutput`` does not have at its default:
        identity pose, no lifetime, not frame-locked, no texture, text or mesh)."""
        frame = frame_id.encode()
        key = ("MarkerArray", frame) + tuple((m.ns, len(m.points), len(m.colors)) for m in markers)

        def build():
            layout = Layout().prim("I")
            for m in markers:
                layout.header(frame).string(m.ns.encode()).prim("i", 3)   # header, ns, id, type, action
                layout.prim("d", 7).prim("d", 3).prim("f", 4)           # pose, scale, color
                layout.prim("i").prim("I").prim("?")                    # lifetime, frame_locked
                layout.prim("I").prim("d", 3 * len(m.points))           # points
                layout.prim("I").prim("f", 4 * len(m.colors))           # colors
                layout.string(b"")                                       # texture_resource
                layout.header(b"").string(b"").prim("I")                 # texture: header, format, data
                layout.prim("I")                                         # uv_coordinates
                layout.string(b"").string(b"")                           # text, mesh_resource
                layout.string(b"").prim("I")                             # mesh_file: filename, data
                layout.prim("?")                                         # mesh_use_embedded_materials
            return layout.struct()

        st = self._layout(key, build)
        sec, nanosec = _split(stamp_ns)
        values = [len(markers)]
        for m in markers:
            ns = m.ns.encode()
            values += [sec, nanosec, len(frame) + 1, frame, len(ns) + 1, ns, m.id, m.type, m.action,
                       0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, *m.scale, *m.color, 0, 0, False, len(m.points)]
            for point in m.points:
                values += point
            values.append(len(m.colors))
            for color in m.colors:
                values += color
            values += _MARKER_TAIL
        return CDR_LE + st.pack(*values)

    def joint_state(self, stamp_ns: int, frame_id: str, names, positions, velocities=()) -> bytes:
        """``sensor_msgs/JointState`` (no efforts; ``velocities`` empty or one per name)."""
        frame = frame_id.encode()
        encoded = tuple(n.encode() for n in names)

        def build():
            layout = Layout().header(frame).prim("I")
            for name in encoded:
                layout.string(name)
            return layout.prim("I").prim("d", len(positions)).prim("I").prim("d", len(velocities)).prim("I").struct()

        st = self._layout(("JointState", frame, encoded, len(positions), len(velocities)), build)
        values = [*_split(stamp_ns), len(frame) + 1, frame, len(encoded)]
        for name in encoded:
            values += (len(name) + 1, name)
        return CDR_LE + st.pack(*values, len(positions), *positions, len(velocities), *velocities, 0)

    def extras(self, ex) -> list:
        """``[(output name, bytes)]`` of the outputs present in
        :class:`~glpma_ros.node.outputs.ExtraOutputs` ``ex``: ``tf`` (``/tf``), ``covariance``
        (``pose_estimate_cov``), ``twist`` (``twist_estimate``), ``markers`` (``~/markers``), ``joint_states``
        (``~/mechanism_joint_states``)."""
        out = []
        if ex.child_frame_id is not None:
            out.append(("tf", self.tf_message(ex.stamp_ns, ex.frame_id, ex.child_frame_id, ex.position,
                                              ex.orientation)))
        if ex.covariance is not None:
            out.append(("covariance", self.pose_with_covariance_stamped(ex.stamp_ns, ex.frame_id, ex.position,
                                                                        ex.orientation, ex.covariance)))
        if ex.twist_out:
            out.append(("twist", self.twist_stamped(ex.stamp_ns, ex.frame_id, *ex.twist)))
        if ex.markers is not None:
            out.append(("markers", self.marker_array(ex.stamp_ns, ex.frame_id, ex.markers)))
        if ex.joint_names is not None:
            out.append(("joint_states", self.joint_state(ex.stamp_ns, ex.frame_id, ex.joint_names, ex.joint_positions,
                                                         ex.joint_velocities)))
        return out


class _Writer:
    """Fields appended one by one with XCDR1 alignment, for messages whose strings change every time."""

    def __init__(self):
        self.parts: list = []
        self.offset = 0

    def raw(self, data: bytes) -> None:
        """``data`` as it is (octets, or primitives already aligned)."""
        self.parts.append(data)
        self.offset += len(data)

    def align(self, size: int) -> None:
        pad = -self.offset % size
        if pad:
            self.raw(bytes(pad))

    def u32(self, value: int) -> None:
        self.align(4)
        self.raw(_U32.pack(value))

    def string(self, text: str) -> None:
        data = text.encode()
        self.u32(len(data) + 1)
        self.raw(data + b"\0")

    def payload(self) -> bytes:
        self.align(4)                  # DataWriter.write pads the payload to a multiple of 4
        return CDR_LE + b"".join(self.parts)


#: values of a DiagnosticStatus encoded between two calls of ``pause`` (a few microseconds each)
DIAGNOSTIC_CHUNK = 10


def diagnostic_array(stamp_ns: int, report, pause=lambda: None) -> bytes:
    """``diagnostic_msgs/DiagnosticArray`` with one ``DiagnosticStatus``: a
    :class:`~glpma_ros.node.diagnostics.DiagnosticReport` (``level``, ``name``, ``message``,
    ``hardware_id``, ``values`` as (key, value) strings); ``pause()`` runs after every
    :data:`DIAGNOSTIC_CHUNK` values (the report thread lets a solve take the interpreter there)."""
    w = _Writer()
    w.raw(_STAMP.pack(*_split(stamp_ns)))
    w.string("")                        # header.frame_id
    w.u32(1)                            # one status
    w.raw(bytes((report.level,)))       # level: byte
    for text in (report.name, report.message, report.hardware_id):
        w.string(text)
    w.u32(len(report.values))
    for k, (key, value) in enumerate(report.values, 1):
        w.string(key)
        w.string(value)
        if k % DIAGNOSTIC_CHUNK == 0:
            pause()
    return w.payload()


#: the fields of a Marker after ``colors``, empty: texture_resource, texture (header, format,
#: data), uv_coordinates, text, mesh_resource, mesh_file (filename, data), mesh_use_embedded_materials
_MARKER_TAIL = (1, b"", 0, 0, 1, b"", 1, b"", 0, 0, 1, b"", 1, b"", 1, b"", 0, False)


# -- input ------------------------------------------------------------------------------------------


def _string(buf, offset: int) -> tuple[str, int]:
    offset += -(offset - HEADER_SIZE) % 4
    (size,) = _U32.unpack_from(buf, offset)
    offset += 4
    return buf[offset:offset + size - 1].decode(), offset + size


def _count(buf, offset: int) -> tuple[int, int]:
    offset += -(offset - HEADER_SIZE) % 4
    return _U32.unpack_from(buf, offset)[0], offset + 4


def _doubles(buf, offset: int) -> tuple[tuple, int]:
    n, offset = _count(buf, offset)
    offset += -(offset - HEADER_SIZE) % 8 if n else 0
    return struct.unpack_from(f"<{n}d", buf, offset), offset + 8 * n


def float64_multi_array_data(buf) -> tuple:
    """``data`` of a ``std_msgs/Float64MultiArray`` in CDR_LE (the layout is skipped)."""
    n_dims, offset = _count(buf, HEADER_SIZE)
    if n_dims == 0:             # the usual message, no layout: data_offset, the data's count, its doubles
        (n,) = _U32.unpack_from(buf, offset + 4)
        return struct.unpack_from(f"<{n}d", buf, offset + 8 + (-(offset + 8 - HEADER_SIZE) % 8 if n else 0))
    for _ in range(n_dims):
        _, offset = _string(buf, offset)
        offset += -(offset - HEADER_SIZE) % 4 + 8                # size, stride
    offset += -(offset - HEADER_SIZE) % 4 + 4                    # data_offset
    return _doubles(buf, offset)[0]


def joint_state_fields(buf) -> tuple[int, tuple, tuple, tuple]:
    """``(header.stamp in ns, name, position, velocity)`` of a ``sensor_msgs/JointState`` in CDR_LE."""
    sec, nanosec = _STAMP.unpack_from(buf, HEADER_SIZE)
    _, offset = _string(buf, HEADER_SIZE + 8)                    # frame_id
    n_names, offset = _count(buf, offset)
    names = []
    for _ in range(n_names):
        name, offset = _string(buf, offset)
        names.append(name)
    position, offset = _doubles(buf, offset)
    velocity, offset = _doubles(buf, offset)
    return sec * 1_000_000_000 + nanosec, tuple(names), position, velocity


def little_endian_cdr(buf) -> bool:
    return buf[:2] == CDR_LE[:2]


# -- Cyclone DDS ------------------------------------------------------------------------------------
_cyclone = None


def _cyclone_calls() -> SimpleNamespace:
    """The binding's raw calls, imported once (the codec above works without Cyclone DDS)."""
    global _cyclone
    if _cyclone is None:
        # cyclonedds: optional for the codec, imported where the binding is used
        from cyclonedds._clayer import ddspy_take, ddspy_write
        from cyclonedds.core import DDSException, InstanceState, SampleState, ViewState
        _cyclone = SimpleNamespace(take=ddspy_take, write=ddspy_write, error=DDSException,
                                   any_state=SampleState.Any | ViewState.Any | InstanceState.Any)   # read or not
    return _cyclone


class RawWriter:
    """Writes bytes from :class:`Encoder` on a ``DataWriter`` (what ``DataWriter.write`` does after
    serializing)."""

    def __init__(self, writer):
        self.writer = writer
        # the entity's handle, which the binding keeps private: it has no public raw write
        self._ref = writer._ref  # noqa: SLF001
        self._write = _cyclone_calls().write

    def write(self, data: bytes) -> None:
        ret = self._write(self._ref, data)
        if ret < 0:
            raise _cyclone.error(ret, f"Occurred while writing sample in {self.writer!r}")


def take_raw(reader, n: int) -> list:
    """Up to ``n`` samples of ``reader`` as ``(bytes, SampleInfo)``, not deserialized."""
    c = _cyclone or _cyclone_calls()
    ret = c.take(reader._ref, c.any_state, n)  # noqa: SLF001 - the binding has no public raw take
    if isinstance(ret, int):
        raise c.error(ret, f"Occurred while taking data in {reader!r}")
    return ret
