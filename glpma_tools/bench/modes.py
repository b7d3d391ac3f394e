"""Every real assembly mode, three ways (issue 13): the fast multistart (``solve_all``'s
default), the certified count (msolve, ``method="exact"``) and the papers' method (200 polished
G3-PCX runs), per case: the seed examples and the random cases of
test/data/assembly_modes_cases.json (their certified modes are stored there)."""
from __future__ import annotations

import gc
import json
from dataclasses import dataclass

import numpy as np

from glpma_ros.errors import GlpmaError
from glpma_ros.models import MODELS
from glpma_ros.solve_all import G3PCX_RUNS, solve_all
from glpma_tools.tables import MISSING, fmt, table
from glpma_tools.timing import REPO_ROOT

CASES_PATH = REPO_ROOT / "test" / "data" / "assembly_modes_cases.json"
#: the manipulators' short names, in the report's order
NAMES = {"planar_3rpr": "3-RPR", "hexapod_66": "6-6"}
HEADING = "## All real assembly modes: fast multistart against msolve and G3-PCX"


@dataclass
class ModesRow:
    label: str
    kind: str
    certified: int | None        # real modes certified by msolve (stored or computed)
    complex_solutions: int | None
    fast_found: int
    fast_starts: int
    fast_s: float
    fast_miss: float
    fast_bound: float
    fast_evaluations: int
    fast_matches: bool | None    # the same modes as the certificate (None: no certificate)
    exact_s: float | None        # None: not run
    g3pcx_found: int | None
    g3pcx_s: float | None


def _cases(scenarios, per_kind) -> list[tuple]:
    """(label, model, legs, stored case or None): the seed examples, then the first ``per_kind`` stored
    random cases (None: all) of each manipulator benchmarked."""
    kinds = {sc.model.kind for sc in scenarios.values()}
    stored = json.loads(CASES_PATH.read_text())["cases"] if CASES_PATH.exists() else []
    chosen = [c for kind in NAMES if kind in kinds for c in [c for c in stored if c["kind"] == kind][:per_kind]]
    seeds = [(f"{sc.label} (seed example)", sc.model, np.asarray(sc.legs, dtype=float), None)
             for sc in scenarios.values()]
    return seeds + [(f"{NAMES[c['kind']]} random seed {c['seed']}",
                     MODELS[c["kind"]](np.array(c["base"]), np.array(c["platform"])), np.array(c["legs"]), c)
                    for c in chosen]


def _same(model, xs, ys) -> bool:
    if len(xs) != len(ys) or not xs:
        return len(xs) == len(ys)
    D = np.array([[model.distance(x, y) for y in ys] for x in xs])
    return bool(np.all(D.min(axis=1) <= 1e-6 * model.scale)) and sorted(D.argmin(axis=1)) == list(range(len(ys)))


def compare(scenarios, per_kind, g3pcx_hexapods, progress=False) -> dict:
    """Rows per case; ``per_kind``: random cases per manipulator (None = all); G3-PCX runs on every
    3-RPR case and on the first ``g3pcx_hexapods`` hexapod cases."""
    try:
        from glpma_ros.exact import msolve_executable
        msolve_executable()
        exact_status = "run"
    except GlpmaError as exc:
        exact_status = str(exc)
    rows, hexapods_done = [], 0
    cases = _cases(scenarios, per_kind)
    for kind in {c[1].kind for c in cases}:             # load the compiled code before timing
        _, model, legs, _ = next(c for c in cases if c[1].kind == kind)
        solve_all(model, legs, max_starts=2)
        solve_all(model, legs, method="g3pcx", runs=1)
    for label, model, legs, stored in cases:
        gc.collect()
        fast = solve_all(model, legs)
        modes = complex_n = exact_s = g = None
        if exact_status == "run":
            ex = solve_all(model, legs, method="exact")
            modes, complex_n, exact_s = [s.x for s in ex.solutions], ex.complex_solutions, ex.elapsed_s
        elif stored is not None:
            modes, complex_n = stored["modes"], stored["complex_solutions"]
        if model.kind == "planar_3rpr" or hexapods_done < g3pcx_hexapods:
            hexapods_done += model.kind == "hexapod_66"
            g = solve_all(model, legs, method="g3pcx", runs=G3PCX_RUNS)
        certified = None if modes is None else len(modes)
        rows.append(ModesRow(label, model.kind, certified, complex_n, len(fast.solutions), fast.starts,
                             fast.elapsed_s, fast.miss_probability, fast.unseen_share_bound, fast.evaluations,
                             None if modes is None else _same(model, [s.x for s in fast.solutions], modes),
                             exact_s, g and len(g.solutions), g and g.elapsed_s))
        if progress:
            print(f"  {label}: multistart {len(fast.solutions)} in {fast.elapsed_s:.3f} s, exact "
                  f"{certified} in {exact_s if exact_s is None else round(exact_s, 3)} s", flush=True)
    return {"exact": exact_status, "rows": rows}


def _s(v):
    return MISSING if v is None else f"{v:.3f}"


def _kind_summary(name, rows) -> str:
    """One line per manipulator: the multistart's times and agreement, msolve's and G3-PCX's where they ran."""
    exact = [r for r in rows if r.exact_s is not None]
    g3pcx = [r for r in rows if r.g3pcx_s is not None]
    return "; ".join(
        [f"- {name}, {len(rows)} cases: multistart median {np.median([r.fast_s for r in rows]):.3f} s "
         f"(max {max(r.fast_s for r in rows):.3f} s), {sum(bool(r.fast_matches) for r in rows)}/"
         f"{sum(r.fast_matches is not None for r in rows)} the same as certified"]
        + ([f"msolve median {np.median([r.exact_s for r in exact]):.3f} s, multistart faster on "
            f"{sum(r.fast_s < r.exact_s for r in exact)}/{len(exact)}"] if exact else [])
        + ([f"G3-PCX {G3PCX_RUNS} runs median {np.median([r.g3pcx_s for r in g3pcx]):.3f} s, all modes on "
            f"{sum(r.g3pcx_found == r.certified for r in g3pcx if r.certified is not None)}/{len(g3pcx)}"]
           if g3pcx else [])) + "."


def section(res, md_path=None) -> list[str]:
    """The BENCHMARKS.md section (``res["modes_comparison"]``: :func:`compare`'s result), prose from
    templates/modes.md."""
    from .report import md_blocks, prose
    data = res["modes_comparison"]
    body = [[r.label, fmt(r.certified), fmt(r.complex_solutions), r.fast_found,
             MISSING if r.fast_matches is None else ("yes" if r.fast_matches else "**no**"), r.fast_starts,
             f"{r.fast_evaluations:,}", _s(r.fast_s), f"{r.fast_miss:.3g} / {r.fast_bound:.3g}", _s(r.exact_s),
             fmt(r.g3pcx_found), _s(r.g3pcx_s)] for r in data["rows"]]
    by_kind = {name: [r for r in data["rows"] if r.kind == kind] for kind, name in NAMES.items()}
    return md_blocks(
        HEADING, prose("modes", runs=G3PCX_RUNS),
        data["exact"] != "run" and f"msolve not run ({data['exact']}); certified counts are the stored ones.",
        table(["case", "real (certified)", "complex", "multistart found", "same as certified", "starts",
               "LM evaluations", "multistart s", "miss: Good-Turing / 95 % bound", "msolve s",
               f"G3-PCX {G3PCX_RUNS} found", f"G3-PCX {G3PCX_RUNS} s"], body),
        "\n".join(_kind_summary(name, rows) for name, rows in by_kind.items() if rows))
