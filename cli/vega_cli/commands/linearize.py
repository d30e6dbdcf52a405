"""``vega linearize``: the frozen-time linear model G_LV(t) as JSON.

``--t 47`` prints one JSON object; ``--t 10:90:10`` prints a JSON list (stop included when
it falls on the step), all from one process.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from vega_core.errors import BadArgument

__all__ = ["register", "parse_times"]


def parse_times(text: str, option: str = "--t", limit: int = 100000
                ) -> tuple[list[float], bool]:
    """Parse ``SECONDS`` or ``START:STOP:STEP`` (stop included when on the step) into
    (times, is_range); ``option`` names the argument in the messages (``vega linearize --t``,
    ``vega margins --at``), ``limit`` caps the number of times.

    Raises
    ------
    BadArgument
        One line naming the bad argument.
    """
    parts = text.split(":")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise BadArgument(f"{option} {text!r}: expected SECONDS or START:STOP:STEP (numbers)"
                          ) from None
    if not all(math.isfinite(v) for v in values):
        raise BadArgument(f"{option} {text!r}: times must be finite")
    if len(values) == 1:
        return values, False
    if len(values) != 3:
        raise BadArgument(f"{option} {text!r}: expected SECONDS or START:STOP:STEP")
    start, stop, step = values
    if step <= 0 or stop < start:
        raise BadArgument(f"{option} {text!r}: need STEP > 0 and STOP >= START")
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    if n > limit:
        raise BadArgument(f"{option} {text!r}: {n} times requested (limit {limit})")
    return [round(start + i * step, 12) for i in range(n)], True


def _record(t: float, context) -> dict:
    from vega_model.dynamics import INPUTS, OUTPUTS, STATES, linear_model

    p = context.parameters(t)
    A, B, C, D = linear_model(p)
    params = p.scalars()
    params.update(
        psi_t_pvp_m=list(p.psi_t_pvp), psi_r_pvp_rad=list(p.psi_r_pvp),
        psi_t_ins_m=list(p.psi_t_ins), psi_r_ins_rad=list(p.psi_r_ins),
    )
    return {
        "t_s": t, "states": list(STATES), "inputs": list(INPUTS), "outputs": list(OUTPUTS),
        "A": A.tolist(), "B": B.tolist(), "C": C.tolist(), "D": D.tolist(),
        "parameters": params,
    }


def _run(args: argparse.Namespace) -> int:
    from vega_model.parameters import PARAMETER_UNITS, default_context

    times, is_range = parse_times(args.t)
    context = default_context()
    lo, hi = context.time_range_s
    for t in times:
        if not lo <= t <= hi:
            raise BadArgument(f"--t {t:g}: outside the flight-condition table ({lo:g}..{hi:g} s)")
    records = [_record(t, context) for t in times]
    if args.json:
        json.dump(records if is_range else records[0], sys.stdout, separators=(",", ":"))
        sys.stdout.write("\n")
        return 0
    for rec in records:
        p = rec["parameters"]
        print(f"t = {rec['t_s']:g} s: " + ", ".join(
            f"{k} = {p[k]:.6g} {PARAMETER_UNITS[k]}" for k in
            ("v_mps", "q_pa", "mach", "cn_alpha_per_rad", "x_cp_m", "x_cg_m", "thrust_n")))
        for name in ("A", "B", "C", "D"):
            print(f"  {name} =")
            for row in rec[name]:
                print("    [" + " ".join(f"{v: .6e}" for v in row) + "]")
    return 0


def register(subparsers) -> None:
    """Add the ``linearize`` sub-command."""
    p = subparsers.add_parser(
        "linearize", help="print the frozen-time linear model G_LV(t) (thesis Eq. 2.44)",
        description="Frozen-time linear pitch-plane model at flight time(s) t. States "
                    "[θ, θ̇, z, ż, q1, q2, q̇1, q̇2], inputs [β, β̈, v_w], outputs "
                    "[Qα (Pa·rad), θ_INS, θ̇_INS, z_INS, ż_INS]; SI units.")
    p.add_argument("--t", required=True, metavar="SECONDS|START:STOP:STEP",
                   help="flight time in s, or an inclusive range")
    p.add_argument("--json", action="store_true",
                   help="print JSON (an object, or a list for a range)")
    p.set_defaults(func=_run)
