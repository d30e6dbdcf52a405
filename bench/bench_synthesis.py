"""Benchmark: the 9-point rate-bounded LPV synthesis and the whole `vega synth` chain.

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python bench/bench_synthesis.py [--full-chain]

Prints the wall time of the weighted plants, of stage 1 (min γ) and stage 2 (back-off) of the
rate-bounded synthesis on the thesis grid with the shipped weights (solver time and iterations
as Clarabel reports them), and with --full-chain the per-stage times of `vega synth`
(verification and the thesis-scenario simulations included) writing to a temporary file.
Targets (issue 3): synthesis ≤ 60 s, `vega synth` ≤ 120 s on the 2-core machine. Timings on a
machine shared with other processes are noisy: the load average is printed with them.
"""

import os
import sys
import tempfile
import time
from pathlib import Path

from offline_synthesis.lpv_synthesis import synthesize
from offline_synthesis.pipeline import (grid_times, gridded_plant, rate_bounds_from_trajectory,
                                        rate_box, run_synthesis)
from offline_synthesis.weights import SHIPPED
from vega_model.parameters import default_context


def main():
    ctx = default_context()
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    plant, _ = gridded_plant(grid_times("thesis", ctx), SHIPPED, ctx)
    rates = rate_box(rate_bounds_from_trajectory(ctx))
    t_plant = time.perf_counter() - t0
    t0 = time.perf_counter()
    result = synthesize(plant, rate_bounds=rates)
    total = time.perf_counter() - t0
    ts = result.times_s
    print(f"load average at start {load:.1f} (2 cores)")
    print(f"weighted plants (9 points): {t_plant:.2f} s")
    print(f"rate-bounded synthesis: {total:.1f} s total; stage 1 {ts['stage1']:.1f} s "
          f"(solver {ts['stage1_solver']:.1f} s, {ts['stage1_iterations']} it), stage 2 "
          f"{ts['stage2']:.1f} s (solver {ts['stage2_solver']:.1f} s, {ts['stage2_iterations']} "
          f"it), certificate included; gamma_min {result.gamma_min:.4f}, gamma {result.gamma:.4f}")
    if "--full-chain" in sys.argv[1:]:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            rep = run_synthesis(out=Path(tmp) / "lpv_controller.npz", context=ctx,
                                progress=lambda line: None)
            wall = time.perf_counter() - t0
        print(f"vega synth chain: {wall:.1f} s; "
              + ", ".join(f"{k} {v:.1f} s" for k, v in rep.stage_times_s.items()))


if __name__ == "__main__":
    main()
