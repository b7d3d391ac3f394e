"""No import cycle among the modules of glpma_ros and glpma_tools (tools/check_import_cycles.py, which
.ci/run also runs on its own), and the checker finds one where there is one."""
import subprocess
import sys

from conftest import ROOT

sys.path.insert(0, str(ROOT / "tools"))
import check_import_cycles


def test_no_import_cycle_in_the_packages():
    edges = check_import_cycles.graph(ROOT, ["glpma_ros", "glpma_tools"])
    assert "glpma_ros.node.service" in edges            # the graph is read, not empty
    assert check_import_cycles.cycles(edges) == []


def test_the_checker_finds_a_cycle_hidden_in_a_function(tmp_path):
    """Else the test above could pass for nothing: a -> b at the top, b -> a inside a function."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import f\n")
    (pkg / "b.py").write_text("def f():\n    from . import a\n    return a\n")
    (pkg / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import a\n")
    edges = check_import_cycles.graph(tmp_path, ["pkg"])
    assert check_import_cycles.cycles(edges) == [["pkg.a", "pkg.b"]]
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "check_import_cycles.py"), "--root", str(tmp_path),
                        "pkg"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 1 and "pkg.a -> pkg.b -> pkg.a" in p.stdout, p.stdout
