"""The load/drift trade of the flown structured design (issue 9 item 3; docs/FLIGHT_DESIGN.md §7).

Variants of a structured controller table that differ only in their drift feedback, each checked
on the nominal frozen loops (vega_loops.margins, every 0.5 s, the requirement of
`vega margins`) and flown on the first N samples of a Monte Carlo campaign of the shipped
dispersions (in process, bit-identical to the SIL; vega_campaign.campaign):

* ``drift xF``: the drift-rate gain k_ż × F from 70 s on (design step 6,
  vega_design.structured.scale_drift without its requirement check, so that the
  variants that break a margin are shown too);
* ``relief L``: k_ż + L·(Q/Q_max)·k_θ/V at every grid time, i.e. feedback of the
  ground-relative angle of attack θ + ż/V weighted by dynamic pressure (L > 0 turns the nose
  towards the drift: load relief with the wind the guidance was designed for; L < 0 the other
  way);
* ``accel L``: the lateral acceleration (the derivative of the INS drift rate through a
  1 s first-order filter) fed back with gain L·(Q/Q_max)·k_θ·m/N_α (rad per m/s²): the
  normal-force part of the acceleration is N_α·α/m, so L = 1 weighs α like the attitude.

Writes ``OUT/trade.json`` (per variant: margins worst values, unstable frozen loops, Monte
Carlo pass fraction, failures per requirement, 95th percentiles) and ``OUT/load_drift_trade.png``.
The table given with ``--table`` must carry its unscaled drift gain (``--table`` of a design
whose step 6 was applied: its recorded factor is divided out first).

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python tools/design/load_drift_trade.py
       [--table F] [--runs 150] [--out DIR] [--variants "drift x1,drift x2,relief -1,..."]
Progress on stderr; ≈ 1–4 min per variant at 150 runs on one core.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "ros2_ws/src/vega_gnc/config/tvc_controller.npz"
DEFAULT_VARIANTS = ("drift x1", "drift x1.5", "drift x2", "drift x2.5", "drift x3",
                    "relief 0.5", "relief -1", "relief -2", "accel -0.05", "accel 0.05")
ACCEL_FILTER_S = 1.0
"""Time constant of the first-order filter on the differentiated drift rate [s] (assumption:
below the ≈ 2 rad/s rigid crossover at max-Q, above the drift dynamics)."""


def _base(table_path: Path):
    """Grid times and unscaled parameters of a structured table."""
    from vega_design import structured as S

    meta = json.loads(str(np.load(table_path)["metadata"]))
    if meta.get("design") != "structured":
        raise SystemExit(f"{table_path}: not a structured design table")
    times = np.array(meta["grid_times_s"], dtype=float)
    x = np.array(meta["parameters_per_grid_time"], dtype=float)
    drift = meta.get("solver", {}).get("drift")
    if drift:
        x[times >= drift["from_s"] - 1e-9, S.DRIFT_RATE_INDEX] /= drift["factor"]
    return times, x, tuple(meta["anchors_s"])


def _variant_table(path: Path, name: str, times, x0, anchors, context) -> Path:
    """Write variant ``name`` of the base design to ``path``."""
    from vega_design import structured as S
    from vega_loops.margins import cascade

    kind, value = name.split()
    value = float(value.lstrip("x"))
    x = x0.copy()
    q_max = max(context.parameters(float(t)).q_pa for t in np.arange(0.5, 100.0, 0.5))
    accel = {}
    for i, t in enumerate(times):
        p = context.parameters(float(t))
        weight = p.q_pa / q_max
        k_theta = 10.0 ** x[i, 0]
        if kind == "drift" and t >= S.DRIFT_SCALE_FROM_S - 1e-9:
            x[i, S.DRIFT_RATE_INDEX] *= value
        elif kind == "relief":
            x[i, S.DRIFT_RATE_INDEX] += value * weight * k_theta / max(p.v_mps, 50.0) * 1e3
        elif kind == "accel":
            accel[i] = (value * weight * k_theta * p.mass_kg / p.normal_force_slope_n
                        if weight > 0.05 else 0.0)
        elif kind not in ("drift", "relief", "accel"):
            raise SystemExit(f"--variants: unknown variant {name!r}")
    design = S.StructuredDesign(times, np.array([context.parameters(float(t)).v_mps
                                                 for t in times]), x, [], anchors, {})
    if kind != "accel":
        S.write_structured_table(path, design, context)
        return path
    original = S.controller_ss
    by_params = {tuple(x[i]): accel[i] for i in accel}

    def with_acceleration(params, omega_modes):
        """The structured controller with k_a·s/(τs + 1)·ż added to its input sum."""
        A, B, C, D = original(params, omega_modes)
        params = np.asarray(params, dtype=float)
        k = 10.0 ** params[0]
        gains = np.array([[k, k * 10.0 ** params[1], params[3] * 1e-6, params[2] * 1e-3]])
        chain = (A, B[:, :1] / k, C, D[:, :1] / k)
        k_a, tau = by_params[tuple(params)], ACCEL_FILTER_S
        pre = (np.array([[-1.0 / tau]]), np.array([[0.0, 0.0, 0.0, 1.0 / tau]]),
               np.array([[-k_a / tau]]), gains + np.array([[0.0, 0.0, 0.0, k_a / tau]]))
        return cascade(pre, chain)

    S.controller_ss = with_acceleration
    try:
        S.write_structured_table(path, design, context)
    finally:
        S.controller_ss = original
    return path


def _nominal_margins(table_path: Path) -> dict:
    """Worst nominal margins over 0–100 s every 0.5 s, through `vega margins` itself."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "vega_cli.cli", "margins", "--table",
                        str(table_path), "--out", tmp], check=False, capture_output=True)
        nominal = json.loads((Path(tmp) / "margins.json").read_text())["nominal"]
    out = {k: nominal[k]["worst"] for k in ("gm_low_db", "gm_high_db", "pm_deg")}
    out["unstable_loops"] = nominal["stability"]["n_unstable_loops"]
    out["meets"] = all(v.get("pass", True) for v in nominal.values() if isinstance(v, dict))
    return out


def _fly(table_path: Path, runs: int) -> dict:
    """The first ``runs`` samples of the shipped dispersions on scenario nominal, seed 0."""
    from vega_campaign import campaign as C
    from vega_gnc.controller_table import load_controller_table
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import load_scenario

    base = load_scenario("nominal")
    disp = C.load_dispersions()
    table = load_controller_table(table_path)
    rows = []
    for i in range(runs):
        scenario, _ = C.sample_scenario(base, disp, 0, i)
        rows.append(C.flight_metrics(run_scenario(scenario, table)))
    failed = [r["failed"].split(",") if r["failed"] else [] for r in rows]
    count = lambda key: sum(key in f for f in failed)  # noqa: E731
    pct = lambda key: float(np.percentile([r[key] for r in rows], 95))  # noqa: E731
    return {"runs": runs, "passed": sum(not f for f in failed),
            "q_alpha": count("q_alpha"), "drift_rate": count("drift_rate"),
            "drift": count("drift"), "unstable": count("stability"),
            "q_alpha_margin_p95": pct("q_alpha_margin"),
            "zdot_p95_mps": pct("max_abs_zdot_mps"), "z_p95_m": pct("max_abs_z_m")}


def _plot(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.4))
    for r in results:
        f = r["flights"]
        kind = r["variant"].split()[0]
        style = {"drift": "o", "relief": "s", "accel": "^"}[kind]
        face = "C0" if r["margins"]["meets"] else "none"
        ax[0].plot(f["zdot_p95_mps"], f["q_alpha_margin_p95"], style, mfc=face, mec="C0", ms=8)
        ax[0].annotate(f"{r['variant']} ({f['passed']}/{f['runs']})",
                       (f["zdot_p95_mps"], f["q_alpha_margin_p95"]), fontsize=7,
                       xytext=(4, 3), textcoords="offset points")
        ax[1].bar(r["variant"], f["q_alpha"], color="C3", label="Qα" if r is results[0] else None)
        ax[1].bar(r["variant"], f["drift_rate"], bottom=f["q_alpha"], color="C1",
                  label="drift rate" if r is results[0] else None)
        ax[1].bar(r["variant"], f["unstable"], bottom=f["q_alpha"] + f["drift_rate"],
                  color="k", label="unstable" if r is results[0] else None)
    ax[0].axvline(15.0, color="C1", ls="--", lw=1)
    ax[0].axhline(1.0, color="C3", ls="--", lw=1)
    ax[0].set_xlabel("95th percentile of max |ż| [m/s] (budget 15)")
    ax[0].set_ylabel("95th percentile of max Qα / envelope")
    ax[0].set_title("load vs drift (filled: nominal margins met)", fontsize=9)
    ax[1].set_ylabel("failed flights")
    ax[1].tick_params(axis="x", rotation=60, labelsize=7)
    ax[1].legend(fontsize=7)
    ax[1].set_title("failures per requirement", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    """Build, check and fly every variant; write trade.json and the plot."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table", type=Path, default=SHIPPED)
    parser.add_argument("--runs", type=int, default=150)
    parser.add_argument("--out", type=Path, default=ROOT / "build/load_drift_trade")
    parser.add_argument("--variants", default=",".join(DEFAULT_VARIANTS))
    args = parser.parse_args(argv)
    if not 1 <= args.runs <= 100000:
        parser.error(f"--runs {args.runs}: must be within 1..100000")
    from vega_model.parameters import default_context

    context = default_context()
    times, x0, anchors = _base(args.table)
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    for name in [v.strip() for v in args.variants.split(",") if v.strip()]:
        t0 = time.perf_counter()
        path = _variant_table(args.out / f"{name.replace(' ', '_')}.npz", name, times, x0,
                              anchors, context)
        row = {"variant": name, "margins": _nominal_margins(path), "flights": _fly(path, args.runs)}
        row["wall_s"] = round(time.perf_counter() - t0, 1)
        results.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
        (args.out / "trade.json").write_text(json.dumps(results, indent=1) + "\n")
    _plot(results, args.out / "load_drift_trade.png")
    print(f"wrote {args.out / 'trade.json'} and {args.out / 'load_drift_trade.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
