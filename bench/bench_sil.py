"""Benchmark: real-time factor of a whole SIL flight, every node its own process.

Usage: .venv/bin/vega-env python bench/bench_sil.py [--scenario NAME] [--table TABLE.npz]
       [--repeat N]

Runs ``vega sil run`` (the real command line, five node processes, lockstep over Fast DDS on
localhost) on the scenario (default ``nominal``: the whole 0–100 s flight on the nonlinear
plant) and reports, per run: the wall time from the start barrier to the last node's exit
(the flight), the real-time factor = simulated span / that wall time (and the plant's own
figure from its log: first to last frame), the start-up time (process start to barrier) and the
whole command's wall time (start-up, flight, report). Without
``--table`` the installed ``lpv_controller.npz`` is flown if it exists, else the PD fixture
table of tests/fixture_tables.py (the controller's cost per step hardly depends on the table).
The run directories go to a temporary directory that is removed afterwards.
"""

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
INSTALLED = ROOT / "ros2_ws/src/vega_gnc/config/lpv_controller.npz"
_FLEW = re.compile(r"flew (?P<span>[\d.]+) s in (?P<wall>[\d.]+) s wall")
_BARRIER = re.compile(r"start barrier complete after (?P<wall>[\d.]+) s")
_CPU = re.compile(r"node CPU time \(start-up included\): (?P<text>.*)")
_PLANT = re.compile(r"plant: flew [\d.]+ s in (?P<wall>[\d.]+) s wall")


def _table(argument, scratch):
    """The controller table to fly (argument, installed, or the PD fixture)."""
    if argument:
        return Path(argument), "given"
    if INSTALLED.is_file():
        return INSTALLED, "installed LPV table"
    sys.path.insert(0, str(ROOT / "tests"))
    from fixture_tables import write_pd_table

    return write_pd_table(Path(scratch) / "pd.npz").path, "PD fixture table"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenario", default="nominal")
    parser.add_argument("--table", default=None)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_sil_") as scratch:
        table, kind = _table(args.table, scratch)
        print(f"bench_sil: scenario {args.scenario}, {kind} ({table})")
        for run in range(args.repeat):
            t0 = time.perf_counter()
            result = subprocess.run(
                [sys.executable, "-m", "vega_cli.cli", "sil", "run", "--scenario",
                 args.scenario, "--table", str(table), "--out", scratch, "--run-id",
                 f"run{run}"], capture_output=True, text=True, check=False)
            total = time.perf_counter() - t0
            flew, barrier = _FLEW.search(result.stderr), _BARRIER.search(result.stderr)
            if result.returncode not in (0, 1) or flew is None:
                sys.exit(f"bench_sil: run failed (exit {result.returncode}):\n{result.stderr}")
            span, wall = float(flew["span"]), float(flew["wall"])
            plant_log = Path(scratch) / f"run{run}" / "logs" / "plant.log"
            plant = _PLANT.search(plant_log.read_text()) if plant_log.is_file() else None
            plant_text = (f"; the plant's own loop {span / float(plant['wall']):.1f}x"
                          if plant else "")
            print(f"run {run + 1}: {span:g} s flight in {wall:.2f} s wall = {span / wall:.1f}x "
                  f"real time (barrier to the last node's exit{plant_text}); start-up "
                  f"{float(barrier['wall']):.1f} s; whole command {total:.1f} s "
                  f"(exit {result.returncode})")
            cpu = _CPU.search(result.stderr)
            if cpu:
                print(f"       CPU: {cpu['text']}")


if __name__ == "__main__":
    main()
