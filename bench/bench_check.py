"""Benchmark: `vega check` on a 100 s run bag (the whole command, as a user runs it).

Usage: .venv/bin/vega-env python bench/bench_check.py [TABLE.npz]
Flies the ``nominal`` scenario (0–100 s) in process with TABLE (default: the shipped
controller table, else the PD test fixture of tests/fixture_tables.py), writes its run bag
with the real message types (vega_bags.simbag), then runs ``vega check BAG`` (the venv's
console script) as a fresh process five times and reports the wall time (interpreter start
and imports included), its CPU time (user + sys: the figure that does not depend on the
machine's load), and the in-process time of :func:`vega_bags.bagcheck.check_bag` alone.
"""

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "ros2_ws/src/vega_gnc/config/lpv_controller.npz"
VEGA = Path(sys.executable).with_name("vega")  # the console script, as a user runs it
RUNS = 5


def _table(directory: Path) -> tuple[Path, str]:
    if len(sys.argv) > 1:
        return Path(sys.argv[1]), "given"
    if SHIPPED.exists():
        return SHIPPED, "shipped"
    sys.path.insert(0, str(ROOT / "tests"))
    from fixture_tables import write_pd_table

    path = directory / "pd.npz"
    write_pd_table(path)
    return path, "PD test fixture"


def main():
    from vega_sim.scenario import load_scenario
    from vega_bags import bagcheck, simbag
    from vega_sim.closed_loop import run_scenario

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        table, kind = _table(tmp)
        scenario = load_scenario("nominal")
        result = run_scenario(scenario, table)
        bag = simbag.write_simulation_bag(tmp / "bag", result, table)
        size = sum(p.stat().st_size for p in bag.iterdir())
        n = sum(1 for _ in bag.glob("*.mcap"))
        span = scenario.t_end_s - scenario.t_start_s
        print(f"bag: {span:g} s of flight ({scenario.name}, {kind} table), "
              f"{size / 1e6:.1f} MB in {n} MCAP file")
        walls, cpus, status = [], [], None
        for _ in range(RUNS):
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            proc = subprocess.run([str(VEGA), "check", str(bag)], capture_output=True,
                                  text=True)
            walls.append(time.perf_counter() - t0)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpus.append(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
            status = proc.returncode
        inproc = []
        for _ in range(RUNS):
            t0 = time.perf_counter()
            bagcheck.check_bag(bag)
            inproc.append(time.perf_counter() - t0)
        print(f"vega check (fresh process, {RUNS} runs): wall median "
              f"{statistics.median(walls):.2f} s, max {max(walls):.2f} s; CPU (user + sys) "
              f"median {statistics.median(cpus):.2f} s (exit status {status}; load average "
              f"{os.getloadavg()[0]:.1f})")
        print(f"check_bag in process (warm imports): median {statistics.median(inproc):.2f} s")


if __name__ == "__main__":
    main()
