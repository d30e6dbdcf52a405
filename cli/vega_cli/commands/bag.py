"""``vega bag``: maintenance of run bags.

``vega bag repair BAG`` rebuilds the summary and ``metadata.yaml`` of a bag whose recorder was
killed (vega_bags.repair): every message of every complete chunk is kept, the cut file stays
beside it as ``*.mcap.truncated``. Exit 0 repaired, 2 bad input (not a bag, a closed bag, no run
metadata).
"""

from __future__ import annotations

import argparse

from vega_core.errors import BadArgument

__all__ = ["register"]


def _repair(args: argparse.Namespace) -> int:
    from vega_bags.repair import repair_bag

    print(repair_bag(args.bag).text())
    return 0


def _no_action(args) -> int:
    raise BadArgument("vega bag: choose an action (repair)")


def register(subparsers) -> None:
    """Add the ``bag`` sub-command (action ``repair``)."""
    parser = subparsers.add_parser("bag", help="maintenance of run bags (repair)",
                                   description="Maintenance of run bags.")
    parser.set_defaults(func=_no_action)
    actions = parser.add_subparsers(dest="action", metavar="ACTION")
    repair = actions.add_parser(
        "repair", help="make a bag whose recorder was killed readable again",
        description="Rebuild the MCAP summary and metadata.yaml of a run bag that was not "
                    "closed, from the complete chunks on disk and the run metadata written "
                    "when the bag was opened; the cut file is kept as *.mcap.truncated.")
    repair.add_argument("bag", metavar="BAG", help="bag directory")
    repair.set_defaults(func=_repair)
