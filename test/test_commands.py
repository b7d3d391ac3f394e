"""``glpma-fk``'s plug-in subcommands (entry-point group ``glpma_fk.commands``): the product's CLI
imports no tool, ``--help`` lists every installed command, and a command whose extra is not
installed is listed with, and refused with, the pip command that installs it."""
from __future__ import annotations

import importlib.metadata
import subprocess
import sys

import pytest

from glpma_ros.cli import main as cli
from glpma_ros.cli.api import Command
from glpma_ros.errors import InputError
from glpma_tools.parallel import EngineError


def _python(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          timeout=120).stdout


def test_help_imports_no_command_code():
    """``import glpma_ros.cli.main`` loads no glpma_tools module and no command; ``glpma-fk --help`` loads the
    commands' lines (glpma_ros.cli.commands, glpma_tools.commands) and none of their code."""
    out = _python("import contextlib, io, sys\n"
                  "import glpma_ros.cli.main as c\n"
                  "ours = lambda: sorted(m for m in sys.modules if m.startswith(('glpma_tools', 'glpma_ros.cli.')))\n"
                  "before = ours()\n"
                  "with contextlib.redirect_stdout(io.StringIO()) as help_text:\n"
                  "    code = c.main(['--help'])\n"
                  "print(','.join(before), ','.join(ours()), code, 'bench' in help_text.getvalue())")
    assert out.split() == ["glpma_ros.cli.api,glpma_ros.cli.main",
                           "glpma_ros.cli.api,glpma_ros.cli.commands,glpma_ros.cli.main,glpma_tools,glpma_tools.commands",
                           "0", "True"], out


def test_the_built_in_commands_are_entry_points_as_the_tools_are():
    installed = {ep.name: ep.value for ep in importlib.metadata.entry_points(group=cli.COMMANDS)}
    assert {"solve", "solve-all", "precompile", "modes", "node"} <= set(installed)
    assert all(isinstance(ep.load(), Command) for ep in cli.commands().values())


def test_help_lists_every_installed_command(capsys):
    installed = {ep.name for ep in importlib.metadata.entry_points(group=cli.COMMANDS)}
    assert {"bag", "bench", "demo", "map", "stress"} <= installed
    assert cli.main(["--help"]) == 0
    text = capsys.readouterr().out
    choices = text.split("{", 1)[1].split("}", 1)[0].split(",")
    assert installed <= set(choices), (installed, choices)
    for name in installed:           # each with its Command's line
        line = next(ln for ln in text.splitlines() if ln.strip().startswith(name + " "))
        assert len(line.split(None, 1)) == 2, line


@pytest.fixture
def without_matplotlib(monkeypatch):
    """As if matplotlib (every tool extra needs it) were not installed."""
    version = importlib.metadata.version

    def fake(name):
        if name.lower() == "matplotlib":
            raise importlib.metadata.PackageNotFoundError(name)
        return version(name)
    monkeypatch.setattr(importlib.metadata, "version", fake)


def test_without_the_extra_help_names_it_and_the_command_says_how_to_install(without_matplotlib, capsys):
    assert cli.missing_requirements("tools") == ["matplotlib"]      # the extra bench needs (its peers are optional)
    assert cli.missing_requirements("bag") == ["matplotlib"]     # rosbags, tqdm: installed with the tests
    assert cli.main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())          # argparse wraps the help lines
    for name, extra in (("bench", "tools"), ("demo", "tools"), ("bag", "bag"), ("map", "map")):
        assert f"pip install 'glpma_ros[{extra}]'" in text, (name, text)
    assert cli.main(["bench", "--quick"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: glpma-fk bench needs matplotlib: pip install 'glpma_ros[tools]' "
                   "(in a checkout: pip install -e '.[tools]')"], err


def test_a_command_main_turns_exits_and_errors_into_statuses(capsys):
    from glpma_ros.errors import GlpmaError

    @cli.command_main
    def main(argv):
        if argv == ["fail"]:
            raise GlpmaError("no such thing")
        return cli.OneLineParser(prog="x").parse_args(argv) and 0
    assert main(["--help"]) == 0
    assert main(["--bogus"]) == 2 and "error: x: unrecognized arguments: --bogus" in capsys.readouterr().err
    assert main(["fail"]) == 2 and capsys.readouterr().err == "error: no such thing\n"


def test_a_command_main_names_its_command_and_keeps_an_errors_own_status(capsys):
    """``command_main(prog=...)``: a GlpmaError's line names the command; a worker's failure
    (glpma_tools.parallel.EngineError) ends with its own status 1, any other GlpmaError with 2."""
    @cli.command_main(prog="glpma-fk x")
    def main(argv):
        raise (EngineError if argv == ["worker"] else InputError)("it went wrong")
    assert main(["worker"]) == 1 and capsys.readouterr().err == "error: glpma-fk x: it went wrong\n"
    assert main([]) == 2 and capsys.readouterr().err == "error: glpma-fk x: it went wrong\n"
