"""Reliability of the node process over real Cyclone DDS (short versions of ``glpma-fk stress``):
a 1 kHz overload with its memory checked, a burst, a controller restart, a large jump of the
legs to another assembly mode, and a node restart (cold, then warm).  One node process serves
every check (it compiles or loads its solvers before it is ready); the restart test comes last.
Counts come from the node's /diagnostics.  Nothing here depends on how fast the machine is:
the checks are that counters add up, every pose answers an input it was sent, the node lives."""
import json
import os

import pytest

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from conftest import CONFIG
from glpma_tools import stress
from glpma_tools.stress.report import json_default


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        for key in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID"):        # Session sets them for this process
            if key in os.environ:
                mp.setenv(key, os.environ[key])
            else:
                mp.delenv(key, raising=False)
        # no domain given: the session claims one no other process on the host uses
        s = stress.Session(CONFIG / "params_3rpr.yaml",
                           log_dir=tmp_path_factory.mktemp("stress_node"))
        try:
            s.start()
        except RuntimeError as exc:
            s.close()
            pytest.fail(str(exc))
        yield s
        s.close()


def show(capsys, name, res):
    with capsys.disabled():
        brief = {k: v for k, v in res.items() if k != "checks"}
        print(f"\n[{name}] {json.dumps(brief, default=json_default)}")


def check(res, session):
    """Every check passed (the expectations, which depend on how busy the machine is, are only shown)."""
    failed = [k for k, ok in res["checks"].items() if not ok]
    assert not failed, f"failed: {failed}\n{json.dumps(res, default=json_default, indent=1)}\n" \
                       f"{session.node.output()}"


def test_overload_1khz_keeps_the_newest_input(session, capsys):
    res = stress.overload(session, 3.0, 1000.0)
    show(capsys, "overload 1 kHz 3 s", res)
    check(res, session)
    assert res["inputs"] == 3000
    # every input the node received is solved, dropped or rejected; none is lost inside the node
    assert res["received"] == res["solved"] + res["dropped"] + res["rejected"]
    assert res["received"] <= res["inputs"]
    assert res["poses"] == res["solved"] and res["unpaired"] == 0


@pytest.mark.timing
def test_burst_of_2000_messages(session, capsys):
    res = stress.burst(session, 2000)
    show(capsys, "burst 2000", res)
    check(res, session)
    assert res["received"] == res["solved"] + res["dropped"] + res["rejected"]
    assert res["solved"] >= 1 and res["unpaired"] == 0
    # the node cannot solve thousands of inputs in the time it takes to write them: the excess is
    # dropped (node) or overwritten (DDS keep-last history), never queued
    assert res["dropped"] + res["lost_in_transport"] > 0


def test_controller_restart_mid_trajectory(session, capsys):
    res = stress.controller_restart(session, 1.0)
    show(capsys, "controller restart", res)
    check(res, session)
    assert res["poses_after"] >= 1


def test_large_jump_to_another_assembly_mode_recovers(session, capsys):
    res = stress.large_jump(session, 1.0)
    show(capsys, "large jump", res)
    check(res, session)
    assert res["jump_legs_max"] > 50 * res["step_legs_max"]
    assert res["poses"] >= 1


def test_node_restart_mid_trajectory_cold_then_warm(session, capsys):
    res = stress.node_restart(session, 1.0)
    show(capsys, "node restart", res)
    check(res, session)
    assert res["first_report"]["starts"]["cold"] >= 1


# -- the figures as JSON, rendered by the bench (no node needed) ----------------------------------------

def test_the_bench_renders_the_stress_figures(tmp_path):
    from glpma_tools.bench.report import reliability_section
    from glpma_tools.stress.report import read_json as load
    from glpma_tools.stress.report import write_json
    flood = {"inputs": 10, "send_s": 0.5, "send_rate_hz": 20.0, "late_sends": 0, "received": 9, "solved": 7,
             "rejected": 1, "dropped": 1, "deadline_misses": 0, "lost_in_transport": 1, "rss_before_mb": 80.0,
             "rss_after_mb": 80.5, "rss_growth_mb": 0.5, "node_latency_ms": {"p50": 1.0, "p99": 2.0, "max": 3.0},
             "starts": {"warm": 7, "widened": 0, "cold": 1}, "poses": 7, "matched": 7, "unpaired": 0,
             "latency_ms": {"p50": 1.5, "p99": 2.5, "max": 3.5, "mean": 1.6}, "residual_max_m": 1e-13,
             "on_trajectory_mode": 7, "checks": {"node alive": True, "one pose per solved input": True},
             "rate_hz": 20.0, "duration_s": 0.5}
    res = {"date": "2024-01-01 00:00 UTC", "quick": True, "revision": "abc", "wall_s": 60.0,
           "machine": {"cpu": "cpu", "cores": 2}, "load_average_start": [1.0, 1.0, 1.0],
           "load_average_end": [2.0, 1.0, 1.0], "passed": True, "command": "glpma-fk stress --quick",
           "sections": {"overload": flood}}
    path = write_json(tmp_path / "doc" / "reliability.json", res)
    lines = reliability_section(load(path), "doc/reliability.json")
    text = "\n".join(lines)
    assert lines[0] == "## Reliability" and "`glpma-fk stress --quick`" in text and "--quick run" in text
    assert "| received by the node | 9 |" in text and "| dropped (replaced by a newer input) | 1 |" in text
    assert "- overload: pass" in text
    missing = "\n".join(reliability_section(load(tmp_path / "none.json"), "doc/bench/reliability.json"))
    assert "Not measured yet" in missing and "doc/bench/reliability.json" in missing


@pytest.mark.parametrize("argv", [["--duration", "0"], ["--burst", "0"], ["--rate", "nan"], ["--domain", "300"],
                                  ["--params-file", "/nonexistent.yaml"], ["--bogus"]])
def test_stress_usage_errors_are_status_2_and_one_line(argv, capsys):
    assert stress.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error" in err[0]


def test_stress_command_runs_a_section_and_replays_its_figures(tmp_path, dds_env, dds_domain, capsys):
    """``glpma-fk stress`` as a user runs it, with every option given a valid value: a short burst
    section against a node on the test's own domain, figures written, then printed again from them."""
    figures = tmp_path / "stress.json"
    argv = ["--quick", "--sections", "burst", "--burst", "200", "--duration", "1", "--rate", "500", "--phase", "1",
            "--deadline-solves", "10", "--budgets-ms", "2", "--params-file", str(CONFIG / "params_3rpr.yaml"),
            "-p", "solver:=glpma", "--domain", str(dds_domain), "--log-dir", str(tmp_path / "logs"),
            "--json-out", str(figures)]
    assert stress.main(argv) == 0, capsys.readouterr()
    res = json.loads(figures.read_text())
    burst = res["sections"]["burst"]
    assert burst["inputs"] == 200 and all(burst["checks"].values()), burst["checks"]
    assert (tmp_path / "logs").is_dir()
    capsys.readouterr()
    assert stress.main(["--from-json", str(figures), "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["sections"]["burst"]["inputs"] == 200
