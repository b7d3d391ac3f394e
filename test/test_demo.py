"""The main job end to end: node process + mock controller over DDS, summary, figure, exit status."""
import json
import os
import subprocess
import sys

import pytest

from conftest import ROOT

pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")


@pytest.mark.timing
def test_demo_tracks_and_writes_figure(tmp_path):
    env = dict(os.environ, CYCLONEDDS_URI=(ROOT / "config" / "cyclonedds-localhost.xml").as_uri())
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "demo", "--duration", "2", "--out", str(tmp_path),
                        "--domain-id", str(201 + os.getpid() % 30)],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=400)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "tracking                  OK" in p.stdout
    png = tmp_path / "demo_3rpr.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    summary = json.loads((tmp_path / "demo_3rpr.json").read_text())
    assert summary["pose_ratio"] >= 0.95
    assert summary["tracking_error"]["position_m"]["max"] <= 1e-6


def test_demo_bad_option_exits_2():
    p = subprocess.run([sys.executable, "-m", "glpma_ros", "demo", "--duration", "-1"], cwd=ROOT,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "positive" in p.stderr and "Traceback" not in p.stderr
