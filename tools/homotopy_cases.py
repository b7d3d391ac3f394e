#!/usr/bin/env python3
"""Write test/data/homotopy_cases.json: random 3-RPRs and general 6-6 hexapods with their real assembly
modes and complex count certified by msolve, for test/test_homotopy.py (the homotopy must find exactly these
modes, on machines with or without the ``exact`` extra).

Case ``k`` of a kind is ``glpma_ros.models.random_geometry.GENERATORS[kind](numpy.random.default_rng(SEED_BASE
+ k))``, solved by ``solve_all(method="exact")``.  Needs the extra: ``pip install 'glpma_ros[exact]'``.

    PYTHONPATH=. python tools/homotopy_cases.py    # about a minute per 6-6 on two busy cores; resumable
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

DEFAULT_OUT = ROOT / "test" / "data" / "homotopy_cases.json"
#: the generator seeds start here (apart from assembly_modes_cases.json's 0, 1, 2, ...)
SEED_BASE = 34_000


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--per-kind", type=int, default=50, help="cases of each kind")
    args = p.parse_args(argv)
    # resumable: the cases already written are kept, the file is rewritten after every new one
    cases = json.loads(args.out.read_text())["cases"] if args.out.exists() else []
    done = {(c["kind"], c["seed"]) for c in cases}
    t0 = time.perf_counter()
    for kind in ("planar_3rpr", "hexapod_66"):
        for k in range(args.per_kind):
            seed = SEED_BASE + k
            if (kind, seed) in done:
                continue
            model, legs, _ = GENERATORS[kind](np.random.default_rng(seed))
            res = solve_all(model, legs, method="exact")
            cases.append({"kind": kind, "seed": seed, "base": model.base.tolist(), "platform": model.platform.tolist(),
                          "legs": [float(v) for v in legs], "complex_solutions": res.complex_solutions,
                          "modes": [[float(v) for v in s.x] for s in res.solutions]})
            print(f"{kind} {seed}: {len(res.solutions)} real of {res.complex_solutions} "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)
            write(args.out, cases)
    return 0


def write(out: Path, cases: list) -> None:
    out.write_text(json.dumps({"about": "random manipulators (glpma_ros.models.random_geometry, seeds from "
                               f"{SEED_BASE}) with their real assembly modes certified by msolve "
                               "(solve_all method exact); written by tools/homotopy_cases.py",
                               "cases": cases}, indent=1) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
