"""The homotopy's paths tracked on several threads (glpma_ros/modes/path_tracker.py ``track``): the same endpoints,
outcomes and steps whatever the thread count, also when several Python threads track at once (the node and the
tools call the homotopy from threads); ``solve_all(threads=N)`` and ``glpma-fk solve-all --threads N`` the same
modes; the defaults (every core the process may run on; the node's modes worker one core fewer)."""
import json
import subprocess
import sys
import threading

import numpy as np
import pytest

from conftest import ROOT
from glpma_ros.errors import GlpmaError
from glpma_ros.models.random_geometry import GENERATORS
from glpma_ros.modes import monodromy
from glpma_ros.modes import path_tracker as pt
from glpma_ros.modes.multistart import solve_all
from glpma_ros.node.modes_worker import modes_threads

#: each path runs the same compiled code on the same numbers whichever thread takes it, so the endpoints agree to
#: round-off at most (in fact exactly); 1e-12 of 1 + |z| is far below SAME_ENDPOINT (1e-6), the distance at which
#: the certificate calls two endpoints one
SAME_ENDPOINT = 1e-12
#: modes polished by the same Levenberg-Marquardt from the same endpoints: within round-off of the scale
SAME_MODE = 1e-9
#: thread counts compared with one thread: two (the machine's cores), three (more than the cores) and more than the
#: 3-RPR's six paths (capped at the path count)
THREAD_COUNTS = (2, 3, 8)
#: the Python threads that track at once in the concurrency test
CONCURRENT_CALLERS = 3


def _target_path(kind, seed):
    start = monodromy.load_start_system(kind)
    model, legs = GENERATORS[kind](np.random.default_rng(seed))[:2]
    path = start.family.parameter_path(start.params, start.family.target(model, legs).params)
    gammas = np.full(len(start.solutions), pt.random_gammas(np.random.default_rng(seed), 1)[0])
    return path, start.solutions, gammas


def _assert_same_tracking(a, b):
    ends_a, jac_a, outcome_a, steps_a, t_a = a
    ends_b, jac_b, outcome_b, steps_b, t_b = b
    assert np.array_equal(outcome_a, outcome_b) and np.array_equal(steps_a, steps_b)
    size = 1.0 + np.max(np.abs(ends_a), axis=1)
    assert np.all(np.max(np.abs(ends_a - ends_b), axis=1) <= SAME_ENDPOINT * size)
    assert np.allclose(t_a, t_b, rtol=0.0, atol=SAME_ENDPOINT)
    assert np.allclose(jac_a, jac_b, rtol=SAME_ENDPOINT, atol=SAME_ENDPOINT)


@pytest.mark.parametrize("kind", ("planar_3rpr", "hexapod_66"))
def test_threads_track_the_same_paths_as_one(kind):
    for seed in range(3):
        path, starts, gammas = _target_path(kind, seed)
        one = pt.track(path, starts, gammas, threads=1)
        assert np.count_nonzero(one[2] == pt.REGULAR) >= len(starts) // 2     # real work, not failures
        for threads in THREAD_COUNTS:
            _assert_same_tracking(one, pt.track(path, starts, gammas, threads=threads))
        _assert_same_tracking(one, pt.track(path, starts, gammas))             # the default


def test_python_threads_tracking_at_once_get_their_own_answers():
    """Several callers share the pool: each gets the answer it gets alone."""
    cases = [_target_path("hexapod_66", seed) for seed in range(CONCURRENT_CALLERS)]
    alone = [pt.track(*case, threads=1) for case in cases]
    together = [None] * len(cases)

    def call(k):
        together[k] = pt.track(*cases[k], threads=2)

    callers = [threading.Thread(target=call, args=(k,)) for k in range(len(cases))]
    for c in callers:
        c.start()
    for c in callers:
        c.join()
    for a, b in zip(alone, together):
        _assert_same_tracking(a, b)


def test_default_threads_are_the_cores_for_enough_paths():
    cores = pt.available_cores()
    assert cores >= 1
    assert pt.default_threads(40) == min(cores, 40 // pt.MIN_PATHS_PER_THREAD)
    assert pt.default_threads(6) == pt.default_threads(1) == 1       # the 3-RPR's paths: one thread
    assert modes_threads() == max(1, cores - 1)


def test_solve_all_threads_give_the_same_modes():
    model, legs = GENERATORS["hexapod_66"](np.random.default_rng(7))[:2]
    one = solve_all(model, legs, method="homotopy", seed=3, threads=1)
    two = solve_all(model, legs, method="homotopy", seed=3, threads=2)
    assert one.complete and two.complete and one.steps == two.steps
    assert len(one.solutions) == len(two.solutions) == one.real_solutions
    for a, b in zip(one.solutions, two.solutions):
        assert model.distance(a.x, b.x) <= SAME_MODE * model.scale


def test_solve_all_refuses_bad_threads():
    model, legs = GENERATORS["planar_3rpr"](np.random.default_rng(1))[:2]
    for bad in (0, -1, 1.5, True):
        with pytest.raises(GlpmaError, match="threads"):
            solve_all(model, legs, method="homotopy", threads=bad)
    with pytest.raises(GlpmaError, match="threads"):
        solve_all(model, legs, method="multistart", threads=2)


def _run(*args):
    return subprocess.run([sys.executable, "-m", "glpma_ros", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, timeout=600)


def test_cli_solve_all_threads_option():
    config = ROOT / "config" / "hexapod_66_rolland.yaml"
    legs = [1250] * 6
    outs = []
    for threads in (1, 2):
        p = _run("solve-all", config, "--legs", *legs, "--threads", threads, "--json")
        assert p.returncode == 0, p.stderr
        outs.append(json.loads(p.stdout))
    one, two = outs
    assert one["complete"] is True and two["complete"] is True and one["steps"] == two["steps"]
    assert len(one["solutions"]) == len(two["solutions"]) == 16
    a = np.array([s["variables"] for s in one["solutions"]])
    b = np.array([s["variables"] for s in two["solutions"]])
    assert np.max(np.abs(a - b)) <= SAME_MODE * np.max(np.abs(a))


def test_cli_threads_bad_values_exit_2():
    config = ROOT / "config" / "hexapod_66_rolland.yaml"
    for extra in (("--threads", 0), ("--threads", "two"), ("--threads", 2, "--method", "multistart")):
        p = _run("solve-all", config, "--legs", *[1250] * 6, *extra)
        assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1 and "threads" in p.stderr


def test_homotopy_bench_times_each_thread_count():
    """tools/homotopy_bench.py (BENCHMARKS.md): the medians on each thread count, the same modes on both; its
    --when-idle samples (here begun whatever the other processes do: a test must not wait for a free machine)."""
    bench = str(ROOT / "tools" / "homotopy_bench.py")
    p = subprocess.run([sys.executable, bench, "--cases", "1", "--exact", "0", "--repeats", "1", "--threads", "1", "2"],
                       capture_output=True, text=True, cwd=ROOT, timeout=1200)
    assert p.returncode == 0, p.stderr
    medians = {line.split()[0]: json.loads(line.split(" MEDIANS ", 1)[1])
               for line in p.stdout.splitlines() if " MEDIANS " in line}
    assert set(medians) == {"dietmaier", "hexapod_66", "planar_3rpr"}
    for m in medians.values():
        assert m["threads_agree"] == m["cases"] == m["complete"]
        assert {"paths_wall_t1", "paths_wall_t2", "homotopy_cpu_t2", "others"} <= set(m)
    p = subprocess.run([sys.executable, bench, "--when-idle", "1", "--cases", "1", "--repeats", "1",
                        "--idle-others", "1000"], capture_output=True, text=True, cwd=ROOT, timeout=1200)
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("SAMPLE ") == 1 and "WHEN_IDLE" in p.stdout
