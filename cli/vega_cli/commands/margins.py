"""``vega margins``: classical margins of the flown controller per frozen flight time.

The loop is broken at the actuator input, with the table's discrete controller interpolated
and clamped exactly as the on-board runtime does, the zero-order hold, the 39 ms loop delay,
the TVC actuator and the linear plant of ``vega linearize`` (vega_loops.margins). Per
time: rigid-body gain margins (low: gain reduction, high: gain increase) and phase margin
(the distance of a gain crossover's phase from −180°, either side, over the crossovers at or
above the frozen-time floor ``vega_loops.margins.PM_FLOOR_RADPS``; those below it are reported
apart), each with the frequency of its crossover, the peak loop gain in each bending band (and
the crossover margins of a mode above −6 dB), and the closed-loop stability of the exact
sampled-data loop. ``--dispersed`` adds 640
corners of the uncertainty set and the plant with thesis Table 2.3's pitch inertia, with the
controller on the nominal schedule, and reports the worst corner per time.

Output: a compact table per time on stdout; with ``--out DIR``: margins.csv, margins.json
(worst value and where per criterion, pass/fail, unstable loops), margins_over_time.png,
nichols_max_q.png (and with ``--dispersed`` margins_worst.csv). Progress on stderr. Exit
status: 0 if the nominal plant meets every requirement at every time, 1 if not, 2 on bad
input.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

from vega_core.errors import BadArgument

__all__ = ["register", "parse_at"]

_DEFAULT_AT = "0:100:0.5"


def parse_at(text: str) -> list[float]:
    """Parse ``--at SECONDS`` or ``START:STOP:STEP`` (:func:`~vega_cli.commands.linearize.
    parse_times`, at most 10000 times)."""
    from vega_cli.commands.linearize import parse_times

    return parse_times(text, option="--at", limit=10000)[0]


def _v(x, width=6, prec=1, bad=False) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        s = "-"
    elif isinstance(x, float) and math.isinf(x):
        s = "inf" if x > 0 else "-inf"
    else:
        s = f"{x:.{prec}f}"
    return f"{s + ('!' if bad else ' '):>{width + 1}}"


def _at(w_radps) -> str:
    """``@ω`` of a crossover [rad/s] (blank when there is none)."""
    if w_radps is None or (isinstance(w_radps, float) and not math.isfinite(w_radps)):
        return " " * 7
    return f"@{w_radps:<6.3g}"


def _line(r, ok) -> str:
    b = lambda i: _v(r[f"b{i}_peak_db"], bad=not ok[f"bending_{i}"]) + (  # noqa: E731
        "p" if r[f"b{i}_phase_stabilised"] else " ")
    gm = (_v(r["gm_low_db"], bad=not ok["gm_low_db"]) + _at(r["w_gm_low_radps"])
          + _v(r["gm_high_db"], bad=not ok["gm_high_db"]) + _at(r["w_gm_high_radps"]))
    return (f"{r['t_s']:6.1f} {r['v_sched_mps']:7.1f}{'c' if r['clamped'] else ' '}|{gm}"
            f"{_v(r['pm_deg'], bad=not ok['pm_deg'])}{_at(r['w_pm_radps'])}|{b(1)}{b(2)}|"
            f"{r['n_unstable']:3d}{'!' if r['n_unstable'] else ' '}")


def _worst_line(w, req) -> str:
    """The worst corner of each criterion at one time, with its crossover frequency (! = a
    stable loop misses it)."""
    def flag(key, limit):
        x = w[key]
        return (_v(x, bad=isinstance(x, float) and math.isfinite(x) and x < limit)
                + _at(w[f"{key}_freq_radps"]))

    return (f" | {flag('gm_low_db', req['gm_db'])}{flag('gm_high_db', req['gm_db'])}"
            f"{flag('pm_deg', req['pm_deg'])} "
            f"{_v(w['b1_peak_db'], bad=w['bending_1_fail_plants'] > 0)}"
            f"{_v(w['b2_peak_db'], bad=w['bending_2_fail_plants'] > 0)} "
            f"{w['n_unstable_plants']:4d}/{w['n_plants']}")


def _fmt_where(v) -> str:
    where = f"t = {v['t_s']:g} s"
    if v.get("w_radps") is not None:
        where += f", {v['w_radps']:.3g} rad/s"
    if "deviations" in v:
        where += f", corner {v['corner']} ({v['family']}: " + (
            ", ".join(f"{k} {d:+g}" for k, d in v["deviations"].items()) or "nominal") + ")"
    return where


def _num(x, unit) -> str:
    return "none (no crossover)" if x is None else f"{x:.1f} {unit}"


def _when(v) -> str:
    ints = v.get("fail_intervals_s", v.get("unstable_intervals_s", []))
    text = ", ".join(f"{a:g}-{b:g}" if a != b else f"{a:g}" for a, b in ints[:6])
    return text + (" ..." if len(ints) > 6 else "")


def _print_verdicts(title, res, relaxed=None) -> None:
    """One line per criterion: worst (over the stable loops) and where, verdicts."""
    print(title)
    for name in ("gm_low_db", "gm_high_db", "pm_deg", "bending_1", "bending_2"):
        v = res[name]
        worst = "none" if v["worst"] is None else f"{v['worst']:.2f} {v['unit']}"
        where = "" if v["worst"] is None else f" at {_fmt_where(v)}"
        if v["worst"] is not None and v.get("w_peak_radps") is not None:
            where += f", peak at {v['w_peak_radps']:.3g} rad/s"
        if name.startswith("bending") and v.get("n_above_limit_loops"):
            pm, gm = v["worst_band_pm"], v["worst_band_gm"]
            where += (f"; above -6 dB in {v['n_above_limit_loops']} loop(s), worst in-band "
                      f"PM {_num(pm['value'], 'deg')} at {_fmt_where(pm)}, GM "
                      f"{_num(gm['value'], 'dB')} at {_fmt_where(gm)}")
        verdict = "PASS" if v["pass"] else f"FAIL at {v['n_fail_times']} time(s) {_when(v)}"
        if relaxed is not None:
            r = relaxed[name]
            verdict += ("; relaxed: PASS" if r["pass"] else
                        f"; relaxed: FAIL at {r['n_fail_times']} time(s) {_when(r)}")
        print(f"  {name:11s} worst {worst}{where}: {verdict}")
    low = res.get("pm_below_floor")
    if low and low["n_loops"]:
        print(f"  (not a criterion) {low['n_loops']} loop(s) with a gain crossover below "
              f"{low['floor_radps']:g} rad/s (too slow for a frozen-time loop), smallest "
              f"distance from -180 deg there {low['worst']:.1f} deg at {_fmt_where(low)}")
    s = res["stability"]
    print(f"  stability   {s['n_unstable_loops']} of {s['n_loops']} frozen loops unstable"
          + (f", at {s['n_unstable_times']} time(s): {_when(s)} s" if s["n_unstable_loops"]
             else "") + f": {'PASS' if s['pass'] else 'FAIL'}")


def _run(args: argparse.Namespace) -> int:
    from vega_loops import margins as M
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_model.parameters import default_context

    times = parse_at(args.at)
    if args.workers is not None and args.workers < 1:
        raise BadArgument(f"--workers {args.workers}: need at least 1")
    context = default_context()
    lo, hi = context.time_range_s
    for t in times:
        if not lo <= t <= hi:
            raise BadArgument(f"--at {t:g}: outside the flight-condition table ({lo:g}..{hi:g} s)")
    table_path = str(args.table) if args.table else str(default_table_path())
    table = load_controller_table(table_path)        # BadFile: one line, exit 2
    out_dir = None
    if args.out:
        out_dir = os.path.abspath(args.out)
        os.makedirs(out_dir, exist_ok=True)           # OSError: one line, exit 2
    workers = args.workers if args.workers is not None else min(2, os.cpu_count() or 1)
    if len(times) == 1 and not args.dispersed:
        workers = 0                                   # one loop: no process start-up

    def progress(line):
        print(line, file=sys.stderr, flush=True)

    result = M.sweep(table_path, times, dispersed=args.dispersed, workers=workers,
                     progress=progress)
    rows = result["rows"]
    nominal = [r for r in rows if r["corner"] == 0]
    worst = M.worst_per_time(rows) if args.dispersed else None
    summary = M.summarise(result, table, times)

    print(f"vega margins: table {table_path} (rate slice {M.runtime_rate(table)} m/s², "
          f"grid {table.grid_v_mps[0]:.1f}-{table.grid_v_mps[-1]:.1f} m/s), "
          f"T = {table.dt_s * 1000:g} ms, delay {M.total_delay_s(context.vehicle) * 1000:g} ms")
    print("  GM low = gain reduction, GM high = gain increase [dB]; PM = distance of the phase "
          f"from -180 deg at the closest gain crossover at or above {M.PM_FLOOR_RADPS:g} rad/s "
          "[deg]; @ = that crossover's frequency [rad/s]; B1/B2 = peak loop gain in the band "
          "[dB] (p: above -6 dB); unst = unstable closed-loop poles; c = controller clamped; "
          "! = requirement not met")
    head = ("   t_s  v_schd | GM low @rad/s  GM hi @rad/s     PM @rad/s |   B1      B2    |unst")
    if args.dispersed:
        head += (f" | worst of {len(result['corners'])} plants: GM lo @rad/s  GM hi @rad/s     "
                 f"PM @rad/s     B1      B2  unstable")
    print(head)
    for k, r in enumerate(nominal):
        ok = M.criteria_ok(r)
        line = _line(r, ok)
        if worst is not None:
            line += _worst_line(worst[k], M.REQUIREMENTS)
        print(line)
    print()
    _print_verdicts("nominal plant (requirement: GM >= 6 dB both sides, PM >= 30 deg, bending "
                    "<= -6 dB or phase-stabilised with >= 30 deg / 6 dB; worst over the stable "
                    "loops):", summary["nominal"])
    if summary.get("nominal_controller_not_clamped") and summary["nominal"][
            "clamped_intervals_s"]:
        _print_verdicts("nominal plant, times where the controller is inside its velocity grid:",
                        summary["nominal_controller_not_clamped"])
    clamp = summary["nominal"]["clamped_intervals_s"]
    if clamp:
        print("  controller clamped to its grid end at " + ", ".join(
            f"{a:g}-{b:g} s" if a != b else f"{a:g} s" for a, b in clamp))
    d = summary["nominal"]["sampled_data_vs_continuous_max_diff"]
    print(f"  exact sampled-data loop vs continuous-equivalent: max |difference| GM low "
          f"{d['gm_low_db']:.2f} dB, GM high {d['gm_high_db']:.2f} dB, PM {d['pm_deg']:.2f} deg, "
          f"B1 {d['b1_peak_db']:.2f} dB, B2 {d['b2_peak_db']:.2f} dB; Nyquist count disagrees "
          f"with the eigenvalues at {summary['nominal']['nyquist_disagreements']} time(s)")
    if args.dispersed:
        disp = summary["dispersed"]
        c = disp["dispersed_criterion"]
        print(f"dispersed: {disp['corners']['n']} plants per time (corner 0 nominal; JSON "
              f"'families' also has all of them together); relaxed criterion = GM >= "
              f"{c['gm_db']:g} dB, PM >= {c['pm_deg']:g} deg, bending <= {c['bending_db']:g} dB")
        for fam, what in (("rigid", "rigid-body and loop corners, bending nominal"),
                          ("bending", "bending x thrust/actuator/delay corners")):
            f = disp["families"][fam]
            _print_verdicts(f"dispersed, {what} ({f['n_plants_per_time']} per time):",
                            f["requirements"], f["dispersed_criterion"])
            if f["requirements_controller_not_clamped"] and summary["nominal"][
                    "clamped_intervals_s"]:
                _print_verdicts(f"dispersed, {what}, controller inside its grid:",
                                f["requirements_controller_not_clamped"])
    print(f"  run time {result['run_time_s']:.1f} s ({result['workers']} worker process(es))")

    if out_dir is not None:
        from vega_analysis.margin_plots import plot_margins_over_time, plot_nichols

        files = []
        path = os.path.join(out_dir, "margins.csv")
        M.write_csv(path, rows)
        files.append(path)
        if worst is not None:
            path = os.path.join(out_dir, "margins_worst.csv")
            cols = list(worst[0].keys())
            M.write_csv(path, worst, cols)
            files.append(path)
        files.append(plot_margins_over_time(os.path.join(out_dir, "margins_over_time.png"),
                                            nominal, worst, clamp))
        t_q = M.max_q_time(context)
        picks = [(0, result["corners"][0])]
        labels = {0: "nominal"}
        if args.dispersed:
            at_q = M.sweep(table_path, [t_q], dispersed=True, workers=1)["rows"]
            stable = [r for r in at_q if r["n_unstable"] == 0]
            chosen = [(f"worst {name}", M.worst_row(stable, key, kind))
                      for name, (key, kind, _) in M.CRITERIA.items() if stable]
            unstable = [r for r in at_q if r["n_unstable"] > 0]
            if unstable:
                chosen.append((f"most unstable of {len(unstable)} unstable",
                               M.worst_row(unstable, "max_abs_eig", "max")))
            for what, w in chosen:
                c = w["corner"]
                if c not in labels:
                    picks.append((c, result["corners"][c]))
                    labels[c] = f"corner {c} ({M.corner_family(c)}): {what}"
                else:
                    labels[c] += f", {what}"
        w, curves = M.nichols_curves(table, context, t_q, picks)
        files.append(plot_nichols(os.path.join(out_dir, "nichols_max_q.png"), w, curves,
                                  labels, t_q, context.parameters(t_q).omega_radps))
        summary["nichols_t_s"] = t_q
        summary["files"] = [os.path.basename(str(f)) for f in files] + ["margins.json"]
        summary["csv_columns"] = list(M.CSV_COLUMNS)
        path = os.path.join(out_dir, "margins.json")
        with open(path, "w", encoding="utf-8") as f:
            json.dump(M.json_ready(summary), f, indent=1, allow_nan=False)
            f.write("\n")
        files.append(path)
        for f in files:
            print(f"  wrote {f}")
    return 0 if all(v["pass"] for v in summary["nominal"].values()
                    if isinstance(v, dict) and "pass" in v) else 1


def register(subparsers) -> None:
    """Add the ``margins`` sub-command."""
    p = subparsers.add_parser(
        "margins", help="classical margins of the flown controller over the flight "
                        "(GM low/high, PM, bending, stability; --dispersed corners)",
        description="Margins at the actuator input per frozen flight time, with the table's "
                    "discrete controller interpolated and clamped as flown, zero-order hold, "
                    "39 ms delay, TVC actuator and the linear plant of `vega linearize`. "
                    "Requirements: GM >= 6 dB both sides, PM >= 30 deg, bending <= -6 dB (or "
                    "phase-stabilised with >= 30 deg and 6 dB). Exit status 0 if the nominal "
                    "plant meets them at every time, 1 if not, 2 on bad input.")
    p.add_argument("--table", metavar="FILE",
                   help="controller table (default: the installed tvc_controller.npz, the one "
                        "the controller node flies)")
    p.add_argument("--dispersed", action="store_true",
                   help="also 640 corners of the uncertainty set (thesis Table 2.3 + TVC ±10 %% "
                        "+ delay ±10 ms) and the plant with Table 2.3's pitch inertia (-21.8 %%), "
                        "the controller on the nominal schedule; worst corner per time and "
                        "criterion")
    p.add_argument("--at", default=_DEFAULT_AT, metavar="T|START:STOP:STEP",
                   help=f"flight time(s) in s (default {_DEFAULT_AT})")
    p.add_argument("--out", metavar="DIR",
                   help="write margins.csv, margins.json and the plots into DIR (created)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="worker processes (default: 2, or 1 on a 1-core machine)")
    p.set_defaults(func=_run)
