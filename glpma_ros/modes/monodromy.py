"""The start systems of the parameter homotopy (:mod:`.homotopy`), built offline by monodromy and shipped.

A start system is a generic *complex* member ``p_0`` of a family (random complex geometry; legs chosen so that a
random complex point is a solution) and all its solutions, found by monodromy loops (Duff, Hill, Jensen, Lee,
Leykin & Sommars 2019, "Solving polynomial systems via homotopy continuation and monodromy", IMA J. Numer. Anal.
39(3)): the known solutions are tracked around a triangle ``p_0 -> p_1 -> p_2 -> p_0`` of random complex members,
the new endpoints are added, until the count has not grown for ``MONODROMY_STABLE_LOOPS`` loops and equals the
family's generic root count.  They are package data under ``start_systems/``
(``python -m glpma_ros.modes.monodromy --build-start-systems`` writes them).  No ROS import.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import GlpmaError
from .homotopy_families import Family, Hexapod66Family, Planar3RPRFamily, _crandn
from .path_tracker import REGULAR, distinct, random_gammas, track

START_SYSTEMS = Path(__file__).with_name("start_systems")
#: the count must not have grown for this many loops before the start system is accepted
MONODROMY_STABLE_LOOPS = 20
#: loops at most
MONODROMY_MAX_LOOPS = 400


@dataclass
class StartSystem:
    family: Family
    params: np.ndarray         # the generic complex member p_0
    solutions: np.ndarray      # all its solutions (root_count, n_unknowns)
    loops: int                 # monodromy loops that found them


def family_of(model) -> str | None:
    """The homotopy family of ``model``, or None: 3-RPR, hexapod (every 6-6, the coincident-joint designs
    included, which are members of the 6-6 family)."""
    return model.kind if model.kind in ("planar_3rpr", "hexapod_66") else None


def has_start_system(model) -> bool:
    """The model's family has a shipped start system."""
    name = family_of(model)
    return name is not None and (START_SYSTEMS / f"{name}.npz").exists()


@lru_cache(maxsize=None)
def load_start_system(name: str) -> StartSystem:
    path = START_SYSTEMS / f"{name}.npz"
    if not path.exists():
        raise GlpmaError(f"no homotopy start system for {name} ({path} missing; build it with "
                         "python -m glpma_ros.modes.monodromy --build-start-systems)")
    data = np.load(path)
    family = Hexapod66Family(data["patch"]) if name == "hexapod_66" else Planar3RPRFamily()
    if int(data["root_count"]) != family.root_count:
        raise GlpmaError(f"{path}: root count {int(data['root_count'])}, expected {family.root_count}")
    return StartSystem(family, data["params"], np.ascontiguousarray(data["solutions"]), int(data["loops"]))


def build_start_system(family: Family, seed: int, *, verbose=False) -> StartSystem:
    """Every solution of a random complex member by monodromy loops (module docstring)."""
    rng = np.random.default_rng(seed)
    p0, z0 = family.random_instance(rng)
    sols = z0[None, :].astype(complex)
    stable = loops = 0
    while loops < MONODROMY_MAX_LOOPS and not (stable >= MONODROMY_STABLE_LOOPS and len(sols) == family.root_count):
        loops += 1
        p1, p2 = family.random_params(rng), family.random_params(rng)
        current = sols
        ok = np.ones(len(current), bool)
        for pa, pb in ((p0, p1), (p1, p2), (p2, p0)):
            gammas = random_gammas(rng, 1).repeat(len(current))
            ends, jac, outcome, _, _ = track(family.parameter_path(pa, pb), current, gammas)
            ok &= outcome == REGULAR
            current = ends
        found = current[ok]
        before = len(sols)
        allpts = np.concatenate([sols, found])
        sols = allpts[distinct(allpts)]
        stable = stable + 1 if len(sols) == before else 0
        if verbose:
            print(f"{family.name}: loop {loops}, {len(sols)} solutions")
    if len(sols) != family.root_count:
        raise GlpmaError(f"monodromy found {len(sols)} solutions of {family.name}, expected {family.root_count}")
    # residual check at p0
    Q = family.quadrics(p0)
    w = np.concatenate([sols, np.ones((len(sols), 1))], 1)
    residual = np.abs(np.einsum("pm,imn,pn->pi", w, Q, w)).max()
    if residual > 1e-9:
        raise GlpmaError(f"start solutions of {family.name} have residual {residual:.3g}")
    return StartSystem(family, p0, sols, loops)


#: seeds of the shipped start systems (any seed gives a generic member with probability one)
BUILD_SEEDS = {"planar_3rpr": 3401, "hexapod_66": 3466}


def build_all(out_dir=START_SYSTEMS, verbose=True, families=tuple(BUILD_SEEDS)) -> None:
    """Build the start systems of ``families`` (names of :data:`BUILD_SEEDS`) into ``out_dir`` as ``NAME.npz``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in families:
        seed = BUILD_SEEDS[name]
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        if name == "hexapod_66":
            family = Hexapod66Family(_crandn(rng, 4))
        else:
            family = Planar3RPRFamily()
        start = build_start_system(family, seed + 1, verbose=verbose)
        extra = {"patch": family.patch} if name == "hexapod_66" else {}
        np.savez(out_dir / f"{name}.npz", params=start.params, solutions=start.solutions,
                 root_count=np.int64(family.root_count), loops=np.int64(start.loops), seed=np.int64(seed), **extra)
        if verbose:
            print(f"{name}: {len(start.solutions)} solutions after {start.loops} loops "
                  f"({time.perf_counter() - t0:.1f} s)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glpma_ros.modes.monodromy",
                                 description="build the start systems of the parameter homotopy (offline, once)")
    ap.add_argument("--build-start-systems", action="store_true", required=True)
    ap.add_argument("--out", default=str(START_SYSTEMS),
                    help="directory of the NAME.npz files (default: the package's)")
    ap.add_argument("--family", action="append", choices=sorted(BUILD_SEEDS),
                    help="build only this family's start system (repeatable; default: every family)")
    args = ap.parse_args(argv)
    build_all(args.out, families=args.family or tuple(BUILD_SEEDS))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
