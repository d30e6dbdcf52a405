"""Benchmark: day-of-launch re-biasing per campaign sample, the cvxpy route against the QP
assembled once, in one run.

Usage: .venv/bin/vega-env python bench/bench_rebias.py [--samples N] [--old K] [--month M]
       [--seed S] [--write]

Samples: the measured profiles (the soundings) of ``--samples`` samples (default 20) of month
``--month`` (default 7) of the shipped Kourou site file, seed ``--seed`` (default 0)
(``vega_campaign.wind_environment``). Per sample, the guidance reference is solved on the
measured profile:

* **old**: ``vega_reference.guidance.design_reference`` with the table as its design wind — the
  rigid models along the nominal (N matrix exponentials), the cvxpy problem, Clarabel — for the
  first ``--old`` samples (default 3; it takes seconds each);
* **new**: ``vega_reference.rebias.rebias_reference`` — the QP assembled once per process
  (timed on its own, once) and re-solved with Clarabel per sample.

The old and new solves alternate over the first ``--old`` samples (a drifting load hits both
alike). Figures per sample: wall seconds and CPU seconds of the process (the load-independent
figure on a shared machine), with the 1-minute load average at the start and end; the target
is ≤ 0.2 s per sample. Checks printed: old and new agree to the solver's tolerance (largest
state and feed-forward difference), and two new solves of one sample are the same bits.
``--write`` also times writing each sample's reference file (``write_rebiased_reference``:
npz, the flight software's loader, the JSON summary; includes a ``git describe``).
"""

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def _timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def _stats(values) -> str:
    v = sorted(values)
    return (f"median {statistics.median(v):.3f} s, min {v[0]:.3f}, max {v[-1]:.3f} "
            f"(n = {len(v)})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--old", type=int, default=3)
    ap.add_argument("--month", type=int, default=7)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()

    from vega_campaign.wind_environment import load_site, sample_profiles, sample_table
    from vega_reference.guidance import DesignWind, design_reference
    from vega_reference.rebias import GuidanceQP, rebias_reference, write_rebiased_reference

    load0 = os.getloadavg()[0]
    samples = sample_profiles(load_site(), args.month, n=args.samples, seed=args.seed)
    tables = [sample_table(samples, int(i), "measured") for i in samples.indices]
    print(f"{len(tables)} measured profiles, month {args.month}, seed {args.seed}; "
          f"|wind| up to {max(np.abs(t.wind_mps).max() for t in tables):.1f} m/s; "
          f"load average {load0:.2f} on {os.cpu_count()} CPUs")

    qp, build_wall, build_cpu = _timed(GuidanceQP)
    print(f"new: QP assembled once in {build_wall:.2f} s wall, {build_cpu:.2f} s CPU")
    rebias_reference(tables[0].altitude_m, tables[0].wind_mps, problem=qp)   # warm-up

    old_wall, old_cpu, new_wall, new_cpu, state_diff, beta_diff = [], [], [], [], [], []
    for k, table in enumerate(tables):
        new, w, c = _timed(lambda t=table: rebias_reference(t.altitude_m, t.wind_mps,
                                                            problem=qp))
        new_wall.append(w)
        new_cpu.append(c)
        if k < args.old:
            wind = DesignWind.from_table(table.altitude_m, table.wind_mps)
            old, w, c = _timed(lambda wd=wind: design_reference(wd))
            old_wall.append(w)
            old_cpu.append(c)
            state_diff.append(float(np.abs(old.states - new.states).max()))
            beta_diff.append(float(np.abs(old.beta_ff_rad - new.beta_ff_rad).max()))
    again = rebias_reference(tables[-1].altitude_m, tables[-1].wind_mps, problem=qp)
    same = all(np.array_equal(getattr(again, n), getattr(new, n))
               for n in ("states", "reference", "beta_ff_rad"))

    print(f"old (cvxpy, models per sample): wall {_stats(old_wall)}; CPU {_stats(old_cpu)}")
    print(f"new (QP assembled once):       wall {_stats(new_wall)}; CPU {_stats(new_cpu)}")
    print(f"speed-up (median wall) {statistics.median(old_wall) / statistics.median(new_wall):.0f}x"
          f", (median CPU) {statistics.median(old_cpu) / statistics.median(new_cpu):.0f}x; "
          f"target <= 0.2 s per sample: "
          f"{'met' if statistics.median(new_wall) <= 0.2 else 'NOT met'} (wall median)")
    print(f"old vs new: largest state difference {max(state_diff):.2e} (of 250 m), "
          f"feed-forward {max(beta_diff):.2e} rad; two new solves identical: {same}")
    if args.write:
        with tempfile.TemporaryDirectory() as tmp:
            times = []
            for k, table in enumerate(tables[:5]):
                design = rebias_reference(table.altitude_m, table.wind_mps, problem=qp)
                _, w, _ = _timed(lambda d=design, t=table, k=k: write_rebiased_reference(
                    Path(tmp) / f"sample{k}.npz", d, t.altitude_m, t.wind_mps))
                times.append(w)
            print(f"writing a reference file: wall {_stats(times)}")
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
