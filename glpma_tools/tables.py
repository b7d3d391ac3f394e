"""Numbers and tables as the tools print them: one cell formatter and one table formatter,
Markdown (BENCHMARKS.md) or aligned plain text (terminal); and :func:`add_summary_options`, the options of a
long run that ends with a summary (``glpma-fk bag``, ``glpma-fk map``)."""
from __future__ import annotations

import math

import numpy as np

#: what a cell shows for a missing or undefined value
MISSING = "—"


def fmt(v, digits: int = 3, unit: str = "") -> str:
    """A number for a table: integers with thousands separators, floats with ``digits``
    significant digits (scientific notation when very large or small), booleans as yes/no."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return MISSING
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return f"{v:,}{unit}"
    a = abs(v)
    if a != 0 and (a >= 1e5 or a < 1e-3):
        return f"{v:.{max(digits - 1, 1)}e}{unit}"
    if a >= 100:
        return f"{v:,.0f}{unit}"
    return f"{v:.{digits}g}{unit}"


def fmt_ci(mean, ci) -> str:
    """``mean ± half-width`` (integers), or the mean alone when the half-width is undefined."""
    if mean is None or not math.isfinite(mean):
        return MISSING
    if ci is None or not math.isfinite(ci):
        return f"{mean:,.0f}"
    return f"{mean:,.0f} ± {ci:,.0f}"


def ratio(a, b, digits: int = 2) -> str:
    """``a / b`` as ``1.5×``; a dash when either is missing or ``b`` is zero."""
    try:
        if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) or b == 0:
            return MISSING
    except TypeError:
        return MISSING
    r = a / b
    return f"{r:.{digits}g}×" if r < 100 else f"{r:,.0f}×"


def spread(d: dict | None, spec: str = ".3f") -> str:
    """``p50 / p99 / max`` of a :func:`glpma_tools.stats.distribution`."""
    if not d or d.get("p50") is None:
        return MISSING
    return " / ".join(format(d[k], spec) for k in ("p50", "p99", "max"))


def table(head, rows, markdown: bool = True) -> str:
    """Rows of cells under ``head`` as a Markdown table, or as aligned plain text (``head`` None:
    no header line)."""
    rows = [[str(c) for c in r] for r in rows]
    if markdown:
        return "\n".join(["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
                         + ["| " + " | ".join(r) + " |" for r in rows])
    lines = rows if head is None else [list(map(str, head)), None, *rows]
    widths = [max(len(r[i]) for r in lines if r is not None) for i in range(len(lines[0]))]
    return "\n".join("  ".join("-" * w for w in widths) if r is None else
                     "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in lines)


def add_summary_options(parser) -> None:
    """``--no-progress`` (the run's progress bar on stderr, shown only where stderr is a terminal) and ``--json``
    (the summary as one JSON object instead of the text) of a command's argparse ``parser``."""
    parser.add_argument("--no-progress", action="store_true", help="no progress bar (none either when stderr is "
                                                                    "not a terminal)")
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
