"""``vega ship VERIFY_DIR``: install a signed-off controller table as the flown default
(:mod:`vega_cli.signoff.ship`; docs/FLIGHT_DESIGN.md §6.5).

Copies the table, its tuning record and its sign-off record into the flown table's directory
only when VERIFY_DIR/verify.json is a complete, passed sign-off of the table's own bytes.
``--check`` checks the same and writes nothing. Exit status: 0 shipped (or, with ``--check``,
shippable), 2 refused (one line, nothing written).
"""

from __future__ import annotations

import argparse

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from vega_cli.signoff.record import signed_off_passes
    from vega_cli.signoff.ship import CONFIG, NAME, ship

    config = Path(args.config) if args.config else CONFIG
    shipped = ship(Path(args.verify_dir), Path(args.table) if args.table else None, config,
                   write=not args.check)
    what = (f"vega ship: {shipped['shipped_from']} (SHA-256 {shipped['table_sha256'][:12]}…, "
            f"{signed_off_passes(shipped)} of {shipped['scope']['runs']} flights)")
    if args.check:
        print(f"{what}: a complete sign-off of these bytes; nothing written (--check)")
    else:
        print(f"{what} is the flown table now: {config / NAME}.npz, .json, .signoff.json; "
              "run make test")
    return 0


def register(subparsers) -> None:
    """Add the ``ship`` sub-command."""
    from vega_cli.signoff.record import FULL_FLIGHT_AT, MIN_RUNS
    from vega_cli.signoff.ship import CONFIG, ROOT

    p = subparsers.add_parser(
        "ship", help="install a signed-off controller table as the flown default",
        description="Install the table signed off in VERIFY_DIR (the --out of `vega verify`) "
                    "as the flown default: the table, its tuning record (.json beside it) and "
                    "the sign-off record, each written by a rename of a complete file. "
                    "Refused (exit 2, nothing written) unless verify.json is signed off with "
                    f"every check and gated scenario, frozen times {FULL_FLIGHT_AT}, at least "
                    f"{MIN_RUNS} flights and a Monte Carlo reference no lower than the flown "
                    "table's own passes, and the table's SHA-256 is the recorded one.")
    p.add_argument("verify_dir", metavar="VERIFY_DIR", help="the --out directory of vega verify")
    p.add_argument("--table", default=None, metavar="FILE",
                   help="the table, if it moved since it was verified (its SHA-256 is checked)")
    p.add_argument("--config", default=None, metavar="DIR",
                   help=f"the flown table's directory (default {CONFIG.relative_to(ROOT)})")
    p.add_argument("--check", action="store_true",
                   help="check the record and the table, write nothing")
    p.set_defaults(func=_run)
