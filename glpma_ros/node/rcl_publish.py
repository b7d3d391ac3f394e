"""Serialized messages written through ``rcl`` with the interpreter lock released.

rclpy's ``Publisher.publish(bytes)`` hands the bytes to ``rcl_publish_serialized_message`` while it
holds the interpreter lock (GIL) for the whole middleware write (copy, then the socket send to each
reader: 4-20 us).  The node writes three more messages after each pose (/tf, covariance, twist);
with the lock held, each write keeps the node's other threads (the executor's parameters and
services, the diagnostics) from running Python meanwhile (BENCHMARKS.md, "Extra outputs and the
transport path", part 4).  :class:`RawPublisher` makes the same ``rcl`` call through :mod:`ctypes`,
which releases the lock for the duration of a foreign call: the write runs beside the Python of the
other threads.  The ``rcl`` publisher is used while rclpy's handle is held (``with
publisher.handle``), as rclpy does, so it cannot be destroyed under the call; a managed
(lifecycle) publisher writes only while activated, as its own ``publish`` does.

Where ``librcl`` does not load or rclpy's publisher does not expose its ``rcl`` pointer (another
rclpy), :class:`RawPublisher` falls back to ``Publisher.publish(bytes)``.  No ROS import: the
adapter (:mod:`glpma_ros.node.ros_node`) hands its rclpy publishers in.
"""
from __future__ import annotations

import ctypes

#: rcl's return code for success (rcl/types.h RCL_RET_OK)
RCL_RET_OK = 0
#: the shared library of rcl, as the dynamic loader finds it in a sourced ROS 2 environment
LIBRCL = "librcl.so"


class _Allocator(ctypes.Structure):
    """``rcutils_allocator_t``: four function pointers and a state pointer (unused here: the
    middleware reads the buffer, never frees or grows it)."""

    _fields_ = [("allocate", ctypes.c_void_p), ("deallocate", ctypes.c_void_p), ("reallocate", ctypes.c_void_p),
                ("zero_allocate", ctypes.c_void_p), ("state", ctypes.c_void_p)]


class SerializedMessage(ctypes.Structure):
    """``rcl_serialized_message_t`` (= ``rcutils_uint8_array_t``): buffer, length, capacity, allocator."""

    _fields_ = [("buffer", ctypes.c_char_p), ("buffer_length", ctypes.c_size_t),
                ("buffer_capacity", ctypes.c_size_t), ("allocator", _Allocator)]


def load_publish():
    """``rcl_publish_serialized_message`` as a ctypes function (which releases the GIL while it runs),
    or None when ``librcl`` does not load."""
    try:
        lib = ctypes.CDLL(LIBRCL)
    except OSError:
        return None
    function = lib.rcl_publish_serialized_message
    function.argtypes = [ctypes.c_void_p, ctypes.POINTER(SerializedMessage), ctypes.c_void_p]
    function.restype = ctypes.c_int
    return function


_PUBLISH = None
_LOADED = False


def rcl_publish_function():
    """The ctypes ``rcl_publish_serialized_message`` (loaded once), None where there is no ``librcl``."""
    global _PUBLISH, _LOADED
    if not _LOADED:
        _PUBLISH, _LOADED = load_publish(), True
    return _PUBLISH


class RawPublisher:
    """Writes CDR bytes on an rclpy ``publisher`` with the GIL released during the write (see the
    module's docstring); :attr:`direct` is False where it falls back to ``publisher.publish(bytes)``."""

    def __init__(self, publisher):
        self.publisher = publisher
        self._publish = rcl_publish_function()
        # the rcl_publisher_t address of rclpy's handle (a property of rclpy's C++ Publisher)
        self._pointer = getattr(publisher.handle, "pointer", None) if self._publish is not None else None
        self.direct = self._pointer is not None
        #: a managed publisher's activation flag is read before each write
        self._managed = hasattr(publisher, "is_activated")

    def publish(self, data: bytes) -> None:
        """Write ``data`` (a whole serialized message: encapsulation header and payload)."""
        if not self.direct:
            self.publisher.publish(data)
            return
        if self._managed and not self.publisher.is_activated:
            return
        message = SerializedMessage(data, len(data), len(data))
        with self.publisher.handle:
            ret = self._publish(self._pointer, ctypes.byref(message), None)
        if ret != RCL_RET_OK:
            raise RuntimeError(f"rcl_publish_serialized_message failed on {self.publisher.topic_name} (rcl code {ret})")
