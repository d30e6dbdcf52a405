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

Errors: the libraries raise ``ValueError`` (or subclasses) with one-line messages for bad
input, and ``OSError`` for files; both are printed as ``vega: error: <message>`` on one line
to stderr with exit status 2, like argparse's own usage errors.
"""

import argparse
import importlib
import os
import shlex
import sys

from vega_bringup import rosenv

__all__ = ["COMMANDS", "build_parser", "main"]

COMMANDS = ("trajectory", "linearize", "plots", "synth", "sil", "check", "replay", "node")
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
    reason = f"{type(error).__name__}: {error}".replace("\n", " ")
    parser = subparsers.add_parser(name, help=f"(unavailable: {reason})", add_help=False)
    parser.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)

    def _fail(args):
        raise ValueError(f"sub-command {name!r} is unavailable: {reason}")

    parser.set_defaults(func=_fail)


def build_parser():
    """Build the ``vega`` argument parser with every sub-command module that exists.

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = argparse.ArgumentParser(
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
        Exit status: 0 on success, 2 on a usage or input error, 130 on Ctrl-C, else the
        sub-command's status.
    """
    caller_domain_id = os.environ.get("ROS_DOMAIN_ID", "").strip()
    try:
        domain_id = rosenv.configure_current_process()
    except ValueError as exc:
        print(f"vega: error: {exc}", file=sys.stderr)
        return 2
    parser = build_parser()
    args = parser.parse_args(argv)
    args.ros_domain_id = domain_id
    args.ros_domain_id_picked = not caller_domain_id
    if args.print_env:
        _print_environment()
        return 0
    if getattr(args, "func", None) is None:
        parser.print_usage(sys.stderr)
        print("vega: error: a COMMAND is required (see vega --help)", file=sys.stderr)
        return 2
    try:
        status = args.func(args)
    except BrokenPipeError:
        # the reader went away (`vega linearize ... | head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (ValueError, OSError) as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        print(f"vega: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    return 0 if status is None else int(status)


if __name__ == "__main__":
    sys.exit(main())
