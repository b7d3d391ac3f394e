"""``glpma-fk map CONFIG --out DIR``: assembly-mode map of a 2-D slice of the workspace.

The slice is a grid over two pose coordinates, the others fixed (3-RPR: ``x y`` at a
fixed ``theta``; hexapod: ``x y`` at a fixed ``z roll pitch yaw``, or any two of them).
At every grid point the pose's legs come from the inverse kinematics, every real
assembly mode for these legs from :func:`glpma_ros.solve_all.solve_all` (seeded from
the point's index, so that the map does not depend on which process computed which
point), and the conditioning of the pose from ``model.conditioning`` (reciprocal
condition number of the leg Jacobian).  Where the Jacobian's determinant changes
sign the conditioning vanishes: a singularity, where two assembly modes meet.  The
singularity curves are therefore drawn as the zero contour of the *signed*
conditioning ``sign(det J) * conditioning``, which a grid resolves, unlike a contour of
the conditioning itself at a small level.  These are the maps of the parallel-robot
literature (assembly-mode regions bounded by singularity curves; e.g. Merlet,
*Parallel Robots*, 2nd ed., 2006, chapter 6).

The grid is cut into chunks (default one grid row); each finished chunk is saved in
``DIR/chunks/<key>/`` (``key`` = hash of the configuration and the grid), so a rerun
skips what is done.  Chunks run in this process (``--workers 1``), on the local cores
(``--workers N``, processes; default all), or on a Dask distributed cluster
(``--scheduler tcp://HOST:PORT``); the results are written by this process only, so
the workers need no shared file system.  Output in DIR: ``assembly_modes.npz`` (counts,
conditioning, Jacobian sign, axes, fixed coordinates, runs, seed, configuration) and
``assembly_modes.png``.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import textwrap
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import yaml

from glpma_ros.cli import OneLineParser
from glpma_ros.config import load_document, model_from_dict, resolve_config
from glpma_ros.errors import GlpmaError, InputError

from .extras import require

PROG = "glpma-fk map"
#: pose coordinates per manipulator kind; angles are in degrees on the command line and in the files
COORDINATES = {"planar_3rpr": ("x", "y", "theta"), "hexapod_66": ("x", "y", "z", "roll", "pitch", "yaw")}
ANGLES = ("theta", "roll", "pitch", "yaw")
#: default half-margin of the x-y range around the base joints' bounding box, in units of the geometry's size
XY_MARGIN = 0.5
#: default range of z, in units of the geometry's size
Z_RANGE = (0.0, 2.0)
#: default z of a hexapod slice, in units of the geometry's size (the platform well above the base)
Z_DEFAULT = 1.0
DEFAULT_RESOLUTION = 101
#: width of the --help texts
HELP_WIDTH = 100
#: independent searches of solve_all per grid point
DEFAULT_RUNS = 50
#: count of a grid point without valid legs (a leg of length 0, or outside the configured leg limits)
OUTSIDE = -1
#: memory per grid point while assembling and drawing the map (arrays, their float copies, the image)
BYTES_PER_POINT = 96
#: share of the available memory a map may take
MEMORY_SHARE = 0.5
OUTPUT_NAME = "assembly_modes"
#: how long to try to reach a Dask scheduler
DASK_CONNECT_TIMEOUT = "5s"


# -- the grid -------------------------------------------------------------------------------------

class EngineError(GlpmaError):
    """A worker failed (exit status 1: not the user's input)."""


@dataclass(frozen=True)
class MapSpec:
    """A grid over two pose coordinates, the other coordinates fixed, and how each point is solved."""

    kind: str
    axes: tuple            # (name along the columns, name along the rows)
    limits: tuple          # ((low, high), (low, high)), config unit or degrees
    shape: tuple           # (columns, rows)
    fixed: tuple           # ((name, value), ...) every coordinate not on the grid
    runs: int
    seed: int

    @property
    def n_points(self) -> int:
        return self.shape[0] * self.shape[1]

    def axis_values(self, k: int) -> np.ndarray:
        return np.linspace(*self.limits[k], self.shape[k])

    def coordinates(self, index: int) -> dict:
        """All pose coordinates of grid point ``index`` (row-major: ``row * columns + column``)."""
        row, col = divmod(int(index), self.shape[0])
        coords = dict(self.fixed)
        coords[self.axes[0]] = float(self.axis_values(0)[col])
        coords[self.axes[1]] = float(self.axis_values(1)[row])
        return coords

    def key(self, config_text: str) -> str:
        """Identifies the chunks of this map of this configuration."""
        blob = json.dumps({"spec": asdict(self), "config": config_text}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Unit quaternion [qx, qy, qz, qw] of R = Rz(yaw) Ry(pitch) Rx(roll) (radians), as in REP 103."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])


def pose_variables(model, coords: dict) -> np.ndarray:
    """Solver variables of the pose with these coordinates (config unit, angles in degrees)."""
    if model.kind == "planar_3rpr":
        position = (coords["x"], coords["y"], 0.0)
        orientation = quaternion_from_rpy(0.0, 0.0, math.radians(coords["theta"]))
    else:
        position = (coords["x"], coords["y"], coords["z"])
        orientation = quaternion_from_rpy(*(math.radians(coords[a]) for a in ("roll", "pitch", "yaw")))
    return model.variables_from_pose(np.array(position, dtype=float), orientation)


def point_seed(seed: int, index: int) -> int:
    """solve_all's seed at grid point ``index``: independent of the engine and of the chunking."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def solve_point(model, spec: MapSpec, index: int) -> tuple[int, float, int]:
    """(real assembly modes, conditioning, sign of det J) at grid point ``index``."""
    from glpma_ros.solve_all import solve_all
    x = pose_variables(model, spec.coordinates(index))
    try:
        legs = model.check_legs(model.inverse_kinematics(x))
    except InputError:                       # a leg of length 0 or outside the leg limits: no such pose
        return OUTSIDE, math.nan, 0
    modes = solve_all(model, legs, runs=spec.runs, seed=point_seed(spec.seed, index))
    _, J = model.pose_residuals_jacobian(model.pose_state(x), legs)
    sign = int(np.sign(np.linalg.det(J * model.pose_column_scale)))
    return len(modes.solutions), float(model.conditioning(x, legs)), sign


_MODELS: dict = {}     # per process: configuration text -> model


def solve_chunk(config_text: str, source: str, spec: MapSpec, start: int, stop: int) -> dict:
    """Grid points ``start`` .. ``stop - 1``: what a worker (process or Dask) runs."""
    model = _MODELS.get(config_text)
    if model is None:
        model = _MODELS[config_text] = model_from_dict(yaml.safe_load(config_text), source)
    n = stop - start
    counts, cond, sign = np.empty(n, np.int16), np.empty(n), np.empty(n, np.int8)
    for k in range(n):
        counts[k], cond[k], sign[k] = solve_point(model, spec, start + k)
    return {"start": start, "stop": stop, "counts": counts, "conditioning": cond, "jacobian_sign": sign}


# -- chunks on disk ---------------------------------------------------------------------------------

def plan(n_points: int, chunk_size: int) -> list:
    return [(a, min(a + chunk_size, n_points)) for a in range(0, n_points, chunk_size)]


def chunk_path(chunk_dir: Path, start: int, stop: int) -> Path:
    return chunk_dir / f"{start:010d}-{stop:010d}.npz"


def load_chunk(path: Path, start: int, stop: int) -> dict | None:
    """A finished chunk, or None when it is missing or unreadable (then it is computed again)."""
    try:
        with np.load(path) as f:
            chunk = {k: f[k] for k in ("counts", "conditioning", "jacobian_sign")}
    except (OSError, ValueError, KeyError, EOFError):
        return None
    return chunk if all(len(v) == stop - start for v in chunk.values()) else None


def save_chunk(path: Path, chunk: dict) -> None:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as f:
        np.savez(f, counts=chunk["counts"], conditioning=chunk["conditioning"],
                 jacobian_sign=chunk["jacobian_sign"])
    os.replace(tmp, path)


# -- engines ------------------------------------------------------------------------------------------

def run_serial(tasks, args, done) -> None:
    for start, stop in tasks:
        done(solve_chunk(*args, start, stop))


def run_processes(tasks, args, done, workers: int) -> None:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    # spawn: a clean interpreter per worker (no forked threads); Numba loads its cache there
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(solve_chunk, *args, start, stop) for start, stop in tasks]
        try:
            for future in as_completed(futures):
                done(future.result())
        except BaseException:
            for future in futures:
                future.cancel()
            raise


def run_dask(tasks, args, done, scheduler: str) -> None:
    from dask.distributed import Client, as_completed
    try:
        client = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"cannot reach the Dask scheduler {scheduler}: {str(exc).splitlines()[0]}") from None
    with client:
        config = client.scatter(args[0], broadcast=True)
        futures = [client.submit(solve_chunk, config, *args[1:], start, stop, pure=False) for start, stop in tasks]
        try:
            for future in as_completed(futures):
                done(future.result())
        except BaseException:
            client.cancel(futures)
            raise


# -- the map --------------------------------------------------------------------------------------------

@dataclass
class MapResult:
    npz: Path
    png: Path
    points: int
    computed: int            # points computed in this run (the rest came from saved chunks)
    chunks_computed: int
    chunks_reused: int
    elapsed_s: float
    engine: str
    modes: dict              # count -> points

    def as_dict(self) -> dict:
        d = asdict(self)
        d.update(npz=str(self.npz), png=str(self.png), modes={str(k): v for k, v in self.modes.items()})
        return d

    def text(self) -> str:
        rate = self.computed / self.elapsed_s if self.elapsed_s > 0 else 0.0
        modes = ", ".join(f"{'no valid legs' if k == OUTSIDE else f'{k} modes'}: {v}"
                          for k, v in sorted(self.modes.items()))
        return (f"{self.npz} and {self.png}: {self.points} points ({self.computed} computed in {self.elapsed_s:.1f} s "
                f"on {self.engine}, {rate:.1f} points/s; {self.chunks_reused} chunks from an earlier run)\n"
                f"  {modes}")


def available_memory() -> int | None:
    """Bytes of memory available to a new process (Linux ``MemAvailable``; else the free pages), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(n_points: int) -> None:
    """:class:`InputError` when the map would not fit in memory."""
    need = n_points * BYTES_PER_POINT
    available = available_memory()
    if available and need > MEMORY_SHARE * available:
        raise InputError(f"a grid of {n_points:,} points needs about {need / 2**30:.1f} GiB, more than "
                         f"{MEMORY_SHARE:.0%} of the {available / 2**30:.1f} GiB available; lower --resolution")


def compute_map(config_text: str, source: str, spec: MapSpec, out_dir: Path, *, workers: int = 1,
                scheduler: str | None = None, chunk_size: int | None = None, progress: bool = True) -> MapResult:
    """Compute (or resume) the map and write ``assembly_modes.npz`` and ``.png`` in ``out_dir``."""
    from tqdm import tqdm
    check_memory(spec.n_points)
    chunk_size = chunk_size or spec.shape[0]
    chunk_dir = out_dir / "chunks" / spec.key(config_text)
    try:
        chunk_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {chunk_dir}: {exc.strerror or exc}") from None
    chunks = plan(spec.n_points, chunk_size)
    counts = np.empty(spec.n_points, np.int16)
    cond = np.empty(spec.n_points)
    sign = np.empty(spec.n_points, np.int8)

    def store(start, stop, chunk):
        counts[start:stop], cond[start:stop], sign[start:stop] = (
            chunk["counts"], chunk["conditioning"], chunk["jacobian_sign"])

    todo = []
    for start, stop in chunks:
        chunk = load_chunk(chunk_path(chunk_dir, start, stop), start, stop)
        if chunk is None:
            todo.append((start, stop))
        else:
            store(start, stop, chunk)
    engine = (f"Dask {scheduler}" if scheduler else "this process" if workers == 1 else f"{workers} processes")
    t0 = time.perf_counter()
    remaining = sum(b - a for a, b in todo)
    with tqdm(total=spec.n_points, initial=spec.n_points - remaining, unit="pt", file=sys.stderr,
              disable=None if progress else True, dynamic_ncols=True, desc="map") as bar:
        def done(chunk):
            start, stop = chunk["start"], chunk["stop"]
            save_chunk(chunk_path(chunk_dir, start, stop), chunk)
            store(start, stop, chunk)
            bar.update(stop - start)

        args = (config_text, source, spec)
        try:
            if not todo:
                pass
            elif scheduler:
                run_dask(todo, args, done, scheduler)
            elif workers == 1 or len(todo) == 1:
                run_serial(todo, args, done)
            else:
                run_processes(todo, args, done, min(workers, len(todo)))
        except (GlpmaError, KeyboardInterrupt):
            raise
        except Exception as exc:  # noqa: BLE001 - a worker's failure, reported in one line
            raise EngineError(f"computing the map failed on {engine}: {type(exc).__name__}: {exc}") from None
    elapsed = time.perf_counter() - t0
    shape = (spec.shape[1], spec.shape[0])           # rows, columns
    data = {"counts": counts.reshape(shape), "conditioning": cond.reshape(shape),
            "jacobian_sign": sign.reshape(shape)}
    npz, png = out_dir / f"{OUTPUT_NAME}.npz", out_dir / f"{OUTPUT_NAME}.png"
    save_map(npz, data, spec, config_text)
    model = model_from_dict(yaml.safe_load(config_text), source)
    draw_map(png, data, spec, model, title=Path(source).name)
    modes = Counter(int(c) for c in counts)
    return MapResult(npz, png, spec.n_points, remaining, len(todo), len(chunks) - len(todo), elapsed, engine,
                     dict(sorted(modes.items())))


def save_map(path: Path, data: dict, spec: MapSpec, config_text: str) -> None:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as f:
        np.savez(f, **data, axis_names=np.array(spec.axes), axis_0=spec.axis_values(0), axis_1=spec.axis_values(1),
                 fixed_names=np.array([n for n, _ in spec.fixed], dtype=str),
                 fixed_values=np.array([v for _, v in spec.fixed], dtype=float),
                 runs=spec.runs, seed=spec.seed, config=np.array(config_text))
    os.replace(tmp, path)


def _label(name: str, unit: str) -> str:
    return f"{name} [{'deg' if name in ANGLES else unit}]"


def draw_map(path: Path, data: dict, spec: MapSpec, model, title: str = "") -> None:
    """Assembly-mode count regions, and the singularity curves (zero contour of the signed conditioning)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    counts = np.ma.masked_less(data["counts"], 0)
    levels = sorted(int(c) for c in np.unique(counts.compressed())) or [0]
    cmap = ListedColormap([f"C{k % 10}" for k in range(len(levels))]).with_extremes(bad="0.85")
    norm = BoundaryNorm([levels[0] - 0.5] + [c + 0.5 for c in levels], cmap.N)
    v0, v1 = spec.axis_values(0), spec.axis_values(1)
    h0, h1 = (v0[1] - v0[0]) / 2, (v1[1] - v1[0]) / 2
    fig = Figure(figsize=(7.5, 6.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    image = ax.imshow(counts, origin="lower",
                      extent=(v0[0] - h0, v0[-1] + h0, v1[0] - h1, v1[-1] + h1), cmap=cmap, norm=norm,
                      interpolation="nearest", aspect="equal" if not set(spec.axes) & set(ANGLES) else "auto")
    bar = fig.colorbar(image, ax=ax, ticks=levels)
    bar.set_label("real assembly modes")
    signed = np.where(np.isfinite(data["conditioning"]), data["jacobian_sign"] * data["conditioning"], np.nan)
    if np.nanmin(signed, initial=np.inf) < 0 < np.nanmax(signed, initial=-np.inf):
        ax.contour(v0, v1, signed, levels=[0.0], colors="k", linewidths=1.2)
    ax.legend(handles=[Line2D([], [], color="k", lw=1.2, label="singularity (det J = 0)")], loc="upper right",
              fontsize="small")
    ax.set_xlabel(_label(spec.axes[0], model.unit))
    ax.set_ylabel(_label(spec.axes[1], model.unit))
    fixed = ", ".join(f"{n} = {v:g}{' deg' if n in ANGLES else ' ' + model.unit}" for n, v in spec.fixed)
    ax.set_title(f"{title}: {fixed}\n{spec.runs} solve_all runs per point", fontsize="medium")
    fig.savefig(path, dpi=110)


# -- command line ------------------------------------------------------------------------------------------

def default_limits(model, name: str) -> tuple:
    if name in ANGLES:
        return (-180.0, 180.0)
    if name == "z":
        return tuple(f * model.scale for f in Z_RANGE)
    k = "xy".index(name)
    lo, hi = float(model.base[:, k].min()), float(model.base[:, k].max())
    return (lo - XY_MARGIN * model.scale, hi + XY_MARGIN * model.scale)


def make_spec(model, args) -> MapSpec:
    names = COORDINATES[model.kind]
    axes = tuple(args.axes)
    for a in axes:
        if a not in names:
            raise InputError(f"--axes: {model.kind} has pose coordinates {' '.join(names)}, not {a!r}")
    if axes[0] == axes[1]:
        raise InputError("--axes needs two different coordinates")
    fixed = {n: (Z_DEFAULT * model.scale if n == "z" else 0.0) for n in names if n not in axes}
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
    if args.runs < 1:
        raise InputError("--runs must be at least 1")
    return MapSpec(model.kind, axes, limits, shape, tuple((n, float(fixed[n])) for n in names if n in fixed),
                   int(args.runs), int(args.seed))


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
            "Assembly-mode map of a 2-D slice of the workspace: at every point of a grid over two pose coordinates "
            "(the others fixed), the number of real assembly modes of the legs of that pose (solve_all) and the "
            "conditioning of the pose. Writes DIR/assembly_modes.npz and a PNG with the mode-count regions and "
            "the singularity curves. Lengths in the config's unit, angles in degrees.",
            HELP_WIDTH, break_on_hyphens=False),
        epilog="pose coordinates: planar_3rpr x y theta; hexapod_66 x y z roll pitch yaw (R = Rz(yaw) Ry(pitch) "
               "Rx(roll)).\ndefaults: x-y range = the base joints' bounding box +- half the geometry's size, z range "
               "0 .. 2 sizes,\nangles -180 .. 180; fixed angles 0 and z = the geometry's size.\n"
               "Finished chunks are kept in DIR/chunks/: a rerun of the same map (same config and grid) skips them.")
    p.add_argument("config", metavar="CONFIG", help="manipulator YAML (or the name of a shipped one)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (created; reused to resume)")
    p.add_argument("--axes", nargs=2, default=("x", "y"), metavar=("A", "B"),
                   help="pose coordinates along the columns and the rows (default x y)")
    p.add_argument("--limits", nargs=4, type=float, default=None, metavar=("LOW_A", "HIGH_A", "LOW_B", "HIGH_B"),
                   help="range of each axis (config unit or degrees; default: see below)")
    p.add_argument("--resolution", nargs="+", type=int, default=[DEFAULT_RESOLUTION], metavar="N",
                   help=f"points per axis: N, or N_A N_B (default {DEFAULT_RESOLUTION})")
    p.add_argument("--at", nargs="+", default=None, metavar="NAME=VALUE",
                   help="the fixed coordinates, e.g. --at theta=30 (3-RPR) or --at z=900 yaw=10 (hexapod)")
    p.add_argument("--runs", type=int, default=DEFAULT_RUNS, metavar="N",
                   help=f"solve_all searches per point (default {DEFAULT_RUNS}; more finds rare modes)")
    p.add_argument("--seed", type=int, default=0, metavar="N",
                   help="base seed; each point's seed derives from it and its index")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes (default: all cores; 1 = in this process)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="run the chunks on this Dask distributed scheduler instead (workers need glpma_ros)")
    p.add_argument("--chunk-size", type=int, default=None, metavar="N",
                   help="grid points per chunk, the unit of work and of resumption (default: one grid row)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (none either when stderr is not "
                                                               "a terminal)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    return p


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
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
        result = compute_map(config_text, str(path), spec, Path(args.out), workers=workers, scheduler=args.scheduler,
                             chunk_size=args.chunk_size, progress=not args.no_progress)
    except GlpmaError as exc:
        print(f"error: {PROG}: {exc}", file=sys.stderr)
        return 1 if isinstance(exc, EngineError) else 2
    except KeyboardInterrupt:
        return 130
    print(json.dumps(result.as_dict()) if args.json else result.text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
