"""``vega check BAG``: the requirements (thesis Table 3.1) and the run's health from a bag.

Prints the requirement table (thesis Table 5.1 form, with margins), the health checks and the
verdict (:mod:`vega_bags.bagcheck`). Exit status: 0 if everything passes, 1 if a requirement
or a health check fails, 2 for a bad bag (missing, corrupt, foreign: one line on stderr).
``--json FILE`` also writes the verdict as JSON; ``--report DIR`` the run report
(:func:`vega_bags.report.write_report`: JSON, Markdown, PNG plots), as ``vega sil run`` does.
"""

from __future__ import annotations

import argparse

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from vega_bags.bagcheck import check_bag
    from vega_sim.requirements import load_requirements

    spec = load_requirements(args.requirements) if args.requirements else None
    if args.report:
        from vega_bags.report import write_report

        result = write_report(args.bag, args.report, spec)
    else:
        result = check_bag(args.bag, spec)
    print(result.table())
    if args.json:
        result.write_json(args.json)
    return result.exit_code


def register(subparsers) -> None:
    """Add the ``check`` sub-command."""
    p = subparsers.add_parser(
        "check", help="check a run bag against the requirements (exit status = verdict)",
        description="Compute the requirements of thesis Table 3.1 (Qα within its envelope "
                    "over Mach — 4°·Q_nom(M), floored below Mach 0.31, docs/REQUIREMENTS.md; "
                    "the 3°·Q objective printed as an informational line — |z| < 500 m, "
                    "|ż| < 15 m/s, |β| < 6.5° on the actuator angle, "
                    "∫|β|dt < 250 °s) and the run's health (no NaN, no message gaps, no "
                    "lockstep stalls, complete span, controller compute time within its "
                    "12 ms budget) from a run bag alone. Exit status 0: all pass; 1: "
                    "something fails; 2: bad bag.")
    p.add_argument("bag", metavar="BAG", help="run bag directory (rosbag2, MCAP)")
    p.add_argument("--json", metavar="FILE", help="also write the verdict as JSON to FILE")
    p.add_argument("--report", metavar="DIR",
                   help="also write the run report (JSON, Markdown, PNG plots) into DIR")
    p.add_argument("--requirements", metavar="FILE",
                   help="requirement file (default: the shipped vega_sim/config/"
                        "requirements.yaml)")
    p.set_defaults(func=_run)
