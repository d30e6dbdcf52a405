"""Benchmark: ``vega sil run`` as a whole command, phase by phase, against a baseline revision.

Usage: .venv/bin/vega-env python bench/bench_sil.py [--scenario NAME] [--table TABLE.npz]
       [--repeat N] [--baseline REV]...

Runs ``vega sil run`` (the real command line, five node processes, lockstep over Fast DDS on
localhost) on the scenario (default ``nominal``: the whole 0–100 s flight on the nonlinear
plant) and times, from the moment the command is started, the lines it writes on stderr:

* ``validate``: to the line naming the scenario (imports, arguments, scenario, table and its
  frozen loops checked, the ROS domain probed);
* ``barrier``: from there to the start barrier (nodes started, imported, discovered);
* ``flight``: from the barrier to the line ``flew …`` (every node has exited: the flight, the
  end of the run and the nodes' exit);
* ``report``: from there to the report line (bag read, checked, plots written);
* ``exit``: from there to the end of the process;
* ``total``: the whole command, and the real-time factor = simulated span / total;
* ``cpu``: the CPU time (user + system) of the command and its five nodes, from
  ``getrusage(RUSAGE_CHILDREN)`` — far less sensitive to other jobs on the machine than the
  wall times (on the shared 2-core machine at load 10–15 a flight's wall time varied 4.5–12 s
  between identical runs), and on two cores a lower bound of twice the wall time.

With ``--baseline REV`` (e.g. the commit before a change; repeat it for a ladder of revisions)
the same runs are made with the packages this benchmark is about (vega_model, vega_sim,
vega_bus, vega_plant, vega_gnc, vega_bags, vega_bringup, vega_cli) of that revision — extracted
with ``git archive`` into a temporary directory and put first on PYTHONPATH for the command and
its nodes — alternating with the working tree's, run by run, so that all see the same load; the
medians and the ratios of each revision's median to the working tree's are printed per phase.
(The other packages and the messages are shared; a revision's numba cache is built by its
warm-up run, and for a revision with ``vega_model/kernels.py`` its ahead-of-time kernels are
compiled into the extracted tree first, as ``make setup`` does.) The command runs as ``python -m
vega_cli.cli`` in both cases: the ``vega`` wrapper's own start (``source tools/env.bash``, ≈
0.1–0.3 s) is not in the phases; it is timed on its own at the end and added to the current
tree's median for the whole command as a user types it. The load average is printed before and
after. Without ``--table`` the installed ``tvc_controller.npz`` (the default table) is flown.
The run directories go to a temporary directory that is removed afterwards.
"""

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tarfile
import tempfile
import threading
import time
from io import BytesIO
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("vega_model", "vega_sim", "vega_bus", "vega_plant", "vega_gnc", "vega_bags",
            "vega_bringup", "vega_cli")
PHASES = ("validate", "barrier", "flight", "report", "exit", "total", "cpu")
_MARKS = (("validate", "vega sil: scenario "), ("barrier", "start barrier complete"),
          ("flight", "vega sil: flew "), ("report", "vega sil: report "))


def _baseline_tree(rev: str, scratch: Path) -> list[str]:
    """Extract the :data:`PACKAGES` of ``rev`` under ``scratch``; their PYTHONPATH entries."""
    paths = [f"ros2_ws/src/{name}/{name}" for name in PACKAGES]
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev, *paths],
                          capture_output=True, check=True).stdout
    with tarfile.open(fileobj=BytesIO(data)) as tar:
        tar.extractall(scratch, filter="data")
    paths = [str(scratch / "ros2_ws" / "src" / name) for name in PACKAGES]
    if (scratch / "ros2_ws/src/vega_model/vega_model/kernels.py").is_file():
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [*paths, os.environ.get("PYTHONPATH", "")]))
        subprocess.run([sys.executable, "-m", "vega_model.kernels"], env=env, check=True,
                       stdout=subprocess.DEVNULL)
    return paths


def _run(args, table, out, run_id, pythonpath):
    """One ``vega sil run``; {phase: seconds}, exit status, stderr."""
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = os.pathsep.join([*pythonpath, env.get("PYTHONPATH", "")])
    command = [sys.executable, "-m", "vega_cli.cli", "sil", "run", "--scenario", args.scenario,
               "--table", str(table), "--out", str(out), "--run-id", run_id]
    usage0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    proc = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, bufsize=1)
    marks, lines = {}, []

    def read():
        for line in proc.stderr:
            now = time.monotonic() - t0
            lines.append(line)
            for phase, text in _MARKS:
                if phase not in marks and text in line:
                    marks[phase] = now

    reader = threading.Thread(target=read)
    reader.start()
    proc.wait()
    total = time.monotonic() - t0
    reader.join()
    stderr = "".join(lines)
    if proc.returncode not in (0, 1) or len(marks) != len(_MARKS):
        errors = [line for line in lines if "error:" in line]
        print(f"          run failed (exit {proc.returncode}): "
              f"{errors[-1].strip() if errors else stderr[-300:]}", flush=True)
        return None, proc.returncode, stderr
    times, last = {}, 0.0
    for phase, _ in _MARKS:
        times[phase] = marks[phase] - last
        last = marks[phase]
    times["exit"] = total - last
    times["total"] = total
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    times["cpu"] = (usage.ru_utime - usage0.ru_utime) + (usage.ru_stime - usage0.ru_stime)
    return times, proc.returncode, stderr


def _line(label, times, span_s):
    return (f"{label:9s} " + "  ".join(f"{p} {times[p]:5.2f}" for p in PHASES)
            + f"  = {span_s / times['total']:4.1f}x real time")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenario", default="nominal")
    parser.add_argument("--table", default=None)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--baseline", action="append", default=[], metavar="REV")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "ros2_ws/src/vega_sim"))
    from vega_sim.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    span_s = scenario.t_end_s - scenario.t_start_s
    with tempfile.TemporaryDirectory(prefix="bench_sil_") as scratch:
        scratch = Path(scratch)
        table = Path(args.table) if args.table else (
            ROOT / "ros2_ws/src/vega_gnc/config/tvc_controller.npz")
        variants = [(rev[:9], _baseline_tree(rev, scratch / f"rev{i}"))
                    for i, rev in enumerate(args.baseline)] + [("current", [])]
        print(f"bench_sil: scenario {args.scenario} ({span_s:g} s), table {table}, "
              f"{args.repeat} run(s) per variant; load average {os.getloadavg()[0]:.2f}")
        results = {label: [] for label, _ in variants}
        failures = {}
        # one warm-up run per variant (numba cache, page cache), not counted
        for j, (_label, path) in enumerate(variants):
            _run(args, table, scratch / "runs", f"warm-v{j}", path)
        for i in range(args.repeat):
            for j, (label, path) in enumerate(variants):
                times, code, _ = _run(args, table, scratch / "runs", f"r{i}-v{j}", path)
                if times is None:
                    failures[label] = failures.get(label, 0) + 1
                    continue
                results[label].append(times)
                print(_line(f"{label[:9]}", times, span_s)
                      + f"  (exit {code}, load {os.getloadavg()[0]:.2f})", flush=True)
        print("medians:")
        medians = {label: {p: statistics.median(t[p] for t in runs) for p in PHASES}
                   for label, runs in results.items() if runs}
        for label, med in medians.items():
            print(_line(label[:9], med, span_s))
        cur = medians["current"]
        for label, _ in variants[:-1]:
            if label not in medians:
                continue
            base = medians[label]
            print(f"ratio {label}/current: " + "  ".join(
                f"{p} {base[p] / cur[p]:.2f}" for p in PHASES if cur[p] > 0))
        if failures:
            print("failed runs (not in the medians): " + ", ".join(
                f"{label} {n}" for label, n in failures.items()))
        wrapper = statistics.median(_wrapper_env_s() for _ in range(max(3, args.repeat)))
        print(f"the vega wrapper's environment (source tools/env.bash, median): {wrapper:.2f} s;"
              f" whole command with it (current): {cur['total'] + wrapper:.2f} s = "
              f"{span_s / (cur['total'] + wrapper):.1f}x real time")
        print(f"load average after: {os.getloadavg()[0]:.2f}")


def _wrapper_env_s() -> float:
    """Wall time of what the ``vega`` wrapper does before Python starts: ``source
    tools/env.bash`` (colcon's local_setup runs a Python helper), from a plain environment
    (this process runs inside the project's, which the script would find set up already)."""
    start = time.monotonic()
    clean = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": os.environ.get("HOME", "/")}
    subprocess.run(["bash", "-c", f"source {ROOT / 'tools/env.bash'}"], check=True,
                   stdout=subprocess.DEVNULL, env=clean)   # a user's shell, not ours
    return time.monotonic() - start


if __name__ == "__main__":
    main()
