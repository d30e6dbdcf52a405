"""``vega plots``: figures of the model (and, later, of the synthesis) as PNG files."""

from __future__ import annotations

import argparse

__all__ = ["register"]


def _model(args: argparse.Namespace) -> int:
    from offline_synthesis.model_plots import plot_model

    for path in plot_model(args.out):
        print(path)
    return 0


def register(subparsers) -> None:
    """Add the ``plots`` sub-command with its ``model`` view."""
    p = subparsers.add_parser("plots", help="write figures (PNG)")
    views = p.add_subparsers(dest="view", required=True, metavar="VIEW")
    m = views.add_parser("model", help="frozen-time Bode θ_INS/β and pole-zero maps at the "
                                       "grid times (thesis Fig. 2.11)")
    m.add_argument("--out", required=True, metavar="DIR", help="output directory")
    m.set_defaults(func=_model)
