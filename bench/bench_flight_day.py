"""Benchmark: a flight-day task, one flight at a time against the batched task, in one run.

Usage: .venv/bin/vega-env python bench/bench_flight_day.py [--samples N] [--repeat R] [--seed S]

Both sides draw, judge and fly the same flight-day samples 0 … N−1 (default 32) of the
campaign seed ``--seed`` (default 0) with the shipped site file, LCC, dispersions and table:

* **one at a time** (the task before the batched engine flew a reference per sample): per
  sample, ``flight_day_sample`` (the re-biased reference, written), ``run_scenario`` of the
  predicted flight, ``evaluate_lcc``, ``run_scenario`` of the sample's flight, its row;
* **batched**: ``vega_signoff.flight_day.fly_flight_day_batch`` on the same indices (the
  predicted flights as one batch, the flights as another).

Each side writes its references into a directory of its own, so both pay the re-biasing. The
fixed costs of a worker process (the guidance problem's assembly, the LCC's drift sensitivity)
are paid once, before either side is timed, and reported. The two sides alternate ``--repeat``
times (default 2) so that the machine's load hits both alike. Figures: CPU seconds of the
process per sample (the load-independent figure), wall seconds per sample, and the ratio; the
rows of both sides are compared (every field but the wall time) and the result printed.
"""

import argparse
import json
import tempfile
import time
from pathlib import Path


def _cpu() -> float:
    return time.process_time()


def one_at_a_time(base, disp, seed, env, table, table_path, spec, indices,
                  out_dir) -> list[dict]:
    """The task as it was before the per-sample references of the batched engine."""
    from vega_campaign.campaign import flight_metrics
    from vega_campaign.wind_environment import change_rms_mps
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import dump_scenario
    from vega_signoff.flight_day import flight_day_metrics, flight_day_sample
    from vega_signoff.lcc import drift_allowance_m, evaluate_lcc, predicted_scenario

    alt = env.site.fine_altitude_m
    rows = []
    for index in indices:
        s = flight_day_sample(base, disp, seed, index, env, out_dir)
        sigma = change_rms_mps(env.site, s.month, env.lag_s)
        dz = drift_allowance_m(dump_scenario(base), table_path, alt, sigma,
                               env.site.change_vertical_correlation_m, env.lcc)
        predicted = run_scenario(predicted_scenario(base, s.measured, s.scenario.guidance),
                                 table)
        lcc = evaluate_lcc(predicted, s.measured, alt, sigma, dz, env.lcc, spec)
        del predicted
        result = run_scenario(s.scenario, table)
        row = {"sample": index, "seed": int(s.scenario.seed), **s.values,
               **flight_metrics(result), **flight_day_metrics(result, spec), **lcc.row()}
        row["flight_day_verdict"] = ("scrubbed" if not row["lcc_go"] else
                                     "pass" if row["passed_allowable"] and row["stable"]
                                     else "fail")
        rows.append(row)
    return rows


def _differ(a: dict, b: dict) -> list[str]:
    """The fields of two rows that differ, as their JSON text (so NaN equals NaN, also inside
    the Mach-binned Qα profile); the wall time left out."""
    return [k for k in sorted((set(a) | set(b)) - {"wall_s"})
            if json.dumps(a.get(k)) != json.dumps(b.get(k))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from vega_campaign.campaign import default_dispersions_path, parse_dispersions
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_sim.requirements import load_requirements
    from vega_sim.scenario import dump_scenario, load_scenario
    from vega_signoff.flight_day import (environment_settings, fly_flight_day_batch,
                                         parse_environment)
    from vega_signoff.lcc import drift_sensitivity

    base = load_scenario("nominal")
    disp_text = default_dispersions_path().read_text()
    disp = parse_dispersions(disp_text, "dispersions")
    settings = environment_settings()
    env = parse_environment(settings)
    table = load_controller_table(default_table_path())
    spec = load_requirements()
    indices = list(range(args.samples))

    c0, t0 = _cpu(), time.perf_counter()
    from vega_reference.rebias import rebias_reference

    rebias_reference(env.site.fine_altitude_m, 0.0 * env.site.fine_altitude_m)
    c1, t1 = _cpu(), time.perf_counter()
    drift_sensitivity(dump_scenario(base), str(default_table_path()), env.lcc)
    c2, t2 = _cpu(), time.perf_counter()
    print(f"fixed per worker process: the first re-biasing (its imports and the guidance "
          f"problem's assembly) {c1 - c0:.1f} CPU s "
          f"({t1 - t0:.1f} s wall); LCC drift sensitivity (62 flights, one batch) "
          f"{c2 - c1:.1f} CPU s ({t2 - t1:.1f} s wall)")

    cpu = {"one at a time": [], "batched": []}
    wall = {"one at a time": [], "batched": []}
    rows = {}
    for r in range(args.repeat):
        for side in ("one at a time", "batched"):
            with tempfile.TemporaryDirectory(prefix="bench_fd_") as scratch:
                c, t = _cpu(), time.perf_counter()
                if side == "batched":
                    got = fly_flight_day_batch(dump_scenario(base), str(default_table_path()),
                                               disp_text, args.seed, settings, scratch, indices)
                else:
                    got = one_at_a_time(base, disp, args.seed, env, table,
                                        str(default_table_path()), spec, indices, Path(scratch))
                cpu[side].append((_cpu() - c) / len(indices))
                wall[side].append((time.perf_counter() - t) / len(indices))
                rows[side] = got
            print(f"  round {r + 1} {side}: {cpu[side][-1]:.3f} CPU s, "
                  f"{wall[side][-1]:.3f} s wall per sample")
    old, new = min(cpu["one at a time"]), min(cpu["batched"])
    print(f"{args.samples} flight-day samples (seed {args.seed}), best of {args.repeat}: "
          f"one at a time {old:.3f} CPU s per sample ({1 / old:.2f} samples/s per core), "
          f"batched {new:.3f} ({1 / new:.2f}): ratio {old / new:.2f}x; wall per sample "
          f"{min(wall['one at a time']):.3f} against {min(wall['batched']):.3f} s")
    differ = sorted({k for a, b in zip(rows["one at a time"], rows["batched"])
                     for k in _differ(a, b)})
    print(f"rows equal on both sides (every field but wall_s): {not differ}"
          + (f"; differing fields: {differ}" if differ else ""))


if __name__ == "__main__":
    main()
