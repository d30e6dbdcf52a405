"""Shared check of a refused command line: exit 2 and one line on stderr naming the problem."""

from vega_cli import cli

__all__ = ["assert_refused"]


def assert_refused(argv, capsys, message):
    """Run ``vega ARGV`` in process (argparse's own errors raise SystemExit) and assert exit
    status 2 with ``message`` on a single stderr line."""
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
