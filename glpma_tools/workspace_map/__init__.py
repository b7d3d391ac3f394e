"""``glpma-fk map CONFIG --out DIR``: assembly-mode map of a 2-D slice of the workspace.

The slice is a grid over two pose coordinates, the others fixed (3-RPR: ``x y`` at a
fixed ``theta``; hexapod: ``x y`` at a fixed ``z roll pitch yaw``, or any two of them).
At every grid point the pose's legs come from the inverse kinematics, every real
assembly mode for these legs from :func:`glpma_ros.modes.multistart.solve_all` -- its multistart
by default, the papers' polished G3-PCX runs with ``method="g3pcx"`` -- (seeded from
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
conditioning, Jacobian sign, double modes, axes, fixed coordinates, runs, seed, configuration) and
``assembly_modes.png``.

A point with a double mode (:func:`.grid.double_modes`) lies on a singularity: two modes met there,
and whether its float legs give two real modes or a complex pair is decided by round-off, so its
count of distinct modes is odd where the counts are otherwise even.  Such points are a class of their
own in the summary (``on_singularity``), the figure and the ``--exact`` sample (left out).

Modules: :mod:`.grid` (the grid and the computation of one point / one chunk),
:mod:`.engines` (chunks on disk, the local / process / Dask engines, :func:`compute_map`),
:mod:`.plot` (the PNG), :mod:`.exact_check` (``--exact``: certified counts of a sample of points),
:mod:`.cli` (the command line, :func:`main`).
"""
from .cli import main
from .engines import MapResult, compute_map
from .grid import DEFAULT_METHOD, DEFAULT_RUNS, METHODS, OUTSIDE, MapSpec, pose_variables, quaternion_from_rpy

__all__ = ["DEFAULT_METHOD", "DEFAULT_RUNS", "METHODS", "OUTSIDE", "MapResult", "MapSpec", "compute_map", "main",
           "pose_variables", "quaternion_from_rpy"]
