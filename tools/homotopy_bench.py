#!/usr/bin/env python3
"""Time the parameter homotopy beside the multistart and msolve in one run (BENCHMARKS.md, "Every assembly
mode: the homotopy"): Dietmaier's 6-6, random 6-6s and random 3-RPRs (glpma_ros.models.random_geometry).

Per case: the homotopy's paths alone (``track``, every path of one round, in-process), the whole
``solve_all(method="homotopy")`` (certificate, real endpoints, LM polish), both on each thread count of
``--threads``, ``solve_all(method="multistart")`` and, with ``--exact N``, msolve on the first N cases of each
kind; the medians over the cases (``_t<N>``: on N threads) of the wall clock and the process CPU time (every
thread's), the modes each found, the load average before and after each kind and the CPU the other processes
used meanwhile (``others``, cores, from /proc/stat).  ``--when-idle N`` instead: N samples of the random 6-6s'
paths and homotopy on each thread count, each begun when the other processes leave every core idle, with the
CPU they used during the sample (the figures of a free machine are those with ``others`` near 0).

    PYTHONPATH=. python tools/homotopy_bench.py [--cases 20] [--exact 3] [--repeats 5] [--threads 1 2]
    PYTHONPATH=. python tools/homotopy_bench.py --when-idle 10 [--cases 20] [--threads 1 2]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from glpma_ros.config import model_from_dict  # noqa: E402
from glpma_ros.models.random_geometry import GENERATORS  # noqa: E402
from glpma_ros.modes import monodromy, path_tracker  # noqa: E402
from glpma_ros.modes.multistart import solve_all  # noqa: E402

DIETMAIER = {"manipulator": "hexapod_66", "unit": "m",
             "base": [[0, 0, 0], [1.107915, 0, 0], [0.549094, 0.756063, 0], [0.735077, -0.223935, 0.525991],
                      [0.514188, -0.526063, -0.368418], [0.590473, 0.094733, -0.205018]],
             "platform": [[0, 0, 0], [0.542805, 0, 0], [0.956919, -0.528915, 0], [0.665885, -0.353482, 1.402538],
                          [0.478359, 1.158742, 0.107672], [-0.137087, -0.235121, 0.353913]]}
DIETMAIER_LEGS = np.array([1.0, 0.645275, 1.086284, 1.503439, 1.281933, 0.771071])


def timed(fn, repeats):
    """(median wall s, median CPU s, last result) of ``repeats`` calls."""
    wall, cpu, out = [], [], None
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu), out


def paths_only(model, legs, seed, threads):
    start = monodromy.load_start_system(model.kind)
    family = start.family
    path = family.parameter_path(start.params, family.target(model, legs).params)
    gammas = np.full(len(start.solutions), path_tracker.random_gammas(np.random.default_rng(seed), 1)[0])
    return lambda: path_tracker.track(path, start.solutions, gammas, threads=threads)


def load_average() -> float:
    return round(os.getloadavg()[0], 2)


def machine_busy_s() -> float:
    """CPU seconds every process of the machine has used (Linux /proc/stat: all but idle and iowait)."""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:9]]
    return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")


class Others:
    """The cores the other processes kept busy from construction to :meth:`cores` (the machine's busy CPU time
    minus this process's, per wall-clock second)."""

    def __init__(self):
        self.busy, self.cpu, self.wall = machine_busy_s(), time.process_time(), time.perf_counter()

    def cores(self) -> float:
        busy = machine_busy_s() - self.busy - (time.process_time() - self.cpu)
        return round(max(busy, 0.0) / (time.perf_counter() - self.wall), 2)


#: --when-idle: a sample begins when the other processes used less than this many cores over IDLE_PROBE_S
#: (--idle-others)
IDLE_OTHERS = 0.05
IDLE_PROBE_S = 0.5
#: ... probing again after this pause while the machine is busy
IDLE_WAIT_S = 5.0
#: ... and the samples whose other processes used at most this many cores count as a free machine
FREE_OTHERS = 0.1


def when_idle(cases, thread_counts, samples, repeats, idle_others=IDLE_OTHERS):
    """``samples`` timings of ``cases`` (random 6-6s) on each thread count, each begun when the other processes
    use less than ``idle_others`` cores."""
    calls = [(paths_only(m, lg, k, n), lambda m=m, lg=lg, k=k, n=n: solve_all(m, lg, method="homotopy", seed=k,
                                                                             threads=n), n)
             for n in thread_counts for k, (m, lg) in enumerate(cases)]
    for paths, whole, _ in calls:                   # load the compiled code and the thread pool
        paths()
        whole()
    out = []
    while len(out) < samples:
        probe = Others()
        time.sleep(IDLE_PROBE_S)
        if probe.cores() >= idle_others:
            time.sleep(IDLE_WAIT_S)
            continue
        sample = {"utc": time.strftime("%H:%M:%S", time.gmtime()), "load": load_average()}
        for n in thread_counts:
            others = Others()
            rows = [(timed(paths, repeats), timed(whole, max(1, repeats // 2))) for paths, whole, t in calls
                    if t == n]
            sample[f"others_t{n}"] = others.cores()
            for key, pick in (("paths_wall", lambda r: r[0][0]), ("paths_cpu", lambda r: r[0][1]),
                              ("homotopy_wall", lambda r: r[1][0]), ("homotopy_cpu", lambda r: r[1][1])):
                sample[f"{key}_t{n}"] = round(statistics.median(pick(r) for r in rows), 5)
        print("SAMPLE", json.dumps(sample), flush=True)
        out.append(sample)
    free = [x for x in out if all(x[f"others_t{n}"] <= FREE_OTHERS for n in thread_counts)]
    summary = {"samples": len(out), "free": len(free)}
    if free:
        for key in free[0]:
            if "_wall" in key or "_cpu" in key:
                v = [x[key] for x in free]
                summary[key] = [round(statistics.median(v), 5), min(v), max(v)]
    print("WHEN_IDLE median [p50, min, max] over the free samples", json.dumps(summary), flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", type=int, default=20, help="random cases of each kind")
    p.add_argument("--exact", type=int, default=3, help="cases of each kind also solved by msolve")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--threads", type=int, nargs="+", default=None, metavar="N",
                   help="thread counts of the homotopy's paths to time (default 1 and the default, the cores this "
                        "process may run on)")
    p.add_argument("--when-idle", type=int, default=0, metavar="N",
                   help="instead: N samples of the random 6-6s' paths and homotopy, each begun on an idle machine")
    p.add_argument("--idle-others", type=float, default=IDLE_OTHERS, metavar="CORES",
                   help=f"--when-idle: a sample begins when the other processes use less than this many cores "
                        f"(default {IDLE_OTHERS})")
    args = p.parse_args(argv)
    thread_counts = args.threads or sorted({1, path_tracker.available_cores()})
    rng = np.random.default_rng(2026)
    if args.when_idle:
        when_idle([GENERATORS["hexapod_66"](rng)[:2] for _ in range(args.cases)], thread_counts, args.when_idle,
                  args.repeats, args.idle_others)
        return 0
    groups = {"dietmaier": [(model_from_dict(DIETMAIER), DIETMAIER_LEGS)],
              "hexapod_66": [GENERATORS["hexapod_66"](rng)[:2] for _ in range(args.cases)],
              "planar_3rpr": [GENERATORS["planar_3rpr"](rng)[:2] for _ in range(args.cases)]}
    for model, legs in (groups["dietmaier"][0], groups["planar_3rpr"][0]):    # load the compiled code
        solve_all(model, legs, method="homotopy")
        solve_all(model, legs, method="multistart")
    report = {}
    for name, cases in groups.items():
        rows = []
        load_before, others = load_average(), Others()
        for k, (model, legs) in enumerate(cases):
            row = {}
            for n in thread_counts:
                row[f"paths_wall_t{n}"], row[f"paths_cpu_t{n}"], _ = timed(paths_only(model, legs, k, n), args.repeats)
            counts = set()
            for n in thread_counts:
                row[f"homotopy_wall_t{n}"], row[f"homotopy_cpu_t{n}"], res = timed(
                    lambda m=model, lg=legs, k=k, n=n: solve_all(m, lg, method="homotopy", seed=k, threads=n),
                    args.repeats)
                row["homotopy_modes"], row["complete"] = res.real_solutions, res.complete
                counts.add((res.real_solutions, res.complete, res.steps))
            row["threads_agree"] = len(counts) == 1
            row["multistart_wall"], row["multistart_cpu"], ms = timed(
                lambda m=model, lg=legs, k=k: solve_all(m, lg, method="multistart", seed=k), max(1, args.repeats // 2))
            row["multistart_modes"] = len(ms.solutions)
            if k < args.exact:
                row["msolve_wall"], row["msolve_cpu"], ex = timed(
                    lambda m=model, lg=legs: solve_all(m, lg, method="exact"), 1)
                row["msolve_modes"] = len(ex.solutions)
            rows.append(row)
            print(name, k, json.dumps({a: (round(b, 5) if isinstance(b, float) else b) for a, b in row.items()}),
                  flush=True)
        med = {key: statistics.median(r[key] for r in rows if key in r)
               for key in rows[0] if "_wall" in key or "_cpu" in key}
        med.update(complete=sum(r["complete"] for r in rows), cases=len(rows), load_before=load_before,
                   threads_agree=sum(r["threads_agree"] for r in rows),
                   load_after=load_average(), others=others.cores(),
                   multistart_missed=sum(r["multistart_modes"] < r["homotopy_modes"] for r in rows),
                   msolve_agrees=sum(r.get("msolve_modes") == r["homotopy_modes"] for r in rows if "msolve_modes" in r))
        report[name] = med
        print(name, "MEDIANS", json.dumps({a: (round(b, 5) if isinstance(b, float) else b) for a, b in med.items()}),
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
