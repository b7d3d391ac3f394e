"""What the launch tests (test_launch_*.py, run by ``colcon test`` on a real Jazzy) share: a ROS
domain of their own, the test's rclpy node and executor, waiting with a bound, the ``ros2`` CLI.

Imported only after ``launch_testing`` was found importable.  At import, this process claims a
ROS domain (glpma_tools.sim.domains, held until the process ends) and puts it, with the loopback
Cyclone DDS configuration, into the environment: the processes the launch starts inherit both,
so a launch test never exchanges messages with another run or with a robot on the host."""
import os
import subprocess
import tempfile
import time
from pathlib import Path

import rclpy
import yaml
from rclpy.executors import SingleThreadedExecutor

from conftest import CONFIG, DDS_CONFIG, GENEROUS_BUDGET_MS
from glpma_tools.sim.domains import claim_domain

CLAIM = claim_domain()
os.environ["ROS_DOMAIN_ID"] = str(CLAIM.domain_id)
os.environ["CYCLONEDDS_URI"] = DDS_CONFIG.as_uri()

#: a bound for a hang, not a timing figure: a first start under a new Python compiles the solvers
#: (Numba, minutes on a busy machine) before the node subscribes
HANG_S = 600.0
#: a bound for one ``ros2`` CLI call (discovery on loopback takes milliseconds)
CLI_TIMEOUT_S = 60.0
#: how long a ``ros2 ... --no-daemon`` call listens for the graph before it answers
CLI_SPIN_S = "3"


class TestNode:
    """An rclpy context, node and single-threaded executor of the test (``with TestNode() as t``)."""

    def __init__(self, name: str = "glpma_launch_test"):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, done, timeout_s: float = HANG_S) -> bool:
        deadline = time.monotonic() + timeout_s
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.1)
        return bool(done())

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Diagnostics:
    """The glpma_fk node's ``/diagnostics`` reports as they come: ``(stamp ns, level, message, values)``."""

    def __init__(self, node, name: str = "glpma_fk"):
        from diagnostic_msgs.msg import DiagnosticArray
        self.reports = []
        self._name = name
        node.create_subscription(DiagnosticArray, "/diagnostics", self._on, 100)

    def _on(self, msg) -> None:
        for s in msg.status:
            if self._name in s.name:
                stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
                self.reports.append((stamp, s.level[0] if isinstance(s.level, bytes) else int(s.level), s.message,
                                     {kv.key: kv.value for kv in s.values}))

    def after(self, stamp_ns: int):
        """The first report stamped after ``stamp_ns``, or None."""
        return next((r for r in self.reports if r[0] > stamp_ns), None)


def ros2(*args: str) -> subprocess.CompletedProcess:
    """``ros2 ARGS`` in this test's domain, without the daemon (none is left running)."""
    return subprocess.run(["ros2", *args, "--no-daemon", "--spin-time", CLI_SPIN_S], capture_output=True, text=True,
                          timeout=CLI_TIMEOUT_S, env=dict(os.environ))


def counters(values: dict) -> dict:
    """The node's input counters from a report's values."""
    return {k: int(values[f"inputs {k}"]) for k in ("received", "solved", "rejected", "dropped")}


_SCRATCH = tempfile.TemporaryDirectory(prefix="glpma_launch_test_")     # removed when the process ends
#: this process's scratch directory (params files, keystores)
SCRATCH = Path(_SCRATCH.name)


def params_file(manipulator: str, **changes) -> str:
    """A copy of the shipped params file of ``manipulator`` (``3rpr``, ``hexapod``) with a time
    budget no correct solve comes near (statuses then depend on the work done only, not on how busy
    the machine is) and ``changes`` (nested mappings, e.g. ``qos_overrides``), as a file path."""
    doc = yaml.safe_load((CONFIG / f"params_{manipulator}.yaml").read_text())
    values = doc["glpma_fk"]["ros__parameters"]
    values.update(time_budget_ms=GENEROUS_BUDGET_MS, deadline_ms=GENEROUS_BUDGET_MS, **changes)
    path = SCRATCH / f"params_{manipulator}_{len(os.listdir(SCRATCH))}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)
