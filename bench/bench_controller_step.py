"""Benchmark: on-board controller step time (vega_gnc ControllerRuntime), median and p99.

Usage: .venv/bin/vega-env python bench/bench_controller_step.py [TABLE.npz ...]
Default tables: the flown structured table (ros2_ws/src/vega_gnc/config/tvc_controller.npz)
and the shipped LPV table (lpv_controller.npz), each if present; without either, a synthetic
19-state, 9-point table of the LPV table's shape (stated in the output).
"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from vega_loops.export import write_controller_table
from vega_gnc.controller_runtime import ControllerRuntime, Measurement
from vega_gnc.controller_table import load_controller_table
from vega_gnc.guidance_reference import load_guidance_reference

CONFIG = Path(__file__).resolve().parent.parent / "ros2_ws/src/vega_gnc/config"
DEFAULT_TABLES = (CONFIG / "tvc_controller.npz", CONFIG / "lpv_controller.npz")
NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]


def _synthetic_table():
    rng = np.random.default_rng(0)
    n, N = 19, 9
    A = -5 * np.eye(n) + 0.3 * rng.standard_normal((N, n, n))
    mats = (A, rng.standard_normal((N, n, 4)), rng.standard_normal((N, 1, n)),
            rng.standard_normal((N, 1, 4)))
    meta = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
            "units": {}, "weights": {}, "solver": {}}
    path = Path(tempfile.mkdtemp()) / "synthetic.npz"
    return write_controller_table(path, np.linspace(96, 1771, N), *mats, dt_s=0.02, gamma=1,
                                  gamma_min=1, rate_bounds_mps2=[5.4, 36.4], metadata=meta)


def _time_steps(runtime, table, n: int = 50_000) -> np.ndarray:
    """Step times [µs] over n measurements sweeping the grid (0–100 s of stamps)."""
    v0, v1 = table.grid_v_mps[0], table.grid_v_mps[-1]
    samples = np.empty(n)
    rng = np.random.default_rng(1)
    noise = 1e-4 * rng.standard_normal((n, 4))
    for k in range(n):
        m = Measurement(k * 0.002, *noise[k], v0 + (v1 - v0) * k / n, True)
        t0 = time.perf_counter()
        runtime.step(m)
        samples[k] = time.perf_counter() - t0
    return samples * 1e6


def main():
    paths = sys.argv[1:] or [p for p in DEFAULT_TABLES if p.exists()]
    tables = [load_controller_table(p) for p in paths] or [_synthetic_table()]
    reference = CONFIG / "guidance_reference.npz"
    for table in tables:
        print(f"table: {table.path} ({table.n_states} states, {table.grid_v_mps.size} grid "
              "points)")
        cases = [("no guidance reference", None)]
        if reference.exists():
            cases.append(("shipped guidance reference", load_guidance_reference(reference)))
        for label, ref in cases:
            us = _time_steps(ControllerRuntime(table, reference=ref), table)
            print(f"controller step, {label}: median {np.median(us):.1f} us, "
                  f"p99 {np.percentile(us, 99):.1f} us, max {us.max():.1f} us over {us.size} "
                  "steps")


if __name__ == "__main__":
    main()
