"""Benchmark: in-process closed-loop simulation speed (× real time) per scenario and plant.

Usage: .venv/bin/vega-env python bench/bench_simulation.py [TABLE.npz]
Runs each case twice (cold: first run of the span, parameter precompute included; warm:
cached) and reports simulated seconds per wall second, and per CPU second of this process
(the load-independent figure on a shared machine).
"""

import dataclasses
import sys
import time
from pathlib import Path

from vega_sim.closed_loop import run_scenario
from vega_sim.scenario import load_scenario

SHIPPED = Path(__file__).resolve().parent.parent / "ros2_ws/src/vega_gnc/config/lpv_controller.npz"


def main():
    table = sys.argv[1] if len(sys.argv) > 1 else str(SHIPPED)
    if not Path(table).exists():
        sys.exit(f"bench_simulation: no controller table at {table} (pass one as the argument)")
    for name in ("thesis", "nominal"):
        for plant in ("linear", "nonlinear"):
            scenario = dataclasses.replace(load_scenario(name), plant=plant)
            span = scenario.t_end_s - scenario.t_start_s
            speeds, cpu = [], []
            for _ in range(2):
                t0, c0 = time.perf_counter(), time.process_time()
                run_scenario(scenario, table)
                speeds.append(span / (time.perf_counter() - t0))
                cpu.append(span / (time.process_time() - c0))
            print(f"{name:8s} {plant:9s} {span:5.1f} s flight: cold {speeds[0]:6.1f}x, "
                  f"warm {speeds[1]:6.1f}x real time (per CPU second: cold {cpu[0]:.0f}x, "
                  f"warm {cpu[1]:.0f}x)")


if __name__ == "__main__":
    main()
