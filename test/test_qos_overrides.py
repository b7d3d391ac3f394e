"""QoS overrides (``qos_overrides.<topic>.<publisher|subscription>.<policy>``), read the way rclpy's
QoSOverridingOptions reads them: the core resolution, and the Cyclone DDS node's endpoints created
with them (seen by an independent participant through DDS's built-in discovery topics).  The rclpy
side is checked on a real Jazzy (test_rclpy_node.py, test_launch_fk.py)."""
import subprocess
import sys
import time

import pytest

from conftest import ROOT
from glpma_ros.errors import InputError
from glpma_ros.node import qos
from glpma_ros.node.ros_args import parse_ros_args

OVERRIDES_YAML = """\
glpma_fk:
  ros__parameters:
    manipulator_config: planar_3rpr_seed
    qos_depth: 7
    qos_overrides:
      /leg_lengths:
        subscription:
          reliability: best_effort
          depth: 3
      /pose_estimate:
        publisher:
          durability: transient_local
"""


def test_a_params_file_overrides_one_endpoint_and_qos_depth_the_others(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text(OVERRIDES_YAML)
    overrides = parse_ros_args(["--ros-args", "--params-file", str(f)]).overrides
    profiles, warnings = qos.resolve(overrides, 7, "leg_lengths", "glpma_fk")
    assert not warnings
    assert profiles[("leg_lengths", qos.SUBSCRIPTION)] == qos.QosSpec("best_effort", "keep_last", 3, "volatile")
    assert profiles[("pose_estimate", qos.PUBLISHER)] == qos.QosSpec("reliable", "keep_last", 7, "transient_local")
    assert profiles[("pose_estimate_cov", qos.PUBLISHER)] == qos.QosSpec(depth=7)
    assert profiles[("/tf", qos.PUBLISHER)].depth == qos.TF_DEPTH
    assert profiles[("~/assembly_modes", qos.PUBLISHER)] == qos.QosSpec(depth=1, durability="transient_local")


def test_keys_use_the_fully_qualified_remapped_topic_as_rclpy_does():
    overrides = {"qos_overrides./glpma_fk/markers.publisher.depth": 2,
                 "qos_overrides./robot/legs.subscription.reliability": "BEST_EFFORT"}
    profiles, warnings = qos.resolve(overrides, 10, "leg_lengths", "glpma_fk",
                                     topic_of=lambda n: "/robot/legs" if n == "leg_lengths" else n)
    assert not warnings
    assert profiles[("~/markers", qos.PUBLISHER)].depth == 2
    assert profiles[("leg_lengths", qos.SUBSCRIPTION)].reliability == "best_effort"


@pytest.mark.parametrize("name, value, words", [
    ("qos_overrides./leg_lengths.subscription.reliability", "fast", "must be one of reliable, best_effort"),
    ("qos_overrides./leg_lengths.subscription.depth", 0, "must be >= 1"),
    ("qos_overrides./leg_lengths.subscription.depth", "5", "must be an integer"),
    ("qos_overrides./pose_estimate.publisher.durability", True, "must be one of volatile"),
])
def test_a_bad_value_is_refused_naming_the_parameter(name, value, words):
    with pytest.raises(InputError, match=words) as err:
        qos.resolve({name: value}, 10, "leg_lengths", "glpma_fk")
    assert name in str(err.value)


def test_an_override_nobody_declares_is_a_warning():
    _, warnings = qos.resolve({"qos_overrides./leg_lengths.publisher.depth": 3,
                               "qos_overrides./leg_lengths.subscription.lifespan": 10}, 10, "leg_lengths", "glpma_fk")
    assert len(warnings) == 2 and all("ignoring QoS override" in w for w in warnings)


def test_qos_overrides_are_not_unknown_node_parameters():
    from glpma_ros.node.params import resolve
    _, warnings = resolve({"qos_overrides./leg_lengths.subscription.depth": 3})
    assert warnings == []


def test_the_dds_node_refuses_a_bad_override_in_one_line(dds_env):
    r = subprocess.run([sys.executable, "-m", "glpma_ros.node.dds.node", "--ros-args", "-p",
                        "qos_overrides./leg_lengths.subscription.reliability:=fast"],
                       capture_output=True, text=True, env=dds_env, cwd=ROOT, timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "qos_overrides./leg_lengths.subscription.reliability" in r.stderr
    assert "Traceback" not in r.stderr


def test_the_dds_node_creates_its_endpoints_with_the_overrides(start_node, tmp_path):  # noqa: F811 - fixture
    """An independent participant reads the node's reader and writer QoS from DDS discovery."""
    pytest.importorskip("cyclonedds", reason="the Cyclone DDS Python binding is not installed")
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
    from cyclonedds.core import Policy
    from cyclonedds.domain import DomainParticipant

    from glpma_ros.node.dds.endpoints import domain_id_from_env
    f = tmp_path / "p.yaml"
    f.write_text(OVERRIDES_YAML)
    start_node("--params-file", str(f))
    dp = DomainParticipant(domain_id_from_env())
    subs = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)
    pubs = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
    found = {}
    deadline = time.monotonic() + 30          # discovery on loopback takes milliseconds; this bounds a hang
    while len(found) < 3 and time.monotonic() < deadline:
        for s in subs.take(64):
            if s.topic_name in ("rt/leg_lengths", "rt/glpma_fk/request_assembly_modes"):
                found[s.topic_name] = s.qos
        for s in pubs.take(64):
            if s.topic_name == "rt/pose_estimate":
                found[s.topic_name] = s.qos
        time.sleep(0.05)
    assert set(found) == {"rt/leg_lengths", "rt/glpma_fk/request_assembly_modes", "rt/pose_estimate"}, found
    legs = found["rt/leg_lengths"]
    assert legs[Policy.Reliability] == Policy.Reliability.BestEffort
    assert legs[Policy.History] == Policy.History.KeepLast(3)
    request = found["rt/glpma_fk/request_assembly_modes"]
    assert isinstance(request[Policy.Reliability], Policy.Reliability.Reliable)
    assert request[Policy.History] == Policy.History.KeepLast(7)        # qos_depth, not overridden
    assert found["rt/pose_estimate"][Policy.Durability] == Policy.Durability.TransientLocal


from test_dds_integration import start_node  # noqa: E402,F401 - fixture
