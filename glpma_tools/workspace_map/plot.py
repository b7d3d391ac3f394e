"""The PNG of ``glpma-fk map``: assembly-mode count regions and the singularity curves
(zero contour of the signed conditioning), drawn with Matplotlib's Agg backend."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .grid import ANGLES, OUTSIDE, MapSpec

#: qualitative palettes whose colours, in order and without their greys, are those of the mode counts
#: (count k gets the k-th colour in every map): tab20's dark shades, then its light ones (so that
#: neighbouring counts get different hues), without its greys (14, 15), then tab20b
MODE_PALETTES = (("tab20", (0, 2, 4, 6, 8, 10, 12, 16, 18, 1, 3, 5, 7, 9, 11, 13, 17, 19)),
                 ("tab20b", tuple(range(20))))
#: colour of the points without valid legs
OUTSIDE_COLOUR = "0.85"
#: class drawn for the points with a double mode (on a singularity: their count is decided by round-off),
#: whatever their count of distinct modes, and its colour: near black, apart from every count's colour
ON_SINGULARITY = -2
ON_SINGULARITY_COLOUR = "0.15"
ON_SINGULARITY_LABEL = "on a singularity\n(a double mode)"
#: class drawn for the points whose homotopy count is not certified (paths failed) and its colour: mid grey
UNCERTIFIED = -3
UNCERTIFIED_COLOUR = "0.55"
UNCERTIFIED_LABEL = "not certified\n(paths failed)"


def _label(name: str, unit: str) -> str:
    return f"{name} [{'deg' if name in ANGLES else unit}]"


def count_colour(count: int):
    """The fixed colour of a mode count, the same in every map: the ``MODE_PALETTES`` colours
    indexed by the count (38 colours; a 6-6 has at most 40 modes, counts beyond wrap), light grey
    (``OUTSIDE_COLOUR``) for a point without valid legs, near black for a point on a singularity."""
    from matplotlib import colormaps  # the tools extra: optional, imported where used
    if count == OUTSIDE:
        return OUTSIDE_COLOUR
    if count == ON_SINGULARITY:
        return ON_SINGULARITY_COLOUR
    if count == UNCERTIFIED:
        return UNCERTIFIED_COLOUR
    colours = [colormaps[name](k) for name, picks in MODE_PALETTES for k in picks]
    return colours[count % len(colours)]


def class_label(count: int) -> str:
    """The legend's name of a class drawn."""
    if count == OUTSIDE:
        return "no valid legs"
    if count == ON_SINGULARITY:
        return ON_SINGULARITY_LABEL
    if count == UNCERTIFIED:
        return UNCERTIFIED_LABEL
    return f"{count} real mode{'' if count == 1 else 's'}"


def draw_map(path: Path, data: dict, spec: MapSpec, model, title: str = "") -> list:
    """Assembly-mode count regions (a fixed colour per count, :func:`count_colour`; a legend entry for
    every class drawn, points without valid legs included; the points with a double mode, ``data``'s
    ``double_modes`` > 0, drawn as their own class ``ON_SINGULARITY``, and the others whose homotopy count is
    not certified, ``certified`` 0, as ``UNCERTIFIED``) and the singularity curves (zero
    contour of the signed conditioning).  Returns the legend's ``(label, colour)`` entries."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # the tools extra: optional, imported where used
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    counts = np.asarray(data["counts"])
    if "certified" in data:
        counts = np.where(np.asarray(data["certified"]) == 0, UNCERTIFIED, counts)
    if "double_modes" in data:
        counts = np.where(np.asarray(data["double_modes"]) > 0, ON_SINGULARITY, counts)
    classes = sorted(int(c) for c in np.unique(counts))
    # each class drawn is an index into a colour list holding exactly the classes present
    index = np.searchsorted(classes, counts)
    cmap = ListedColormap([count_colour(c) for c in classes])
    v0, v1 = spec.axis_values(0), spec.axis_values(1)
    h0, h1 = (v0[1] - v0[0]) / 2, (v1[1] - v1[0]) / 2
    fig = Figure(figsize=(7.5, 6.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.imshow(index, origin="lower", extent=(v0[0] - h0, v0[-1] + h0, v1[0] - h1, v1[-1] + h1), cmap=cmap,
              vmin=-0.5, vmax=len(classes) - 0.5, interpolation="nearest",
              aspect="equal" if not set(spec.axes) & set(ANGLES) else "auto")
    handles = [Patch(facecolor=count_colour(c), edgecolor="0.3", label=class_label(c)) for c in classes]
    signed = np.where(np.isfinite(data["conditioning"]), data["jacobian_sign"] * data["conditioning"], np.nan)
    if np.nanmin(signed, initial=np.inf) < 0 < np.nanmax(signed, initial=-np.inf):
        ax.contour(v0, v1, signed, levels=[0.0], colors="k", linewidths=1.2)
        handles.append(Line2D([], [], color="k", lw=1.2, label="singularity (det J = 0)"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize="small", borderaxespad=0.0)
    ax.set_xlabel(_label(spec.axes[0], model.unit))
    ax.set_ylabel(_label(spec.axes[1], model.unit))
    fixed = ", ".join(f"{n} = {v:g}{' deg' if n in ANGLES else ' ' + model.unit}" for n, v in spec.fixed)
    ax.set_title(f"{title}: {fixed}\nmodes counted by {spec.describe_method()}", fontsize="medium")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return [(h.get_label(), h.get_facecolor() if isinstance(h, Patch) else h.get_color()) for h in handles]
