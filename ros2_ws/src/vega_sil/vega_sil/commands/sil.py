"""``vega sil``: software-in-the-loop runs (placeholder until the SIL issue lands)."""

import argparse
import sys

__all__ = ["register"]


def _run(args):
    """Say that SIL runs are not available yet; exit status 2."""
    print("vega sil: not yet: SIL lands with the SIL issue", file=sys.stderr)
    return 2


def register(subparsers):
    """Add the ``sil`` sub-command."""
    parser = subparsers.add_parser(
        "sil", help="software-in-the-loop runs (not yet available)",
        description="Fly a scenario through the ROS 2 node graph, record a bag and check the "
                    "requirements. Not available yet: it lands with the SIL issue.")
    parser.add_argument("action", nargs=argparse.REMAINDER, metavar="ACTION ...",
                        help="what to do, e.g. run")
    parser.set_defaults(func=_run)
