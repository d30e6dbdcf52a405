"""Benchmark: dispersed 100 s flights, the per-flight path against the batched engine, in one run.

Usage: .venv/bin/vega-env python bench/bench_batch.py [--batch N] [--single K] [--repeat R]
       [--seed S] [--scenario NAME]

Both sides fly Monte Carlo samples of ``--scenario`` (default ``nominal``) drawn by
``vega_campaign.campaign.sample_scenario`` with the shipped dispersions and campaign seed
``--seed`` (default 0), and compute each flight's campaign row (``flight_metrics``: the
requirement verdict and metrics), as ``vega mc run`` does:

* **per-flight**: ``run_scenario`` once per sample (``fly_sample``'s work), ``--single`` samples
  (default 6);
* **batched**: ``vega_sim.batch.fly_batch`` over ``--batch`` samples at once (default 64).

The two alternate ``--repeat`` times (default 2) in this one process after a warm-up of each
(compiled code loaded, tables read), so that the machine's load hits both alike. Figures: CPU
seconds of the process per flight (the load-independent figure on a shared machine), flights
per CPU second (= per core) and wall seconds per flight; the ratio per-flight/batched of the
CPU figures; and the batched engine's CPU split into sampling, per-sample inputs (parameter
track, wind, noise), the frame loop (compiled truth side + batched controller) and the metrics.

The samples flown on both sides are also compared: every recorded array of the per-flight
flights against the same samples of the batch, as bytes ("bit-identical" in the output).
"""

import argparse
import os
import time

import numpy as np


def _cpu() -> float:
    return time.process_time()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64, help="samples per batch")
    parser.add_argument("--single", type=int, default=6, help="per-flight samples per repeat")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0, help="campaign seed")
    parser.add_argument("--scenario", default="nominal")
    args = parser.parse_args()

    from vega_campaign.campaign import flight_metrics, load_dispersions, sample_scenario
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_sim import batch
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import load_scenario

    base, disp = load_scenario(args.scenario), load_dispersions()
    table = load_controller_table(default_table_path())
    span = base.t_end_s - base.t_start_s

    def draw(first, count):
        return [sample_scenario(base, disp, args.seed, i)[0] for i in range(first, first + count)]

    # warm-up: compiled kernels loaded (numba cache), reference and tables read
    warm = draw(10_000, 1)
    flight_metrics(run_scenario(warm[0], table))
    flight_metrics(batch.fly_batch(warm, table)[0])

    load0 = os.getloadavg()
    single_cpu, single_wall, batch_cpu, batch_wall = [], [], [], []
    split = {"sampling": 0.0, "inputs": 0.0, "loop": 0.0, "metrics": 0.0}
    identical = True
    inputs = batch._sample_inputs
    spent = {"inputs": 0.0}

    def timed_inputs(*a, **k):
        c = _cpu()
        try:
            return inputs(*a, **k)
        finally:
            spent["inputs"] += _cpu() - c

    batch._sample_inputs = timed_inputs
    first = 0
    for _ in range(args.repeat):
        # per-flight path: sample, fly, metrics
        singles = []
        c, w = _cpu(), time.perf_counter()
        for i in range(first, first + args.single):
            scenario = sample_scenario(base, disp, args.seed, i)[0]
            result = run_scenario(scenario, table)
            flight_metrics(result)
            singles.append(result)
        single_cpu.append((_cpu() - c) / args.single)
        single_wall.append((time.perf_counter() - w) / args.single)
        # batched: sample all, fly at once, metrics of each
        spent["inputs"] = 0.0
        c, w = _cpu(), time.perf_counter()
        scenarios = draw(first, args.batch)
        c1 = _cpu()
        results = batch.fly_batch(scenarios, table)
        c2 = _cpu()
        for result in results:
            flight_metrics(result)
        c3 = _cpu()
        batch_cpu.append((c3 - c) / args.batch)
        batch_wall.append((time.perf_counter() - w) / args.batch)
        split["sampling"] += (c1 - c) / args.batch
        split["inputs"] += spent["inputs"] / args.batch
        split["loop"] += (c2 - c1 - spent["inputs"]) / args.batch
        split["metrics"] += (c3 - c2) / args.batch
        for expected, got in zip(singles, results):
            a, b = expected.arrays(), got.arrays()
            identical &= all(a[k].dtype == b[k].dtype and a[k].tobytes() == b[k].tobytes()
                             for k in a)
        first += max(args.batch, args.single)
    load1 = os.getloadavg()

    s_cpu, b_cpu = float(np.mean(single_cpu)), float(np.mean(batch_cpu))
    print(f"bench_batch: {args.scenario} {span:g} s flights, campaign seed {args.seed}, "
          f"batch of {args.batch}, {args.single} per-flight samples, {args.repeat} repeats; "
          f"load average {load0[0]:.2f} -> {load1[0]:.2f}")
    print(f"  per-flight: {s_cpu:.4f} CPU s/flight ({1.0 / s_cpu:.2f} flights/s/core), "
          f"{np.mean(single_wall):.4f} wall s/flight; repeats "
          + ", ".join(f"{x:.4f}" for x in single_cpu))
    print(f"  batched:    {b_cpu:.4f} CPU s/flight ({1.0 / b_cpu:.2f} flights/s/core), "
          f"{np.mean(batch_wall):.4f} wall s/flight; repeats "
          + ", ".join(f"{x:.4f}" for x in batch_cpu))
    print(f"  ratio per-flight/batched (CPU): {s_cpu / b_cpu:.2f}x")
    print("  batched CPU s/flight by part: " + ", ".join(
        f"{k} {v / args.repeat:.4f}" for k, v in split.items()))
    print(f"  bit-identical on the {args.single * args.repeat} samples flown both ways: "
          f"{'yes' if identical else 'NO'}")
    return 0 if identical else 1


if __name__ == "__main__":
    raise SystemExit(main())
