import gc
import math
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from glpma_ros.config import load_manipulator

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config"
RPR_YAML = CONFIG / "planar_3rpr_seed.yaml"
HEX_YAML = CONFIG / "hexapod_66_rolland.yaml"

#: A budget no correct solve comes near, even on a busy machine: tests of what is computed use it
#: (or an evaluation cap), so that their result does not depend on how busy the machine is.
GENEROUS_BUDGET_S = 5.0
GENEROUS_BUDGET_MS = GENEROUS_BUDGET_S * 1e3
#: A solve under a deadline stops: it returns within OVERRUN_FACTOR times its budget plus
#: OVERRUN_SLACK_MS after the budget ran out (check_deadline).  How close to the budget it stops is
#: measured by the benchmark (glpma-fk bench, Deadline honouring).
OVERRUN_FACTOR = 10.0
OVERRUN_SLACK_MS = 50.0


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
