"""Benchmark: Monte Carlo campaign throughput and its scaling from 1 to 2 workers.

Usage: .venv/bin/vega-env python bench/bench_mc.py [RUNS] [SPAN_S]
Flies the same RUNS dispersed samples (default 16) of `nominal` cut to its first SPAN_S seconds
(default 30, from lift-off) on a LocalCluster of 1 and then 2 worker processes, in one run, and
prints flights per second, simulated seconds per wall second per worker, and the 2/1 ratio
(targets >= 1.8 and >= 200x real time per core, docs/MONTE_CARLO.md §8). Campaign directories
go to a temporary folder.
"""

import sys
import tempfile
import time
from pathlib import Path


def main():
    import dataclasses

    from vega_campaign.campaign import load_dispersions
    from vega_campaign.campaign_run import run_campaign
    from vega_gnc.controller_table import default_table_path
    from vega_sim.scenario import load_scenario

    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 16
    span = float(sys.argv[2]) if len(sys.argv) > 2 else 30.0
    scenario = dataclasses.replace(load_scenario("nominal"), t_end_s=span)
    disp = load_dispersions()
    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        for workers in (1, 2):
            out = Path(tmp) / f"w{workers}"
            t0 = time.perf_counter()
            run_campaign(scenario, disp, runs=runs, seed=0, out=out,
                         table_path=default_table_path(), workers=workers,
                         progress=lambda line: None)
            wall = time.perf_counter() - t0
            rates[workers] = runs / wall
            print(f"{workers} worker(s): {runs} flights of {span:g} s in {wall:.1f} s = "
                  f"{rates[workers]:.2f} flights/s, {rates[workers] * span / workers:.0f}x "
                  f"real time per worker (cluster start-up included)")
    print(f"scaling 1 -> 2 workers: {rates[2] / rates[1]:.2f}x")


if __name__ == "__main__":
    main()
