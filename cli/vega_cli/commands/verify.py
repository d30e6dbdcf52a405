"""``vega verify TABLE [--out DIR]``: the sign-off checks of a controller table
(:mod:`vega_cli.signoff.verify`; docs/FLIGHT_DESIGN.md §6.5).

Runs the SIL verdict scenarios, ``vega margins --dispersed``, ``vega robust --no-mu``, an
852-flight thesis-box campaign and a 1 440-sample flight-day campaign on TABLE, writes
DIR/verify.json (the sign-off record ``vega ship`` reads) and prints one line per check. Exit
status: 0 when every gated check passes, 1 when one fails (or the table file changed while the
checks ran), 2 on bad input (one line, before anything runs).
"""

from __future__ import annotations

import argparse

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from vega_cli.commands.margins import parse_at
    from vega_cli.signoff.verify import default_out, plan, verify

    p = plan(args.table, args.out if args.out else default_out(), checks=args.checks,
             scenarios=args.scenarios, runs=args.runs, mc_reference=args.mc_reference,
             flight_day_runs=args.flight_day_runs, workers=args.workers, at=args.at,
             heldout_reference=args.heldout_reference)
    if {"margins", "robust"} & set(p.checks):
        parse_at(args.at)                       # a bad --at: one line, before anything runs
    return 0 if verify(p)["signed_off"] else 1


def register(subparsers) -> None:
    """Add the ``verify`` sub-command."""
    from vega_cli.signoff.record import CHECKS, GATED_SCENARIOS, REPORTED_SCENARIOS
    from vega_cli.signoff.verify import (DEFAULT_AT, DEFAULT_FLIGHT_DAY_RUNS, DEFAULT_RUNS,
                                         MAX_RUNS, MAX_WORKERS)

    p = subparsers.add_parser(
        "verify", help="the sign-off checks of a controller table (≈ 25 min)",
        description="Run the sign-off checks of a controller table — SIL verdict scenarios "
                    "(gated: " + ", ".join(GATED_SCENARIOS) + "; reported: "
                    + ", ".join(REPORTED_SCENARIOS) + "), `vega margins --dispersed` "
                    "(0 unstable dispersed loops, the exact bending criterion everywhere), "
                    "`vega robust --no-mu`, a thesis-box Monte Carlo campaign (0 unstable "
                    "flights, at least --mc-reference passes), a flight-day campaign (99.73 % "
                    "at 90 % shown, 0 unstable, 0 rate-limited, the design's availability "
                    "≥ 90 % every month) — and write OUT/verify.json, the record "
                    "`vega ship` installs a table with. Exit 0 every gated check passed, 1 one "
                    "failed (or TABLE changed while the checks ran), 2 bad input.")
    p.add_argument("table", metavar="TABLE", help="controller table (.npz)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="where the logs, results and verify.json go (must not exist or be "
                        "empty; default: bags/verify-<UTC time>)")
    p.add_argument("--checks", default=",".join(CHECKS), metavar="A,B",
                   help=f"checks to run (default: {','.join(CHECKS)})")
    p.add_argument("--scenarios", default=",".join(GATED_SCENARIOS + REPORTED_SCENARIOS),
                   metavar="A,B", help="SIL scenarios (default: every gated and reported one)")
    p.add_argument("--runs", type=int, default=DEFAULT_RUNS, metavar="N",
                   help=f"flights of the thesis-box campaign (1..{MAX_RUNS}; default "
                        f"{DEFAULT_RUNS})")
    p.add_argument("--flight-day-runs", type=int, default=DEFAULT_FLIGHT_DAY_RUNS, metavar="N",
                   help=f"samples of the flight-day campaign (1..{MAX_RUNS}; default "
                        f"{DEFAULT_FLIGHT_DAY_RUNS})")
    p.add_argument("--mc-reference", type=int, default=None, metavar="PASSED",
                   help="passes the campaign must reach (those of the flown table's sign-off)")
    p.add_argument("--workers", type=int, default=2, metavar="K",
                   help=f"worker processes of margins, robust and mc (1..{MAX_WORKERS}; "
                        "default 2)")
    p.add_argument("--at", default=DEFAULT_AT, metavar="T|START:STOP:STEP",
                   help=f"frozen times of margins and robust (default {DEFAULT_AT}, the "
                        "flight)")
    p.add_argument("--heldout-reference", default=None, metavar="CAMPAIGN_DIR",
                   help="a campaign of the reference table on a held-out seed: TABLE is flown "
                        "on its samples and compared flight by flight (reported, not gated)")
    p.set_defaults(func=_run)
