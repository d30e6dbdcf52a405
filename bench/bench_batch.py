"""Benchmark: dispersed 100 s flights, the per-flight path against the batched engine, in one run.

Usage: .venv/bin/vega-env python bench/bench_batch.py [--batch N] [--single K] [--repeat R]
       [--seed S] [--scenario NAME] [--mc RUNS [--mc-batch B] [--no-inprocess]]

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

``--mc RUNS`` then measures the real command, ``vega mc run --environment thesis-box
--scenario nominal --runs RUNS``
(seed 0, fresh processes, a LocalCluster each), old against new: ``--batch 1`` (one
``fly_sample`` task per flight, the per-flight path) and ``--batch B`` (``--mc-batch``, default
the command's), each on 1 and on 2 workers, in the order per-flight/1, batched/1, batched/2,
per-flight/2 (so that a drifting load hits both paths alike). Per campaign: the whole command's
wall time; the runner's flying rate (its last progress line: from the cluster's start to the
last row written) and that rate per worker, = flights/s per core when each worker has a core;
the CPU seconds of the command and all its processes per flight (start-up, cluster, imports,
results and plots included: the load-independent figure); and the ratios batched/per-flight and
2/1 workers. Both paths' results.parquet are compared row by row (wall times apart).
``--no-inprocess`` skips the in-process comparison.
"""

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

_RATE = re.compile(r"mc: \d+/\d+ done, .*?, (?P<rate>[\d.]+) flights/s")


def _campaign(runs: int, batch: int, workers: int, out: Path) -> dict:
    """One ``vega mc run`` in a fresh process: its wall, flying rate and CPU of its tree."""
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "vega_cli.cli", "mc", "run", "--environment",
                           "thesis-box", "--scenario", "nominal", "--runs", str(runs),
                           "--seed", "0", "--workers",
                           str(workers), "--batch", str(batch), "--out", str(out)],
                          capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode not in (0, 1):               # 1: some flight failed its verdict
        sys.exit(f"bench_batch: vega mc run failed:\n{done.stderr[-2000:]}")
    rates = [float(m) for m in _RATE.findall(done.stdout)]
    return {"wall_s": wall, "flying": rates[-1] if rates else float("nan"),
            "cpu_s": (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)}


def _rows(out: Path) -> str:
    import pyarrow.parquet as pq

    rows = pq.read_table(out / "results.parquet").to_pylist()
    for r in rows:
        r.pop("wall_s")
    return json.dumps(rows, sort_keys=True)


def _mc(runs: int, batch: int) -> bool:
    """The ``--mc`` comparison (module docstring); True when both paths gave the same rows."""
    order = (("per-flight", 1, 1), ("batched", batch, 1), ("batched", batch, 2),
             ("per-flight", 1, 2))
    got, rows = {}, {}
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="bench_batch_mc_") as scratch:
        for path, b, workers in order:
            out = Path(scratch) / f"{path}-w{workers}"
            got[path, workers] = r = _campaign(runs, b, workers, out)
            rows[path, workers] = _rows(out)
            print(f"  vega mc run --runs {runs} --batch {b} --workers {workers}: "
                  f"{r['wall_s']:.1f} s wall; flying {r['flying']:.2f} flights/s = "
                  f"{r['flying'] / workers:.2f} per worker; CPU {r['cpu_s']:.1f} s = "
                  f"{r['cpu_s'] / runs:.3f} s per flight ({runs / r['cpu_s']:.2f} flights per "
                  f"CPU s)", flush=True)
    load1 = os.getloadavg()
    same = len(set(rows.values())) == 1
    print(f"bench_batch --mc: nominal 100 s flights, campaign seed 0, {runs} runs, batch {batch} "
          f"against --batch 1; load average {load0[0]:.2f} -> {load1[0]:.2f}")
    for workers in (1, 2):
        old, new = got["per-flight", workers], got["batched", workers]
        print(f"  {workers} worker(s): flying per worker {old['flying'] / workers:.2f} -> "
              f"{new['flying'] / workers:.2f} flights/s = {new['flying'] / old['flying']:.2f}x; "
              f"flights per CPU s (whole command) {runs / old['cpu_s']:.2f} -> "
              f"{runs / new['cpu_s']:.2f} = {old['cpu_s'] / new['cpu_s']:.2f}x; whole command "
              f"{old['wall_s']:.1f} -> {new['wall_s']:.1f} s = "
              f"{old['wall_s'] / new['wall_s']:.2f}x")
    for path in ("per-flight", "batched"):
        one, two = got[path, 1], got[path, 2]
        print(f"  scaling 1 -> 2 workers, {path}: flying {two['flying'] / one['flying']:.2f}x, "
              f"whole command {one['wall_s'] / two['wall_s']:.2f}x")
    print(f"  results.parquet rows of the four campaigns identical (wall times apart): "
          f"{'yes' if same else 'NO'}")
    return same


def _cpu() -> float:
    return time.process_time()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64, help="samples per batch")
    parser.add_argument("--single", type=int, default=6, help="per-flight samples per repeat")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0, help="campaign seed")
    parser.add_argument("--scenario", default="nominal")
    parser.add_argument("--mc", type=int, default=0, metavar="RUNS",
                        help="also time vega mc run, --batch 1 against batched (0: not)")
    parser.add_argument("--mc-batch", type=int, default=None, metavar="B",
                        help="the batched campaigns' --batch (default: the command's)")
    parser.add_argument("--no-inprocess", action="store_true",
                        help="skip the in-process comparison")
    args = parser.parse_args()
    identical = True
    if not args.no_inprocess:
        identical = _inprocess(args)
    if args.mc:
        from vega_campaign.campaign_run import DEFAULT_BATCH

        identical &= _mc(args.mc, args.mc_batch or DEFAULT_BATCH)
    return 0 if identical else 1


def _inprocess(args) -> bool:
    """The in-process comparison (module docstring); True when bit-identical."""
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
          f"{'yes' if identical else 'NO'}", flush=True)
    return identical


if __name__ == "__main__":
    raise SystemExit(main())
