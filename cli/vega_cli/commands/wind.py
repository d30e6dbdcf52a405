"""``vega wind``: the statistical wind environment of a launch site (wind_environment).

``vega wind sample [--site FILE] --month M --n N --seed S --out OUT [--lag-s L] [--mode
full_speed|in_plane]`` draws N measured/flown wind profile pairs of month M from the site file
(default: the shipped Kourou file) and writes them to OUT — Parquet if OUT ends in ``.parquet``,
CSV if ``.csv`` — one row per sample and altitude (columns ``sample``, ``altitude_m``,
``measured_wind_mps``, ``flown_wind_mps``; docs/WINDS.md §7), with a plot of their percentile
bands next to it (OUT with the suffix ``.png``). Exit 0, or 2 on bad input (checked before
anything is drawn).
"""

from __future__ import annotations

import argparse
import math
import time

from vega_core.errors import BadArgument

__all__ = ["register"]

MAX_SAMPLES = 10_000
"""Largest ``--n``. Assumption (a memory bound, not a physical one): a sample is 301 altitudes
× 5 profiles of float64 held until written, 12 kB; 10 000 samples are 3 million rows and about
0.2 GB in memory, about 10 s to draw."""

MAX_LAG_S = 86_400.0
"""Largest ``--lag-s`` [s] (one day): the cited wind-change statistics reach 4 h; beyond, the
change is at its climatological saturation (docs/WINDS.md §5)."""


def _int_in(lo: int, hi: int):
    """argparse type: an integer in lo..hi."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be within {lo}..{hi}, got {text!r}")
        return value
    return parse


def _lag(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and 0.0 <= value <= MAX_LAG_S):
        raise argparse.ArgumentTypeError(f"must be within 0..{MAX_LAG_S:g} s, got {text!r}")
    return value


def _sample(args: argparse.Namespace) -> int:
    """``vega wind sample``: every input checked, then the profiles drawn and written."""
    from pathlib import Path

    from vega_bringup.planning import _checked_seed
    from vega_campaign.wind_environment import (load_site, plot_samples, sample_profiles,
                                                write_samples)

    out = Path(args.out)
    if out.suffix not in (".parquet", ".csv"):
        raise BadArgument(f"--out {out}: must end in .parquet or .csv")
    if out.is_dir():
        raise BadArgument(f"--out {out}: is a directory")
    seed = _checked_seed(args.seed)
    site = load_site(args.site)                  # a bad site file: one line, exit 2
    t0 = time.monotonic()
    print(f"vega wind: {args.n} profiles of month {args.month} from {site.path} (seed {seed}, "
          f"lag {args.lag_s:g} s, mode {args.mode})", flush=True)
    samples = sample_profiles(site, args.month, n=args.n, seed=seed, lag_s=args.lag_s,
                              mode=args.mode)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_samples(samples, out)
    png = plot_samples(samples, out.with_suffix(".png"), site.name)
    rows = samples.measured_wind_mps.size
    print(f"vega wind: wrote {out} ({rows} rows: {args.n} samples x "
          f"{samples.altitude_m.size} altitudes 0-{samples.altitude_m[-1]:g} m), {png} "
          f"in {time.monotonic() - t0:.1f} s")
    return 0


def _no_action(args) -> int:
    raise BadArgument("vega wind: choose an action (sample)")


def register(subparsers) -> None:
    """Add the ``wind`` sub-command (action ``sample``)."""
    from vega_campaign.wind_environment import DEFAULT_LAG_S, DEFAULT_MODE, MODES

    parser = subparsers.add_parser(
        "wind", help="statistical wind environment of a launch site",
        description="Sample the wind profiles of a launch site's monthly statistics: the "
                    "sounding (measured) and what the vehicle meets (flown).")
    parser.set_defaults(func=_no_action)
    actions = parser.add_subparsers(dest="action", metavar="ACTION")
    sample = actions.add_parser(
        "sample", help="draw measured/flown profile pairs to Parquet or CSV",
        description="N measured/flown wind profile pairs of month M (sample i depends on the "
                    "seed, the month and i only), written one row per sample and altitude "
                    "(sample, altitude_m, measured_wind_mps, flown_wind_mps; in-plane m/s, + "
                    "toward downrange) with a percentile plot OUT.png. Exit 0, 2 on bad input.")
    sample.add_argument("--site", default=None, metavar="FILE",
                        help="site file (default: the shipped "
                             "offline/vega_campaign/data/sites/kourou.yaml)")
    sample.add_argument("--month", type=_int_in(1, 12), required=True, metavar="M",
                        help="month 1-12")
    sample.add_argument("--n", type=_int_in(1, MAX_SAMPLES), required=True, metavar="N",
                        help=f"number of samples (1..{MAX_SAMPLES})")
    sample.add_argument("--seed", default="0", metavar="S", help="seed (default 0)")
    sample.add_argument("--out", required=True, metavar="OUT",
                        help="output table, .parquet or .csv (the plot goes to OUT.png)")
    sample.add_argument("--lag-s", type=_lag, default=DEFAULT_LAG_S, metavar="L",
                        help=f"time from the sounding to lift-off [s] (default "
                             f"{DEFAULT_LAG_S:g})")
    sample.add_argument("--mode", choices=MODES, default=DEFAULT_MODE,
                        help=f"in-plane wind: the whole speed (full_speed) or the projection "
                             f"on the flight azimuth (in_plane); default {DEFAULT_MODE}")
    sample.set_defaults(func=_sample)
