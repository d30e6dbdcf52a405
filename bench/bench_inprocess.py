"""Benchmark: the in-process nonlinear closed loop, old code against new, and `vega mc run` scaling.

Usage: .venv/bin/vega-env python bench/bench_inprocess.py [--old REV] [--repeat N]
       [--samples K] [--runs R] [--no-scaling | --scaling-only]

One run measures, in this order (targets: docs/MONTE_CARLO.md §8):

1. **Old vs new, as ratios.** The old code is a git worktree of ``--old`` (default: the parent
   of the commit that added ``vega_model/nonlinear_kernel.py``, i.e. the code before the
   first speed-up; ``--old 2a9975c`` is the code before the second, docs/MONTE_CARLO.md §8),
   put first on PYTHONPATH; the new code is this checkout. Each side runs in its own
   fresh process, the two alternating ``--repeat`` times (default 2), so that the machine's
   load hits both alike. Per side:

   * ``nominal`` 0–100 s (nonlinear plant, shipped table and reference), warm (the parameter
     track cached): simulated seconds per CPU second of the process (× real time per core) and
     per wall second; best of 3;
   * Monte Carlo flights as ``vega mc run`` flies them (``vega_campaign.campaign.
     fly_sample``: sample, fly, metrics; every flight builds its own parameter track): mean CPU
     and wall seconds per 100 s flight over ``--samples`` samples (default 4) after one warm-up;
   * the plant node's start-up: a fresh process importing the plant factory, building the
     ``nominal`` plant and integrating one frame (numba import and cache load included on the
     new side).

2. **Scaling of `vega mc run`** (new code only): the real command, ``--runs R`` (default 32)
   dispersed 100 s flights of ``nominal`` with ``--workers 1`` and then ``--workers 2``
   (LocalCluster), wall time of the whole command (process and cluster start-up, results and
   plots included) and the runner's own flights per second (its last progress line: from the
   cluster's start to the last flight), their 2/1 ratios (target ≥ 1.8×), × real time per
   worker, and the CPU seconds of the command and all its processes (scheduler, nannies,
   workers: equal CPU for 1 and 2 workers means the runner adds no serial work, so a machine
   with two free cores gets the scaling the CPU allows).

CPU seconds are the load-independent figure on a shared 2-core machine; wall seconds depend on
what else runs. Figures in docs/MONTE_CARLO.md "Speed".
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

ROOT = Path(__file__).resolve().parent.parent
KERNEL = "ros2_ws/src/vega_model/vega_model/nonlinear_kernel.py"
_RATE = re.compile(r"mc: \d+/\d+ done, .*?, (?P<rate>[\d.]+) flights/s")


def _measure(samples: int) -> dict:
    """Run in a fresh process: the figures of the code on PYTHONPATH (one JSON line)."""
    import vega_sim
    from vega_campaign.campaign import default_dispersions_path, fly_sample
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import dump_scenario, load_scenario

    scenario = load_scenario("nominal")
    span = scenario.t_end_s - scenario.t_start_s
    table_path = str(default_table_path())
    table = load_controller_table(table_path)
    run_scenario(scenario, table)                               # cold: track, compiled code
    cpu, wall = [], []
    for _ in range(3):
        t0, c0 = time.perf_counter(), time.process_time()
        run_scenario(scenario, table)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    text = dump_scenario(scenario)
    disp = Path(default_dispersions_path()).read_text()
    fly_sample(text, table_path, disp, 0, samples)              # warm-up (another sample)
    f_cpu, f_wall = [], []
    for i in range(samples):
        t0, c0 = time.perf_counter(), time.process_time()
        fly_sample(text, table_path, disp, 0, i)
        f_wall.append(time.perf_counter() - t0)
        f_cpu.append(time.process_time() - c0)
    return {"code": str(Path(vega_sim.__file__).resolve().parent), "span_s": span,
            "warm_cpu_s": min(cpu), "warm_wall_s": min(wall),
            "flight_cpu_s": sum(f_cpu) / samples, "flight_wall_s": sum(f_wall) / samples}


def _startup() -> dict:
    """Run in a fresh process: the plant node's start-up (import, build, first frame)."""
    t0, c0 = time.perf_counter(), time.process_time()
    from vega_sim.assembly import make_plant
    from vega_sim.scenario import load_scenario

    plant = make_plant(load_scenario("nominal"))
    plant.advance((0.0,) * 10, (0.0,) * 10)
    return {"startup_wall_s": time.perf_counter() - t0, "startup_cpu_s": time.process_time() - c0}


def _old_rev() -> str:
    added = subprocess.run(["git", "-C", str(ROOT), "log", "--diff-filter=A", "--format=%H",
                            "--", KERNEL], capture_output=True, text=True, check=True).stdout
    commits = added.split()
    if not commits:
        sys.exit(f"bench_inprocess: {KERNEL} is not committed yet; pass --old REV")
    return commits[-1] + "^"


def _pythonpath(tree: Path) -> str:
    """The old tree's ROS packages and offline packages (offline_synthesis/ before the split,
    offline/ and cli/ after it), ahead of the workspace's."""
    dirs = [str(p.parent.parent) for p in sorted((tree / "ros2_ws/src").glob("*/*/__init__.py"))
            if p.parent.name == p.parent.parent.name]
    dirs += [str(tree / base) for base in ("offline_synthesis", "offline", "cli")
             if (tree / base).is_dir()]
    return os.pathsep.join(dirs + [os.environ.get("PYTHONPATH", "")])


def _child(args: list[str], pythonpath: str | None) -> dict:
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath
    out = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True,
                         env=env, check=False)
    if out.returncode != 0:
        sys.exit(f"bench_inprocess: child {args} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _compare(old_rev: str, repeat: int, samples: int) -> None:
    with tempfile.TemporaryDirectory(prefix="bench_inprocess_") as scratch:
        tree = Path(scratch) / "old"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree),
                        old_rev], capture_output=True, check=True)
        try:
            sides = {"old": _pythonpath(tree), "new": None}
            got = {side: [] for side in sides}
            for _ in range(repeat):
                for side, path in sides.items():
                    row = _child(["--measure", str(samples)], path)
                    row.update(_child(["--startup"], path))
                    got[side].append(row)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                           capture_output=True, check=False)
    best = {side: {k: min(r[k] for r in rows) for k in rows[0] if k.endswith("_s")}
            for side, rows in got.items()}
    span = best["new"]["span_s"]
    print(f"old = {old_rev} ({got['old'][0]['code']}), new = this checkout; best of {repeat} "
          f"alternating runs; load average now {os.getloadavg()[0]:.1f}")
    print(f"{'':38s} {'old':>9s} {'new':>9s} {'new/old speed':>14s}")

    def line(label, key, per_core):
        o, n = best["old"][key], best["new"][key]
        speed = (lambda s: f"{span / s:7.0f}x") if per_core else (lambda s: f"{s:7.3f} s")
        print(f"{label:38s} {speed(o):>9s} {speed(n):>9s} {o / n:13.2f}x")

    line("nominal 100 s warm, x real time / CPU s", "warm_cpu_s", True)
    line("nominal 100 s warm, x real time / wall s", "warm_wall_s", True)
    line("MC flight (fly_sample), x RT / CPU s", "flight_cpu_s", True)
    line("MC flight (fly_sample), x RT / wall s", "flight_wall_s", True)
    o, n = best["old"]["flight_cpu_s"], best["new"]["flight_cpu_s"]
    print(f"{'MC flight (fly_sample), CPU s':38s} {o:8.3f}s {n:8.3f}s  "
          f"({100.0 * (1.0 - n / o):.1f} % less CPU)")
    o, n = best["old"], best["new"]
    print(f"{'plant node start-up, CPU s':38s} {o['startup_cpu_s']:8.3f}s "
          f"{n['startup_cpu_s']:8.3f}s  ({n['startup_cpu_s'] - o['startup_cpu_s']:+.3f} s)")
    print(f"{'plant node start-up, wall s':38s} {o['startup_wall_s']:8.3f}s "
          f"{n['startup_wall_s']:8.3f}s  ({n['startup_wall_s'] - o['startup_wall_s']:+.3f} s)")


def _scaling(runs: int) -> None:
    rates, flying = {}, {}
    with tempfile.TemporaryDirectory(prefix="bench_inprocess_mc_") as scratch:
        for workers in (1, 2):
            out = Path(scratch) / f"w{workers}"
            c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            done = subprocess.run([sys.executable, "-m", "vega_cli.cli", "mc", "run",
                                   "--environment", "thesis-box", "--scenario", "nominal",
                                   "--runs", str(runs), "--seed", "0", "--workers",
                                   str(workers), "--out", str(out)],
                                  capture_output=True, text=True, check=False)
            wall = time.perf_counter() - t0
            c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)
            if done.returncode not in (0, 1):           # 1: some flight failed its verdict
                sys.exit(f"bench_inprocess: vega mc run failed:\n{done.stderr[-2000:]}")
            rates[workers] = runs / wall
            # the runner's own rate (from the cluster's start to the last flight): its last
            # progress line "mc: k/N done, ..., X flights/s, ETA ..."
            rate = [float(m) for m in _RATE.findall(done.stdout + done.stderr)]
            flying[workers] = rate[-1] if rate else float("nan")
            print(f"vega mc run --runs {runs} --workers {workers}: {wall:.1f} s wall (whole "
                  f"command: start-up, cluster, flights, results, plots) = "
                  f"{rates[workers]:.2f} flights/s, {rates[workers] * 100.0 / workers:.0f}x "
                  f"real time per worker; flying alone {flying[workers]:.2f} flights/s = "
                  f"{flying[workers] * 100.0 / workers:.0f}x real time per worker; CPU of "
                  f"the command and its processes {cpu:.1f} s ({cpu / runs:.2f} s per flight)")
    print(f"scaling 1 -> 2 workers: whole command {rates[2] / rates[1]:.2f}x, flying "
          f"{flying[2] / flying[1]:.2f}x (target >= 1.8x); load average now "
          f"{os.getloadavg()[0]:.1f}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--old", default=None, help="git revision of the old code")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--runs", type=int, default=32)
    parser.add_argument("--no-scaling", action="store_true")
    parser.add_argument("--scaling-only", action="store_true")
    parser.add_argument("--measure", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--startup", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure is not None:
        print(json.dumps(_measure(args.measure)))
        return
    if args.startup:
        print(json.dumps(_startup()))
        return
    if not args.scaling_only:
        _compare(args.old or _old_rev(), args.repeat, args.samples)
    if not args.no_scaling:
        _scaling(args.runs)


if __name__ == "__main__":
    main()
