"""Benchmark: the memory of a large campaign (`vega mc run` and its Dask workers, from /proc).

Usage: .venv/bin/vega-env python bench/bench_mc_memory.py [--runs N] [--workers K]
       [--environment thesis-box|flight-day] [--batch B]

Runs ``vega mc run --environment E --scenario nominal --runs N --seed 0 --workers K`` (default
10 000 thesis-box flights on 2 workers, batches of the command's default) in a fresh process
and, every 0.5 s while it runs, reads the resident set size (VmRSS) of the command and of every
process below it (the Dask scheduler's and workers' processes) from /proc. Figures: the peak
of the whole tree's RSS and the peak of each process's, the RSS at a quarter, half and three
quarters of the flights (a memory that grows with the flights flown shows there), the wall
time, and the size of the results and of the per-sample rows on disk. A campaign holds no time
history outside a batch's flights (≈ 9 MB per 100-s flight while its batch flies, per worker):
its rows go to disk as each task returns.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_DONE = re.compile(r"mc: (\d+)/(\d+) done")


def _children(pid: int) -> list[int]:
    """Every process below ``pid`` (from /proc/*/stat's parent field)."""
    parents: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        parents.setdefault(ppid, []).append(int(entry))
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(parents.get(p, []))
    return out


def _rss_mb(pid: int) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--environment", default="thesis-box")
    parser.add_argument("--batch", type=int, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_mc_memory_") as scratch:
        out = Path(scratch) / "c"
        command = [sys.executable, "-m", "vega_cli.cli", "mc", "run", "--environment",
                   args.environment, "--scenario", "nominal", "--runs", str(args.runs),
                   "--seed", "0", "--workers", str(args.workers), "--out", str(out)]
        if args.batch:
            command += ["--batch", str(args.batch)]
        log = Path(scratch) / "log"
        t0 = time.perf_counter()
        with open(log, "w") as f:
            proc = subprocess.Popen(command, stdout=f, stderr=subprocess.STDOUT)
        peak_total, peak_each, marks = 0.0, {}, {}
        while proc.poll() is None:
            pids = _children(proc.pid)
            rss = {p: _rss_mb(p) for p in pids}
            total = sum(rss.values())
            peak_total = max(peak_total, total)
            for p, mb in rss.items():
                peak_each[p] = max(peak_each.get(p, 0.0), mb)
            done = _DONE.findall(log.read_text())
            if done:
                fraction = int(done[-1][0]) / args.runs
                for q in (0.25, 0.5, 0.75):
                    if fraction >= q and q not in marks:
                        marks[q] = total
            time.sleep(0.5)
        wall = time.perf_counter() - t0
        if proc.returncode not in (0, 1):
            sys.exit(f"bench_mc_memory: vega mc run failed:\n{log.read_text()[-2000:]}")
        results = out / "results.parquet"
        rows = sum(p.stat().st_size for p in (out / "samples").glob("*.json"))
        top = sorted(peak_each.values(), reverse=True)[:4]
        print(f"vega mc run --environment {args.environment} --runs {args.runs} --workers "
              f"{args.workers}: {wall:.0f} s wall")
        print(f"  peak RSS of the whole tree {peak_total:.0f} MB; largest processes "
              + ", ".join(f"{mb:.0f}" for mb in top) + " MB")
        print("  tree RSS at " + ", ".join(f"{int(q * 100)} %: {mb:.0f} MB"
                                           for q, mb in sorted(marks.items()))
              + " of the flights")
        print(f"  results.parquet {results.stat().st_size / 1e6:.1f} MB; per-sample rows "
              f"{rows / 1e6:.1f} MB on disk")


if __name__ == "__main__":
    main()
