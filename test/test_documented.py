"""What the documentation promises is what the program does.

* Every option of every ``glpma-fk`` subcommand (read from the program's own ``--help``, so a new
  option is covered the moment it exists) appears in some test that is not a bad-input test: a test
  runs it with a valid value.  Bad-value tests stay, but do not count.
* Every concrete ``glpma-fk`` command in README.md's code blocks is run here (exit status and key
  words of its output checked, loosely); every option a README synopsis shows exists in the
  program's ``--help``.  The README cannot drift from the program.
"""
from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import ROOT, interrupt

README = ROOT / "README.md"
TEST_DIR = Path(__file__).resolve().parent
#: a bound for a hung command, not a timing figure (a cold Numba cache on a busy machine takes minutes)
TIMEOUT_S = 600
#: a test whose name holds one of these checks refusals or the help text, not a run: its option strings
#: do not count as valid runs
BAD_INPUT_WORDS = ("bad", "error", "invalid", "exit_2", "exits_2", "usage", "unknown", "help")
#: options every argparse parser has, and the ROS arguments the node's help lists (run by the node tests)
GENERIC = {"--help", "--version"}
OPTION = re.compile(r"(?<![\w-])(--[a-z][a-z0-9]*(?:-[a-z0-9]+)*)")


def glpma_fk(*args, env=None, timeout=TIMEOUT_S):
    return subprocess.run([sys.executable, "-m", "glpma_ros", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, timeout=timeout, env=env)


def subcommands() -> list[str]:
    """The subcommands ``glpma-fk --help`` lists."""
    text = glpma_fk("--help").stdout
    choices = re.search(r"\{([\w,-]+)\}", text)
    assert choices, text
    return choices.group(1).split(",")


def options_of(command: str) -> set[str]:
    """The options a subcommand's ``--help`` shows (its usage line and option list)."""
    p = glpma_fk(command, "--help")
    assert p.returncode == 0, p.stderr
    # option names are at the start of an option line or in the usage; help prose may name others
    usage_and_options = [ln for ln in p.stdout.splitlines()
                         if ln.lstrip().startswith("-") or ln.startswith("usage:") or ln.startswith(" " * 10)]
    found = set()
    for line in usage_and_options:
        stripped = line.lstrip()
        if stripped.startswith("-"):
            head = re.split(r"\s{2,}", stripped, maxsplit=1)[0]      # the option column, not its help
            found |= set(OPTION.findall(head))
        elif line.startswith("usage:") or re.match(r"^\s+\[", line):
            found |= set(OPTION.findall(line))
    return found - GENERIC


def _is_bad_input_test(name: str) -> bool:
    return any(w in name.lower() for w in BAD_INPUT_WORDS)


def option_strings_in_valid_runs() -> set[str]:
    """Every ``--option`` string literal in the test sources outside bad-input tests (test functions,
    fixtures and helpers; parametrize lists of a bad-input test excluded with it)."""
    found = set()
    for path in TEST_DIR.glob("*.py"):
        if path.name == Path(__file__).name:
            continue
        tree = ast.parse(path.read_text())
        excluded = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and _is_bad_input_test(node.name):
                excluded |= {id(n) for n in ast.walk(node)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in excluded:
                found |= set(OPTION.findall(node.value))
    return found


@pytest.fixture(scope="module")
def covered():
    return option_strings_in_valid_runs()


@pytest.mark.parametrize("command", subcommands())
def test_every_option_runs_with_a_valid_value_in_a_test(command, covered):
    missing = sorted(options_of(command) - covered)
    assert not missing, (f"glpma-fk {command}: no test runs {', '.join(missing)} with a valid value "
                         f"(a bad-input test does not count)")


# -- README.md -------------------------------------------------------------------------------------------

def readme_commands() -> list[str]:
    """The ``glpma-fk`` lines of README.md's code blocks, comments stripped."""
    out, inside = [], False
    for line in README.read_text().splitlines():
        if line.startswith("```"):
            inside = not inside
            continue
        line = line.split("  #", 1)[0].strip()
        # "glpma-fk calibrate: ..." is a line of output shown in the README, not a command
        if inside and line.startswith("glpma-fk") and not re.match(r"glpma-fk [\w-]+:", line):
            out.append(line)
    return out


def _is_synopsis(cmd: str) -> bool:
    """A usage line (placeholders, optional parts) rather than a command to type."""
    return any(t in cmd for t in ("[", "...", "CONFIG", "INPUT", "OUTPUT", "NAME:=VALUE"))


def test_readme_synopses_name_only_real_options():
    for cmd in filter(_is_synopsis, readme_commands()):
        words = cmd.split()
        if len(words) < 2 or words[1].startswith("-") or words[1] == "node":
            continue            # node: its options after --ros-args are ROS arguments, checked by its tests
        shown = set(OPTION.findall(cmd.split("(section")[0])) - GENERIC
        unknown = shown - options_of(words[1])
        assert not unknown, f"README shows {sorted(unknown)} for glpma-fk {words[1]}, which has no such option"


#: how each concrete README command is checked: (exit status, words its output must contain)
README_CHECKS = {
    "glpma-fk --version": (0, ["glpma-fk"]),
    "glpma-fk solve planar_3rpr_seed --legs 100 120 150": (0, ["converged", "position", "orientation"]),
    "glpma-fk solve-all delta_irb360 --legs 0.021727 0.008779 0.199391": (0, ["2 distinct real assembly modes",
                                                                             "closed form"]),
    "glpma-fk solve delta_irb360 --legs 0.021727 0.008779 0.199391": (0, ["converged", "position"]),
    "glpma-fk solve-all linear_delta_kossel_mini --legs 286.699199 296.251580 274.211481": (
        0, ["2 distinct real assembly modes", "closed form"]),
    "glpma-fk urdf planar_3rpr_seed": (0, ["<robot", "leg1_actuator", "platform_mount"]),
}
#: README commands that need a running node: checked by test_readme_node_and_modes
NODE_COMMANDS = ("glpma-fk node ", "glpma-fk modes")


def test_every_concrete_readme_command_is_checked_here():
    concrete = [c for c in readme_commands() if not _is_synopsis(c)]
    unchecked = [c for c in concrete if c not in README_CHECKS and not c.startswith(NODE_COMMANDS)]
    assert not unchecked, f"README commands no test runs: {unchecked}"


@pytest.mark.parametrize("cmd", list(README_CHECKS))
def test_readme_command(cmd):
    assert cmd in readme_commands(), f"{cmd!r} is no longer in README.md: update README_CHECKS"
    code, words = README_CHECKS[cmd]
    p = glpma_fk(*cmd.split()[1:])
    assert p.returncode == code and "Traceback" not in p.stderr, p.stdout + p.stderr
    for w in words:
        assert w in p.stdout, (w, p.stdout)


def test_readme_node_and_modes(dds_env):
    """README's ``glpma-fk node --transport dds ...`` runs (as typed, from the repository root) and
    ``glpma-fk modes`` asks it; before any input the node says so (exit 1, one line)."""
    pytest.importorskip("cyclonedds", reason="Cyclone DDS Python binding not installed")
    node_cmd = next(c for c in readme_commands() if c.startswith("glpma-fk node ") and not _is_synopsis(c))
    modes_cmd = next(c for c in readme_commands() if c.startswith("glpma-fk modes") and not _is_synopsis(c))
    node = subprocess.Popen([sys.executable, "-m", "glpma_ros", *node_cmd.split()[1:]], cwd=ROOT, env=dds_env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline, lines = time.monotonic() + TIMEOUT_S, []
        while time.monotonic() < deadline:
            line = node.stdout.readline()
            if not line:
                break
            lines.append(line)
            if "ready" in line:
                break
        assert any("ready" in ln for ln in lines), "".join(lines)
        p = glpma_fk(*modes_cmd.split()[1:], "--timeout", 60, env=dds_env)
        assert p.returncode == 1 and "no input received yet" in p.stderr, p.stdout + p.stderr
        assert len(p.stderr.strip().splitlines()) == 1
    finally:
        interrupt(node)
    assert node.returncode == 0


def test_readme_scripts_exist_and_ci_runs_the_test_command():
    """The quick start's scripts exist; ``.ci/run`` calls the README's test command (the demo script
    runs ``glpma-fk demo``, run by test_demo.py; the test scripts are what CI runs)."""
    blocks = README.read_text()
    for script in re.findall(r"bash (tools/[\w.-]+\.sh)", blocks):
        assert (ROOT / script).is_file(), script
    assert "bash tools/test.sh" in (ROOT / ".ci" / "run").read_text()
    assert "glpma-fk demo" in (ROOT / "tools" / "demo.sh").read_text()


@pytest.mark.skipif(shutil.which("ros2") is None, reason="ROS 2 is not sourced (ros2 not on PATH)")
def test_readme_ros_commands_name_real_executables():
    """The README's ``ros2 run glpma_ros X`` executables are installed by this package."""
    from importlib.metadata import entry_points
    scripts = {e.name for e in entry_points(group="console_scripts")}
    for exe in set(re.findall(r"ros2 run glpma_ros (\S+)", README.read_text())):
        assert exe in scripts, exe


def test_the_floor_environment_tests_exactly_the_floors_of_setup_py():
    """tools/test-floor.sh installs exactly the lowest versions setup.py's install_requires accepts."""
    setup = (ROOT / "setup.py").read_text()
    requires = re.search(r"install_requires=\[([^\]]*)\]", setup).group(1)
    floors = dict(re.findall(r'"([\w.-]+)>=([\w.]+)"', requires))
    script = (ROOT / "tools" / "test-floor.sh").read_text()
    pinned = dict(re.findall(r"([\w.-]+)==([\w.]+)", re.search(r"FLOORS=\(([^)]*)\)", script).group(1)))
    from packaging.version import Version  # Version("1.24") == Version("1.24.0")
    assert {k.lower(): Version(v) for k, v in pinned.items()} == {k.lower(): Version(v) for k, v in floors.items()}
    assert "tools/test-floor.sh" in (ROOT / ".ci" / "run").read_text()
