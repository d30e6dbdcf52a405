"""``vega plots``: figures of the model and of the synthesised controller as PNG files."""

from __future__ import annotations

import argparse

__all__ = ["register"]


def _model(args: argparse.Namespace) -> int:
    from vega_lpv.model_plots import plot_model

    for path in plot_model(args.out):
        print(path)
    return 0


def _synthesis(args: argparse.Namespace) -> int:
    from vega_lpv.synthesis_plots import plot_synthesis

    for path in plot_synthesis(args.out, args.table, simulate=not args.no_simulation):
        print(path)
    return 0


def register(subparsers) -> None:
    """Add the ``plots`` sub-command with its ``model`` and ``synthesis`` views."""
    p = subparsers.add_parser("plots", help="write figures (PNG)")
    views = p.add_subparsers(dest="view", required=True, metavar="VIEW")
    m = views.add_parser("model", help="frozen-time Bode θ_INS/β and pole-zero maps at the "
                                       "grid times (thesis Fig. 2.11)")
    m.add_argument("--out", required=True, metavar="DIR", help="output directory")
    m.set_defaults(func=_model)
    s = views.add_parser("synthesis", help="weights, closed-loop Bode at the grid points, pole "
                                           "maps and the thesis-scenario time histories of a "
                                           "controller table")
    s.add_argument("--out", required=True, metavar="DIR", help="output directory")
    s.add_argument("--table", metavar="FILE",
                   help="controller table (default: the committed lpv_controller.npz)")
    s.add_argument("--no-simulation", action="store_true",
                   help="skip the time histories (the thesis scenario, ~10 s)")
    s.set_defaults(func=_synthesis)
