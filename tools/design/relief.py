"""Re-tune the grid points of a structured table in a max-Q window with load relief (issue 9).

Issue 9 item 3, docs/FLIGHT_DESIGN.md §7: load-relief feedback added on top of the tuned
attitude gains broke the nominal margins; this re-tunes the attitude gains *with* it. Every
grid point of the window is re-tuned with the relief parameters of
vega_design.structured (RELIEF_PARAMETERS: the lateral acceleration derived from the INS
drift rate, k_a·s/(τs + 1)·ż) and the load objective (``--load-weight`` × the nominal loop's
peak wind → α gain V·|α/v_w| over 0.02–1 rad/s, structured.with_load) added to the design
cost; seeded from the table's own parameters (relief off) and from the previous re-tuned
point. Grid points outside the window keep their parameters with the relief off (k_a = 0: the
same controller, order 9 instead of 8).

A re-tuned point is kept only where it adds no requirement miss (structured.requirement_misses:
PM, GM low/high, unstable design plants, exact bending criterion at a design plant) to the
point it replaces; the flown (interpolated) controller midway between every pair of neighbours
whose interval touches the window is then checked on its design set against the table's own
flown controller there: nothing is written when one adds a miss (as graft.py). The tuning record
holds ``solver.relief``, one entry per run (window, weight, budget, seed, per grid time the
relief gain and the wind → α gain before and after).

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python tools/design/relief.py TABLE
       --window 14 66 [--times 40,42] [--load-weight 0.5] [--maxiter 30] [--popsize 8]
       [--local] --out FILE.npz
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from design_table import misses_check, write_design


def _design(path: Path):
    meta = json.loads(str(np.load(path)["metadata"]))
    if meta.get("design") != "structured":
        raise SystemExit(f"{path}: not a structured design table")
    return meta


def retune(context, uset, t_s: float, starts, weight: float, seed: int, maxiter: int,
           popsize: int, local: bool, metric: str = "peak"):
    """Re-tune one grid time with relief and the load objective from the best of ``starts``
    (16-parameter vectors). Returns (x, cost, detail)."""
    from scipy.optimize import minimize

    from vega_design import structured as S

    ds = S.with_load(S.design_set(context, t_s, uset), context, weight, metric)
    x0 = min(starts, key=lambda c: S.evaluate(c, ds))
    if not local:
        return S.tune_point(ds, x0, seed=seed, maxiter=maxiter, popsize=popsize)
    lo, hi = S.bounds_for(x0.size)
    res = minimize(S.evaluate, x0, args=(ds,), method="Nelder-Mead",
                   bounds=list(zip(lo, hi)),
                   options={"maxfev": maxiter * popsize * x0.size, "xatol": 1e-4,
                            "fatol": 1e-6, "initial_simplex": _simplex(x0, lo, hi)})
    x = np.clip(res.x, lo, hi)
    cost, detail = S.evaluate(x, ds, detail=True)
    return x, cost, detail


def _simplex(x0, lo, hi):
    """Nelder–Mead start: x0 and a step of 5 % of the box along each parameter (inward)."""
    out = [x0]
    for i in range(x0.size):
        x = x0.copy()
        step = 0.05 * (hi[i] - lo[i])
        x[i] = x[i] + step if x[i] + step <= hi[i] else x[i] - step
        out.append(x)
    return np.array(out)


def main(argv=None) -> int:
    """Re-tune, check, write."""
    from vega_design import structured as S
    from vega_model.parameters import default_context
    from vega_model.uncertainty import UncertaintySet

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", type=Path)
    parser.add_argument("--window", type=float, nargs=2, default=(14.0, 66.0),
                        metavar=("START", "STOP"))
    parser.add_argument("--times", default="", help="only these grid times (comma-separated)")
    parser.add_argument("--load-weight", type=float, default=0.5)
    parser.add_argument("--load-metric", choices=S.LOAD_METRICS, default="peak")
    parser.add_argument("--maxiter", type=int, default=30)
    parser.add_argument("--popsize", type=int, default=8)
    parser.add_argument("--seed", type=int, default=5000)
    parser.add_argument("--local", action="store_true",
                        help="Nelder–Mead only (maxiter·popsize·16 evaluations), no evolution")
    parser.add_argument("--no-relief", action="store_true",
                        help="re-tune the 14 parameters with the load objective only (no relief "
                             "branch: the table keeps order 8)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    start, stop = args.window
    if not start < stop:
        parser.error(f"--window {start:g} {stop:g}: start must be before stop")
    if not (np.isfinite(args.load_weight) and args.load_weight >= 0.0):
        parser.error(f"--load-weight {args.load_weight}: must be finite and >= 0")
    meta = _design(args.table)
    context = default_context()
    uset = UncertaintySet.from_vehicle(context.vehicle)
    times = [float(t) for t in meta["grid_times_s"]]
    n0 = len(S.PARAMETERS)
    old = [np.asarray(x, dtype=float) for x in meta["parameters_per_grid_time"]]
    if args.no_relief and any(x.size != n0 for x in old):
        parser.error("--no-relief: the table has relief parameters already")
    if not args.no_relief:
        old = [S.with_relief(x, *S.RELIEF_OFF) if x.size == n0 else x for x in old]
    inside = [t for t in times if start - 1e-9 <= t <= stop + 1e-9]
    if args.times:
        wanted = [float(v) for v in args.times.split(",")]
        missing = [t for t in wanted if t not in inside]
        if missing:
            parser.error(f"--times {missing}: not grid times inside the window")
        inside = wanted
    new = [x.copy() for x in old]
    record = {"window_s": [start, stop], "load_weight": args.load_weight,
              "load_metric": args.load_metric,
              "relief_branch": not args.no_relief,
              "maxiter": args.maxiter, "popsize": args.popsize, "seed": args.seed,
              "search": "nelder-mead" if args.local else "differential evolution + polish",
              "band_radps": list(S.LOAD_BAND_RADPS), "per_time": {}}
    prev = None
    for k, t in enumerate(inside):
        i = times.index(t)
        t0 = time.perf_counter()
        starts = [old[i]] + ([prev] if prev is not None else [])
        x, cost, detail = retune(context, uset, t, starts, args.load_weight, args.seed + k,
                                 args.maxiter, args.popsize, args.local, args.load_metric)
        ds = S.with_load(S.design_set(context, t, uset), context, args.load_weight,
                         args.load_metric)
        before = S.evaluate(old[i], ds, detail=True)[1]
        kept = all(a <= b for a, b in zip(S.requirement_misses(detail),
                                          S.requirement_misses(before)))
        if kept:
            new[i] = x
            prev = x
        relief = (f"k_acc {x[14]:.2f} mrad/(m/s2), tau {10 ** x[15]:.2f} s, "
                  if x.size > n0 else "")
        print(f"{'kept' if kept else 'refused'} t = {t:g} s ({time.perf_counter() - t0:.0f} s): "
              f"{relief}k_theta {10 ** old[i][0]:.3f} -> {10 ** x[0]:.3f}, wind->alpha "
              f"{before['wind_alpha_gain']:.3f} -> {detail['wind_alpha_gain']:.3f}, PM "
              f"{before['pm_deg']:.2f} -> {detail['pm_deg']:.2f} deg, GM "
              f"{before['gm_low_db']:.2f}/{before['gm_high_db']:.2f} -> "
              f"{detail['gm_low_db']:.2f}/{detail['gm_high_db']:.2f} dB, misses "
              f"{S.requirement_misses(before)} -> {S.requirement_misses(detail)}", flush=True)
        record["per_time"][f"{t:g}"] = {
            "kept": kept, "k_acc_mrad_per_mps2": float(x[14]) if x.size > n0 else None,
            "tau_acc_s": float(10 ** x[15]) if x.size > n0 else None,
            "x": [float(v) for v in x],
            "wind_alpha_gain_before": before["wind_alpha_gain"],
            "wind_alpha_gain_after": detail["wind_alpha_gain"] if kept
            else before["wind_alpha_gain"],
            "pm_deg": detail["pm_deg"], "gm_low_db": detail["gm_low_db"],
            "gm_high_db": detail["gm_high_db"],
            "wind_alpha_peak_before": before["wind_alpha_peak"],
            "wind_alpha_peak_after": detail["wind_alpha_peak"] if kept
            else before["wind_alpha_peak"]}
    worse = []
    check = misses_check(context, uset, worse)
    changed = [i for i in range(len(times)) if not np.array_equal(new[i], old[i])]
    pairs = sorted({(j, j + 1) for i in changed for j in (i - 1, i) if 0 <= j < len(times) - 1})
    for a, b in pairs:
        mid = 0.5 * (times[a] + times[b])
        check("midpoint", mid,
              S.flown_between(context, (times[a], new[a]), (times[b], new[b]), mid),
              S.flown_between(context, (times[a], old[a]), (times[b], old[b]), mid))
    if worse:
        print(f"not written: the relief adds a requirement miss at {', '.join(worse)}",
              file=sys.stderr)
        return 1
    tuning = {k: v for k, v in meta.get("solver", {}).items() if k not in ("method", "scipy")}
    previous = tuning.get("relief", [])
    tuning["relief"] = (previous if isinstance(previous, list) else [previous]) + [record]
    how = dict(tuning.get("how", {}))
    for i in changed:
        key = f"{times[i]:g}"
        how[key] = f"{how.get(key, 'given')}; re-tuned with load relief (tools/design/relief.py)"
    tuning["how"] = how
    write_design(args.out, context, uset, times, new, meta["anchors_s"], tuning)
    print(f"wrote {args.out} ({len(changed)} grid points re-tuned with relief) and "
          f"{args.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
