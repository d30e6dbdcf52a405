"""``vega wind``: the statistical wind environment of a launch site (wind_environment).

``vega wind sample [--site FILE] --month M --n N --seed S --out OUT [--lag-s L] [--mode
full_speed|in_plane]`` draws N measured/flown wind profile pairs of month M from the site file
(default: the shipped Kourou file) and writes them to OUT — Parquet if OUT ends in ``.parquet``,
CSV if ``.csv`` — one row per sample and altitude (columns ``sample``, ``altitude_m``,
``measured_wind_mps``, ``flown_wind_mps``; docs/WINDS.md §7), with a plot of their percentile
bands next to it (OUT with the suffix ``.png``). Exit 0, or 2 on bad input (checked before
anything is drawn).

``vega wind capability [--table FILE] [--site FILE --month M] [--out DIR] [--workers N]``
searches the vehicle's wind capability (vega_analysis.capability; docs/WINDS.md, "The vehicle's
capability"): the largest wind change per altitude band after re-biasing on a measured profile
(calm, or month M's mean speed profile of the site file), and the largest upper-wind jet,
re-biased on it, with the shipped reference and with no bias. Writes DIR/capability.csv,
capability.json and two plots. Exit 0, or 2 on bad input (checked before anything is flown).
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


DEFAULT_CAPABILITY_OUT = "campaigns"
"""Parent of the default ``--out`` of ``vega wind capability`` (``campaigns/capability-calm``
or ``campaigns/capability-month<M>``), beside the Monte Carlo campaigns."""

MAX_SEARCH_STEPS = 4096
"""Largest ``--cap-mps`` / ``--resolution-mps``. Assumption (a sanity bound): the search flies
about log2 of it per band and sign, 13 at most."""


def _km_bands(text: str) -> tuple[tuple[float, float], ...]:
    """argparse type: ``LO-HI[,LO-HI...]`` in km, 0 <= LO < HI <= 30 (the profile's top)."""
    bands = []
    for item in text.split(","):
        lo, sep, hi = item.strip().partition("-")
        try:
            band = (float(lo), float(hi))
        except ValueError:
            raise argparse.ArgumentTypeError(f"not LO-HI in km: {item.strip()!r}") from None
        if not (sep and all(math.isfinite(x) for x in band) and 0 <= band[0] < band[1] <= 30):
            raise argparse.ArgumentTypeError(
                f"must be LO-HI with 0 <= LO < HI <= 30 km, got {item.strip()!r}")
        bands.append(band)
    return tuple(bands)


def _km_centres(text: str) -> tuple[float, ...]:
    """argparse type: jet centres ``C[,C...]`` in km, 3 <= C <= 27 (the jet, ± 3 km, inside
    the 0–30 km profile)."""
    out = []
    for item in text.split(","):
        try:
            c = float(item)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {item.strip()!r}") from None
        if not (math.isfinite(c) and 3.0 <= c <= 27.0):
            raise argparse.ArgumentTypeError(f"must be within 3..27 km, got {item.strip()!r}")
        out.append(c)
    return tuple(out)


def _speed(text: str) -> float:
    """argparse type: a speed in (0, 100] m/s."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and 0.0 < value <= 100.0):
        raise argparse.ArgumentTypeError(f"must be within (0, 100] m/s, got {text!r}")
    return value


def _capability(args: argparse.Namespace) -> int:
    """``vega wind capability``: every input checked, then the searches flown and written."""
    from pathlib import Path

    from vega_analysis.capability import (calm_profile, capability, check_amplitudes,
                                          month_mean_profile, write_capability)
    from vega_gnc.controller_table import default_table_path, load_controller_table

    if args.site is not None and args.month is None:
        raise BadArgument("--site FILE needs --month M (the month whose mean profile is "
                          "measured)")
    for name, cap in (("--cap-mps", args.cap_mps), ("--upper-cap-mps", args.upper_cap_mps)):
        if args.resolution_mps > cap:
            raise BadArgument(f"--resolution-mps {args.resolution_mps:g} exceeds {name} "
                              f"{cap:g}")
        if cap / args.resolution_mps > MAX_SEARCH_STEPS:
            raise BadArgument(f"{name} / --resolution-mps must be <= {MAX_SEARCH_STEPS}, got "
                              f"{cap / args.resolution_mps:g}")
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise BadArgument(f"--out {out}: must not exist or be an empty directory")
    table = Path(args.table) if args.table else default_table_path()
    load_controller_table(table)                 # a bad table: one line, exit 2
    if args.month is None:
        base, what, name = calm_profile(), {"kind": "calm"}, "capability-calm"
    else:
        from vega_campaign.wind_environment import load_site

        site = load_site(args.site)              # a bad site file: one line, exit 2
        base = month_mean_profile(site, args.month)
        what = {"kind": "month_mean", "month": args.month, "site": site.path,
                "site_name": site.name}
        name = f"capability-month{args.month}"
    try:
        check_amplitudes(base, args.bands, args.jets, args.cap_mps, args.upper_cap_mps)
    except ValueError as exc:
        raise BadArgument(str(exc)) from None
    if out is None:
        out = Path(DEFAULT_CAPABILITY_OUT) / name
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            raise BadArgument(f"--out {out} (the default): must not exist or be an empty "
                              "directory; name another with --out")
    print(f"vega wind: capability of {table} on the measured profile: {base.source} "
          f"({len(args.bands)} bands, {len(args.jets)} jet altitudes, both signs, to "
          f"{args.resolution_mps:g} m/s up to {args.cap_mps:g} / {args.upper_cap_mps:g} m/s, "
          f"{args.workers} workers)",
          flush=True)
    result = capability(table, base, bands_km=args.bands, jet_centres_km=args.jets,
                        cap_mps=args.cap_mps, upper_cap_mps=args.upper_cap_mps,
                        resolution_mps=args.resolution_mps,
                        workers=args.workers, base_description=what,
                        progress=lambda line: print(f"vega wind: {line}", flush=True))
    paths = write_capability(result, out)
    for r in result.rows:
        value = ("the measured profile alone fails" if r["max_mps"] is None
                 else f">= {r['max_mps']:g} m/s" if r["cap_reached"]
                 else f"{r['max_mps']:g} m/s")
        where = (f"{r['lo_km']:g}-{r['hi_km']:g} km" if r["kind"] == "wind_change"
                 else f"at {r['centre_km']:g} km")
        binding = f" (binding: {r['binding']})" if r["binding"] else ""
        print(f"vega wind: {r['kind']} {where} {'+' if r['sign'] > 0 else '-'}: {value}"
              f"{binding}")
    print(f"vega wind: wrote {', '.join(str(p) for p in paths)}: {result.flights} flights in "
          f"{result.rounds} rounds, {result.wall_s:.0f} s wall, {result.cpu_s:.0f} s CPU")
    return 0


def _no_action(args) -> int:
    raise BadArgument("vega wind: choose an action (sample or capability)")


def register(subparsers) -> None:
    """Add the ``wind`` sub-command (actions ``sample`` and ``capability``)."""
    from vega_campaign.wind_environment import DEFAULT_LAG_S, DEFAULT_MODE, MODES

    parser = subparsers.add_parser(
        "wind", help="statistical wind environment of a launch site",
        description="Sample the wind profiles of a launch site's monthly statistics: the "
                    "sounding (measured) and what the vehicle meets (flown); or search the "
                    "vehicle's wind capability.")
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
    _register_capability(actions)


def _register_capability(actions) -> None:
    """Add ``vega wind capability``."""
    import os

    from vega_analysis.capability import (CAP_MPS, DEFAULT_BANDS_KM, DEFAULT_JET_CENTRES_KM,
                                          RESOLUTION_MPS, UPPER_CAP_MPS)
    from vega_cli.commands.mc import MAX_WORKERS      # the same bound as vega mc

    cap = actions.add_parser(
        "capability", help="the largest tolerable wind change per band and upper wind",
        description="The vehicle's wind capability: per altitude band and sign, the largest "
                    "wind change (a raised-cosine bump) the flight passes after the guidance "
                    "is re-biased on the measured profile; per jet altitude and sign, the "
                    "largest jet peak it passes re-biased on the jet, with the shipped "
                    "reference and with no bias. Pass: the flight-day verdict (Qa allowable "
                    "of docs/REQUIREMENTS.md section 6, stable, not rate-limited); nominal "
                    "plant, steady wind only. Writes DIR/capability.csv, capability.json and "
                    "two plots. Exit 0, 2 on bad input.")
    cap.add_argument("--table", default=None, metavar="FILE",
                     help="controller table (default: the installed one)")
    cap.add_argument("--site", default=None, metavar="FILE",
                     help="site file of --month (default: the shipped "
                          "offline/vega_campaign/data/sites/kourou.yaml)")
    cap.add_argument("--month", type=_int_in(1, 12), default=None, metavar="M",
                     help="measured profile: month M's mean wind speed in the site file "
                          "(default: calm)")
    cap.add_argument("--out", default=None, metavar="DIR",
                     help=f"output directory (must not exist or be empty; default "
                          f"{DEFAULT_CAPABILITY_OUT}/capability-calm or "
                          f"{DEFAULT_CAPABILITY_OUT}/capability-month<M>)")
    cap.add_argument("--workers", type=_int_in(1, MAX_WORKERS),
                     default=min(2, os.cpu_count() or 1), metavar="N",
                     help=f"worker processes (1..{MAX_WORKERS}; 1: in this process; default 2, "
                          f"or 1 on one core)")
    cap.add_argument("--bands", type=_km_bands, default=DEFAULT_BANDS_KM, metavar="LO-HI,...",
                     help="altitude bands of the wind change [km] (default " + ",".join(
                         f"{a:g}-{b:g}" for a, b in DEFAULT_BANDS_KM) + ")")
    cap.add_argument("--jets", type=_km_centres, default=DEFAULT_JET_CENTRES_KM,
                     metavar="C,...", help="jet centres [km], half-width 3 km (default "
                     + ",".join(f"{c:g}" for c in DEFAULT_JET_CENTRES_KM) + ")")
    cap.add_argument("--cap-mps", type=_speed, default=CAP_MPS, metavar="V",
                     help=f"largest wind change searched [m/s] (default {CAP_MPS:g})")
    cap.add_argument("--upper-cap-mps", type=_speed, default=UPPER_CAP_MPS, metavar="V",
                     help=f"largest jet peak searched [m/s] (default {UPPER_CAP_MPS:g})")
    cap.add_argument("--resolution-mps", type=_speed, default=RESOLUTION_MPS, metavar="V",
                     help=f"resolution of the search [m/s] (default {RESOLUTION_MPS:g})")
    cap.set_defaults(func=_capability)
