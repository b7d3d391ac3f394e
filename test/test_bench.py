"""glpma-fk bench, smallest path: the 3-RPR only, a handful of runs, every section,
report and figures in a temporary directory."""
import pytest

from glpma_tools.bench import main

SECTIONS = ["## Summary", "## The papers' tables (001 Tables 5 and 8)", "### 3-RPR: 001 Table 5",
            "## Success vs evaluations", "## Pure G3-PCX against peer implementations",
            "## Why the papers' pure G3-PCX figures do not reproduce", "## All real assembly modes",
            "## Warm tracking latency (solve only)", "## Warm solve against `scipy.optimize.least_squares`",
            "## Deadline honouring", "## DDS end to end", "## Extra outputs and the transport path",
            "## Waits of an input for anything but its own solve",
            "## Offline: bag processing and workspace maps", "| where the CPU time of one input goes | µs |",
            "| counting methods, seed 3-RPR map 8 x 8 | value |", "Same statuses on every engine: yes."]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    md = out / "BENCH.md"
    rc = main(["--", "--quick", "--only", "3rpr", "--runs", "2", "--peer-runs", "1", "--gap-runs", "2",
               "--track-steps", "30", "--deadline-solves", "2", "--budgets-ms", "1", "--deadline-solvers", "glpma",
               "--deadline-stall-seconds", "0.2", "--solve-all-runs", "20",
               "--dds-steps", "20", "--outputs-inputs", "5", "--outputs-seconds", "0.3", "--outputs-profile", "20",
               "--outputs-rclpy-seconds", "0", "--outputs-rclpy-runs", "1",
               "--waits-rounds", "1", "--waits-inputs", "300",
               "--no-progress", "--out", str(out), "--markdown", str(md),
               "--reliability", str(out / "none.json"), "--save-data", str(out / "res.pkl"),
               # the hexapod's counts (unused with --only 3rpr, but parsed and checked) and the small ones
               "--hexapod-runs", "1", "--peer-hexapod-runs", "0", "--table2-runs", "2", "--track-budget-ms", "20"])
    assert rc == 0
    return out, md.read_text()


def test_chosen_sections_only_without_figures(tmp_path):
    """--sections runs only the sections named (here the all-modes comparison and the offline tools)
    and --no-plots writes no figure."""
    md = tmp_path / "BENCH.md"
    rc = main(["--", "--quick", "--only", "3rpr", "--sections", "solve-all", "offline", "--solve-all-runs", "10",
               "--solve-all-repeats", "1", "--modes-cases", "1", "--modes-g3pcx-hexapods", "0",
               "--bag-messages", "40", "--map-resolution", "3", "--no-plots", "--no-progress", "--out", str(tmp_path),
               "--markdown", str(md), "--reliability", str(tmp_path / "none.json")])
    assert rc == 0
    text = md.read_text()
    assert "## All real assembly modes" in text and "## Warm tracking latency (solve only)" not in text
    assert not list(tmp_path.glob("*.png"))


def test_markdown_has_every_table(report):
    _, text = report
    for heading in SECTIONS:
        assert heading in text, heading
    assert "Machine: " in text and "Command: `glpma-fk bench --quick --only 3rpr" in text
    assert "6-6 hexapod" not in text.split("## Summary")[1]
    # the paper's rows, ours beside the published figures
    for method, pop, paper_evals in (("RCGA", "50", "7,301 ± 218"), ("RCGA", "100", "5,111 ± 189"),
                                     ("G3-PCX", "100", "2,984 ± 73"), ("GLPMA", "(100, 100)", "7,448 ± 243")):
        for mode in ("pure", "default (polish)"):
            rows = [ln for ln in text.splitlines() if ln.startswith(f"| {method} | {pop} | {mode} | 2 |")]
            assert len(rows) == 1 and paper_evals in rows[0], (method, pop, mode)
    for peer in ("pypop7 G3PCX", "pymoo G3PCX"):
        assert any(ln.startswith(f"| {peer} |") for ln in text.splitlines()), peer
    assert "| 3-RPR | 30 | 20 |" in text                      # tracking row
    assert "| ours: Estimator (warm: compiled LM) |" in text and "| scipy `lm`, analytic |" in text
    assert "| plain NumPy Newton |" in text and "ours/row (p99)" in text
    assert "| 3-RPR | 20 | U[" in text                          # solve_all row: 20 runs
    for load in ("no load added", "every core busy"):          # the deadline rows, a solver's and the Estimator's
        assert f"| 3-RPR, legs without an assembly | glpma | 1 | {load} | 2 |" in text, load
        told = "3-RPR, legs without an assembly, told by a pair's loop bounds (Estimator: GLPMA, cold)"
        assert f"| {told} | Estimator | 1 | {load} | 2 |" in text, load
        assert f"| planar_3rpr | {load} | 3 |" in text, load      # its smallest deciding budget, 3 Estimators
    assert "p99.9 / max of end − deadline, ms" in text
    for load in ("no load added", "every core busy"):          # the machine's stalls probed under each load
        assert f"| {load} | 0.2 |" in text, load
        floor = "a loop that only reads the clock until its deadline (no solve: the machine's floor)"
        # ... and the floor beside the solvers, as many times as a solver in all (its two cases of the 3-RPR)
        assert f"| {floor} | clock only | 1 | {load} | 4 |" in text, load
    waits = text.split("## Waits of an input")[1].split("\n## ")[0]
    for setup in ("handle", "handle + reports", "node at 1 kHz"):
        assert f"| {setup} | 300 |" in waits, setup
    assert "Same statuses on every engine: yes." in text and "identical on every engine: NO" not in text


def test_polished_rows_converge_and_figures_exist(report):
    out, text = report
    for line in text.splitlines():
        if "| default (polish) | 2 |" in line:
            assert "| 100 % |" in line, line
    for name in ("success_vs_evals_3rpr.png", "latency_3rpr.png", "deadline.png"):
        assert (out / name).stat().st_size > 1000, name


def test_bad_arguments_return_status_2(capsys):
    assert main(["--only", "nonsense"]) == 2
    assert main(["--runs", "-1"]) == 2
    assert main(["--deadline-solvers", "nonsense"]) == 2


def test_the_reliability_section_comes_from_the_stress_json(report):
    _, text = report
    assert text.count("## Reliability") == 1
    assert "Not measured yet" in text.split("## Reliability")[1]      # --reliability pointed at no file


def test_quick_never_writes_over_the_committed_report():
    import shutil

    from glpma_tools.bench.runner import DEFAULT_MARKDOWN, DEFAULT_OUT, build_parser, output_paths
    out, md = output_paths(build_parser().parse_args(["--quick"]))
    shutil.rmtree(out)                                              # the scratch directory it made
    assert md != DEFAULT_MARKDOWN and out != DEFAULT_OUT and md.parent == out
    out, md = output_paths(build_parser().parse_args(["--quick", "--markdown", "/tmp/x/B.md"]))
    assert str(md) == "/tmp/x/B.md" and str(out) == "/tmp/x"
    assert output_paths(build_parser().parse_args([])) == (DEFAULT_OUT, DEFAULT_MARKDOWN)


def test_render_rewrites_the_report_from_saved_data(report):
    out, text = report
    md = out / "again.md"
    assert main(["--render", str(out / "res.pkl"), "--markdown", str(md), "--out", str(out),
                 "--reliability", str(out / "none.json")]) == 0
    again = md.read_text()
    for heading in SECTIONS:
        assert heading in again, heading
    section = again.split("## Extra outputs and the transport path")[1].split("\n## ")[0]
    assert section == text.split("## Extra outputs and the transport path")[1].split("\n## ")[0]
    for process in ("node", "node, extra outputs off", "echo (transport floor)"):
        assert f"| 3-RPR | {process} | 1000 Hz, 0.3 s |" in section, process
