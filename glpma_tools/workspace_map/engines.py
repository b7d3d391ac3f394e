"""How ``glpma-fk map`` computes a map: chunks, engines, resumption, output files.

The grid is cut into chunks (:func:`plan`); each finished chunk is saved under
``DIR/chunks/<key>/`` and reused by a rerun; the chunks still to do run in this process,
in local worker processes (spawned) or on a Dask distributed cluster
(:func:`glpma_tools.parallel.run_tasks`); :func:`compute_map`
assembles them, writes ``assembly_modes.npz`` and draws ``assembly_modes.png``
(:mod:`.plot`).
"""
from __future__ import annotations

import os
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from glpma_ros.config import model_from_dict
from glpma_ros.errors import InputError

from ..parallel import EngineError, engine_name, run_tasks
from .grid import OUTSIDE, MapSpec, solve_chunk
from .plot import draw_map

#: memory per grid point while assembling and drawing the map (arrays, their float copies, the image)
BYTES_PER_POINT = 96
#: share of the available memory a map may take
MEMORY_SHARE = 0.5
OUTPUT_NAME = "assembly_modes"
#: the per-point arrays of a chunk and of the map (a chunk saved without one of them is computed again)
CHUNK_ARRAYS = ("counts", "conditioning", "jacobian_sign", "double_modes", "certified")


# -- chunks on disk ---------------------------------------------------------------------------------

def plan(n_points: int, chunk_size: int) -> list:
    return [(a, min(a + chunk_size, n_points)) for a in range(0, n_points, chunk_size)]


def chunk_path(chunk_dir: Path, start: int, stop: int) -> Path:
    return chunk_dir / f"{start:010d}-{stop:010d}.npz"


def load_chunk(path: Path, start: int, stop: int) -> dict | None:
    """A finished chunk, or None when it is missing or unreadable (then it is computed again)."""
    try:
        with np.load(path) as f:
            chunk = {k: f[k] for k in CHUNK_ARRAYS}
    except (OSError, ValueError, KeyError, EOFError):
        return None
    return chunk if all(len(v) == stop - start for v in chunk.values()) else None


def save_chunk(path: Path, chunk: dict) -> None:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as f:
        np.savez(f, **{k: chunk[k] for k in CHUNK_ARRAYS})
    os.replace(tmp, path)


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
    modes: dict              # count -> points without a double mode (count OUTSIDE = -1: no valid legs)
    method: str = ""         # how the modes were counted: "multistart" or "g3pcx (N runs)"
    counts: np.ndarray = field(default=None, repr=False)   # the map (rows, columns), not in the summary
    double: np.ndarray = field(default=None, repr=False)   # its double modes per point (rows, columns)
    on_singularity: dict = field(default_factory=dict)     # count of distinct modes -> points with a double mode
    uncertified: dict | None = None   # homotopy: count -> points without a double mode the certificate misses
    certified: np.ndarray = field(default=None, repr=False)  # per point: 1 / 0 certified or not, -1 n/a

    def as_dict(self) -> dict:
        """The JSON summary: ``modes`` maps a mode count to its points (those without a double mode); the
        points without valid legs (count -1 in the npz) are ``no_valid_legs``; the points on a singularity
        (a double mode: their count is decided by round-off) are ``on_singularity``, by their count of
        distinct modes; with the homotopy, the points whose count its root count does not certify (paths
        failed) and that have no double mode are ``uncertified``, by their count (a lower bound), apart from
        ``modes`` (None with the other methods, which certify nothing)."""
        return {"npz": str(self.npz), "png": str(self.png), "points": self.points, "computed": self.computed,
                "chunks_computed": self.chunks_computed, "chunks_reused": self.chunks_reused,
                "elapsed_s": self.elapsed_s, "engine": self.engine, "method": self.method,
                "modes": {str(k): v for k, v in self.modes.items() if k != OUTSIDE},
                "no_valid_legs": self.modes.get(OUTSIDE, 0),
                "on_singularity": {str(k): v for k, v in self.on_singularity.items()},
                "uncertified": None if self.uncertified is None else {str(k): v for k, v in self.uncertified.items()}}

    def text(self) -> str:
        rate = self.computed / self.elapsed_s if self.elapsed_s > 0 else 0.0
        modes = ", ".join(f"{'no valid legs' if k == OUTSIDE else f'{k} modes'}: {v}"
                          for k, v in sorted(self.modes.items()))
        if self.on_singularity:
            modes += (f"; on a singularity (a double mode, the count decided by round-off): "
                      f"{sum(self.on_singularity.values())} ("
                      + ", ".join(f"{k} distinct: {v}" for k, v in sorted(self.on_singularity.items())) + ")")
        if self.uncertified:
            modes += (f"; not certified (paths failed; the modes found, at least): {sum(self.uncertified.values())} ("
                      + ", ".join(f"{k} modes: {v}" for k, v in sorted(self.uncertified.items())) + ")")
        elif self.uncertified is not None:
            modes += "; every other count certified by the homotopy's root count"
        return (f"{self.npz} and {self.png}: {self.points} points ({self.computed} computed in {self.elapsed_s:.1f} s "
                f"on {self.engine}, {rate:.1f} points/s; {self.chunks_reused} chunks from an earlier run; "
                f"modes counted by {self.method})\n  {modes}")


def available_memory() -> int:
    """Bytes of memory available to a new process without swapping (psutil: Linux ``MemAvailable``)."""
    import psutil  # the tools extra: optional, imported where used
    return psutil.virtual_memory().available


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
    from tqdm import tqdm  # the tools extra: optional, imported where used
    check_memory(spec.n_points)
    chunk_size = chunk_size or spec.shape[0]
    chunk_dir = out_dir / "chunks" / spec.key(config_text)
    try:
        chunk_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {chunk_dir}: {exc.strerror or exc}") from None
    chunks = plan(spec.n_points, chunk_size)
    arrays = {"counts": np.empty(spec.n_points, np.int16), "conditioning": np.empty(spec.n_points),
              "jacobian_sign": np.empty(spec.n_points, np.int8), "double_modes": np.empty(spec.n_points, np.int8),
              "certified": np.empty(spec.n_points, np.int8)}

    def store(start, stop, chunk):
        for k in CHUNK_ARRAYS:
            arrays[k][start:stop] = chunk[k]

    todo = []
    for start, stop in chunks:
        chunk = load_chunk(chunk_path(chunk_dir, start, stop), start, stop)
        if chunk is None:
            todo.append((start, stop))
        else:
            store(start, stop, chunk)
    engine = engine_name(workers, scheduler)
    t0 = time.perf_counter()
    remaining = sum(b - a for a, b in todo)
    with tqdm(total=spec.n_points, initial=spec.n_points - remaining, unit="pt", file=sys.stderr,
              disable=None if progress else True, dynamic_ncols=True, desc="map") as bar:
        def done(chunk):
            start, stop = chunk["start"], chunk["stop"]
            save_chunk(chunk_path(chunk_dir, start, stop), chunk)
            store(start, stop, chunk)
            bar.update(stop - start)

        try:
            run_tasks(solve_chunk, todo, done, shared=(config_text, source, spec), workers=workers,
                      scheduler=scheduler)
        except EngineError as exc:
            raise EngineError(f"computing the map failed on {exc}") from None
    elapsed = time.perf_counter() - t0
    shape = (spec.shape[1], spec.shape[0])           # rows, columns
    data = {k: arrays[k].reshape(shape) for k in CHUNK_ARRAYS}
    npz, png = out_dir / f"{OUTPUT_NAME}.npz", out_dir / f"{OUTPUT_NAME}.png"
    save_map(npz, data, spec, config_text)
    model = model_from_dict(yaml.safe_load(config_text), source)
    draw_map(png, data, spec, model, title=Path(source).name)
    counts, double = arrays["counts"], arrays["double_modes"] > 0
    uncertain = (arrays["certified"] == 0) & ~double
    modes = Counter(int(c) for c in counts[~double & ~uncertain])
    singular = Counter(int(c) for c in counts[double])
    uncertified = dict(sorted(Counter(int(c) for c in counts[uncertain]).items())) if spec.method == "homotopy" \
        else None
    return MapResult(npz, png, spec.n_points, remaining, len(todo), len(chunks) - len(todo), elapsed, engine,
                     dict(sorted(modes.items())), spec.describe_method(), data["counts"], data["double_modes"],
                     dict(sorted(singular.items())), uncertified, data["certified"])


def save_map(path: Path, data: dict, spec: MapSpec, config_text: str) -> None:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as f:
        np.savez(f, **data, axis_names=np.array(spec.axes), axis_0=spec.axis_values(0), axis_1=spec.axis_values(1),
                 fixed_names=np.array([n for n, _ in spec.fixed], dtype=str),
                 fixed_values=np.array([v for _, v in spec.fixed], dtype=float),
                 method=np.array(spec.method), runs=spec.runs, seed=spec.seed, config=np.array(config_text))
    os.replace(tmp, path)
