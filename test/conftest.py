import gc
import math
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from glpma_ros.config import load_manipulator
from glpma_ros.modes.exact import ExactUnavailableError, msolve_executable
from glpma_tools.sim.domains import claim_domain

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config"
RPR_YAML = CONFIG / "planar_3rpr_seed.yaml"
HEX_YAML = CONFIG / "hexapod_66_rolland.yaml"
#: loopback-only unicast discovery (no multicast): every DDS process of the tests uses it
DDS_CONFIG = CONFIG / "cyclonedds-localhost.xml"

#: A budget no correct solve comes near, even on a busy machine: tests of what is computed use it
#: (or an evaluation cap), so that their result does not depend on how busy the machine is.
GENEROUS_BUDGET_S = 5.0
GENEROUS_BUDGET_MS = GENEROUS_BUDGET_S * 1e3
#: A solve under a deadline stops: it returns within OVERRUN_FACTOR times its budget plus
#: OVERRUN_SLACK_MS after the budget ran out (check_deadline).  How close to the budget it stops is
#: measured by the benchmark (glpma-fk bench, Deadline honouring).
OVERRUN_FACTOR = 10.0
OVERRUN_SLACK_MS = 50.0


def _have_msolve() -> bool:
    try:
        msolve_executable()
    except ExactUnavailableError:
        return False
    return True


#: whether the exact extra's msolve is installed (or on PATH); ``needs_msolve`` skips a test without it
HAVE_MSOLVE = _have_msolve()
needs_msolve = pytest.mark.skipif(not HAVE_MSOLVE, reason="the exact extra (msolve) is not installed")


def overrun_bound_ms(budget_ms: float) -> float:
    """The largest overrun (ms past the budget) a test of the deadline accepts."""
    return OVERRUN_FACTOR * budget_ms + OVERRUN_SLACK_MS


def check_deadline(solve, budget_ms: float, runs: int) -> None:
    """``solve(seed)`` under a ``budget_ms`` deadline stops: every run within the bound in this
    thread's CPU time (a run preempted by the OS does not use CPU meanwhile, so that holds on a
    busy machine), and at least one within it in wall time.  The garbage collector is off during
    each run (its pauses are the test process's, not the solver's)."""
    cpu, wall = [], []
    for seed in range(runs):
        gc.disable()
        try:
            c0, t0 = time.thread_time(), time.perf_counter()
            solve(seed)
            wall.append((time.perf_counter() - t0) * 1e3 - budget_ms)
            cpu.append((time.thread_time() - c0) * 1e3 - budget_ms)
        finally:
            gc.enable()
    bound = overrun_bound_ms(budget_ms)
    assert max(cpu) <= bound and min(wall) <= bound, {"cpu overrun ms": cpu, "wall overrun ms": wall}


@pytest.fixture(scope="session")
def rpr():
    return load_manipulator(RPR_YAML)


@pytest.fixture(scope="session")
def hexapod():
    return load_manipulator(HEX_YAML)


@pytest.fixture(scope="session")
def rpr_solutions():
    doc = yaml.safe_load(RPR_YAML.read_text())
    return [np.array([s["x"], s["y"], math.radians(s["theta_deg"])]) for s in doc["real_solutions"]]


@pytest.fixture(scope="session")
def hex_published():
    return np.array(yaml.safe_load(HEX_YAML.read_text())["published_solutions"])


@pytest.fixture
def dds_domain():
    """A ROS domain id no other process on the host uses (glpma_tools.sim.domains: an exclusive lock
    per id, held until the test ends), so that a second run of the suite, the demo or a robot's own
    nodes never exchange messages with this test."""
    with claim_domain() as claim:
        yield claim.domain_id


@pytest.fixture
def dds_env(dds_domain, monkeypatch):
    """Environment of one test's processes: loopback unicast discovery and the test's own domain; set
    in this process too, for participants created inside it."""
    env = dict(os.environ, CYCLONEDDS_URI=DDS_CONFIG.as_uri(), ROS_DOMAIN_ID=str(dds_domain),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    for key in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID"):
        monkeypatch.setenv(key, env[key])
    return env


def interrupt(proc: subprocess.Popen, timeout: float = 30.0) -> int:
    """Stop a node process as Ctrl-C does (SIGINT), killing it if it has not exited within
    ``timeout`` seconds (a bound for a hang, not a timing figure); returns its exit status."""
    proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait()
