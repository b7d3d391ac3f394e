"""The node's further outputs over real Cyclone DDS, read by an independent client.

The client imports nothing from glpma_ros: its types are written here from the ROS 2 Jazzy
``.msg`` files (type names ``pkg::msg::dds_::Name_``), its topics are ``rt/<name>``, its
USER_DATA carries the Jazzy type hashes.  It sends leg lengths and reads ``rt/pose_estimate``,
``rt/tf``, ``rt/pose_estimate_cov``, ``rt/twist_estimate`` and ``rt/glpma_fk/markers``.
"""
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint8, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from conftest import CONFIG

# the independent client's types it shares with the contract participant there (no glpma_ros import)
from test_dds_integration import (
    Float64MultiArray,
    Header,
    Point,
    Pose,
    PoseStamped,
    Quaternion,
    start_node,  # noqa: F401 - fixture
)

SEED_X = [52.860968946, 84.886500470, math.radians(-33.461467708)]
HASHES = {
    "Float64MultiArray": "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f",
    "PoseStamped": "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    "TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "PoseWithCovarianceStamped": "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e",
    "TwistStamped": "RIHS01_5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64",
    "MarkerArray": "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf",
}


@dataclass
class Duration(IdlStruct, typename="builtin_interfaces::msg::dds_::Duration_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class ColorRGBA(IdlStruct, typename="std_msgs::msg::dds_::ColorRGBA_"):
    r: float32 = 0.0
    g: float32 = 0.0
    b: float32 = 0.0
    a: float32 = 0.0


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped] = field(default_factory=list)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class PoseWithCovarianceStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"):
    header: Header = field(default_factory=Header)
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TwistStamped_"):
    header: Header = field(default_factory=Header)
    twist: Twist = field(default_factory=Twist)


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    header: Header = field(default_factory=Header)
    format: str = ""
    data: sequence[uint8] = field(default_factory=list)


@dataclass
class UVCoordinate(IdlStruct, typename="visualization_msgs::msg::dds_::UVCoordinate_"):
    u: float32 = 0.0
    v: float32 = 0.0


@dataclass
class MeshFile(IdlStruct, typename="visualization_msgs::msg::dds_::MeshFile_"):
    filename: str = ""
    data: sequence[uint8] = field(default_factory=list)


@dataclass
class Marker(IdlStruct, typename="visualization_msgs::msg::dds_::Marker_"):
    header: Header = field(default_factory=Header)
    ns: str = ""
    id: int32 = 0
    type: int32 = 0
    action: int32 = 0
    pose: Pose = field(default_factory=Pose)
    scale: Vector3 = field(default_factory=Vector3)
    color: ColorRGBA = field(default_factory=ColorRGBA)
    lifetime: Duration = field(default_factory=Duration)
    frame_locked: bool = False
    points: sequence[Point] = field(default_factory=list)
    colors: sequence[ColorRGBA] = field(default_factory=list)
    texture_resource: str = ""
    texture: CompressedImage = field(default_factory=CompressedImage)
    uv_coordinates: sequence[UVCoordinate] = field(default_factory=list)
    text: str = ""
    mesh_resource: str = ""
    mesh_file: MeshFile = field(default_factory=MeshFile)
    mesh_use_embedded_materials: bool = False


@dataclass
class MarkerArray(IdlStruct, typename="visualization_msgs::msg::dds_::MarkerArray_"):
    markers: sequence[Marker] = field(default_factory=list)


def stamp_ns(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def qos(type_name, depth=10):
    return Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(depth),
               Policy.Durability.Volatile, Policy.Userdata(f"typehash={HASHES[type_name]};".encode()))


def test_tf_covariance_twist_and_markers_reach_an_independent_client(start_node):
    start_node("--params-file", str(CONFIG / "params_3rpr.yaml"), "-p", "time_budget_ms:=50.0",
               "-p", "publish_markers:=true", "-p", "markers_period_s:=0.0", "-p", "child_frame_id:=top")
    dp = DomainParticipant(int(os.environ["ROS_DOMAIN_ID"]))
    writer = DataWriter(dp, Topic(dp, "rt/leg_lengths", Float64MultiArray), qos("Float64MultiArray"))
    readers = {name: DataReader(dp, Topic(dp, topic, msg_type), qos(msg_type.__name__, 100))
               for name, topic, msg_type in (("pose", "rt/pose_estimate", PoseStamped), ("tf", "rt/tf", TFMessage),
                                             ("cov", "rt/pose_estimate_cov", PoseWithCovarianceStamped),
                                             ("twist", "rt/twist_estimate", TwistStamped),
                                             ("markers", "rt/glpma_fk/markers", MarkerArray))}
    deadline = time.monotonic() + 30
    while not (writer.get_matched_subscriptions() and all(r.get_matched_publications() for r in readers.values())):
        assert time.monotonic() < deadline, "the node's endpoints were not discovered"
        time.sleep(0.05)
    time.sleep(0.3)
    # the node's /tf writer carries the Jazzy type hash
    tf_reader = readers["tf"]
    peer = tf_reader.get_matched_publication_data(tf_reader.get_matched_publications()[0])
    assert peer.qos[Policy.Userdata].data == f"typehash={HASHES['TFMessage']};".encode()

    legs = [[0.100, 0.120, 0.150], [0.100, 0.120, 0.1502]]       # metres
    got = {name: [] for name in readers}

    def collect(poses: int, timeout_s: float = 10.0) -> None:
        deadline = time.monotonic() + timeout_s
        while len(got["pose"]) < poses and time.monotonic() < deadline:
            for name, reader in readers.items():
                got[name] += reader.take(10)
            time.sleep(0.01)

    for k, data in enumerate(legs):
        writer.write(Float64MultiArray(data=data))
        collect(k + 1)
    time.sleep(0.3)                                     # the extra messages follow the pose
    for name, reader in readers.items():
        got[name] += reader.take(10)
    assert len(got["pose"]) == 2 and len(got["tf"]) == 2 and len(got["cov"]) == 2 and len(got["markers"]) == 2
    assert len(got["twist"]) == 1                       # a finite difference needs two poses

    for pose, tf, cov, markers in zip(got["pose"], got["tf"], got["cov"], got["markers"]):
        (t,) = tf.transforms
        assert (t.header.frame_id, t.child_frame_id) == ("base", "top")
        assert stamp_ns(t.header) == stamp_ns(pose.header) == stamp_ns(cov.header)
        p, q = pose.pose.position, pose.pose.orientation
        np.testing.assert_allclose([t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
                                   [p.x, p.y, p.z], rtol=0, atol=1e-12)
        np.testing.assert_allclose([t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
                                    t.transform.rotation.w], [q.x, q.y, q.z, q.w], rtol=0, atol=1e-12)
        assert cov.pose.pose == pose.pose
        c = np.array(cov.pose.covariance).reshape(6, 6)
        assert np.all(np.isfinite(c)) and np.array_equal(c, c.T)
        assert c[2, 2] == c[3, 3] == c[4, 4] == 1e6                # planar: z, roll, pitch not measured
        assert 0 < c[0, 0] < 1e-8 and 0 < c[5, 5] < 1e-6
        assert {m.ns for m in markers.markers} == {"base_joints", "platform_joints", "legs", "base", "platform"}
        legs_marker = next(m for m in markers.markers if m.ns == "legs")
        ends = np.array([[pt.x, pt.y, pt.z] for pt in legs_marker.points])
        lengths = np.linalg.norm(ends[1::2] - ends[0::2], axis=1)
        np.testing.assert_allclose(lengths, legs[got["pose"].index(pose)], atol=1e-12)
    np.testing.assert_allclose([got["pose"][0].pose.position.x, got["pose"][0].pose.position.y],
                               [SEED_X[0] / 1000, SEED_X[1] / 1000], atol=1e-9)
    twist = got["twist"][0]
    assert stamp_ns(twist.header) == stamp_ns(got["pose"][1].header) and twist.header.frame_id == "base"
    dt = (stamp_ns(got["pose"][1].header) - stamp_ns(got["pose"][0].header)) * 1e-9
    p0, p1 = got["pose"][0].pose.position, got["pose"][1].pose.position
    np.testing.assert_allclose([twist.twist.linear.x, twist.twist.linear.y],
                               [(p1.x - p0.x) / dt, (p1.y - p0.y) / dt], rtol=1e-9)
