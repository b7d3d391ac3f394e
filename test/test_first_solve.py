"""The first solve after start-up loads nothing: ``precompile.exercise`` (what ``glpma-fk solve`` and the node
run before their first input) leaves no compiled code for a later solve to load or compile, so that the first
solve under a deadline keeps it as the others do.

Each manipulator runs in a fresh process (in this one, earlier tests have loaded everything already): after the
exercise of a solver, every solve is checked on its own -- no compiled function gained a signature (compiled, or
loaded from Numba's cache: either adds an overload to its dispatcher) and no module was imported.  One check per
solve in a row is as strict as one process per solve: whatever a solve loads lazily, the first solve that needs
it is the one caught.  Counts, not times: this holds on a busy machine as on an idle one."""
import json
import subprocess
import sys

import pytest

from conftest import ROOT
from glpma_ros.solvers import SOLVERS

#: what the child process runs: ``glpma-fk solve``'s own code path (its ``main``, with the exercise it runs
#: first), the Estimator's cold path as the node runs it, and every solver on its own (the bench's deadline
#: cells); prints one JSON object per solve: what it loaded
CHILD = r"""
import gc, io, json, sys, contextlib
import numpy as np
from numba.core.dispatcher import Dispatcher
from glpma_ros import solvers
from glpma_ros.cli import solve as cli
from glpma_ros.config import load_manipulator, resolve_config
from glpma_ros.estimation.estimator import Estimator
from glpma_ros.node.dds import cdr
from glpma_ros.node.input_topic import model_is_actuated
from glpma_ros.node.service import FkService
from glpma_ros.runtime import precompile
from glpma_ros.units import UNIT_TO_METRES

path, config, legs_cases, budget_ms = json.loads(sys.argv[1])
model = load_manipulator(resolve_config(config))


def signatures():
    return {id(d): (f"{d.py_func.__module__}.{d.py_func.__qualname__}", set(d.overloads))
            for d in gc.get_objects() if isinstance(d, Dispatcher)}


def report(what, before, modules):
    after = signatures()
    new = sorted(name for k, (name, sigs) in after.items() if sigs - before.get(k, (name, set()))[1])
    print(json.dumps({"what": what, "loaded": new, "imported": sorted(set(sys.modules) - modules)}))


if path == "node":
    # the node's service: its warm-up at start, then its inputs (each a cold start: the warm state forgotten)
    svc = FkService({"manipulator_config": str(resolve_config(config)), "time_budget_ms": budget_ms})
    svc.warm_up()
    si = 1.0 if model_is_actuated(model) else UNIT_TO_METRES[model.unit]     # inputs in SI units
    for label, legs in legs_cases:
        svc.estimator.reset()
        before, modules = signatures(), set(sys.modules)
        svc.handle([v * si for v in legs], stamp_ns=0)
        report(f"node input, {label}", before, modules)
        # the same legs again as a leg_lengths message, from the warm state that input left (if it was solved):
        # the one-call way (nothing, for an actuated family or without a warm state), its estimate after the write
        message = cdr.Encoder().float64_multi_array([v * si for v in legs])
        before, modules = signatures(), set(sys.modules)
        outcome = svc.solve_message(message, 0)
        if outcome is not None:
            svc.account(outcome)
        report(f"node message, {label}", before, modules)
    sys.exit(0)

# glpma-fk solve: its exercise, then its solve (the estimator built and run)
exercise = precompile.exercise
marks = {}


def exercise_then_mark(model, solver):
    seconds = exercise(model, solver)
    marks["before"], marks["modules"] = signatures(), set(sys.modules)
    return seconds


precompile.exercise = exercise_then_mark
for label, legs in legs_cases:
    with contextlib.redirect_stdout(io.StringIO()):
        cli.main([config, "--legs", *map(str, legs), "--budget-ms", str(budget_ms), "--json"])
    report(f"glpma-fk solve, {label}", marks["before"], marks["modules"])
precompile.exercise = exercise

# the Estimator's cold path (a new estimator per input: no warm state)
for label, legs in legs_cases:
    est = Estimator(model, time_budget_s=budget_ms / 1e3)
    before, modules = signatures(), set(sys.modules)
    est.estimate(np.array(legs))
    report(f"Estimator cold, {label}", before, modules)

# every solver on its own after its exercise, the papers' settings (as the bench's deadline cells call it)
for name in solvers.SOLVERS:
    precompile.exercise(model, name)
    for label, legs in legs_cases:
        before, modules = signatures(), set(sys.modules)
        solvers.solve(name, model, model.check_legs(np.array(legs)), rng=1, budget_s=budget_ms / 1e3,
                      max_evals=10**9)
        report(f"{name} on its own, {label}", before, modules)
"""

#: a budget of the size a controller gives (the load must fit in neither)
BUDGET_MS = 2.0
#: per manipulator: legs with an assembly, legs every pair of legs could close but no pose reaches (the
#: search and the probe decide), legs a pair's loop bounds tell at once
CASES = {
    "planar_3rpr_seed": [("feasible", [100.0, 120.0, 150.0]), ("no assembly", [400.0, 400.0, 400.0]),
                         ("told", [10.0, 10.0, 400.0])],
    "hexapod_66_rolland": [("feasible", [1000.0] * 5 + [1500.0]), ("no assembly", [900.0, 1600.0] * 3),
                           ("told", [100.0] * 6)],
    # the Delta's closed form answers without a search; its arm angles in radians, within the limits
    "delta_irb360": [("feasible", [0.021727, 0.008779, 0.199391]), ("other mode", [1.39, -0.69, -0.69])],
}


@pytest.mark.parametrize("path", ["node", "cli"])
@pytest.mark.parametrize("config", list(CASES))
def test_first_solve_after_warm_up_loads_nothing(config, path):
    """``node``: the node's service after its warm-up, on each input and on it again as a message; ``cli``:
    ``glpma-fk solve`` (its
    exercise, then its solve), the Estimator's cold path and every solver on its own."""
    out = subprocess.run([sys.executable, "-c", CHILD, json.dumps([path, config, CASES[config], BUDGET_MS])],
                         capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    steps = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    # every path ran, on each case
    assert len(steps) == len(CASES[config]) * (2 if path == "node" else 2 + len(SOLVERS)), out.stdout
    late = [s for s in steps if s["loaded"] or s["imported"]]
    assert not late, late
