"""Every real assembly mode, three ways: the fast multistart (``solve_all``'s default), the certified count
(msolve, ``method="exact"``) and the papers' method (200 polished G3-PCX runs), per case: the seed examples and the
random cases of test/data/assembly_modes_cases.json (their certified modes are stored there)."""
from __future__ import annotations

import gc
import json

import numpy as np

from glpma_ros.errors import GlpmaError
from glpma_ros.models import MODELS
from glpma_ros.modes.exact import msolve_executable
from glpma_ros.modes.multistart import G3PCX_RUNS, solve_all
from glpma_tools.tables import MISSING, fmt, table
from glpma_tools.timing import REPO_ROOT, progress_bar

from .markdown import md_blocks, prose

CASES_PATH = REPO_ROOT / "test" / "data" / "assembly_modes_cases.json"
#: the manipulators' short names, in the report's order
NAMES = {"planar_3rpr": "3-RPR", "hexapod_66": "6-6"}
#: found and certified modes are the same when each is this share of the model's scale from its partner
SAME_MODE_SHARE = 1e-6
#: a row's figures that are None where unknown (no certificate) or not run (msolve, G3-PCX)
ROW_EXTRAS = ("certified", "complex", "same", "exact_s", "g3pcx_found", "g3pcx_s")


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
    """Whether the poses ``xs`` and ``ys`` are the same modes, one to one."""
    if len(xs) != len(ys) or not xs:
        return len(xs) == len(ys)
    D = np.array([[model.distance(x, y) for y in ys] for x in xs])
    close = np.all(D.min(axis=1) <= SAME_MODE_SHARE * model.scale)
    return bool(close) and sorted(D.argmin(axis=1)) == list(range(len(ys)))


def compare(scenarios, per_kind, g3pcx_hexapods, progress=False) -> dict:
    """A row (dict) per case; ``per_kind``: random cases per manipulator (None = all); G3-PCX runs on every 3-RPR
    case and on the first ``g3pcx_hexapods`` hexapod cases.  Certified counts are msolve's, else the stored ones."""
    try:
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
    for label, model, legs, stored in progress_bar(cases, "assembly modes", progress):
        gc.collect()
        fast = solve_all(model, legs)
        row = dict.fromkeys(ROW_EXTRAS) | {
            "label": label, "kind": model.kind, "fast_found": len(fast.solutions), "starts": fast.starts,
            "evaluations": fast.evaluations, "fast_s": fast.elapsed_s, "miss": fast.miss_probability,
            "bound": fast.unseen_share_bound, "complex": stored and stored["complex_solutions"]}
        modes = stored and stored["modes"]
        if exact_status == "run":
            ex = solve_all(model, legs, method="exact")
            modes = [s.x for s in ex.solutions]
            row.update(complex=ex.complex_solutions, exact_s=ex.elapsed_s)
        if modes is not None:
            row.update(certified=len(modes), same=_same(model, [s.x for s in fast.solutions], modes))
        if model.kind == "planar_3rpr" or hexapods_done < g3pcx_hexapods:
            hexapods_done += model.kind == "hexapod_66"
            g = solve_all(model, legs, method="g3pcx", runs=G3PCX_RUNS)
            row.update(g3pcx_found=len(g.solutions), g3pcx_s=g.elapsed_s)
        rows.append(row)
    return {"exact": exact_status, "rows": rows}


def _s(v):
    return MISSING if v is None else f"{v:.3f}"


def _kind_summary(name, rows) -> str:
    """One line per manipulator: the multistart's times and agreement, msolve's and G3-PCX's where they ran."""
    exact = [r for r in rows if r["exact_s"] is not None]
    g3pcx = [r for r in rows if r["g3pcx_s"] is not None]
    fast_s = [r["fast_s"] for r in rows]
    return "; ".join(
        [f"- {name}, {len(rows)} cases: multistart median {np.median(fast_s):.3f} s (max {max(fast_s):.3f} s), "
         f"{sum(bool(r['same']) for r in rows)}/{sum(r['same'] is not None for r in rows)} the same as certified"]
        + ([f"msolve median {np.median([r['exact_s'] for r in exact]):.3f} s, multistart faster on "
            f"{sum(r['fast_s'] < r['exact_s'] for r in exact)}/{len(exact)}"] if exact else [])
        + ([f"G3-PCX {G3PCX_RUNS} runs median {np.median([r['g3pcx_s'] for r in g3pcx]):.3f} s, all modes on "
            f"{sum(r['g3pcx_found'] == r['certified'] for r in g3pcx if r['certified'] is not None)}/{len(g3pcx)}"]
           if g3pcx else [])) + "."


def section(res, md_path=None) -> list[str]:
    """The BENCHMARKS.md section (``res["modes_comparison"]``: :func:`compare`'s result), prose from
    templates/modes.md."""
    data = res["modes_comparison"]
    body = [[r["label"], fmt(r["certified"]), fmt(r["complex"]), r["fast_found"],
             MISSING if r["same"] is None else ("yes" if r["same"] else "**no**"), r["starts"],
             f"{r['evaluations']:,}", _s(r["fast_s"]), f"{r['miss']:.3g} / {r['bound']:.3g}", _s(r["exact_s"]),
             fmt(r["g3pcx_found"]), _s(r["g3pcx_s"])] for r in data["rows"]]
    by_kind = {name: [r for r in data["rows"] if r["kind"] == kind] for kind, name in NAMES.items()}
    return md_blocks(
        "## All real assembly modes: fast multistart against msolve and G3-PCX", prose("modes", runs=G3PCX_RUNS),
        data["exact"] != "run" and f"msolve not run ({data['exact']}); certified counts are the stored ones.",
        table(["case", "real (certified)", "complex", "multistart found", "same as certified", "starts",
               "LM evaluations", "multistart s", "miss: Good-Turing / 95 % bound", "msolve s",
               f"G3-PCX {G3PCX_RUNS} found", f"G3-PCX {G3PCX_RUNS} s"], body),
        "\n".join(_kind_summary(name, rows) for name, rows in by_kind.items() if rows))
