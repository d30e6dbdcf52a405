"""Soak check of the test suite: N rounds, each running K copies of the whole suite at once
(the requirement of docs/TESTING.md, "The soak check": the whole suite passes 10 times in a row
with two copies running at once on the 2-core machine).

Usage:
    .venv/bin/vega-env python tools/soak.py [--rounds 10] [--copies 2] [--log FILE]
        [--stop-on-failure] [-- PYTEST_ARGS...]

Each copy is ``python -m pytest -q -p no:cacheprovider PYTEST_ARGS`` (default: ``tests``, the
whole suite) from this checkout, with its own pytest temporary directory; each picks a
ROS_DOMAIN_ID of its own as every test run does (``vega_bringup.rosenv.pick_domain_id``: a
locked per-user counter, so copies started together get different ids). A round passes when
every copy exits 0 with at least one test passed and none failed, errored or skipped; the
round's line (copies' exit codes, pass/fail/skip counts, wall time, the load average before
and after) is printed and appended to the log (JSON lines), with the failing tests' ids; the
copies' whole output of a failing round is kept beside the log
(``<log stem>-round<n>-copy<i>.log``).
Exit status 0 when every round passed, 1 otherwise; bad arguments: one line,
exit 2. Long: a round of the whole suite is ≈ 15–25 min with two copies on two cores.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_SUMMARY = re.compile(r"(\d+) (passed|failed|skipped|errors?|xfailed|xpassed|deselected)")
_FAILED = re.compile(r"^(?:FAILED|ERROR) (\S+)", re.M)


def summary(text: str) -> dict[str, int]:
    """Counts from pytest's last summary line (``1 failed, 12 passed, 2 skipped in …``)."""
    lines = [line for line in text.splitlines() if " in " in line and _SUMMARY.search(line)]
    counts = {"passed": 0, "failed": 0, "skipped": 0, "errors": 0}
    if lines:
        for number, what in _SUMMARY.findall(lines[-1]):
            key = "errors" if what.startswith("error") else what
            counts[key] = counts.get(key, 0) + int(number)
    return counts


def round_passed(codes: list[int], counts: list[dict[str, int]]) -> bool:
    """Every copy exited 0, ran at least one test, and none failed, errored or skipped."""
    return all(code == 0 and c["passed"] > 0 and not (c["failed"] or c["errors"] or c["skipped"])
               for code, c in zip(codes, counts))


def run_round(copies: int, pytest_args: list[str], scratch: Path) -> dict:
    """Start the copies together, wait for all; their results."""
    load0 = os.getloadavg()[0]
    start = time.monotonic()
    procs = []
    for i in range(copies):
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1",
                   ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        for name in ("ROS_LOCALHOST_ONLY", "ROS_DOMAIN_ID"):
            env.pop(name, None)
        out = open(scratch / f"copy{i}.log", "w+")
        command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                   f"--basetemp={scratch / f'tmp{i}'}", *(pytest_args or ["tests"])]
        procs.append((subprocess.Popen(command, cwd=ROOT, env=env, stdout=out,
                                       stderr=subprocess.STDOUT), out))
    codes, counts, failing = [], [], []
    for proc, out in procs:
        codes.append(proc.wait())
        out.seek(0)
        text = out.read()
        out.close()
        counts.append(summary(text))
        failing.append(_FAILED.findall(text))
    return {"codes": codes, "counts": counts, "failing": failing,
            "wall_s": round(time.monotonic() - start, 1), "load_before": round(load0, 2),
            "load_after": round(os.getloadavg()[0], 2),
            "passed": round_passed(codes, counts)}


def main(argv: list[str] | None = None) -> int:
    """Run the rounds; exit 0 when all passed."""
    argv = sys.argv[1:] if argv is None else argv
    own, _, pytest_args = (argv[:argv.index("--")], None, argv[argv.index("--") + 1:]) \
        if "--" in argv else (argv, None, [])
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--copies", type=int, default=2)
    parser.add_argument("--log", type=Path, default=ROOT / "build" / "soak.jsonl")
    parser.add_argument("--stop-on-failure", action="store_true")
    args = parser.parse_args(own)
    if args.rounds < 1 or args.copies < 1:
        print("soak: --rounds and --copies must be at least 1", file=sys.stderr)
        return 2
    args.log.parent.mkdir(parents=True, exist_ok=True)
    all_passed = True
    for n in range(1, args.rounds + 1):
        with tempfile.TemporaryDirectory(prefix="vega_soak_") as scratch:
            result = run_round(args.copies, pytest_args, Path(scratch))
            if not result["passed"]:          # the failing round's output, for its root cause
                kept = []
                for i in range(args.copies):
                    target = args.log.parent / f"{args.log.stem}-round{n}-copy{i}.log"
                    target.write_bytes((Path(scratch) / f"copy{i}.log").read_bytes())
                    kept.append(str(target))
                result["copy_logs"] = kept
        result.update(round=n, rounds=args.rounds, copies=args.copies, args=pytest_args,
                      when=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
        with open(args.log, "a") as log:
            log.write(json.dumps(result) + "\n")
        print(f"soak round {n}/{args.rounds}: {'PASS' if result['passed'] else 'FAIL'} "
              f"codes {result['codes']} counts {result['counts']} {result['wall_s']} s, "
              f"load {result['load_before']} -> {result['load_after']}"
              + (f"; failing {result['failing']}" if not result["passed"] else ""), flush=True)
        all_passed &= result["passed"]
        if not result["passed"] and args.stop_on_failure:
            break
    return 0 if all_passed else 1


if __name__ == "__main__":
    sys.exit(main())
