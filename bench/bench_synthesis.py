"""Benchmark: the 9-point rate-bounded LPV synthesis and the whole `vega synth` chain.

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python bench/bench_synthesis.py [--compare]
       [--points 30,40,50] [--full-chain]

Prints the wall time of the weighted plants, of stage 1 (min γ) and stage 2 (back-off) of the
rate-bounded synthesis on the thesis grid with the shipped weights (solver time and iterations
as Clarabel reports them), and with --full-chain the per-stage times of `vega synth`
(verification and the thesis-scenario simulations included) writing to a temporary file.
Targets (issue 10): synthesis ≤ 60 s, `vega synth` ≤ 120 s on the 2-core machine. Timings on a
machine shared with other processes are noisy: the load average is printed with them.

--compare runs the path before issue 10 (Clarabel, stage-1 LMIs in the 3×3-block form) and the
default path (in-house IPM for stage 1 on the Schur-reduced LMIs, Clarabel for stage 2) back to
back on the same plant and prints the ratios (old / new) per stage, γ_min and the certificates.
--points gives other grid times (e.g. 30,40,50 for the 3-point problem of issue 10).
"""

import os
import sys

import numpy as np
import tempfile
import time
from pathlib import Path

from offline_synthesis.lpv_synthesis import synthesize
from offline_synthesis.pipeline import (grid_times, gridded_plant, rate_bounds_from_trajectory,
                                        rate_box, run_synthesis)
from offline_synthesis.weights import SHIPPED
from vega_model.parameters import default_context


OLD_PATH = dict(solver="CLARABEL", fallback="SCS", stage1_form="full")
NEW_PATH = dict(solver="IPM", fallback=("CLARABEL", "SCS"), stage1_form="reduced")


def _run(plant, rates, label, **options):
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    result = synthesize(plant, rate_bounds=rates, **options)
    total = time.perf_counter() - t0
    ts = result.times_s
    print(f"[{label}] load {load:.1f}->{os.getloadavg()[0]:.1f}: {total:.1f} s total; stage 1 "
          f"{ts['stage1']:.1f} s ({result.solvers['stage1']}, {ts['stage1_iterations']} it), "
          f"stage 2 {ts['stage2']:.1f} s ({result.solvers['stage2']}, "
          f"{ts['stage2_iterations']} it); gamma_min {result.gamma_min:.5f}, gamma "
          f"{result.gamma:.5f}, certificate {result.certificate_max_eig:.2e}", flush=True)
    return result, total


def _compare(plant, rates):
    old, t_old = _run(plant, rates, "before issue 10", **OLD_PATH)
    new, t_new = _run(plant, rates, "experimental (IPM stage 1, reduced LMIs)", **NEW_PATH)
    print(f"ratios old/new: total {t_old / t_new:.2f}, stage 1 "
          f"{old.times_s['stage1'] / new.times_s['stage1']:.2f}, stage 2 "
          f"{old.times_s['stage2'] / new.times_s['stage2']:.2f}; gamma_min new/old - 1 = "
          f"{new.gamma_min / old.gamma_min - 1.0:+.2e}; certificates "
          f"{old.certificate_max_eig:.2e} / {new.certificate_max_eig:.2e}")


def main():
    ctx = default_context()
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    args = sys.argv[1:]
    times = (np.array([float(v) for v in args[args.index("--points") + 1].split(",")])
             if "--points" in args else grid_times("thesis", ctx))
    plant, _ = gridded_plant(times, SHIPPED, ctx)
    rates = rate_box(rate_bounds_from_trajectory(ctx))
    t_plant = time.perf_counter() - t0
    if "--compare" in args:
        print(f"weighted plants ({times.size} points): {t_plant:.2f} s")
        _compare(plant, rates)
        return
    t0 = time.perf_counter()
    result = synthesize(plant, rate_bounds=rates)
    total = time.perf_counter() - t0
    ts = result.times_s
    print(f"load average at start {load:.1f} (2 cores)")
    print(f"weighted plants ({times.size} points): {t_plant:.2f} s")
    print(f"rate-bounded synthesis: {total:.1f} s total; stage 1 {ts['stage1']:.1f} s "
          f"(solver {ts['stage1_solver']:.1f} s, {ts['stage1_iterations']} it), stage 2 "
          f"{ts['stage2']:.1f} s (solver {ts['stage2_solver']:.1f} s, {ts['stage2_iterations']} "
          f"it), certificate included; gamma_min {result.gamma_min:.4f}, gamma {result.gamma:.4f}")
    if "--full-chain" in args:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            rep = run_synthesis(out=Path(tmp) / "lpv_controller.npz", context=ctx,
                                progress=lambda line: None)
            wall = time.perf_counter() - t0
        print(f"vega synth chain: {wall:.1f} s; "
              + ", ".join(f"{k} {v:.1f} s" for k, v in rep.stage_times_s.items()))


if __name__ == "__main__":
    main()
