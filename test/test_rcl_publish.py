"""glpma_ros.node.rcl_publish: the extra outputs' bytes written through rcl's C call (the GIL released),
with rclpy's handle held and a managed publisher's activation respected, and rclpy's own
``publish(bytes)`` where that call is not available.  rcl itself is faked here; test_rclpy_node checks
on the real one that subscribers read the messages so written."""
import ctypes

import pytest

from glpma_ros.node import rcl_publish
from glpma_ros.node.dds import cdr


class FakeHandle:
    """rclpy's C++ publisher: the address of its rcl publisher, held with ``with``."""

    def __init__(self, pointer):
        self.pointer, self.held, self.max_held = pointer, 0, 0

    def __enter__(self):
        self.held += 1
        self.max_held = max(self.max_held, self.held)
        return self

    def __exit__(self, *exc):
        self.held -= 1


class FakePublisher:
    topic_name = "/tf"

    def __init__(self, pointer=0x1234, activated=None):
        self.handle = FakeHandle(pointer)
        self.published = []
        if activated is not None:           # a LifecyclePublisher
            self.is_activated = activated

    def publish(self, data):
        self.published.append(data)


def fake_rcl(calls, handle_of, ret=rcl_publish.RCL_RET_OK):
    """An ``rcl_publish_serialized_message`` recording (pointer, the bytes, whether the handle was held)."""
    def publish(pointer, message, allocation):
        msg = message._obj      # noqa: SLF001 - the structure ctypes.byref() points to
        address = ctypes.cast(ctypes.pointer(msg), ctypes.POINTER(ctypes.c_void_p))[0]     # the buffer field
        calls.append((pointer, ctypes.string_at(address, msg.buffer_length), handle_of().held, allocation))
        return ret
    return publish


@pytest.fixture
def tf_bytes():
    # CDR with NUL bytes inside: the whole buffer must go out, not a C string
    return cdr.Encoder().tf_message(1_795_000_000_123_456_789, "base", "platform", (0.1, 0.2, 0.0), (0, 0, 0, 1.0))


def test_the_bytes_go_to_rcl_with_the_handle_held(monkeypatch, tf_bytes):
    calls, pub = [], FakePublisher()
    monkeypatch.setattr(rcl_publish, "rcl_publish_function", lambda: fake_rcl(calls, lambda: pub.handle))
    raw = rcl_publish.RawPublisher(pub)
    assert raw.direct
    raw.publish(tf_bytes)
    assert calls == [(0x1234, tf_bytes, 1, None)] and pub.published == [] and pub.handle.held == 0


def test_a_managed_publisher_writes_only_while_activated(monkeypatch, tf_bytes):
    calls, pub = [], FakePublisher(activated=False)
    monkeypatch.setattr(rcl_publish, "rcl_publish_function", lambda: fake_rcl(calls, lambda: pub.handle))
    raw = rcl_publish.RawPublisher(pub)
    raw.publish(tf_bytes)
    assert calls == []
    pub.is_activated = True
    raw.publish(tf_bytes)
    assert len(calls) == 1


def test_an_rcl_error_is_raised_naming_the_topic(monkeypatch, tf_bytes):
    calls, pub = [], FakePublisher()
    monkeypatch.setattr(rcl_publish, "rcl_publish_function", lambda: fake_rcl(calls, lambda: pub.handle, ret=1))
    with pytest.raises(RuntimeError, match="/tf.*rcl code 1"):
        rcl_publish.RawPublisher(pub).publish(tf_bytes)
    assert pub.handle.held == 0


@pytest.mark.parametrize("why", ["no librcl", "no rcl pointer"])
def test_without_the_c_call_rclpys_publish_writes(monkeypatch, tf_bytes, why):
    calls = []
    pub = FakePublisher(pointer=None) if why == "no rcl pointer" else FakePublisher()
    if why == "no rcl pointer":
        del pub.handle.pointer
    monkeypatch.setattr(rcl_publish, "rcl_publish_function",
                        lambda: None if why == "no librcl" else fake_rcl(calls, lambda: pub.handle))
    raw = rcl_publish.RawPublisher(pub)
    raw.publish(tf_bytes)
    assert not raw.direct and pub.published == [tf_bytes] and calls == []


def test_librcl_missing_is_no_error(monkeypatch):
    monkeypatch.setattr(rcl_publish, "LIBRCL", "libglpma_no_such_library.so")
    assert rcl_publish.load_publish() is None
