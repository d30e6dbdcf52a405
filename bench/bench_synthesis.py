"""Benchmark: the 9-point rate-bounded LPV synthesis and the whole `vega synth` chain.

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python bench/bench_synthesis.py [--compare]
       [--points 30,40,50 | --grid thesis|refined] [--path ipm|hybrid] [--full-chain]
       [--chain-only]

Prints the wall time of the weighted plants, of stage 1 (min γ) and stage 2 (back-off) of the
rate-bounded synthesis on the thesis grid with the shipped weights (solver time and iterations
as Clarabel reports them), and with --full-chain the per-stage times of `vega synth`
(verification and the thesis-scenario simulations included) writing to a temporary file.
Targets (docs/SYNTHESIS.md §8): synthesis ≤ 60 s, `vega synth` ≤ 120 s on the 2-core machine.
Timings on a machine shared with other processes are noisy: the load average is printed with
them.

--compare runs the "clarabel" path (pipeline.SOLVER_PATHS["clarabel"], the path of the shipped
lpv_controller.npz: Clarabel, stage-1 LMIs in the 3×3-block form) and the IPM path
(SOLVER_PATHS["ipm"]: the in-house interior point for stage 1 on the Schur-reduced LMIs and for
stage 2 on the self-dual embedding) back to back on the same plant and prints the ratios
(old / new) per stage, γ_min and the certificates; with --full-chain also the whole `vega synth`
chain both ways (old: Clarabel, stages one after the other; new: IPM, LTI bounds and quadratic
synthesis in a second process), with the dense certificate. --path picks the new path (default
ipm; hybrid = Clarabel stage 1, IPM stage 2, the path for the 26-point grid, docs/SYNTHESIS.md
§8). --points gives other grid times (e.g. 30,40,50 for the 3-point problem of
docs/SYNTHESIS.md §8), --grid a named grid (the chain runs on the grid named by --grid, default
refined); --chain-only skips the synthesis comparison.
"""

import os
import resource
import sys

import numpy as np
import tempfile
import time
from pathlib import Path

from vega_lpv.lpv_synthesis import synthesize
from vega_lpv.pipeline import (SOLVER_PATHS, grid_times, gridded_plant,
                                        rate_bounds_from_trajectory, rate_box, run_synthesis)
from vega_lpv.weights import SHIPPED
from vega_model.parameters import default_context


OLD_PATH = "clarabel"


def _cpu():
    """CPU time [s] of this process and its finished children (user + system): on the shared
    machine the wall time depends on the load, the CPU time much less."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _run(plant, rates, label, **options):
    load = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), _cpu()
    result = synthesize(plant, rate_bounds=rates, **options)
    total, cpu = time.perf_counter() - t0, _cpu() - c0
    ts = result.times_s
    print(f"[{label}] load {load:.1f}->{os.getloadavg()[0]:.1f}: {total:.1f} s total "
          f"(CPU {cpu:.1f} s); stage 1 "
          f"{ts['stage1']:.1f} s ({result.solvers['stage1']}, {ts['stage1_iterations']} it), "
          f"stage 2 {ts['stage2']:.1f} s ({result.solvers['stage2']}, "
          f"{ts['stage2_iterations']} it); gamma_min {result.gamma_min:.5f}, gamma "
          f"{result.gamma:.5f}, certificate {result.certificate_max_eig:.2e}", flush=True)
    return result, total, cpu


def _chain(label, grid, ctx, **options):
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), _cpu()
        rep = run_synthesis(grid=grid, out=Path(tmp) / "lpv_controller.npz", context=ctx,
                            progress=lambda line: None, **options)
        wall, cpu = time.perf_counter() - t0, _cpu() - c0
    dense = rep.certificate_dense
    print(f"[{label}] vega synth --grid {grid}: {wall:.1f} s (CPU {cpu:.1f} s incl. the second "
          f"process; load {load:.1f}->{os.getloadavg()[0]:.1f}); " + ", ".join(f"{k} {v:.1f} s"
                                                   for k, v in rep.stage_times_s.items())
          + f"; gamma_min {rep.gamma_min:.5f}, gamma {rep.gamma:.5f}, quadratic "
          f"{rep.gamma_quadratic:.4f}; certificate grid {rep.certificate_grid_max:.2e}, 4x denser "
          f"{dense['n_failed']} of {dense['n_points']} fail (max {rep.certificate_dense_max:.2e})",
          flush=True)
    return rep, wall, cpu


def _compare_chain(grid, ctx, path):
    old, t_old, c_old = _chain("before issue 10", grid, ctx, solver_path="clarabel",
                               parallel=False)
    new, t_new, c_new = _chain(f"{path} path, second process", grid, ctx, solver_path=path,
                               parallel=True)
    print(f"chain ratios old/new: total {t_old / t_new:.2f} (CPU {c_old / c_new:.2f}), "
          f"rate-bounded synthesis "
          f"{old.stage_times_s['lpv_rate_bounded'] / new.stage_times_s['lpv_rate_bounded']:.2f}"
          f"; gamma_min new/old - 1 = {new.gamma_min / old.gamma_min - 1.0:+.2e}, gamma "
          f"{new.gamma / old.gamma - 1.0:+.2e}")


def _compare(plant, rates, path):
    old, t_old, c_old = _run(plant, rates, "before issue 10", **SOLVER_PATHS[OLD_PATH])
    new, t_new, c_new = _run(plant, rates, f"{path} path", **SOLVER_PATHS[path])
    print(f"ratios old/new: total {t_old / t_new:.2f} (CPU {c_old / c_new:.2f}), stage 1 "
          f"{old.times_s['stage1'] / new.times_s['stage1']:.2f}, stage 2 "
          f"{old.times_s['stage2'] / new.times_s['stage2']:.2f}; gamma_min new/old - 1 = "
          f"{new.gamma_min / old.gamma_min - 1.0:+.2e}; certificates "
          f"{old.certificate_max_eig:.2e} / {new.certificate_max_eig:.2e}")


def main():
    ctx = default_context()
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    args = sys.argv[1:]
    grid = args[args.index("--grid") + 1] if "--grid" in args else None
    path = args[args.index("--path") + 1] if "--path" in args else "ipm"
    times = (np.array([float(v) for v in args[args.index("--points") + 1].split(",")])
             if "--points" in args else grid_times(grid or "thesis", ctx, SHIPPED))
    plant, _ = gridded_plant(times, SHIPPED, ctx)
    rates = rate_box(rate_bounds_from_trajectory(ctx))
    t_plant = time.perf_counter() - t0
    if "--compare" in args:
        print(f"weighted plants ({times.size} points): {t_plant:.2f} s")
        if "--chain-only" not in args:
            _compare(plant, rates, path)
        if "--full-chain" in args:
            _compare_chain(grid or "refined", ctx, path)
        return
    t0 = time.perf_counter()
    result = synthesize(plant, rate_bounds=rates, **SOLVER_PATHS[path])
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
            rep = run_synthesis(grid=grid or "refined", out=Path(tmp) / "lpv_controller.npz",
                                context=ctx, progress=lambda line: None, solver_path=path)
            wall = time.perf_counter() - t0
        print(f"vega synth chain: {wall:.1f} s; "
              + ", ".join(f"{k} {v:.1f} s" for k, v in rep.stage_times_s.items()))


if __name__ == "__main__":
    main()
