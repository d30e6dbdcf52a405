"""The ``vega`` command line: one entry point, one module per sub-command.

Each name in :data:`COMMANDS` is a module ``vega_cli.commands.<name>`` exporting
``register(subparsers)``, which adds its sub-parser and sets ``func``: a callable taking the
parsed arguments and returning an exit status (``None`` means 0). A module that does not exist
yet is left out of the command line; one that exists but fails to import still gets its
sub-command, which then reports the import error, so one broken module never takes the whole
command line down. Command modules import heavy libraries (numpy, rclpy, ...) inside ``func``.

Before anything else, :func:`main` applies the project's ROS environment to the process
(:func:`vega_bringup.rosenv.configure_current_process`): LOCALHOST discovery and a ROS_DOMAIN_ID
picked for this invocation unless the caller set one.

Errors (:mod:`vega_core.errors`): the libraries raise :class:`~vega_core.errors.BadInput`
(or a subclass) with a one-line message for input the user can correct, and ``OSError`` for
files; both are printed as ``vega: error: <message>`` on one line to stderr with exit status 2,
like argparse's own usage errors (one line too, without the usage block:
:class:`_Parser`). Any other exception (a ``ValueError`` from numpy, a
``KeyError``, ...) is a defect, not the user's mistake: :func:`main` prints its traceback and a
last line ``vega: internal error: …`` to stderr and returns 1 (it does not re-raise, so that
callers and tests get the status like any other). A closed stdout (``vega … | head``) exits 0;
Ctrl-C exits 130.
"""

import argparse
import importlib
import os
import shlex
import sys
import traceback

from vega_core.errors import BadInput, one_line

from vega_bringup import rosenv

__all__ = ["COMMANDS", "build_parser", "main"]

COMMANDS = ("trajectory", "linearize", "plots", "synth", "design", "guidance", "margins",
            "robust", "sil", "mc", "wind", "verify", "ship", "check", "bag", "replay", "node")
"""Sub-command modules, in the order ``vega --help`` lists them."""

_PRINTED_VARIABLES = (
    "ROS_DOMAIN_ID",
    "ROS_AUTOMATIC_DISCOVERY_RANGE",
    "ROS_LOCALHOST_ONLY",
    "ROS_STATIC_PEERS",
    "RMW_IMPLEMENTATION",
    "AMENT_PREFIX_PATH",
    "VIRTUAL_ENV",
)


def _register_unavailable(subparsers, name, error):
    """Add sub-command ``name`` whose module failed to import; running it reports ``error``."""
    reason = f"{type(error).__name__}: {one_line(error)}"
    parser = subparsers.add_parser(name, help=f"(unavailable: {reason})", add_help=False)
    parser.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)

    def _fail(args):
        raise BadInput(f"sub-command {name!r} is unavailable: {reason}")

    parser.set_defaults(func=_fail)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, ``vega: error: <prog>: <message>``
    (the sub-command named without the leading ``vega``), exit status 2 — no usage block, like
    every other input error of the command line. ``--help`` prints the full help as before.
    Sub-parsers (``add_subparsers``) are of the parser's own class, so every level gets it."""

    def error(self, message):
        where = self.prog.partition(" ")[2]
        prefix = f"{where}: " if where else ""
        self.exit(2, f"vega: error: {prefix}{one_line(message)} (see {self.prog} --help)\n")


def build_parser():
    """Build the ``vega`` argument parser with every sub-command module that exists.

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = _Parser(
        prog="vega",
        description="VEGA thrust-vector-control tools: trajectory, linearisation, synthesis, "
                    "software-in-the-loop runs, bag checks, replay, plots and ROS 2 nodes.")
    parser.add_argument("--print-env", action="store_true", help=argparse.SUPPRESS)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module_name = f"vega_cli.commands.{name}"
        try:
            module = importlib.import_module(module_name)
            register = module.register
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                continue
            _register_unavailable(subparsers, name, exc)
        except (ImportError, AttributeError, SyntaxError) as exc:
            _register_unavailable(subparsers, name, exc)
        else:
            register(subparsers)
    return parser


def _print_environment():
    """Print the ROS-related variables in force as shell lines (``--print-env``)."""
    for name in _PRINTED_VARIABLES:
        value = os.environ.get(name)
        print(f"unset {name}" if value is None else f"{name}={shlex.quote(value)}")


def main(argv=None):
    """Run the ``vega`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name. Default: ``sys.argv[1:]``.

    Returns
    -------
    int
        Exit status: 0 on success, 2 on a usage or input error (:class:`BadInput`,
        ``OSError``), 1 on an internal error (any other exception: a defect, printed with its
        traceback), 130 on Ctrl-C, else the sub-command's status.
    """
    caller_domain_id = os.environ.get("ROS_DOMAIN_ID", "").strip()
    try:
        domain_id = rosenv.configure_current_process()
    except BadInput as exc:  # rosenv.DomainIdError: the caller's ROS_DOMAIN_ID
        print(f"vega: error: {one_line(exc)}", file=sys.stderr)
        return 2
    parser = build_parser()
    args = parser.parse_args(argv)
    args.ros_domain_id = domain_id
    args.ros_domain_id_picked = not caller_domain_id
    if args.print_env:
        _print_environment()
        return 0
    if getattr(args, "func", None) is None:
        print("vega: error: a COMMAND is required (see vega --help)", file=sys.stderr)
        return 2
    try:
        status = args.func(args)
    except BrokenPipeError:
        # the reader went away (`vega linearize ... | head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (BadInput, OSError) as exc:
        print(f"vega: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # noqa: BLE001 - a defect: show where, never as the user's mistake
        traceback.print_exc()
        print(f"vega: internal error: {type(exc).__name__}: {one_line(exc)} (a defect, not "
              f"bad input; the traceback above says where)", file=sys.stderr)
        return 1
    return 0 if status is None else int(status)


if __name__ == "__main__":
    sys.exit(main())
