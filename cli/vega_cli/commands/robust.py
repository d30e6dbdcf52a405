"""``vega robust``: robust analysis of the flown controller over the whole uncertainty set.

Per frozen flight time (vega_analysis.robust): (a) the worst case over the set — the 642
corners of ``vega margins --dispersed`` and a differential-evolution search over all 13
parameters minimising the disk margin (an unstable plant ranks below every stable one); (b) a μ
lower bound from (a) — the destabilising scale of the box along the worst-case ray — and a μ
upper bound over an LFT of the set (vega_analysis.mu_analysis, Slycot ab13md; ``--no-mu``
skips it); (c) disk margins at the actuator input, nominal and worst case. ``--time-domain``
adds the time-domain margins of the nonlinear in-process loop per flight segment
(vega_analysis.time_margins).

Output: a table per time on stdout; with ``--out DIR``: robust.csv, robust.json,
robust_over_time.png, mu_max_q.png (the μ bounds over frequency at max-Q; and
time_margins.csv/.png). Progress on stderr. Exit
status 0 if no unstable plant was found and the worst case meets the bending criteria at every
time, 1 if not, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

from vega_core.errors import BadArgument

__all__ = ["register"]

_DEFAULT_AT = "0:100:0.5"
_CSV_SKIP = ("worst_deviations", "max_radius_deviations", "mu_curve")


def _f(x, spec=".3f") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-" if x is None or math.isnan(x) else ("inf" if x > 0 else "-inf")
    return format(x, spec)


def _at(w_radps) -> str:
    """``@ω`` [rad/s] of the crossover a margin belongs to (``@-`` where there is none)."""
    return f"@{_f(w_radps, '.3g'):<6}"


def _whole(r) -> str:
    """The μ bound's whole-matrix ab13md calls at one time: made, won, stopped (! if any)."""
    if "mu_whole_calls" not in r:
        return ""
    stopped = r["mu_whole_stopped"]
    return (f" {r['mu_whole_calls']:>5} {r['mu_whole_won']:>3} {stopped:>4}"
            + ("!" if stopped else ""))


def _line(r) -> str:
    bend = "ok" if r["worst_bending_1_ok"] and r["worst_bending_2_ok"] else "FAIL"
    return (f"{r['t_s']:6.1f} | {_f(r['nominal_disk_alpha']):>6} "
            f"{_f(r['nominal_disk_gm_db'], '.1f'):>5} {_f(r['nominal_disk_pm_deg'], '.1f'):>5} | "
            f"{_f(r['worst_disk_alpha']):>6} "
            f"{_f(r['worst_disk_gm_db'], '.1f'):>5} {_f(r['worst_disk_pm_deg'], '.1f'):>5} "
            f"{_f(r['worst_gm_low_db'], '.1f'):>5}{_at(r['worst_w_gm_low_radps'])} "
            f"{_f(r['worst_gm_high_db'], '.1f'):>5}{_at(r['worst_w_gm_high_radps'])} "
            f"{_f(r['worst_pm_deg'], '.1f'):>5}{_at(r['worst_w_pm_radps'])} "
            f"{bend:>4} {r['worst_source'][:6]:>6} | "
            f"{_f(r['max_radius'], '.5f')}{'!' if r['max_radius'] > 1 + 1e-6 else ' '}| "
            f"{_f(r['mu_lower']):>6} {_f(r.get('mu_upper')):>6}{_whole(r)}")


def _worst_at(figure) -> str:
    """``t s, ω rad/s``: where a summary figure is (its time and crossover frequency)."""
    w = figure.get("w_radps")
    return f"{figure['t_s']:g} s" + ("" if w is None or not math.isfinite(w) else
                                     f", {w:.3g} rad/s")


def _write_csv(path, rows) -> None:
    from vega_loops.margins import write_csv

    cols = [k for k in rows[0] if k not in _CSV_SKIP]
    flat = []
    for r in rows:
        row = {k: r[k] for k in cols}
        row.update({f"dev_{k}": v for k, v in r["worst_deviations"].items()})
        flat.append(row)
    write_csv(path, flat, cols + [f"dev_{k}" for k in rows[0]["worst_deviations"]])


def _time_domain(args, table_path, out_dir, progress) -> list[dict]:
    from vega_analysis import time_margins as TM

    rows = TM.time_domain_margins(table_path, workers=args.workers_n, progress=progress)
    print("time-domain margins (nonlinear in-process loop, perturbation inside the segment "
          "only) beside the frequency-domain margins of the nominal plant:")
    print(TM.markdown(rows))
    if out_dir is not None:
        from vega_analysis.robust_plots import plot_time_margins

        path = os.path.join(out_dir, "time_margins.csv")
        TM.write_csv(path, rows)
        print(f"  wrote {path}")
        print(f"  wrote {plot_time_margins(os.path.join(out_dir, 'time_margins.png'), rows)}")
    return rows


def _run(args: argparse.Namespace) -> int:
    from vega_loops import margins as M
    from vega_analysis import robust as R
    from vega_analysis.mu_analysis import WHOLE_TIMEOUT_S
    from vega_cli.commands.margins import parse_at
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_model.parameters import default_context

    times = parse_at(args.at)
    if args.workers is not None and not 1 <= args.workers <= 64:
        raise BadArgument(f"--workers {args.workers}: must be within 1..64")
    if not 0 <= args.seed < 2 ** 32:
        raise BadArgument(f"--seed {args.seed}: must be within 0..2**32-1")
    context = default_context()
    lo, hi = context.time_range_s
    for t in times:
        if not lo <= t <= hi:
            raise BadArgument(f"--at {t:g}: outside the flight-condition table ({lo:g}..{hi:g} s)")
    table_path = str(args.table) if args.table else str(default_table_path())
    load_controller_table(table_path)                 # BadFile: one line, exit 2
    out_dir = None
    if args.out:
        out_dir = os.path.abspath(args.out)
        os.makedirs(out_dir, exist_ok=True)           # OSError: one line, exit 2
    workers = args.workers if args.workers is not None else min(2, os.cpu_count() or 1)
    args.workers_n = workers

    def progress(line):
        print(line, file=sys.stderr, flush=True)

    result = R.sweep(table_path, times, workers=0 if len(times) == 1 else workers,
                     seed=args.seed, progress=progress, mu=not args.no_mu)
    rows = result["rows"]
    summary = R.summarise(rows)
    print(f"vega robust: table {table_path}; uncertainty set: thesis Table 2.3 + TVC ±10 % + "
          f"delay ±10 ms (13 parameters); controller on the nominal schedule")
    print("  disk margin α (balanced) with its gain [dB] and phase [deg] margins, nominal and "
          "at the worst case found (src: corner | search); worst-case rigid GM low/high [dB] "
          "and PM dist = distance of the phase from -180 deg at the closest gain crossover at "
          f"or above {M.PM_FLOOR_RADPS:g} rad/s [deg], each @ its crossover's frequency "
          "[rad/s]; bending criteria; max |z| over the plants evaluated (! unstable); μ lower "
          "bound (destabilising scale along the worst-case ray) and upper bound (LFT, ab13md)"
          + ("" if args.no_mu else
             "; whole/won/stop = its whole-matrix ab13md calls made, whose certificate was the "
             f"smaller, stopped at the {WHOLE_TIMEOUT_S:g} s limit (! the reduced call's "
             "certificate stands there)"))
    print("   t_s |  nom α  DGM   DPM |  wst α  DGM   DPM GMlow @rad/s  GMhi @rad/s "
          "PMdst @rad/s bend    src |  max |z|  |  μ_low   μ_up"
          + ("" if args.no_mu else " whole won stop"))
    for r in rows:
        print(_line(r))
    print()
    s = summary
    print(f"  worst disk margin {s['worst_disk_alpha']['value']:.3f} at t = "
          f"{s['worst_disk_alpha']['t_s']:g} s (DGM {s['worst_disk_gm_db']['value']:.2f} dB at "
          f"{s['worst_disk_gm_db']['t_s']:g} s, DPM {s['worst_disk_pm_deg']['value']:.1f} deg at "
          f"{s['worst_disk_pm_deg']['t_s']:g} s); nominal worst "
          f"{s['nominal_disk_alpha']['value']:.3f} at {s['nominal_disk_alpha']['t_s']:g} s")
    print(f"  worst-case rigid margins: GM low {s['worst_gm_low_db']['value']:.2f} dB at "
          f"{_worst_at(s['worst_gm_low_db'])}, GM high {s['worst_gm_high_db']['value']:.2f} dB "
          f"at {_worst_at(s['worst_gm_high_db'])}, PM (distance from -180 deg) "
          f"{s['worst_pm_deg']['value']:.1f} deg at {_worst_at(s['worst_pm_deg'])}")
    stab = ("no unstable plant found" if s["robust_stability_pass"] else
            "UNSTABLE at " + ", ".join(f"{t:g}" for t in s["unstable_times_s"]) + " s")
    print(f"  stability: {stab} (largest |z| {s['max_radius']['value']:.6f} at "
          f"{s['max_radius']['t_s']:g} s)")
    bend = s["worst_case_bending_fail_times_s"]
    print("  bending criteria at the worst case: "
          + ("met at every time" if not bend else
             f"MISSED at {len(bend)} time(s): " + ", ".join(f"{t:g}" for t in bend[:10])
             + (" ..." if len(bend) > 10 else "")))
    lo_txt = ("not established along the worst-case rays (no destabilising scale up to "
              f"{R.S_MAX:g}x)" if s["mu_lower"] is None else
              f"{s['mu_lower']['value']:.3f} at {s['mu_lower']['t_s']:g} s")
    print(f"  mu lower bound peak {lo_txt}")
    if s.get("mu_upper") is None:
        print("  mu upper bound: not computed (--no-mu)")
    else:
        up = s["mu_upper"]
        proof = ("< 1 at every time with a stable centre: every plant of the set is stable "
                 "(to the fit-error cover)" if s["mu_proves_stability"] else
                 f">= 1 (or unstable centre) at {len(rows) - s['mu_upper_below_1_times']} "
                 "time(s): the bound does not prove the set stable there")
        print(f"  mu upper bound peak {up['value']:.3f} at {up['t_s']:g} s, "
              f"{up['w_radps']:.2f} rad/s; {proof}; largest fit error "
              f"{s['mu_fit_loop_rel']:.3f} of |1 + L| (covered)")
        stopped = s["mu_whole_stopped_times_s"]
        print(f"  mu whole-matrix ab13md calls: {s['mu_whole_calls']} made, {s['mu_whole_won']} "
              f"gave the smaller certificate, {s['mu_whole_stopped']} stopped at the "
              f"{WHOLE_TIMEOUT_S:g} s limit"
              + (" (at " + ", ".join(f"{t:g}" for t in stopped) + " s: the reduced call's "
                 "certificate stands there, the bound depends on the machine's speed)"
                 if stopped else "")
              + f"; {s['mu_whole_time_s']:.1f} s of ab13md")
        if s["mu_gap"] is not None:
            g = s["mu_gap"]
            print(f"  mu gap at {g['t_s']:g} s (largest lower bound): {g['lower']:.3f} <= mu "
                  f"<= {g['upper_at_same_time']:.3f}")
    print(f"  run time {result['run_time_s']:.1f} s ({result['workers']} worker process(es))")

    td = _time_domain(args, table_path, out_dir, progress) if args.time_domain else None
    if out_dir is not None:
        from vega_analysis.robust_plots import plot_robust_over_time

        files = []
        path = os.path.join(out_dir, "robust.csv")
        _write_csv(path, rows)
        files.append(path)
        files.append(plot_robust_over_time(os.path.join(out_dir, "robust_over_time.png"), rows))
        if any("mu_curve" in r for r in rows):
            from vega_loops.margins import max_q_time
            from vega_analysis.robust_plots import plot_mu_frequency

            files.append(plot_mu_frequency(os.path.join(out_dir, "mu_max_q.png"), rows,
                                           max_q_time(context)))
        path = os.path.join(out_dir, "robust.json")
        with open(path, "w", encoding="utf-8") as f:
            json.dump(M.json_ready({"summary": summary, "rows": rows, "time_domain": td,
                                    "run_time_s": result["run_time_s"],
                                    "search": R.SEARCH, "s_max": R.S_MAX}),
                      f, indent=1, allow_nan=False)
            f.write("\n")
        files.append(path)
        for f in files:
            print(f"  wrote {f}")
    return 0 if summary["robust_stability_pass"] and summary["worst_case_bending_pass"] else 1


def register(subparsers) -> None:
    """Add the ``robust`` sub-command."""
    p = subparsers.add_parser(
        "robust", help="robust analysis over the uncertainty set: worst-case search, mu lower "
                       "and upper bounds, disk margins (--time-domain: nonlinear-loop margins)",
        description="Per frozen flight time, with the flown controller on the nominal schedule: "
                    "the worst case over the uncertainty set (642 corners + a differential-"
                    "evolution search minimising the disk margin), a mu lower bound from the "
                    "worst case (destabilising scale along its ray), a mu upper bound over an "
                    "LFT of the set (Slycot ab13md), and disk margins. Exit "
                    "status 0 if no unstable plant was found and the worst "
                    "case meets the bending criteria at every time, 1 if not, 2 on bad input.")
    p.add_argument("--table", metavar="FILE",
                   help="controller table (default: the installed tvc_controller.npz)")
    p.add_argument("--at", default=_DEFAULT_AT, metavar="T|START:STOP:STEP",
                   help=f"flight time(s) in s (default {_DEFAULT_AT})")
    p.add_argument("--out", metavar="DIR",
                   help="write robust.csv, robust.json and the plots into DIR (created)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="worker processes (default: 2, or 1 on a 1-core machine)")
    p.add_argument("--seed", type=int, default=0, metavar="S",
                   help="seed of the worst-case search (default 0)")
    p.add_argument("--no-mu", action="store_true",
                   help="skip the mu upper bound (LFT + ab13md, ≈ 7 s per time on one core)")
    p.add_argument("--time-domain", action="store_true",
                   help="also the time-domain margins of the nonlinear in-process loop per "
                        "flight segment (gain up/down and extra delay until unstable)")
    p.set_defaults(func=_run)
