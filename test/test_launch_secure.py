"""Launch test on a secured ROS 2 Jazzy (SROS2: Cyclone DDS with DDS-Security, ``ros2 security``):
``fk.launch.py secure:=true keystore:=...`` with the shipped policies.

* a secured controller (the mock publisher in enclave ``/controller``, ``controller.policy.xml``) gets
  correct poses (seen by this test in an all-allowed enclave ``/operator``);
* an unsecured publisher's legs are never solved (the node's ``/diagnostics`` counters stay the same);
* a secured enclave whose policy does not grant ``leg_lengths`` cannot even create the publisher.

Skipped where launch_testing or sros2 is not importable."""
import os
import subprocess
import sys
import unittest

import pytest

pytest.importorskip(
    "launch_testing", reason="launch_testing is not importable (ROS 2 Jazzy not sourced): the launch tests run "
                             "under colcon test on a real Jazzy")
pytest.importorskip("sros2", reason="sros2 is not importable: the secured launch test needs a ROS 2 with security "
                                    "(ros2 security)")
import launch_testing.actions
import launch_testing.asserts

from conftest import CONFIG
from glpma_ros.testing import TrackingMonitor, fk_with_mock
from launch import LaunchDescription
from launch_support import CLI_TIMEOUT_S, HANG_S, SCRATCH, Diagnostics, TestNode, counters, params_file

RATE_HZ = 20.0
#: seconds of the mock's trajectory: it then stops, so that the node's counters settle
MOCK_S = 6.0
POSES = 60
KEYSTORE = SCRATCH / "keystore"
SECURITY = CONFIG / "security"
#: an enclave that may run an rclpy node (what glpma_fk.policy.xml grants every node) and read the
#: pose, but not publish the legs
INTRUDER_POLICY = """<?xml version="1.0" encoding="UTF-8"?>
<policy version="0.2.0"><enclaves><enclave path="/intruder"><profiles><profile ns="/" node="intruder">
  <topics publish="ALLOW"><topic>rosout</topic></topics>
  <topics publish="ALLOW" subscribe="ALLOW"><topic>/parameter_events</topic></topics>
  <services reply="ALLOW"><service>~/describe_parameters</service><service>~/get_parameter_types</service>
    <service>~/get_parameters</service><service>~/list_parameters</service><service>~/set_parameters</service>
    <service>~/set_parameters_atomically</service><service>~/get_type_description</service></services>
  <topics subscribe="ALLOW"><topic>pose_estimate</topic></topics>
</profile></profiles></enclave></enclaves></policy>
"""
#: a process that publishes 3-RPR legs (argv[1] seconds at 20 Hz), or exits 3 when it may not
PUBLISHER = """
import sys, time, rclpy
from std_msgs.msg import Float64MultiArray
rclpy.init(args=sys.argv)
node = rclpy.create_node(sys.argv[2])
try:
    pub = node.create_publisher(Float64MultiArray, "leg_lengths", 10)
except Exception as exc:
    print("refused:", exc)
    sys.exit(3)
for k in range(int(float(sys.argv[1]) * 20)):
    pub.publish(Float64MultiArray(data=[0.100, 0.120, 0.150 + 1e-5 * k]))
    time.sleep(0.05)
print("published")
"""
SECURE_ENV = {"ROS_SECURITY_KEYSTORE": str(KEYSTORE), "ROS_SECURITY_ENABLE": "true", "ROS_SECURITY_STRATEGY": "Enforce"}


def security(*args):
    r = subprocess.run(["ros2", "security", *args], capture_output=True, text=True, timeout=CLI_TIMEOUT_S)
    assert r.returncode == 0, r.stdout + r.stderr
    return r


def make_keystore():
    """The keystore for this test's domain (a keystore is bound to ROS_DOMAIN_ID)."""
    (SCRATCH / "intruder.policy.xml").write_text(INTRUDER_POLICY)
    security("create_keystore", str(KEYSTORE))
    for enclave, policy in (("/glpma_fk", SECURITY / "glpma_fk.policy.xml"),
                            ("/controller", SECURITY / "controller.policy.xml"),
                            ("/intruder", SCRATCH / "intruder.policy.xml"), ("/operator", None)):
        security("create_enclave", str(KEYSTORE), enclave)
        if policy is not None:
            security("create_permission", str(KEYSTORE), enclave, str(policy))


@pytest.mark.launch_test
def generate_test_description():
    make_keystore()
    return LaunchDescription([
        *fk_with_mock("3rpr", input_type="joint_state", rate_hz=RATE_HZ, duration_s=MOCK_S,
                      params_file=params_file("3rpr"), keystore=str(KEYSTORE)),
        launch_testing.actions.ReadyToTest(),
    ])


def publish(seconds: float, name: str, secured_enclave: str | None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_SECURITY")}
    args = []
    if secured_enclave is not None:
        env.update(SECURE_ENV)
        args = ["--ros-args", "--enclave", secured_enclave]
    return subprocess.run([sys.executable, "-c", PUBLISHER, str(seconds), name, *args], capture_output=True,
                          text=True, env=env, timeout=CLI_TIMEOUT_S)


class TestSecured(unittest.TestCase):
    def setUp(self):
        self.saved = {k: os.environ.get(k) for k in (*SECURE_ENV, "ROS_SECURITY_ENCLAVE_OVERRIDE")}
        os.environ.update(SECURE_ENV, ROS_SECURITY_ENCLAVE_OVERRIDE="/operator")   # this test's node: /operator

    def tearDown(self):
        for k, v in self.saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v

    def test_only_the_controller_moves_the_estimate(self):
        with TestNode() as t:
            monitor = TrackingMonitor(t.node, "planar_3rpr_seed", "joint_state")
            diagnostics = Diagnostics(t.node)
            self.assertTrue(monitor.spin_until(t.executor, POSES, HANG_S), f"{len(monitor.poses)} poses")
            monitor.assert_tracking(min_poses=POSES)
            self.assertTrue(t.spin_until(lambda: len(monitor.truths) >= round(MOCK_S * RATE_HZ), HANG_S))

            def settled():
                """The counters of two consecutive reports after now that agree (the node is idle)."""
                start = t.node.get_clock().now().nanoseconds
                found = []

                def done():
                    later = [r for r in diagnostics.reports if r[0] > start]
                    found[:] = [counters(a[3]) for a, b in zip(later, later[1:]) if counters(a[3]) == counters(b[3])]
                    return bool(found)
                self.assertTrue(t.spin_until(done, HANG_S))
                return found[0]

            before = settled()
            self.assertGreaterEqual(before["solved"], POSES)
            outsider = publish(2.0, "outsider", None)            # unsecured: never matches the secured node
            self.assertEqual(outsider.returncode, 0, outsider.stdout + outsider.stderr)
            self.assertEqual(settled(), before)
            intruder = publish(2.0, "intruder", "/intruder")     # secured, but leg_lengths is not granted
            self.assertEqual(intruder.returncode, 3, intruder.stdout + intruder.stderr)
            self.assertIn("refused", intruder.stdout)
            self.assertEqual(settled(), before)


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    def test_node_and_mock_exit_0(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info)
