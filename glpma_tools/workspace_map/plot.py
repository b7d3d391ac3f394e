"""The PNG of ``glpma-fk map``: assembly-mode count regions and the singularity curves
(zero contour of the signed conditioning), drawn with Matplotlib's Agg backend."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .grid import ANGLES, MapSpec


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
