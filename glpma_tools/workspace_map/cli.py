"""Command line of ``glpma-fk map`` (:func:`main`): the arguments, the grid they describe
(:func:`make_spec`, default ranges), the run (:func:`.engines.compute_map`) and its summary."""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import textwrap
from pathlib import Path

import yaml

from glpma_ros.cli.api import command_main, manipulator_parser
from glpma_ros.config import load_document, model_from_dict, resolve_config
from glpma_ros.errors import InputError

from ..extras import require
from ..tables import add_summary_options
from .engines import compute_map
from .exact_check import exact_check, require_exact
from .grid import ANGLES, CLOSED_FORM, DEFAULT_RUNS, METHODS, MapSpec, coordinates_of, default_method

PROG = "glpma-fk map"
#: default half-margin of the x-y range around the base joints' bounding box, in units of the geometry's size
XY_MARGIN = 0.5
#: default range of z, in units of the geometry's size
Z_RANGE = (0.0, 2.0)
#: default z of a hexapod slice, in units of the geometry's size (the platform well above the base)
Z_DEFAULT = 1.0
DEFAULT_RESOLUTION = 101
#: width of the --help texts
HELP_WIDTH = 100


def default_limits(model, name: str) -> tuple:
    if name in ANGLES:
        return (-180.0, 180.0)
    if getattr(model, "actuated", False):     # an actuated family: the box its platform origin can reach
        lo, hi = model.reach_box()
        k = "xyz".index(name)
        return (float(lo[k]), float(hi[k]))
    if name == "z":
        return tuple(f * model.scale for f in Z_RANGE)
    k = "xy".index(name)
    lo, hi = float(model.base[:, k].min()), float(model.base[:, k].max())
    return (lo - XY_MARGIN * model.scale, hi + XY_MARGIN * model.scale)


def make_spec(model, args) -> MapSpec:
    names = coordinates_of(model)
    axes = tuple(args.axes)
    for a in axes:
        if a not in names:
            raise InputError(f"--axes: {model.kind} has pose coordinates {' '.join(names)}, not {a!r}")
    if axes[0] == axes[1]:
        raise InputError("--axes needs two different coordinates")
    fixed = {n: (Z_DEFAULT * model.scale if n == "z" else 0.0) for n in names if n not in axes}
    if getattr(model, "actuated", False) and "z" in fixed:     # an actuated family: the height of its home pose
        fixed["z"] = float(model.pose(model.home_variables()).position[2])
    for item in args.at or []:
        name, sep, value = item.partition("=")
        if not sep or name not in names:
            raise InputError(f"--at expects NAME=VALUE with NAME one of {' '.join(names)}, got {item!r}")
        if name in axes:
            raise InputError(f"--at {name}: {name} is on the grid (--axes)")
        try:
            fixed[name] = float(value)
        except ValueError:
            raise InputError(f"--at {name}: {value!r} is not a number") from None
        if not math.isfinite(fixed[name]):
            raise InputError(f"--at {name}: must be finite")
    if args.limits is None:
        limits = (default_limits(model, axes[0]), default_limits(model, axes[1]))
    else:
        limits = ((args.limits[0], args.limits[1]), (args.limits[2], args.limits[3]))
    for name, (lo, hi) in zip(axes, limits):
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InputError(f"--limits for {name}: needs finite LOW < HIGH, got {lo:g} {hi:g}")
    resolution = list(args.resolution)
    shape = (resolution[0], resolution[-1])
    if min(shape) < 2 or len(resolution) > 2:
        raise InputError("--resolution expects one or two numbers of points per axis, each at least 2")
    method = args.method or ("g3pcx" if args.runs is not None else "multistart" if args.max_starts is not None
                             else default_method(model))
    if method == CLOSED_FORM and default_method(model) != CLOSED_FORM:
        raise InputError(f"--method closed_form: {model.kind} has no closed-form forward kinematics")
    if args.runs is not None and method != "g3pcx":
        raise InputError(f"--runs counts G3-PCX searches (--method g3pcx); {method} does not take it")
    if args.max_starts is not None and method != "multistart":
        raise InputError("--max-starts limits --method multistart")
    if args.runs is not None and args.runs < 1:
        raise InputError("--runs must be at least 1")
    if args.max_starts is not None and args.max_starts < 1:
        raise InputError("--max-starts must be at least 1")
    if args.seed < 0:
        raise InputError("--seed must be a non-negative integer")
    per_point = (DEFAULT_RUNS if args.runs is None else args.runs) if method == "g3pcx" else (args.max_starts or 0)
    return MapSpec(model.kind, axes, limits, shape, tuple((n, float(fixed[n])) for n in names if n in fixed),
                   int(per_point), int(args.seed), method)


def build_parser() -> argparse.ArgumentParser:
    p = manipulator_parser(
        PROG, metavar="CONFIG", formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
            "Assembly-mode map of a 2-D slice of the workspace: at every point of a grid over two pose coordinates "
            "(the others fixed), the number of real assembly modes of the legs of that pose (solve_all) and the "
            "conditioning of the pose. Writes DIR/assembly_modes.npz and a PNG with the mode-count regions and "
            "the singularity curves. Lengths in the config's unit, angles in degrees.",
            HELP_WIDTH, break_on_hyphens=False),
        epilog="pose coordinates: planar_3rpr, planar_3rrr x y theta; hexapod_66, rus_6 x y z roll pitch yaw "
               "(R = Rz(yaw) Ry(pitch) Rx(roll)); delta x y z.\ndefaults: x-y range = the base joints' bounding box "
               "+- half the geometry's size, z range 0 .. 2 sizes,\nangles -180 .. 180; fixed angles 0 and z = the "
               "geometry's size; an actuated family: the box its platform can reach, z of its home pose.\n"
               "Finished chunks are kept in DIR/chunks/: a rerun of the same map (same config and grid) skips them.")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (created; reused to resume)")
    p.add_argument("--axes", nargs=2, default=("x", "y"), metavar=("A", "B"),
                   help="pose coordinates along the columns and the rows (default x y)")
    p.add_argument("--limits", nargs=4, type=float, default=None, metavar=("LOW_A", "HIGH_A", "LOW_B", "HIGH_B"),
                   help="range of each axis (config unit or degrees; default: see below)")
    p.add_argument("--resolution", nargs="+", type=int, default=[DEFAULT_RESOLUTION], metavar="N",
                   help=f"points per axis: N, or N_A N_B (default {DEFAULT_RESOLUTION})")
    p.add_argument("--at", nargs="+", default=None, metavar="NAME=VALUE",
                   help="the fixed coordinates, e.g. --at theta=30 (3-RPR) or --at z=900 yaw=10 (hexapod)")
    p.add_argument("--method", choices=METHODS, default=None,
                   help="how the modes of a point are counted: homotopy (default where the family has a start "
                        "system, the 3-RPR and the hexapods: solve_all's parameter homotopy, each count certified "
                        "by the root count or the point marked uncertified), multistart (solve_all's multistart of "
                        "Levenberg-Marquardt solves with its stopping rule; the default for the other families "
                        "and when --max-starts is given), g3pcx (the papers' polished G3-PCX searches, --runs of "
                        "them; default when --runs is given) or closed_form (the Delta's sphere intersection; its "
                        "default)")
    p.add_argument("--runs", type=int, default=None, metavar="N",
                   help=f"g3pcx: searches per point (default {DEFAULT_RUNS}; more finds rare modes)")
    p.add_argument("--max-starts", type=int, default=None, metavar="N",
                   help="multistart: cap on the starts per point (default: solve_all's, 20000; the stopping "
                        "rule ends it far earlier); implies --method multistart")
    p.add_argument("--exact", type=int, default=None, metavar="K",
                   help="spot check: after the map, certify the counts of K grid points drawn at random (seeded "
                        "by --seed) with msolve (glpma-fk solve-all --exact; pip install 'glpma_ros[exact]'); "
                        "exit status 1 when a count differs")
    p.add_argument("--seed", type=int, default=0, metavar="N",
                   help="base seed; each point's seed derives from it and its index")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes (default: all cores; 1 = in this process)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="run the chunks on this Dask distributed scheduler instead (workers need glpma_ros)")
    p.add_argument("--chunk-size", type=int, default=None, metavar="N",
                   help="grid points per chunk, the unit of work and of resumption (default: one grid row)")
    add_summary_options(p)
    return p


@command_main(prog=PROG)
def main(argv=None) -> int:
    """Exit status: 0 done, 1 when a worker failed or the --exact check disagrees, 2 bad input, 130 interrupted."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    require("map", PROG, modules=("matplotlib", "tqdm") + (("dask", "distributed") if args.scheduler else ()))
    path = resolve_config(args.config)
    doc = load_document(path)
    model = model_from_dict(doc, str(path))
    config_text = yaml.safe_dump(doc, sort_keys=True)
    spec = make_spec(model, args)
    workers = (os.cpu_count() or 1) if args.workers is None else args.workers
    if workers < 1:
        raise InputError("--workers must be at least 1")
    if args.chunk_size is not None and args.chunk_size < 1:
        raise InputError("--chunk-size must be at least 1")
    if args.exact is not None:
        if args.exact < 1:
            raise InputError("--exact needs at least 1 point")
        if getattr(model, "actuated", False):
            raise InputError(f"--exact: msolve has no formulation of the actuated family {model.kind}")
        require_exact()
    result = compute_map(config_text, str(path), spec, Path(args.out), workers=workers, scheduler=args.scheduler,
                         chunk_size=args.chunk_size, progress=not args.no_progress)
    check = None if args.exact is None else exact_check(model, spec, result.counts, args.exact, result.double,
                                                        result.certified)
    if args.json:
        print(json.dumps({**result.as_dict(), **({} if check is None else {"exact_check": check.as_dict()})}))
    else:
        print(result.text() + ("" if check is None else "\n" + check.text()))
    return 1 if check is not None and check.disagree else 0

if __name__ == "__main__":
    sys.exit(main())
