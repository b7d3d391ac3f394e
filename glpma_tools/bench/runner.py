"""``glpma-fk bench``: argument parsing and the order of the experiments."""
from __future__ import annotations

import os
import pickle
import shlex
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import psutil

from glpma_ros import solvers
from glpma_ros.cli.api import OneLineParser, command_main
from glpma_ros.errors import GlpmaError
from glpma_tools.stress.report import read_json
from glpma_tools.timing import REPO_ROOT, git_revision, machine

from . import dds, modes, offline, outputs, plots, report, timing, waits
from . import experiments as ex
from .scenarios import load

SECTIONS = ("tables", "peers", "solve-all", "tracking", "deadline", "baselines", "dds", "outputs", "waits",
            "offline")

#: run counts (and the tracking budget): option -> (full, --quick, type, what it counts); 0 skips what it counts
DEFAULTS = {
    "runs": (100, 10, int, "runs per configuration of ours, every row but the pure hexapod ones"),
    "hexapod_runs": (100, 5, int, "runs per pure hexapod configuration (up to 500,000 evaluations each)"),
    "peer_runs": (100, 5, int, "runs per peer on the 3-RPR"),
    "peer_hexapod_runs": (None, 0, int, "runs per peer on the hexapod (default pypop7 10, pymoo 3)"),
    "gap_runs": (100, 10, int, "runs of the larger-cap G3-PCX diagnostics"),
    "track_steps": (1000, 300, int, "steps of each tracking trajectory"),
    "deadline_solves": (100, 20, int, "solves per deadline cell"),
    "deadline_stall_seconds": (30.0, 2.0, float, "seconds per load of the deadline section's probe of the machine's "
                               "own stalls (a loop that only reads the clock, a share after each cell)"),
    "solve_all_repeats": (5, 1, int, "solve_all repetitions with seeds 0.."),
    "modes_cases": (None, 2, int, "random cases per manipulator of the multistart/msolve/G3-PCX comparison "
                    "(default all stored)"),
    "modes_g3pcx_hexapods": (3, 0, int, "hexapod cases of that comparison also solved by 200 G3-PCX runs"),
    "dds_steps": (60_000, 2000, int, "inputs of each DDS end-to-end run at 1 kHz"),
    "outputs_inputs": (3000, 200, int, "inputs per output configuration of the extra outputs' cost"),
    "outputs_seconds": (60, 2, float, "seconds of each legs written -> pose read run of the outputs section: node, "
                        "node with extra outputs off, echo"),
    "outputs_profile": (5000, 500, int, "writes and thread round trips of the outputs section's micro-profile"),
    "outputs_rclpy_seconds": (10, 2, float, "seconds per rclpy executor variant of the outputs section, where "
                              "rclpy imports"),
    "outputs_rclpy_runs": (5, 1, int, "runs of the rclpy echo floor beside the shipped node in the outputs section"),
    "waits_rounds": (4, 1, int, "rounds per setup of the waits section"),
    "waits_inputs": (5000, 1000, int, "inputs per round of the waits section"),
    "bag_messages": (10_000, 1000, int, "inputs of the recorded run glpma-fk bag processes"),
    "map_resolution": (101, 8, int, "points per axis of the glpma-fk map grids, 3-RPR and 6-6 slice "
                       "(the command's default)"),
    "table2_runs": (50, 5, int, "runs per 004 Table II row (paper: 50)"),
    "solve_all_runs": (100, 100, int, "searches per solve_all (paper: 100)"),
    "track_budget_ms": (20.0, 20.0, float, "Estimator time budget while tracking, so latency is not clipped"),
}
#: peers' runs on the hexapod: each costs 500,000 evaluations of Python overhead (see BENCHMARKS.md)
PEER_HEXAPOD_RUNS = {"pypop7": 10, "pymoo": 3}
QUICK_SKIP = "skipped in --quick (500,000 evaluations of Python overhead per run)"
#: where a full run writes its report and figures, and reads the stress test's figures
DEFAULT_MARKDOWN = REPO_ROOT / "BENCHMARKS.md"
DEFAULT_OUT = REPO_ROOT / "doc" / "bench"
DEFAULT_RELIABILITY = DEFAULT_OUT / "reliability.json"


def build_parser() -> OneLineParser:
    """The options; the run counts from :data:`DEFAULTS`."""
    p = OneLineParser(
        prog="glpma-fk bench",
        description="Reproduce the papers' tables (001 Tables 5 and 8, 002's all-solutions experiment) against "
                    "peer implementations, measure warm-tracking latency and deadline honouring, and write "
                    "BENCHMARKS.md with figures.")
    p.add_argument("--quick", action="store_true",
                   help="few runs per row (a few minutes); writes into a scratch directory unless --out or "
                        "--markdown is given")
    p.add_argument("--only", choices=["3rpr", "hexapod"], nargs="+", help="restrict to these manipulators")
    p.add_argument("--sections", choices=SECTIONS, nargs="+",
                   help=f"run only these sections (default: all of {', '.join(SECTIONS)})")
    p.add_argument("--budgets-ms", type=float, nargs="+", default=[1.0, 2.0, 5.0], help="deadline budgets")
    p.add_argument("--deadline-solvers", nargs="+", metavar="SOLVER",
                   help="solvers of the deadline section (default: every registered solver)")
    for name, (full, quick, kind, what) in DEFAULTS.items():
        default = "" if full is None else f" (default {full:,g}; --quick {quick:,g})"
        p.add_argument("--" + name.replace("_", "-"), type=kind, metavar="N", help=what + default)
    p.add_argument("--out", type=Path,
                   help="directory for the PNGs (default doc/bench; --quick: the --markdown file's directory or a "
                        "scratch directory)")
    p.add_argument("--markdown", type=Path,
                   help="report path (default BENCHMARKS.md; --quick: BENCHMARKS.md in the --out directory)")
    p.add_argument("--reliability", type=Path, default=DEFAULT_RELIABILITY, metavar="JSON",
                   help="figures of `glpma-fk stress` for the Reliability section (default doc/bench/reliability.json)")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--save-data", type=Path, help="also pickle the measurements to this file")
    p.add_argument("--render", type=Path, metavar="PICKLE",
                   help="run nothing: redraw the figures and rewrite the report from --save-data output")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def output_paths(args) -> tuple[Path, Path]:
    """(figures directory, report path): the repository's for a full run; a --quick run writes
    beside what is given, else into a new scratch directory, never over the committed report."""
    out, md = args.out, args.markdown
    if not args.quick:
        return (out or DEFAULT_OUT).resolve(), (md or DEFAULT_MARKDOWN).resolve()
    if out is None:
        out = md.parent if md is not None else Path(tempfile.mkdtemp(prefix="glpma_bench_quick_"))
    return out.resolve(), (md or out / "BENCHMARKS.md").resolve()


def _count(args, name):
    """The option ``name``'s value, else its default for a full or a --quick run."""
    value = getattr(args, name)
    if value is not None and value < 0:
        raise GlpmaError(f"glpma-fk bench: --{name.replace('_', '-')} must be >= 0")
    return DEFAULTS[name][1 if args.quick else 0] if value is None else value


def _peer_runs(args, counts, key) -> dict:
    """Runs per peer on manipulator ``key`` (and why a peer does not run, under ``<peer>_why``)."""
    n = counts["peer_hexapod_runs" if key == "hexapod" else "peer_runs"]
    runs = dict(PEER_HEXAPOD_RUNS) if n is None else dict.fromkeys(PEER_HEXAPOD_RUNS, n)
    if key == "hexapod" and args.quick and args.peer_hexapod_runs is None:
        runs.update({f"{name}_why": QUICK_SKIP for name in PEER_HEXAPOD_RUNS})
    return runs


@command_main
def main(argv=None) -> int:
    """``glpma-fk bench``: the sections asked for, in this order, then the figures and the report (or only these,
    from the measurements ``--render`` reads)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--"]:          # `glpma-fk bench -- --quick` (the CLI passes the rest through)
        argv = argv[1:]
    args = build_parser().parse_args(argv)
    counts = {name: _count(args, name) for name in DEFAULTS}
    unknown = sorted(set(args.deadline_solvers or ()) - set(solvers.SOLVERS))
    if unknown:
        raise GlpmaError(f"glpma-fk bench: unknown solver(s) {', '.join(unknown)}; "
                         f"choose from {', '.join(solvers.SOLVERS)}")
    stress_figures = _reliability(args.reliability)       # before hours of measurements: it may not read
    os.environ.setdefault("MPLBACKEND", "Agg")

    t_start = time.perf_counter()

    def say(msg, section=None):
        if section:         # the load average at the start of each section, for the report's header
            res["load"].append((section, "/".join(f"{v:.2f}" for v in psutil.getloadavg())))
        print(f"[bench {time.perf_counter() - t_start:6.1f} s] {msg}", file=sys.stderr, flush=True)

    out_dir, args.markdown = output_paths(args)
    say(f"report: {args.markdown}; figures: {out_dir}")
    if args.render:                 # the models hold compiled functions: the pickle names the scenarios
        saved = pickle.loads(args.render.read_bytes())
        saved.update(scenarios={k: load(k) for k in saved["scenarios"]}, figures={})
        return finish(saved, args, out_dir, say, stress_figures)
    sections, progress = set(args.sections or SECTIONS), not args.no_progress
    scenarios = {k: load(k) for k in args.only or ["3rpr", "hexapod"]}
    runs, hex_runs, listed = counts["runs"], counts["hexapod_runs"], list(scenarios.values())
    res = {"date": datetime.now(timezone.utc).astimezone().strftime("%Y-%m-%d %H:%M %Z"), "machine": machine(),
           "revision": git_revision(), "quick": args.quick,
           # the canonical command, and the command line this process was started with
           "command": (shlex.join(["glpma-fk", "bench", *argv]), shlex.join(getattr(sys, "orig_argv", sys.argv))),
           "scenarios": scenarios, "tables": {}, "peers": {}, "gap": None, "all_solutions": {}, "tracking": {},
           "scipy": {}, "deadline": [], "dds": None, "baselines": None, "outputs": None, "offline": None,
           "figures": {}, "load": []}
    for k, sc in scenarios.items() if "tables" in sections else ():
        say(f"{sc.label}: the papers' table, pure and default", f"{sc.key} tables")
        res["tables"][k] = ex.paper_tables(sc, hex_runs if k == "hexapod" else runs, runs, progress)
    for k, sc in scenarios.items() if "peers" in sections else ():
        say(f"{sc.label}: pure G3-PCX peers", f"{sc.key} peers")
        res["peers"][k] = ex.peer_g3pcx(sc, _peer_runs(args, counts, k), progress)
    if "peers" in sections and "3rpr" in scenarios and counts["gap_runs"] > 0:
        say("3-RPR: G3-PCX with larger evaluation caps")
        res["gap"] = ex.gap_diagnostics(scenarios["3rpr"], counts["gap_runs"], progress)
    for k, sc in scenarios.items() if "solve-all" in sections else ():
        say(f"{sc.label}: all solutions", f"{sc.key} solve-all")
        res["all_solutions"][k] = ex.all_solutions(sc, counts["solve_all_runs"], max(1, counts["solve_all_repeats"]),
                                                   progress)
    if "solve-all" in sections:
        say("all real assembly modes: multistart, msolve, G3-PCX", "solve-all modes")
        res["modes_comparison"] = modes.compare(scenarios, counts["modes_cases"], counts["modes_g3pcx_hexapods"],
                                                progress)
    for k, sc in scenarios.items() if "tracking" in sections else ():
        say(f"{sc.label}: warm tracking and scipy least_squares", f"{sc.key} tracking")
        res["tracking"][k], res["scipy"][k] = timing.tracking(sc, max(2, counts["track_steps"]),
                                                              counts["track_budget_ms"], progress)
    if "deadline" in sections:
        say("deadline honouring", "deadline")
        res["deadline"] = timing.deadlines(listed, args.budgets_ms, max(1, counts["deadline_solves"]), progress,
                                           args.deadline_solvers, stall_seconds=counts["deadline_stall_seconds"])
    if "baselines" in sections:
        say("baselines: 004 Table II, DE on 001's protocols", "baselines")
        res["baselines"] = ex.baselines(scenarios, counts["table2_runs"], runs, hex_runs, progress)
    if "dds" in sections:
        say("DDS end to end", "dds")
        res["dds"] = dds.dds_end_to_end(listed, counts["dds_steps"], args.quick)
    if "outputs" in sections:
        say("extra outputs and the transport path", "outputs")
        res["outputs"] = outputs.measure(listed, counts["outputs_inputs"], counts["outputs_seconds"],
                                         counts["outputs_profile"], counts["outputs_rclpy_seconds"], say,
                                         rclpy_runs=max(1, counts["outputs_rclpy_runs"]))
    if "waits" in sections and counts["waits_rounds"] > 0:
        say("waits of an input for anything but its own solve", "waits")
        res["waits"] = waits.measure(counts["waits_rounds"], max(1, counts["waits_inputs"]))
    if "offline" in sections:
        say("offline: glpma-fk bag throughput and fleet, glpma-fk map on each engine and against G3-PCX, "
            "glpma-fk calibrate", "offline")
        res["offline"] = offline.measure(counts["bag_messages"], counts["map_resolution"], args.quick,
                                         hexapod="hexapod" in scenarios)
    res["wall_s"] = time.perf_counter() - t_start
    if args.save_data:              # first: the figures or the report may fail; the models hold compiled functions,
        args.save_data.write_bytes(pickle.dumps({**res, "scenarios": list(scenarios)}))     # a render loads them
        say(f"saved the measurements to {args.save_data}")
    return finish(res, args, out_dir, say, stress_figures)


def _reliability(path: Path) -> tuple[dict | None, str]:
    """The figures ``glpma-fk stress`` wrote to ``path`` (None: none yet), and where they are, for the report."""
    try:
        figures = read_json(path)
    except (OSError, ValueError) as exc:
        raise GlpmaError(f"glpma-fk bench: cannot read {path}: {exc}") from exc
    path = path.resolve()
    return figures, str(path.relative_to(REPO_ROOT)) if path.is_relative_to(REPO_ROOT) else str(path)


def finish(res, args, out_dir, say, reliability) -> int:
    """Figures and the report from the measurements; ``reliability``: :func:`_reliability`'s."""
    if not args.no_plots:
        out_dir.mkdir(parents=True, exist_ok=True)
        say("figures")
        res["figures"] = plots.draw(res, out_dir)
    args.markdown.parent.mkdir(parents=True, exist_ok=True)
    args.markdown.write_text(report.render(res, args.markdown, *reliability))
    say(f"wrote {args.markdown}")
    return 0
