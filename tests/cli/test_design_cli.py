"""`vega design`: refusals of bad arguments (one line, exit 2, nothing written); the tuning
itself is tested in tests/synthesis/test_structured_design.py (a full run takes most of an hour)."""

from pathlib import Path

import pytest

from cli_errors import assert_refused

LPV = Path(__file__).resolve().parents[2] / "ros2_ws/src/vega_gnc/config/lpv_controller.npz"


@pytest.mark.parametrize("args, message", [
    (["--out", "{d}/t.txt"], "must end in .npz"),
    (["--out", "{d}/t.npz", "--maxiter", "0"], "--maxiter 0: must be within 1..1000"),
    (["--out", "{d}/t.npz", "--workers", "-1"], "--workers -1: must be within 0..64"),
    (["--out", "{d}/t.npz", "--anchors-from", str(LPV)], "not a structured design table"),
    (["--out", "{d}/t.npz", "--anchors-from", "{d}/missing.npz"], "no such file"),
    (["--out", "{d}/t.npz", "--maxiter", "x"], "invalid int value"),
    (["--out", "{d}/t.npz", "--repair-from", str(LPV)], "--repair-from"),
    (["--out", "{d}/t.npz", "--repair-from", str(LPV), "--anchors-from", str(LPV)],
     "--anchors-from and --repair-from: give one of them"),
    (["--out", "{d}/t.npz", "--tail-from", str(LPV)], "--tail-from"),
    (["--out", "{d}/t.npz", "--repair-from", str(LPV), "--tail-from", str(LPV)],
     "--repair-from and --tail-from: give one of them"),
    (["--out", "{d}/t.npz", "--corner-repair-from", str(LPV)],
     f"--corner-repair-from {LPV}: not a structured design table"),
    (["--out", "{d}/t.npz", "--drift-from", str(LPV), "--corner-repair-from", str(LPV)],
     "--drift-from and --corner-repair-from: give one of them"),
    (["--out", "{d}/t.npz", "--drift-from", str(LPV), "--no-corner-repair"],
     "--no-corner-repair with --drift-from: that option runs one step only"),
    (["--out", "{d}/t.npz", "--corner-repair-from", str(LPV), "--no-corner-repair"],
     "--no-corner-repair with --corner-repair-from"),
    (["--out", "{d}/t.npz", "--drift-from", str(LPV), "--journal", "{d}/j.jsonl"],
     "--journal with --drift-from: only the tuning of a full run"),
    (["--out", "{d}/t.npz", "--journal", "{d}"], "is a directory"),
    (["--out", "{d}/t.npz", "--drift-gains", "{d}/missing.yaml"],
     "missing.yaml: cannot read drift-gain schedule"),
    (["--out", "{d}/t.npz", "--drift-gains", str(LPV)], str(LPV)),
    (["--out", "{d}/t.npz", "--drift-gains", "{d}/g.yaml", "--free-drift-gains"],
     "--drift-gains and --free-drift-gains: give one of them"),
    (["--out", "{d}/t.npz", "--tail-from", str(LPV), "--free-drift-gains"],
     "--free-drift-gains with --tail-from: only a full run, --anchors-from or --repair-from"),
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


def _shipped_with(tmp_path, edit):
    """A copy of the shipped structured table with its metadata changed by ``edit``."""
    import json

    import numpy as np

    with np.load(LPV.with_name("tvc_controller.npz")) as f:
        arrays = dict(f)
    meta = json.loads(str(arrays["metadata"]))
    edit(meta)
    arrays["metadata"] = np.array(json.dumps(meta))
    table = tmp_path / "in" / "t.npz"
    table.parent.mkdir()
    np.savez(table, **arrays)
    return table


def test_anchors_without_parameters_are_refused(tmp_path, capsys):
    """A structured table whose metadata lacks an anchor's parameters: one line, exit 2."""
    table = _shipped_with(tmp_path, lambda meta: meta.update(anchors_s=meta["anchors_s"] + [123.0]))
    assert_refused(["design", "--out", str(tmp_path / "t.npz"), "--anchors-from", str(table)],
                   capsys, "its anchors have no 14 tuned parameters")
    assert not (tmp_path / "t.npz").exists()


def test_tail_without_its_hold_time_is_refused(tmp_path, capsys):
    """A structured table with no grid point at the tail-off hold time: one line, exit 2."""
    def drop_86(meta):
        keep = [i for i, t in enumerate(meta["grid_times_s"]) if t != 86.0]
        meta["grid_times_s"] = [meta["grid_times_s"][i] for i in keep]
        meta["parameters_per_grid_time"] = [meta["parameters_per_grid_time"][i] for i in keep]

    table = _shipped_with(tmp_path, drop_86)
    assert_refused(["design", "--out", str(tmp_path / "t.npz"), "--tail-from", str(table)],
                   capsys, "no grid point at the tail-off hold time 86 s")
    assert not (tmp_path / "t.npz").exists()


def test_drift_already_scaled_is_refused(tmp_path, capsys):
    """--drift-from on a table whose drift-rate gain was already scaled (its tuning record says
    so): one line, exit 2 — scaling twice would compound the factor."""
    table = _shipped_with(tmp_path, lambda meta: meta["solver"].update(
        drift={"factor": 2.0, "from_s": 70.0}))
    assert_refused(["design", "--out", str(tmp_path / "t.npz"), "--drift-from", str(table)],
                   capsys, "its drift-rate gain was already scaled")
    assert not (tmp_path / "t.npz").exists()


def test_drift_and_tail_together_are_refused(tmp_path, capsys):
    """--drift-from is one of the mutually exclusive sources."""
    assert_refused(["design", "--out", str(tmp_path / "t.npz"), "--tail-from", str(LPV),
                    "--drift-from", str(LPV)], capsys,
                   "--tail-from and --drift-from: give one of them")


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

    from vega_cli.commands.design import heartbeat

    journal = tmp_path / "t.journal.jsonl"
    journal.write_text("header\n" + "task\n" * 3)
    out, stop = io.StringIO(), threading.Event()
    thread = threading.Thread(target=heartbeat, args=(journal, stop, 0.02, out))
    thread.start()
    time.sleep(0.15)
    stop.set()
    thread.join(5)
    lines = out.getvalue().splitlines()
    assert not thread.is_alive() and lines
    assert all(line.startswith("vega design: 0 min, 3 tuning tasks finished (journal ")
               for line in lines)
    n = len(lines)
    time.sleep(0.1)
    assert len(out.getvalue().splitlines()) == n
