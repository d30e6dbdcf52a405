"""The load-relief trade at one grid time: relief gain vs nominal margins vs the wind → α gain.

Issue 9 item 3, docs/FLIGHT_DESIGN.md §7. For each relief gain k_a (held fixed) the other 15
parameters of the structured controller with relief (vega_design.structured:
PARAMETERS + RELIEF_PARAMETERS, the filter time constant τ included) are re-tuned jointly on
the design set of that time with the load objective (structured.with_load, ``--load-weight``):
differential evolution seeded from the table's own parameters (k_θ lowered by 0, 0.1, 0.2,
0.3 decades and τ 0.32, 1, 3.2 s: relief adds attitude stiffness), then a Nelder–Mead polish,
as structured.tune_point. Printed and written per k_a: the cost, the nominal PM and GM low/high
of the design evaluation, the requirement misses (structured.requirement_misses) and the
nominal loop's peak wind → α gain V·|α/v_w| over 0.02–1 rad/s (1 for a vehicle holding its
attitude; the shipped table ≈ 1.8 at max-Q).

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python tools/design/relief_trade.py TABLE TIME
       --gains 0,-8,-16,-25 [--load-weight 0.5] [--maxiter 35] [--popsize 8] --out DIR
Writes DIR/relief_trade_<TIME>.json (appended per gain, so a partial run keeps its rows);
``relief_trade.py --out DIR --plot FILE.png`` plots every such file of DIR.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from design_table import structured_grid_point


def tune_fixed_gain(ds, base, k_acc: float, seed: int, maxiter: int, popsize: int):
    """Tune every parameter but k_a (fixed at ``k_acc``) on design set ``ds``; ``base`` is a
    16-parameter start. Returns (x, cost, detail)."""
    from scipy.optimize import differential_evolution, minimize

    from vega_design import structured as S

    lo, hi = S.bounds_for(base.size)
    free = [i for i in range(base.size) if i != 14]
    L, U = lo[free], hi[free]

    def full(y):
        x = np.empty(base.size)
        x[free] = y
        x[14] = k_acc
        return x

    def f(y):
        return S.evaluate(full(y), ds)

    rng = np.random.default_rng(seed)
    n = popsize * len(free)
    pop = L + rng.random((n, len(free))) * (U - L)
    starts = []
    for dk in (0.0, -0.1, -0.2, -0.3):
        for log_tau in (-0.5, 0.0, 0.5):
            y = base[free].copy()
            y[0] += dk
            y[-1] = log_tau
            starts.append(np.clip(y, L, U))
    starts.sort(key=f)
    pop[:6] = starts[:6]
    pop[6:n // 3] = np.clip(starts[0] + 0.05 * (U - L) * rng.standard_normal(
        (n // 3 - 6, len(free))), L, U)
    res = differential_evolution(f, list(zip(L, U)), seed=seed, maxiter=maxiter,
                                 popsize=popsize, init=pop, tol=1e-8, polish=False)
    loc = minimize(f, res.x, method="Nelder-Mead", bounds=list(zip(L, U)),
                   options={"maxfev": 1500, "xatol": 1e-4, "fatol": 1e-6})
    y = min([np.clip(res.x, L, U), np.clip(loc.x, L, U)], key=f)
    x = full(y)
    cost, detail = S.evaluate(x, ds, detail=True)
    return x, cost, detail


def _campaign(path: Path) -> dict:
    """Sample → (Qα ratio, max |z| [m], failed) of a `vega mc run` directory."""
    out = {}
    for f in sorted((path / "samples").glob("*.json")):
        r = json.loads(f.read_text())
        out[r["sample"]] = (r["q_alpha_margin"], r["max_abs_z_m"], r["failed"])
    return out


def plot(json_paths, out_png: Path, window_report: Path | None = None,
         campaigns: tuple[Path, Path] | None = None) -> None:
    """The trade of every relief_trade_<TIME>.json: the wind → α gain against k_a (filled:
    every requirement met on the design set) and the nominal margins against k_a; with
    ``window_report`` (the JSON report of a table written by relief.py) a third panel, the
    wind → α gain per re-tuned grid time before and after."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = 2 + bool(window_report) + bool(campaigns)
    fig, ax = plt.subplots(1, n, figsize=(5.4 * n, 4.2))
    for c, path in enumerate(sorted(json_paths, key=lambda p: float(p.stem.split("_")[-1]))):
        rows = json.loads(Path(path).read_text())
        t = path.stem.split("_")[-1]
        given, tuned = rows[0], rows[1:]
        col = f"C{c}"
        ax[0].axhline(given["wind_alpha_gain"], color=col, ls=":", lw=1)
        ks = [r["k_acc_mrad_per_mps2"] for r in tuned]
        ax[0].plot(ks, [r["wind_alpha_gain"] for r in tuned], "-", color=col, lw=1,
                   label=f"{t} s (dotted: shipped table)")
        for r in tuned:
            ok = not any(r["misses"])
            ax[0].plot(r["k_acc_mrad_per_mps2"], r["wind_alpha_gain"], "o", mec=col,
                       mfc=col if ok else "none", ms=8)
        ax[1].plot(ks, [r["gm_low_db"] for r in tuned], "v-", color=col, label=f"GM low {t} s")
        ax[1].plot(ks, [r["gm_high_db"] for r in tuned], "^--", color=col,
                   label=f"GM high {t} s")
        ax[1].plot(ks, [r["pm_deg"] / 5.0 for r in tuned], "s:", color=col,
                   label=f"PM/5 {t} s")
    ax[0].axhline(1.0, color="k", lw=0.8)
    ax[0].set_xlabel("relief gain k_a [mrad/(m/s²)] (< 0: nose into the wind)")
    ax[0].set_ylabel("peak V·|α/v_w|, 0.02–1 rad/s (nominal loop)")
    ax[0].set_title("load figure after the joint re-tuning (filled: requirements met)",
                    fontsize=9)
    ax[0].legend(fontsize=7)
    ax[1].axhline(6.0, color="k", lw=0.8)
    ax[1].set_xlabel("relief gain k_a [mrad/(m/s²)]")
    ax[1].set_ylabel("GM [dB], PM/5 [deg/5] (requirement 6: 6 dB, 30°)")
    ax[1].set_title("nominal margins of the re-tuned point (design grid)", fontsize=9)
    ax[1].legend(fontsize=6, ncol=2)
    if window_report:
        runs = json.loads(Path(window_report).read_text())["tuning"]["relief"]
        for k, run in enumerate(runs if isinstance(runs, list) else [runs]):
            per = run["per_time"]
            ts = [float(t) for t in per]
            ax[2].plot(ts, [per[t]["wind_alpha_gain_before"] for t in per], "o:", color="0.5",
                       label="shipped table" if k == 0 else None)
            ax[2].plot(ts, [per[t]["wind_alpha_gain_after"] for t in per], "o-", color="C3",
                       label=f"re-tuned, load weight {run['load_weight']:g}"
                       + ("" if run.get("relief_branch", True) else " (no relief branch)"))
        ax[2].axhline(1.0, color="k", lw=0.8)
        ax[2].set_xlabel("grid time [s]")
        ax[2].set_ylabel("peak V·|α/v_w|, 0.02–1 rad/s")
        ax[2].set_title("the window re-tuned (tools/design/relief.py)", fontsize=9)
        ax[2].legend(fontsize=7)
    if campaigns:
        before, after = (_campaign(Path(c)) for c in campaigns)
        common = sorted(set(before) & set(after))
        a = np.array([before[i][0] for i in common])
        b = np.array([after[i][0] for i in common])
        ax[-1].plot(a, b, ".", ms=3, color="C0")
        ax[-1].plot([0.2, 1.8], [0.2, 1.8], "k-", lw=0.8)
        ax[-1].axvline(1.0, color="C3", ls="--", lw=0.8)
        ax[-1].axhline(1.0, color="C3", ls="--", lw=0.8)
        ax[-1].set_xlabel(f"max Qα / envelope, {Path(campaigns[0]).name}")
        ax[-1].set_ylabel(f"max Qα / envelope, {Path(campaigns[1]).name}")
        ax[-1].set_title(f"Monte Carlo per sample ({len(common)} flights, seed 0)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    """Tune per gain, print, write JSON (or, with --plot, only plot the JSON files)."""
    from vega_design import structured as S
    from vega_model.parameters import default_context
    from vega_model.uncertainty import UncertaintySet

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", type=Path, nargs="?")
    parser.add_argument("time", type=float, nargs="?", help="grid time [s]")
    parser.add_argument("--plot", type=Path, default=None,
                        help="only plot DIR's relief_trade_*.json into this PNG")
    parser.add_argument("--window-report", type=Path, default=None,
                        help="with --plot: the JSON report of a table written by relief.py")
    parser.add_argument("--campaigns", type=Path, nargs=2, default=None,
                        metavar=("BEFORE", "AFTER"),
                        help="with --plot: two `vega mc run` directories, Qα per sample")
    parser.add_argument("--gains", default="0,-8,-16,-25",
                        help="k_a [mrad/(m/s²)], comma-separated")
    parser.add_argument("--load-weight", type=float, default=0.5)
    parser.add_argument("--maxiter", type=int, default=35)
    parser.add_argument("--popsize", type=int, default=8)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if args.plot is not None:
        plot(list(args.out.glob("relief_trade_*.json")), args.plot, args.window_report,
             args.campaigns)
        print(f"wrote {args.plot}")
        return 0
    if args.table is None or args.time is None:
        parser.error("TABLE and TIME are required (unless --plot)")
    meta, times, index = structured_grid_point(args.table, args.time)
    x_table = np.asarray(meta["parameters_per_grid_time"][index], dtype=float)
    base = S.with_relief(x_table, *S.RELIEF_OFF) if x_table.size == len(S.PARAMETERS) else x_table
    context = default_context()
    uset = UncertaintySet.from_vehicle(context.vehicle)
    ds = S.with_load(S.design_set(context, args.time, uset), context, args.load_weight)
    _, d0 = S.evaluate(base, ds, detail=True)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"relief_trade_{args.time:g}.json"
    rows = [{"k_acc_mrad_per_mps2": None, "what": "table as given", "pm_deg": d0["pm_deg"],
             "gm_low_db": d0["gm_low_db"], "gm_high_db": d0["gm_high_db"],
             "wind_alpha_gain": d0["wind_alpha_gain"],
             "misses": list(S.requirement_misses(d0))}]
    print(json.dumps(rows[0]), flush=True)
    for k_acc in [float(v) for v in args.gains.split(",")]:
        t0 = time.perf_counter()
        x, cost, d = tune_fixed_gain(ds, base, k_acc, args.seed, args.maxiter, args.popsize)
        rows.append({"k_acc_mrad_per_mps2": k_acc, "tau_acc_s": float(10 ** x[15]),
                     "k_theta": float(10 ** x[0]), "cost": cost, "penalty": d["penalty"],
                     "pm_deg": d["pm_deg"], "gm_low_db": d["gm_low_db"],
                     "gm_high_db": d["gm_high_db"], "wind_alpha_gain": d["wind_alpha_gain"],
                     "misses": list(S.requirement_misses(d)),
                     "penalty_terms": {k: v for k, v in d["penalty_terms"].items() if v},
                     "x": [float(v) for v in x], "wall_s": round(time.perf_counter() - t0, 1),
                     "time_s": args.time, "load_weight": args.load_weight,
                     "maxiter": args.maxiter, "popsize": args.popsize, "seed": args.seed})
        print(json.dumps({k: v for k, v in rows[-1].items() if k != "x"}), flush=True)
        path.write_text(json.dumps(rows, indent=1) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
