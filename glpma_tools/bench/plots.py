"""Figures (matplotlib, Agg backend): PNG files, one per question."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from matplotlib import __version__ as MATPLOTLIB_VERSION
from matplotlib.figure import Figure

from glpma_ros import solvers
from glpma_ros.runtime.compat import version_tuple
from glpma_tools.timing import DEADLINE_MARGIN_MS

from .common import SUCCESS_TOLERANCE
from .markdown import SOLVER_LABEL
from .scenarios import LATENCY_TARGET_MS

COLORS = {"rcga": "tab:blue", "g3pcx": "tab:orange", "glpma": "tab:green", "pypop7": "tab:purple",
          "pymoo": "tab:brown"}
#: the papers' other populations of the same solver (001 Tables 5 and 8)
EXTRA_COLORS = {("rcga", 50): "tab:cyan", ("g3pcx", 600): "tab:red", ("g3pcx", 1000): "gold"}
#: a run's history needs this many points (median over runs) for a convergence curve
MIN_HISTORY_POINTS = 4
#: the warm peer (its row's label, :func:`.timing.tracking`) the latency figures draw beside ours
DRAWN_PEER = "scipy `lm`, analytic"
#: the figures' resolution (dots per inch)
DPI = 110
#: horizontal boxes: orientation= from matplotlib 3.10 on, vert=False before (Ubuntu 24.04, Debian 12: 3.6)
HORIZONTAL = {"orientation": "horizontal"} if version_tuple(MATPLOTLIB_VERSION) >= (3, 10) else {"vert": False}


def draw(res, out_dir: Path) -> dict:
    """Every figure of the measurements ``res`` into ``out_dir``: ``{name: path}``."""
    figures = {}
    for k, sc in res["scenarios"].items():
        series = [(f"{SOLVER_LABEL[c.solver]} {c.pop_label} {'default' if c.polish else 'pure'}",
                   EXTRA_COLORS.get((c.solver, c.population), COLORS[c.solver]), "--" if c.polish else "-", r.runs)
                  for r in res["tables"].get(k, []) for c in [r.config]]
        series += [(f"{r.name} G3PCX", COLORS[r.name], ":", r.runs) for r in res["peers"].get(k, [])
                   if r.status == "run"]
        if series:
            figures[f"success_{k}"] = success_curves(out_dir / f"success_vs_evals_{k}.png",
                                                     f"{sc.label}: success and convergence",
                                                     solvers.PAPER_SETTINGS[sc.model.kind]["max_evals"], series)
        if k in res["tracking"]:
            figures[f"latency_{k}"] = latency_histogram(
                out_dir / f"latency_{k}.png", f"{sc.label}: warm tracking, solve time per step",
                res["tracking"][k], res["scipy"].get(k, ()), LATENCY_TARGET_MS[k])
    if res["deadline"]:
        figures["deadline"] = deadline_plot(out_dir / "deadline.png", res["deadline"])
    return figures


def _save(fig, path: Path, title: str | None = None) -> Path:
    """Save the bare ``Figure`` ``fig`` (through matplotlib's Agg canvas: no window, no pyplot state to close)."""
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    return path


def _median_best(runs, grid) -> np.ndarray:
    """The median over ``runs`` of the best fitness so far at each evaluation count of ``grid``: a run's
    history is (evaluations, best) per chunk, a step function; a run stops at success and stays below
    the threshold afterwards."""
    curves = []
    for r in (r for r in runs if r.history):
        h = np.array(r.history, dtype=float)
        idx = np.searchsorted(h[:, 0], grid, side="right") - 1
        best = np.where(idx >= 0, np.minimum.accumulate(h[:, 1])[np.maximum(idx, 0)], np.nan)
        curves.append(np.where(grid >= r.nfev, np.minimum(best, r.fun), best) if r.success else best)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(np.array(curves), axis=0)


def success_curves(path: Path, title, max_evals, series) -> Path:
    """ECDF of evaluations to success and median best fitness vs evaluations.

    ``series``: list of (label, color, linestyle, runs) where runs are ``common.Run``; dashed
    series (the refined runs, which converge in their first compiled chunk) appear on the left only."""
    fig = Figure(figsize=(12, 4.5))
    ax1, ax2 = fig.subplots(1, 2)
    grid = np.unique(np.logspace(0, np.log10(max_evals), 400).astype(int))
    coarse = []
    for label, color, ls, runs in (s for s in series if s[3]):
        ok = np.sort([r.nfev for r in runs if r.success])
        ax1.step(grid, 100 * np.searchsorted(ok, grid, side="right") / len(runs), where="post", color=color, ls=ls,
                 label=f"{label} ({len(runs)} runs)")
        if ls == "--" or not any(r.history for r in runs):
            continue
        if np.median([len(r.history) for r in runs]) < MIN_HISTORY_POINTS:
            coarse.append(label)
        else:
            ax2.step(grid, np.maximum(_median_best(runs, grid), 1e-32), where="post", color=color, ls=ls, label=label)
    evaluations = {"xscale": "log", "xlabel": "fitness evaluations", "xlim": (1, max_evals)}
    ax1.set(**evaluations, ylabel=f"runs with fitness < {SUCCESS_TOLERANCE:g} (%)", ylim=(-2, 102),
            title="success vs evaluations")
    ax2.set(**evaluations, yscale="log", ylabel="median best fitness", title="convergence (median over runs)")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    ax1.legend(fontsize=7, loc="upper left")
    ax2.axhline(SUCCESS_TOLERANCE, color="k", lw=0.8, ls=":")
    if coarse:
        ax2.text(0.02, 0.07, "not drawn (the whole run is one compiled chunk; no history):\n" + "\n".join(coarse),
                 transform=ax2.transAxes, fontsize=7, va="bottom")
    return _save(fig, path, title)


def latency_histogram(path: Path, title, ours, peers, target_ms) -> Path:
    """The solve times of the warm tracking (``ours``, and the peer :data:`DRAWN_PEER`), our p50, p99 and target."""
    fig = Figure(figsize=(7, 4))
    ax = fig.subplots()
    ms = ours.latency_s * 1e3
    hi = max(float(np.percentile(ms, 99.9)) * 1.3, target_ms * 1.2)
    bins = np.linspace(0.0, hi, 80)
    ax.hist(np.clip(ms, 0, hi), bins=bins, color="tab:green", alpha=0.75, label="ours: Estimator (warm)")
    for row in (r for r in peers if r.label == DRAWN_PEER and r.latency_s is not None):
        ax.hist(np.clip(row.latency_s * 1e3, 0, hi), bins=bins, histtype="step", color="tab:red",
                label="scipy least_squares lm, analytic J")
    for q, ls in (("p50", "--"), ("p99", "-")):
        ax.axvline(ours.stats[q], color="k", ls=ls, lw=1, label=f"{q} {ours.stats[q]:.3f} ms")
    ax.axvline(target_ms, color="tab:red", ls=":", lw=1.5, label=f"target p99 ≤ {target_ms:g} ms")
    ax.set(yscale="log", xlabel="solve time per step (ms), values above the range clipped into the last bin",
           ylabel="steps", title=title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def deadline_plot(path: Path, rows) -> Path:
    """The overruns of each deadline cell (case and solver), one panel per budget."""
    rows = [r for r in rows if hasattr(r, "overrun_ms")]        # not the smallest deciding budgets
    budgets = sorted({r.budget_ms for r in rows})
    labels = list(dict.fromkeys(r.label for r in rows))
    fig = Figure(figsize=(3.6 * len(budgets) + 3.0, 0.35 * len(labels) + 1.6))
    axes = fig.subplots(1, len(budgets), sharey=True, squeeze=False)
    for ax, b in zip(axes[0], budgets):
        by_label = {r.label: r.overrun_ms for r in rows if r.budget_ms == b}
        ax.boxplot([by_label.get(label, np.array([np.nan])) for label in labels], whis=(0, 100), showfliers=False,
                   **HORIZONTAL)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.axvline(DEADLINE_MARGIN_MS, color="tab:red", ls=":", label=f"budget + {DEADLINE_MARGIN_MS:g} ms")
        ax.set(xlabel="elapsed − budget (ms)", title=f"budget {b:g} ms")
        ax.grid(alpha=0.3)
    axes[0][0].set_yticks(range(1, len(labels) + 1), labels, fontsize=7)
    axes[0][-1].legend(fontsize=7)
    return _save(fig, path, "deadline honouring: whiskers span min to max")
