"""Reliability of the node process over real Cyclone DDS (short versions of ``glpma-fk stress``):
a 1 kHz overload with its memory checked, a burst, a controller restart, a large jump of the
legs to another assembly mode, and a node restart (cold, then warm).  One node process serves
every check (it takes ~10-20 s to start: it compiles or loads its solvers); the restart test
comes last.  Counts come from the node's /diagnostics."""
import json
import os

import pytest

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")

from glpma_tools import stress  # noqa: E402

from conftest import CONFIG  # noqa: E402

#: 50 domains away from test_dds_integration's (100 + pid % 100 and the next few)
DOMAIN = 100 + (os.getpid() % 100 + 50) % 100


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        for key in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID"):        # Session sets them for this process
            if key in os.environ:
                mp.setenv(key, os.environ[key])
            else:
                mp.delenv(key, raising=False)
        s = stress.Session(CONFIG / "params_3rpr.yaml", domain_id=DOMAIN,
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
        print(f"\n[{name}] {json.dumps(brief, default=stress._json_default)}")


def check(res, session):
    failed = [k for k, ok in res["checks"].items() if not ok]
    assert not failed, f"failed: {failed}\n{json.dumps(res, default=stress._json_default, indent=1)}\n" \
                       f"{session.node.output()}"


def test_overload_1khz_keeps_the_newest_input_and_its_memory(session, capsys):
    res = session.overload(3.0, 1000.0)
    show(capsys, "overload 1 kHz 3 s", res)
    check(res, session)
    assert res["inputs"] == 3000
    # every input written is solved, dropped, rejected or (a small slack) lost in transport
    assert res["received"] == res["solved"] + res["dropped"] + res["rejected"]
    assert res["inputs"] - res["received"] <= stress.LOST_SLACK * res["inputs"]
    assert res["rss_growth_mb"] <= stress.RSS_SLACK_MB


@pytest.mark.timing
def test_burst_of_2000_messages(session, capsys):
    res = session.burst(2000)
    show(capsys, "burst 2000", res)
    check(res, session)
    assert res["received"] == res["solved"] + res["dropped"] + res["rejected"]
    assert res["solved"] >= 1
    # the node cannot solve thousands per second: the excess is dropped (node) or overwritten (DDS
    # keep-last history), never queued
    assert res["dropped"] + res["lost_in_transport"] > 0
    assert res["rss_growth_mb"] <= stress.RSS_SLACK_MB


def test_controller_restart_mid_trajectory(session, capsys):
    res = session.controller_restart(1.0)
    show(capsys, "controller restart", res)
    check(res, session)


def test_large_jump_to_another_assembly_mode_recovers(session, capsys):
    res = session.large_jump(1.0)
    show(capsys, "large jump", res)
    check(res, session)
    assert res["jump_legs_max"] > 50 * res["step_legs_max"]


def test_node_restart_mid_trajectory_cold_then_warm(session, capsys):
    res = session.node_restart(1.0)
    show(capsys, "node restart", res)
    check(res, session)
    assert res["first_report"]["starts"]["cold"] >= 1
    assert res["final"]["last start"] == "warm"


# -- the Reliability section of BENCHMARKS.md (no node needed) ------------------------------------------

def test_reliability_section_is_replaced_in_place_and_kept_by_the_bench(tmp_path):
    from glpma_tools.bench import report
    text = "# Benchmarks\n\nintro\n\n## Deadline honouring\n\nd\n\n## DDS end to end\n\ne\n"
    once = stress.splice_section(text, ["## Reliability", "", "first"])
    assert once.startswith(text.rstrip()) and once.rstrip().endswith("first")
    twice = stress.splice_section(once, ["## Reliability", "", "second"])
    assert "first" not in twice and twice.count("## Reliability") == 1
    middle = "# B\n\n## Reliability\n\nold\n\n## Later\n\nl\n"
    assert stress.splice_section(middle, ["## Reliability", "", "new"]) == "# B\n\n## Reliability\n\nnew\n\n## Later\n\nl\n"
    md = tmp_path / "BENCHMARKS.md"
    md.write_text(twice)
    assert report.kept_sections(md) == ["", "## Reliability", "", "second"]
    assert report.kept_sections(tmp_path / "missing.md") == []


@pytest.mark.parametrize("argv", [["--duration", "0"], ["--burst", "0"], ["--rate", "nan"], ["--domain", "300"],
                                  ["--params-file", "/nonexistent.yaml"], ["--bogus"]])
def test_stress_usage_errors_are_status_2_and_one_line(argv, capsys):
    assert stress.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error" in err[0]
