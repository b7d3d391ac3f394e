#!/usr/bin/env python3
"""Write test/data/assembly_modes_cases.json: random manipulators with their certified real
assembly modes, for test/test_assembly_modes_exact.py on machines without the ``exact`` extra.

Cases come from ``glpma_ros.models.random_geometry`` with ``numpy.random.default_rng(seed)``
for seed = 0, 1, 2, ...; each is solved by ``solve_all(method="exact")`` (msolve) and kept
while its number of real modes is still wanted (3-RPR: so many with 2, 4 and 6 modes;
hexapod: so many with at least ``--hexapod-rich`` modes and so many others).  Needs the extra:
``pip install 'glpma_ros[exact]'``.

    PYTHONPATH=. python tools/assembly_modes_cases.py            # takes several minutes
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from glpma_ros.models.random_geometry import GENERATORS  # noqa: E402
from glpma_ros.modes.multistart import solve_all  # noqa: E402

DEFAULT_OUT = ROOT / "test" / "data" / "assembly_modes_cases.json"


def case_record(kind, seed, model, legs, res) -> dict:
    return {"kind": kind, "seed": seed, "base": model.base.tolist(), "platform": model.platform.tolist(),
            "legs": [float(v) for v in legs], "complex_solutions": res.complex_solutions,
            "modes": [[float(v) for v in s.x] for s in res.solutions]}


def collect(kind, wanted, max_seed, log) -> list:
    """Seeds 0.. until each ``wanted[label]`` (label -> (predicate on the mode count, number)) is met."""
    left = {label: n for label, (_, n) in wanted.items()}
    cases = []
    for seed in range(max_seed):
        if not any(left.values()):
            break
        model, legs, _ = GENERATORS[kind](np.random.default_rng(seed))
        t0 = time.perf_counter()
        res = solve_all(model, legs, method="exact")
        n = len(res.solutions)
        label = next((lb for lb, (ok, _) in wanted.items() if ok(n) and left[lb] > 0), None)
        log(f"{kind} seed {seed}: {n} real of {res.complex_solutions} complex, {time.perf_counter() - t0:.1f} s"
            + (f" -> kept ({label})" if label else ""))
        if label:
            left[label] -= 1
            cases.append(case_record(kind, seed, model, legs, res))
    if any(left.values()):
        raise SystemExit(f"{kind}: not enough cases below seed {max_seed}: still wanted {left}")
    return cases


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--planar", type=int, nargs=3, default=(8, 7, 6), metavar=("N2", "N4", "N6"),
                   help="3-RPR cases with 2, 4 and 6 real modes")
    p.add_argument("--hexapod", type=int, default=12, help="hexapod cases")
    p.add_argument("--hexapod-rich", type=int, nargs=2, default=(8, 4), metavar=("MODES", "N"),
                   help="of which N with at least MODES real modes")
    p.add_argument("--max-seed", type=int, default=5000)
    args = p.parse_args(argv)

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    n2, n4, n6 = args.planar
    planar = collect("planar_3rpr", {"2": (lambda n: n == 2, n2), "4": (lambda n: n == 4, n4),
                                     "6": (lambda n: n == 6, n6)}, args.max_seed, log)
    rich, n_rich = args.hexapod_rich
    hexapod = collect("hexapod_66", {f">={rich}": (lambda n: n >= rich, n_rich),
                                     "other": (lambda n: n < rich, args.hexapod - n_rich)}, args.max_seed, log)
    doc = {"about": "random manipulators (glpma_ros.models.random_geometry, numpy.random.default_rng(seed)) and "
                    "their real assembly modes certified by solve_all(method='exact'); written by "
                    "tools/assembly_modes_cases.py",
           "cases": planar + hexapod}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    log(f"wrote {len(doc['cases'])} cases to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
