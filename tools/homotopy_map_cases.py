#!/usr/bin/env python3
"""Write test/data/homotopy_map_cases.json: points of the shipped maps (the default ``glpma-fk map`` grid of
the seed 3-RPR and the default x-y slice of the 6-6) with their real assembly modes counted by msolve, for
test/test_homotopy.py (the map's count at each point must be exactly this, on machines with or without the
``exact`` extra).

The points are drawn from the grid (a ``numpy.random.Generator`` seeded by ``SAMPLE_SEED``, without
replacement) among those with valid legs (the map's count -1 otherwise); a point where msolve cannot decide
(a degenerate system) or where a certified mode is double (its leg Jacobian's reciprocal condition number below
``DOUBLE_CONDITIONING``: the point is on a singularity, its count decided by round-off) is left out and
another drawn.  ``--extra INDEX`` adds named grid points (on the 6-6 slice, the two points the multistart
counted 10 where msolve certifies 12).  Needs the extra: ``pip install 'glpma_ros[exact]'``.

    PYTHONPATH=. python tools/homotopy_map_cases.py --config hexapod_66_rolland --extra 5745 6050
    # 20 s to a minute per 6-6 point on two busy cores; resumable
    PYTHONPATH=. python tools/homotopy_map_cases.py --check hexapod_66_rolland DIR/assembly_modes.npz
    # a map computed with the defaults (glpma-fk map hexapod_66_rolland --out DIR) against the stored counts
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

from glpma_ros.config import load_manipulator, resolve_config  # noqa: E402
from glpma_ros.errors import GlpmaError, InputError  # noqa: E402
from glpma_ros.modes.multistart import DOUBLE_CONDITIONING, solve_all  # noqa: E402
from glpma_tools.workspace_map.cli import build_parser, make_spec  # noqa: E402
from glpma_tools.workspace_map.grid import pose_variables  # noqa: E402

DEFAULT_OUT = ROOT / "test" / "data" / "homotopy_map_cases.json"
CONFIGS = ("planar_3rpr_seed", "hexapod_66_rolland")
#: seed of the sample of grid points (apart from the maps' own point seeds)
SAMPLE_SEED = 3450


def default_spec(config: str):
    """The grid of ``glpma-fk map CONFIG`` with its defaults (the method does not change the grid)."""
    model = load_manipulator(resolve_config(config))
    return model, make_spec(model, build_parser().parse_args([config, "--out", "unused"]))


def certify(model, spec, index: int) -> dict | None:
    """The point's certified count, or None when it has no valid legs, msolve cannot decide or a mode is
    double."""
    coords = spec.coordinates(index)
    try:
        legs = model.check_legs(model.inverse_kinematics(pose_variables(model, coords)))
    except InputError:
        return None
    t0 = time.perf_counter()
    try:
        res = solve_all(model, legs, method="exact")
    except GlpmaError as exc:
        print(f"  index {index}: undecided ({exc})", flush=True)
        return None
    cond = [float(model.conditioning(s.x, legs)) for s in res.solutions]
    if cond and min(cond) < DOUBLE_CONDITIONING:
        print(f"  index {index}: a double mode (conditioning {min(cond):.3g}), left out", flush=True)
        return None
    return {"index": int(index), "coordinates": coords, "legs": [float(v) for v in legs],
            "real_solutions": len(res.solutions), "complex_solutions": res.complex_solutions,
            "min_conditioning": min(cond) if cond else None, "msolve_s": round(time.perf_counter() - t0, 2)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--config", choices=CONFIGS, action="append", help="map(s) to sample (default both)")
    p.add_argument("--points", type=int, default=50, help="sampled points per map")
    p.add_argument("--extra", type=int, nargs="*", default=[], help="grid indices to certify as well")
    p.add_argument("--check", type=Path, nargs=2, action="append", metavar=("CONFIG", "NPZ"),
                   help="instead: compare the counts of a map computed with the defaults (DIR/assembly_modes.npz) "
                        "with the stored certified ones; exit 1 when one differs")
    args = p.parse_args(argv)
    if args.check:
        return check(json.loads(args.out.read_text()), args.check)
    data = json.loads(args.out.read_text()) if args.out.exists() else {"maps": {}}
    for config in args.config or CONFIGS:
        model, spec = default_spec(config)
        entry = data["maps"].setdefault(config, {"grid": [spec.axes, spec.limits, spec.shape, spec.fixed],
                                                 "points": []})
        done = {c["index"] for c in entry["points"]}
        for index in args.extra:
            if index not in done:
                case = certify(model, spec, index)
                if case is not None:
                    entry["points"].append({**case, "named": True})
                    done.add(index)
                    write(args.out, data)
        rng = np.random.default_rng(SAMPLE_SEED)
        order = rng.permutation(spec.n_points)
        sampled = sum(not c.get("named") for c in entry["points"])
        for index in order:
            if sampled >= args.points:
                break
            if int(index) in done:
                continue
            case = certify(model, spec, int(index))
            done.add(int(index))
            if case is None:
                continue
            entry["points"].append(case)
            sampled += 1
            print(f"{config} {index}: {case['real_solutions']} real of {case['complex_solutions']} "
                  f"({case['msolve_s']} s)", flush=True)
            write(args.out, data)
    return 0


def check(data: dict, maps: list) -> int:
    """The stored points' certified counts against each map's counts (and certificate flags)."""
    differ = 0
    for config, npz in maps:
        points = data["maps"][str(config)]["points"]
        with np.load(npz) as f:
            counts = f["counts"].reshape(-1)
            # a map by a method without a certificate (or from before the flag) is compared by its counts alone
            certified = f["certified"].reshape(-1) if "certified" in f.files else np.ones_like(counts)
            method = str(f["method"])
        bad = [(c["index"], int(counts[c["index"]]), c["real_solutions"]) for c in points
               if int(counts[c["index"]]) != c["real_solutions"] or certified[c["index"]] != 1]
        differ += len(bad)
        named = [(c["index"], int(counts[c["index"]])) for c in points if c.get("named")]
        print(f"{config} ({method}): {len(points) - len(bad)} of {len(points)} points agree with msolve"
              + (f"; named points (index, map count): {named}" if named else "")
              + "".join(f"\n  differs at {i}: map {m}, certified {e}" for i, m, e in bad))
    return 1 if differ else 0


def write(out: Path, data: dict) -> None:
    data["about"] = ("grid points of the default maps of planar_3rpr_seed and hexapod_66_rolland (glpma-fk map "
                     "defaults) with their real assembly modes certified by msolve (solve_all method exact); "
                     "written by tools/homotopy_map_cases.py")
    out.write_text(json.dumps(data, indent=1) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
