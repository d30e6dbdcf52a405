"""``vega mc run`` / ``vega mc margins``: --runs and --workers have upper bounds, refused in one
line (exit 2) before anything starts (docs/ADVERSARIAL.md): without them a --runs of 10^12
lists every sample index in memory until the process is OOM-killed, without a word, and
--workers 100000 starts a LocalCluster of that many processes."""

import subprocess
import sys
import time

import pytest

from cli_errors import assert_refused
from vega_cli import cli
from vega_cli.commands import mc


@pytest.mark.parametrize("action", ["run", "margins"])
@pytest.mark.parametrize("option, value, message", [
    ("--runs", mc.MAX_RUNS + 1, f"argument --runs: must be <= {mc.MAX_RUNS}, got '1000001'"),
    ("--runs", 10**12, f"argument --runs: must be <= {mc.MAX_RUNS}, got '1000000000000'"),
    ("--workers", mc.MAX_WORKERS + 1, "argument --workers: must be <= 64, got '65'"),
    ("--workers", 100000, "argument --workers: must be <= 64, got '100000'"),
])
def test_beyond_the_bound_is_one_line_exit_2(tmp_path, capsys, action, option, value, message):
    out = tmp_path / "c"
    args = ["--runs", "3", option, str(value)] if option == "--workers" else [option, str(value)]
    assert_refused(["mc", action, *args, "--out", str(out)], capsys, message)
    assert not out.exists()


def test_the_bounds_themselves_are_accepted():
    """Exactly --runs 1000000 and --workers 64 parse (the bounds are inclusive)."""
    args = cli.build_parser().parse_args(["mc", "run", "--runs", "1000000", "--workers", "64"])
    assert (args.runs, args.workers) == (1_000_000, 64)
    args = cli.build_parser().parse_args(["mc", "margins", "--runs", "1", "--workers", "1"])
    assert (args.runs, args.workers) == (1, 1)


def test_huge_runs_are_refused_at_once_in_a_real_process(tmp_path):
    """The real command line with --runs 10^12: refused within seconds, before any memory is
    taken (unbounded, it runs out of memory after about 100 s)."""
    t0 = time.monotonic()
    result = subprocess.run([sys.executable, "-m", "vega_cli.cli", "mc", "run", "--runs",
                             str(10**12), "--out", str(tmp_path / "c")],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().count("\n") == 0
    assert "must be <= 1000000" in result.stderr
    assert time.monotonic() - t0 < 60
    assert not (tmp_path / "c").exists()
