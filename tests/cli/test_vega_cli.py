"""The ``vega`` command-line skeleton: sub-command discovery, errors, ``sil`` and ``node``.

Run in-process through :func:`vega_cli.cli.main` (``vega node`` only on its error paths: on
success it replaces the process; tests/cli/test_environment.py runs it for real).
"""

import sys
import types

import pytest

from vega_cli import cli
from vega_core.errors import BadInput


def _fake_command_module(name, error):
    """A command module whose sub-command ``name`` raises ``error``."""
    module = types.ModuleType(f"vega_cli.commands.{name}")

    def _fail(args):
        raise error

    def register(subparsers):
        subparsers.add_parser(name).set_defaults(func=_fail)

    module.register = register
    return module


def test_help_lists_existing_commands_only(capsys):
    """``vega --help`` exits 0 and lists sil and node; modules not written yet are skipped."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "sil" in out and "node" in out
    assert "unavailable" not in out


def test_missing_module_is_skipped(monkeypatch):
    """A name in COMMANDS without a module does not break the command line."""
    monkeypatch.setattr(cli, "COMMANDS", ("no_such_command_module", "sil"))
    parser = cli.build_parser()
    assert parser.parse_args(["sil", "run"]).command == "sil"
    with pytest.raises(SystemExit):
        parser.parse_args(["no_such_command_module"])


def test_broken_module_reports_itself(monkeypatch, capsys):
    """A module that cannot register gets a sub-command that says why, in one line."""
    monkeypatch.setattr(cli, "COMMANDS", ("broken", "sil"))
    monkeypatch.setitem(sys.modules, "vega_cli.commands.broken",
                        types.ModuleType("vega_cli.commands.broken"))
    assert cli.main(["broken"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vega: error: sub-command 'broken' is unavailable: AttributeError")
    assert err.count("\n") == 1


@pytest.mark.parametrize("error, message", [
    (BadInput("bad input:\n  line two"), "bad input: line two"),
    (FileNotFoundError(2, "No such file or directory", "table.yaml"),
     "[Errno 2] No such file or directory: 'table.yaml'"),
])
def test_errors_print_one_line_and_exit_2(monkeypatch, capsys, error, message):
    """BadInput and OSError from a sub-command: ``vega: error: <message>``, exit status 2
    (any other exception is a defect: tests/core/test_errors.py)."""
    monkeypatch.setattr(cli, "COMMANDS", ("explode",))
    monkeypatch.setitem(sys.modules, "vega_cli.commands.explode",
                        _fake_command_module("explode", error))
    assert cli.main(["explode"]) == 2
    assert capsys.readouterr().err == f"vega: error: {message}\n"


def test_no_command_is_a_usage_error(capsys):
    """``vega`` alone: usage on stderr, exit status 2."""
    assert cli.main([]) == 2
    assert "vega: error: a COMMAND is required" in capsys.readouterr().err


def test_unknown_command_is_a_usage_error():
    """argparse's usage errors keep exit status 2."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["no-such-command"])
    assert exit_info.value.code == 2


@pytest.mark.parametrize("argv, line", [
    (["no-such-command"], "vega: error: argument COMMAND: invalid choice: 'no-such-command' "),
    (["--no-such-option"], "vega: error: unrecognized arguments: --no-such-option "
                           "(see vega --help)"),
    (["sil", "run", "--seed"], "vega: error: sil run: argument --seed: expected one argument "
                               "(see vega sil run --help)"),
    (["sil", "run", "--scenario"], "vega: error: sil run: argument --scenario: expected one "
                                   "argument (see vega sil run --help)"),
    (["sil", "run", "--bogus"], "vega: error: unrecognized arguments: --bogus"),
    (["plots"], "vega: error: plots: the following arguments are required: VIEW "
                "(see vega plots --help)"),
    (["replay", ".", "--rate", "-1"], "vega: error: replay: argument --rate: '-1': must be a "
                                      "finite number >= 0"),
])
def test_argparse_errors_are_one_line_without_the_usage_block(capsys, argv, line):
    """Every level of the parser (``vega``, ``vega sil``, ``vega sil run``, ...): one line
    ``vega: error: …`` on stderr, exit status 2, no ``usage:`` block."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(argv)
    assert exit_info.value.code == 2
    captured = capsys.readouterr()
    assert captured.err.startswith(line), captured.err
    assert captured.err.count("\n") == 1 and "usage:" not in captured.err
    assert captured.out == ""


@pytest.mark.parametrize("argv", [["--help"], ["sil", "--help"], ["sil", "run", "--help"],
                                  ["plots", "model", "--help"]])
def test_help_still_prints_the_full_help(capsys, argv):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(argv)
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: vega {' '.join(argv[:-1])}".rstrip()) and "options:" in out


def test_node_unknown_package(capsys):
    """``vega node`` with a package missing from the ament index: one-line error, exit 2."""
    assert cli.main(["node", "no_such_package", "talker"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vega: error: package 'no_such_package' not found in the ament index")
    assert err.count("\n") == 1


def test_node_unknown_executable(capsys, tmp_path, monkeypatch):
    """``vega node`` with an executable the package lacks lists the ones it has."""
    prefix = tmp_path / "prefix"
    marker = prefix / "share" / "ament_index" / "resource_index" / "packages" / "vega_fake"
    marker.parent.mkdir(parents=True)
    marker.write_text("")
    lib = prefix / "lib" / "vega_fake"
    lib.mkdir(parents=True)
    for name, mode in (("talker", 0o755), ("listener", 0o755), ("notes.txt", 0o644)):
        (lib / name).write_text("#!/bin/sh\n")
        (lib / name).chmod(mode)
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    assert cli.main(["node", "vega_fake", "notes.txt"]) == 2
    assert capsys.readouterr().err == (
        "vega: error: no executable 'notes.txt' in package 'vega_fake' "
        "(available: listener, talker)\n")
    assert cli.main(["node", "vega_fake", "../vega_fake/talker"]) == 2
    assert "no executable" in capsys.readouterr().err


def test_node_passes_ros_args_through():
    """Everything after EXE, options included, belongs to the executable."""
    args = cli.build_parser().parse_args(
        ["node", "vega_plant", "plant", "--ros-args", "--params-file", "p.yaml", "-h"])
    assert (args.package, args.executable) == ("vega_plant", "plant")
    assert args.arguments == ["--ros-args", "--params-file", "p.yaml", "-h"]
