"""SROS2: the Cyclone DDS transport refuses to start when security is enabled (it cannot join a secured
domain and never runs unsecured instead), and the shipped policy grants the node exactly its
endpoints.  The secured node itself is tested on a secured Jazzy (test_launch_secure.py)."""
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from conftest import CONFIG, ROOT
from glpma_ros.errors import InputError
from glpma_ros.node import qos
from glpma_ros.node.dds.security import check_dds_transport, security_enabled

POLICIES = CONFIG / "security"


@pytest.mark.parametrize("value, enabled", [("true", True), ("True", False), ("1", False), ("", False)])
def test_security_is_enabled_as_rcl_decides_it(value, enabled):
    assert security_enabled({"ROS_SECURITY_ENABLE": value}) is enabled
    assert not security_enabled({})


def test_a_participant_is_refused_under_ros_security_enable(monkeypatch):
    monkeypatch.setenv("ROS_SECURITY_ENABLE", "true")
    with pytest.raises(InputError, match="cannot join a secured ROS 2 domain"):
        check_dds_transport()
    pytest.importorskip("cyclonedds", reason="the Cyclone DDS Python binding is not installed")
    from glpma_ros.node.dds.endpoints import Participant
    with pytest.raises(InputError):
        Participant(0)


@pytest.mark.parametrize("command", [["-m", "glpma_ros.node.dds.node"],
                                     ["-m", "glpma_ros", "node", "--transport", "dds"]])
def test_the_dds_node_refuses_to_start_under_ros_security_enable(dds_env, command):
    env = dict(dds_env, ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY="Enforce")
    r = subprocess.run([sys.executable, *command, "--ros-args", "--params-file", str(CONFIG / "params_3rpr.yaml")],
                       capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "ROS_SECURITY_ENABLE=true" in r.stderr, r.stderr
    assert "ready" not in r.stdout and "Traceback" not in r.stderr


def _profile(path, node):
    """{(kind, permission): names} granted (ALLOW) by the profile of ``node`` in a policy file."""
    profile = next(p for p in ET.parse(path).getroot().iter("profile") if p.get("node") == node)
    grants: dict = {}
    for child in profile:
        if child.tag in ("topics", "services"):
            for permission, value in child.attrib.items():
                if value == "ALLOW":
                    grants.setdefault((child.tag, permission), set()).update(e.text for e in child)
    return grants


def test_the_node_policy_grants_every_endpoint_and_no_other_topic():
    grants = _profile(POLICIES / "glpma_fk.policy.xml", "glpma_fk")
    endpoints = {**qos.node_endpoints(10, "leg_lengths"), **qos.node_endpoints(10, "joint_states")}
    subscribed = {name for name, entity in endpoints if entity == qos.SUBSCRIPTION}
    published = {name for name, entity in endpoints if entity == qos.PUBLISHER}
    infrastructure = {"rosout", "/parameter_events", "~/transition_event"}
    assert grants[("topics", "subscribe")] - {"/parameter_events"} == subscribed
    assert grants[("topics", "publish")] - infrastructure == published
    assert "~/set_parameters" in grants[("services", "reply")]          # it serves them ...
    assert ("services", "request") not in grants                         # ... and calls no service


def test_the_controller_policy_may_publish_the_legs_and_nothing_of_the_node():
    for node in ("controller", "glpma_mock_publisher"):
        grants = _profile(POLICIES / "controller.policy.xml", node)
        assert {"leg_lengths", "joint_states"} <= grants[("topics", "publish")]
        assert ("services", "request") not in grants            # no ros2 param set /glpma_fk, no lifecycle
        assert not any(name.startswith("/glpma_fk") for names in grants.values() for name in names)
