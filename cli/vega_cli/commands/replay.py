"""``vega replay BAG``: republish a run bag, or re-run the controller on its measurements.

``vega replay BAG [--rate R]`` publishes the recorded topics again (raw bytes, /clock
included) paced by their log times at R × real time (0: as fast as possible).
``vega replay BAG --check-controller [--table FILE]`` feeds the recorded INS measurements to a
fresh ``tvc_controller`` node and compares its commands with the recorded ones (every field
but ``compute_time_s``): exit status 0 identical, 1 different (the first difference is
printed), 2 bad input. See :mod:`vega_bags.replay`.
"""

from __future__ import annotations

import argparse
import signal
import sys

from vega_core.errors import BadArgument

__all__ = ["register"]


def _say(line: str) -> None:
    print(f"vega replay: {line}", file=sys.stderr, flush=True)


def _run(args: argparse.Namespace) -> int:
    from vega_bags import replay

    if args.check_controller:
        result = replay.check_controller(args.bag, args.table,
                                         barrier_timeout_s=args.barrier_timeout, progress=_say)
        print(result.summary())
        return result.exit_code
    if args.table:
        raise BadArgument("--table only applies with --check-controller")
    stopped = []
    previous = signal.signal(signal.SIGTERM, lambda *_: stopped.append(True))
    try:
        result = replay.play(args.bag, args.rate, wait_subscribers_s=args.wait_subscribers,
                             stop=lambda: bool(stopped), progress=_say)
    finally:
        signal.signal(signal.SIGTERM, previous)
    total = sum(result.counts.values())
    _say(f"published {total} messages ({', '.join(f'{k} {v}' for k, v in result.counts.items())})"
         f", {result.span_s:g} s of sim time in {result.wall_s:.2f} s"
         + (" (stopped)" if stopped else ""))
    return 0


def _rate(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value >= 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r}: must be a finite number >= 0")
    return value


def register(subparsers) -> None:
    """Add the ``replay`` sub-command."""
    p = subparsers.add_parser(
        "replay", help="republish a run bag, or check a controller against it",
        description="Republish the recorded topics of a run bag with /clock, paced by their "
                    "log times; or, with --check-controller, feed the recorded INS "
                    "measurements to a fresh tvc_controller node and compare its commands "
                    "with the recorded ones (exit status 0 identical, 1 different, 2 bad "
                    "input).")
    p.add_argument("bag", metavar="BAG", help="run bag directory (rosbag2, MCAP)")
    p.add_argument("--rate", type=_rate, default=1.0, metavar="R",
                   help="playback rate, sim seconds per wall second (default 1; 0 = as fast "
                        "as possible)")
    p.add_argument("--wait-subscribers", type=float, default=0.0, metavar="S",
                   help="first wait up to S seconds until every topic has a subscriber")
    p.add_argument("--check-controller", action="store_true",
                   help="re-run the controller on the recorded measurements and compare")
    p.add_argument("--table", metavar="FILE",
                   help="controller table for --check-controller (default: the one recorded "
                        "in the bag)")
    p.add_argument("--barrier-timeout", type=float, default=60.0, metavar="S",
                   help=argparse.SUPPRESS)
    p.set_defaults(func=_run)
