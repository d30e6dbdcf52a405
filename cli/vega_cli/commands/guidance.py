"""``vega guidance``: compute and export the wind-biased guidance reference.

``vega guidance --out FILE.npz`` solves the guidance problem of ``vega_reference.guidance``
(docs/GUIDANCE.md) for a design wind — the steady profile V_w(h) of thesis Eq. 2.54, or a
changed one (``--wind-scale``, ``--wind-shift-m``: e.g. a day-of-launch update) — and writes
the reference the controller tracks, its JSON summary (``FILE.json``) and a plot
(``FILE.png``, or ``--plot``). The product flies the committed copy,
``vega_gnc/config/guidance_reference.npz``; regenerate it with ``--out
ros2_ws/src/vega_gnc/config/guidance_reference.npz --plot docs/figures/guidance_reference.png``.
Exit 0, or 2 on bad input.
"""

from __future__ import annotations

import argparse
import math

from vega_core.errors import BadArgument

from vega_cli.commands._paths import npz_out

__all__ = ["register"]


def _finite(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return x


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from vega_reference.guidance import (DesignWind, GuidanceWeights, design_reference,
                                            plot_guidance, write_guidance_reference)

    out = npz_out(args.out)
    if args.plot and not args.plot.endswith(".png"):
        raise BadArgument(f"--plot {args.plot}: must end in .png")
    if abs(args.wind_scale) > 3.0 or abs(args.wind_shift_m) > 10_000.0:
        raise BadArgument("--wind-scale must be within ±3 and --wind-shift-m within ±10000 m "
                          "(the scenario limits)")
    name = "thesis Eq. 2.54 steady profile V_w(h) (vehicle.yaml wind.profile)"
    if args.wind_scale != 1.0 or args.wind_shift_m != 0.0:
        name = f"{args.wind_scale:g} x V_w(h - {args.wind_shift_m:g} m), V_w of thesis Eq. 2.54"
    wind = DesignWind(scale=args.wind_scale, shift_m=args.wind_shift_m, name=name)
    weights = GuidanceWeights()
    design = design_reference(wind, weights, progress=print)
    write_guidance_reference(out, design, wind, weights)
    png = plot_guidance(design, Path(args.plot) if args.plot else out.with_suffix(".png"))
    s = design.summary
    print(f"wrote {out} ({design.t_s.size} samples, {design.t_s[0]:g}-{design.t_s[-1]:g} s), "
          f"{out.with_suffix('.json')}, {png}")
    print(f"design flight: max |Qα|/envelope {s['design_q_alpha_ratio_max']:.3f} at "
          f"{s['design_q_alpha_ratio_time_s']:.1f} s (holding the nominal attitude: "
          f"{s['hold_q_alpha_ratio_max']:.3f} at {s['hold_q_alpha_ratio_time_s']:.1f} s); "
          f"max θ_ref {s['theta_max_deg']:.2f} deg, z_ref {s['z_max_m']:.1f} m, "
          f"ż_ref {s['z_dot_max_mps']:.2f} m/s, β_ff {s['beta_ff_max_deg']:.3f} deg")
    return 0


def register(subparsers) -> None:
    """Add the ``guidance`` sub-command."""
    p = subparsers.add_parser(
        "guidance", help="compute the wind-biased guidance reference the controller tracks",
        description="Solve the guidance problem (docs/GUIDANCE.md): the reference deviations "
                    "from the nominal pitch programme and the nozzle feed-forward that fly "
                    "the design wind at low structural load, within half the drift budget. "
                    "Writes FILE.npz (the flight software's reference), FILE.json and "
                    "FILE.png.")
    p.add_argument("--out", required=True, metavar="FILE.npz", help="output reference file")
    p.add_argument("--plot", default=None, metavar="FILE.png",
                   help="where the plot goes (default: FILE.png beside --out)")
    p.add_argument("--wind-scale", type=_finite, default=1.0, metavar="S",
                   help="design wind = S x V_w(h - H) (default 1)")
    p.add_argument("--wind-shift-m", type=_finite, default=0.0, metavar="H",
                   help="upward shift H of the design profile [m] (default 0)")
    p.set_defaults(func=_run)
