"""`vega design`: refusals of bad arguments (one line, exit 2, nothing written); the tuning
itself is tested in tests/synthesis/test_structured_design.py (a full run takes hours)."""

from pathlib import Path

import pytest

from cli_errors import assert_refused

LPV = Path(__file__).resolve().parents[2] / "ros2_ws/src/vega_gnc/config/lpv_controller.npz"


@pytest.mark.parametrize("args, message", [
    (["--out", "{d}/t.txt"], "must end in .npz"),
    (["--out", "{d}/t.npz", "--maxiter", "0"], "--maxiter 0: must be within 1..1000"),
    (["--out", "{d}/t.npz", "--workers", "-1"], "--workers -1: must be within 0..64"),
    (["--out", "{d}/t.npz", "--maxiter", "x"], "invalid int value"),
    (["--out", "{d}/t.npz", "--journal", "{d}"], "is a directory"),
    (["--out", "{d}/t.npz", "--drift-gains", "{d}/missing.yaml"],
     "missing.yaml: cannot read drift-gain schedule"),
    (["--out", "{d}/t.npz", "--drift-gains", str(LPV)], str(LPV)),
    (["--out", "{d}/t.npz", "--drift-gains", "{d}/g.yaml", "--free-drift-gains"],
     "--drift-gains and --free-drift-gains: give one of them"),
    # a table is made from its inputs alone: no option takes an earlier table
    (["--out", "{d}/t.npz", "--drift-from", str(LPV)], "unrecognized arguments: --drift-from"),
])
def test_bad_arguments(tmp_path, capsys, args, message):
    assert_refused(["design", *(a.replace("{d}", str(tmp_path)) for a in args)], capsys,
                   message)
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("journal_text, message", [
    ("# my notes\n", "line 1 is not a 'vega design task journal' header"),
    ('{"format": "vega design task journal", "version": 1, "code": "0123456789abcdef"}\n',
     "written by other design code (digest 0123456789ab"),
])
def test_a_foreign_journal_is_refused_before_any_tuning(tmp_path, capsys, journal_text,
                                                        message):
    """The default journal next to --out (FILE.journal.jsonl) holding something else: one line,
    exit 2, the file untouched, no table written."""
    journal = tmp_path / "t.journal.jsonl"
    journal.write_text(journal_text)
    assert_refused(["design", "--out", str(tmp_path / "t.npz")], capsys,
                   f"design journal {journal}: {message}")
    assert journal.read_text() == journal_text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.journal.jsonl"]


def test_design_runs_with_one_blas_thread_unless_told(monkeypatch, capsys):
    """The tuning's spawned processes run with one BLAS thread; so does `vega design` itself
    (a task of a resumed run may run in it), unless the caller set a value."""
    import os

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    assert_refused(["design", "--out", "t.npz", "--maxiter", "0"], capsys, "--maxiter 0")
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1" and os.environ["OMP_NUM_THREADS"] == "3"


def test_heartbeat_counts_the_finished_tasks_until_stopped(tmp_path):
    """The progress line between two finished searches: minutes and finished tasks (journal
    lines after the header); nothing after the stop."""
    import io
    import threading
    import time

    from load_scaling import budget_s
    from vega_cli.commands.design import heartbeat

    journal = tmp_path / "t.journal.jsonl"
    journal.write_text("header\n" + "task\n" * 3)
    out, stop = io.StringIO(), threading.Event()
    thread = threading.Thread(target=heartbeat, args=(journal, stop, 0.02, out))
    thread.start()
    # wait for the first line rather than a fixed time: the thread may be scheduled late
    deadline = time.monotonic() + budget_s(10.0)
    while not out.getvalue() and time.monotonic() < deadline:
        time.sleep(0.01)
    stop.set()
    thread.join(5)
    lines = out.getvalue().splitlines()
    assert not thread.is_alive() and lines
    assert all(line.startswith("vega design: 0 min, 3 tuning tasks finished (journal ")
               for line in lines)
    n = len(lines)
    time.sleep(0.1)
    assert len(out.getvalue().splitlines()) == n
