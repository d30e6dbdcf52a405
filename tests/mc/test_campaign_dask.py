"""Campaigns on real Dask clusters (every server on 127.0.0.1): a LocalCluster of worker
processes, a `dask scheduler` with two `dask worker` processes, a campaign killed with SIGKILL
and resumed, and bad input refused before anything starts. Campaigns fly in batches (the
batched engine) by default; ``--batch 1`` flies one sample per task (the per-flight path), and
both give the same rows."""

import contextlib
import io
import json
import shutil
import os
import signal
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest

from load_scaling import budget_s
from sil_flights import write_short_scenario
from vega_cli import cli

RUNS = 6


def _rows(directory):
    """The results table without the wall time, as JSON text (NaN compares equal)."""
    rows = pq.read_table(directory / "results.parquet").to_pylist()
    for r in rows:
        r.pop("wall_s")
    return json.dumps(rows, sort_keys=True)


def _mc(*args):
    return [sys.executable, "-m", "vega_cli.cli", "mc", "run", "--environment", "thesis-box",
            *map(str, args)]


def _scheduler_address(path, proc, timeout_s):
    """The address in a ``dask scheduler --scheduler-file`` once the file holds it: the
    scheduler creates the file, then writes the JSON into it (not atomically), so the file
    may exist and still be empty or cut."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return json.loads(path.read_text())["address"]
        except (OSError, ValueError, KeyError):
            assert proc.poll() is None, f"dask scheduler ended with status {proc.returncode}"
            assert time.monotonic() < deadline, f"no address in {path} after {timeout_s:g} s"
            time.sleep(0.1)


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    return write_short_scenario(tmp_path_factory.mktemp("sc"), "nominal", "nominal_mc_short",
                                40.0, 41.0)


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory, scenario):
    """The campaign flown on a LocalCluster of ONE worker with the default batch (all six
    samples in one batched task), and what it printed."""
    out = tmp_path_factory.mktemp("mc") / "one"
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = cli.main(["mc", "run", "--environment", "thesis-box",
                         "--scenario", str(scenario), "--runs", str(RUNS),
                         "--seed", "4", "--workers", "1", "--out", str(out)])
    assert code in (0, 1)
    return out, text.getvalue()


@pytest.fixture(scope="module")
def reference(reference_run):
    return reference_run[0]


@pytest.mark.slow
def test_default_campaign_flies_one_batch_per_worker_and_prints_per_batch(reference_run):
    out, text = reference_run
    assert f"mc: batched engine, 1 task(s) of up to {RUNS} flights" in text
    assert f"mc: {RUNS}/{RUNS} done, " in text and "mc: 1/" not in text
    walls = {json.loads(p.read_text())["wall_s"] for p in (out / "samples").glob("*.json")}
    assert len(walls) == 1          # the batch's wall time shared equally by its samples


@pytest.mark.slow
def test_per_flight_path_gives_the_same_rows(reference, scenario, tmp_path, capsys):
    """``--batch 1`` (one fly_sample task per sample, on two workers) and the default
    batched campaign: the same results.parquet rows, wall times apart."""
    out = tmp_path / "per_flight"
    code = cli.main(["mc", "run", "--environment", "thesis-box",
                     "--scenario", str(scenario), "--runs", str(RUNS), "--seed", "4",
                     "--workers", "2", "--batch", "1", "--out", str(out)])
    text = capsys.readouterr().out
    assert code in (0, 1) and "batched engine" not in text
    assert [f"mc: {k}/{RUNS} done" in text for k in range(1, RUNS + 1)] == [True] * RUNS
    assert _rows(out) == _rows(reference)


@pytest.mark.slow
def test_resume_flies_only_the_missing_samples_of_a_batch(reference, tmp_path, capsys):
    """A campaign that lost two rows of its batch (as a kill between the row writes would):
    ``--resume`` flies those two as a new batch, leaves the other rows untouched, and the
    table equals the campaign flown in one go."""
    out = tmp_path / "partial"
    shutil.copytree(reference, out)
    for name in ("results.parquet", "summary.json"):
        (out / name).unlink()
    samples = out / "samples"
    for i in (1, 4):
        (samples / f"{i:06d}.json").unlink()
    kept = {p.name: p.stat().st_mtime_ns for p in samples.glob("*.json")}
    code = cli.main(["mc", "run", "--resume", str(out), "--workers", "1"])
    text = capsys.readouterr().out
    assert code in (0, 1)
    assert f"{RUNS - 2} already flown, 2 to fly" in text
    assert "mc: batched engine, 1 task(s) of up to 2 flights" in text
    assert {n: (samples / n).stat().st_mtime_ns for n in kept} == kept
    assert _rows(out) == _rows(reference)


@pytest.mark.slow
def test_same_samples_whatever_the_worker_count(reference, scenario, tmp_path, capsys):
    out = tmp_path / "two"
    code = cli.main(["mc", "run", "--environment", "thesis-box",
                     "--scenario", str(scenario), "--runs", str(RUNS), "--seed", "4",
                     "--workers", "2", "--out", str(out)])
    text = capsys.readouterr().out
    assert code in (0, 1) and "Dask LocalCluster, 2 workers" in text
    assert "batched engine, 2 task(s) of up to 3 flights" in text     # other batches
    assert _rows(out) == _rows(reference)
    rows = json.loads(_rows(out))
    assert [r["sample"] for r in rows] == list(range(RUNS))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"] == RUNS and summary["passed"] == sum(
        r["verdict"] == "pass" for r in rows)
    for name in ("histograms.png", "sensitivity_q_alpha.png", "q_alpha_band.png", "summary.md"):
        assert (out / name).stat().st_size > 0


@pytest.mark.slow
def test_scheduler_and_worker_processes_on_loopback(reference, scenario, tmp_path):
    sched_file = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [subprocess.Popen(dask + ["--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                      "--scheduler-file", str(sched_file)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        address = _scheduler_address(sched_file, procs[0], budget_s(60.0))
        assert address.startswith("tcp://127.0.0.1:")
        for _ in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers", "1",
                 "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        out = tmp_path / "remote"
        result = subprocess.run(_mc("--scenario", scenario, "--runs", RUNS, "--seed", 4,
                                    "--scheduler", address, "--out", out),
                                capture_output=True, text=True, timeout=300)
        assert result.returncode in (0, 1), result.stderr
        assert f"Dask scheduler {address}" in result.stdout
        assert _rows(out) == _rows(reference)
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture(scope="module")
def long_scenario(tmp_path_factory):
    """60 s flights (≈ 1 s of computing each): the killed campaign's samples come one by one."""
    return write_short_scenario(tmp_path_factory.mktemp("scl"), "nominal", "nominal_mc_kill",
                                40.0, 100.0)


def _without_wall(row):
    return {k: v for k, v in row.items() if k != "wall_s"}


KILLED_RUNS = 12


@pytest.mark.slow
def test_killed_campaign_resumes_without_reflying(long_scenario, tmp_path):
    """SIGKILL at an event — the first sample file written — then ``--resume``: the kept
    samples are not flown again, the others are, and the resumed rows are the flights
    themselves (flown again here in process by fly_sample, the per-flight path, without the
    campaign machinery).

    The campaign flies in batches of two (six tasks on one worker; a batch's rows are written
    when it returns) and the flights are 60 s long, so that the kill surely comes between the
    first sample written and the last: the other five batches take seconds of the worker's
    computing after the first. (With 1 s flights a loaded machine can write every row in one
    burst before the kill comes.)"""
    from vega_campaign.campaign import fly_sample
    from vega_campaign.campaign_run import SAMPLES_DIR

    out = tmp_path / "killed"
    proc = subprocess.Popen(_mc("--scenario", long_scenario, "--runs", KILLED_RUNS, "--seed", 4,
                                "--workers", "1", "--batch", 2, "--out", out),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    samples = out / SAMPLES_DIR
    deadline = time.monotonic() + 300           # an event wait: the limit only ends a hang
    while time.monotonic() < deadline and proc.poll() is None:
        if samples.is_dir() and any(samples.glob("*.json")):
            break
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    kept = sorted(p.name for p in samples.glob("*.json"))
    assert 1 <= len(kept) < KILLED_RUNS, kept
    mtimes = {p.name: p.stat().st_mtime_ns for p in samples.glob("*.json")}
    result = subprocess.run(_mc("--resume", out), capture_output=True, text=True, timeout=300)
    assert result.returncode in (0, 1), result.stderr
    assert f"{len(kept)} already flown, {KILLED_RUNS - len(kept)} to fly" in result.stdout
    assert "batched engine" in result.stdout
    assert all((samples / n).stat().st_mtime_ns == t for n, t in mtimes.items())
    rows = pq.read_table(out / "results.parquet").to_pylist()
    assert [r["sample"] for r in rows] == list(range(KILLED_RUNS))
    inputs = json.loads((out / "campaign.json").read_text())
    resumed = [i for i in range(KILLED_RUNS) if f"{i:06d}.json" not in kept]
    for i in (resumed[0], resumed[-1]):
        again = fly_sample(inputs["scenario_yaml"], inputs["table"], inputs["dispersions_yaml"],
                           inputs["seed"], i)
        written = json.loads((samples / f"{i:06d}.json").read_text())
        assert json.dumps(_without_wall(written), sort_keys=True) == json.dumps(
            _without_wall(json.loads(json.dumps(again))), sort_keys=True)


@pytest.mark.parametrize("args, message", [
    (["--runs", "0"], "argument --runs: must be >= 1"),
    (["--runs", "3", "--dispersions", "/nonexistent.yaml"], "/nonexistent.yaml"),
    (["--runs", "3", "--scenario", "no_such"], "unknown scenario 'no_such'"),
    (["--runs", "3", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
     "--workers and --scheduler exclude each other"),
    (["--runs", "3", "--table", "/nonexistent.npz"], "/nonexistent.npz: no such file"),
    (["--runs", "3", "--seed", "-4"], "--seed must be an integer >= 0"),
    (["--runs", "3", "--batch", "0"], "argument --batch: must be >= 1"),
    (["--runs", "3", "--batch", "513"], "argument --batch: must be <= 512"),
])
def test_bad_input_one_line_exit_2_nothing_started(tmp_path, capsys, args, message):
    out = tmp_path / "c"
    try:
        code = cli.main(["mc", "run", *args, "--out", str(out)])
    except SystemExit as exc:       # argparse's usage errors exit from the parser
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert not out.exists()


@pytest.mark.slow
def test_rerun_of_a_sample_through_the_ros_nodes_gives_its_row(reference_run, tmp_path,
                                                                capsys):
    """`vega mc rerun`: sample 1 of the campaign flown by the five SIL processes; the metrics
    computed from its bag equal the campaign row (the same code on bit-identical data). The
    campaign was flown by the batched engine (one task for its six samples)."""
    reference, text = reference_run
    assert "batched engine" in text
    code = cli.main(["mc", "rerun", str(reference), "--sample", "1", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "every metric of the campaign row identical" in out
    assert (tmp_path / "nominal_mc_short_mc1.yaml").is_file()


@pytest.mark.slow
@pytest.mark.ros
def test_rerun_of_a_flight_day_sample_through_the_ros_nodes_gives_its_row(scenario, tmp_path,
                                                                          capsys):
    """A flight-day campaign (statistical wind, guidance re-biased per sample, LCC): sample 1
    (February's flown profile, its own reference file in the campaign directory) flown again
    by the five SIL processes gives every metric of its row, the §6 and §2 verdicts and the
    time and Mach of max |Qα| included."""
    camp = tmp_path / "fd"
    code = cli.main(["mc", "run", "--scenario", str(scenario), "--runs", "2", "--seed", "4",
                     "--workers", "1", "--environment", "flight-day", "--out", str(camp)])
    assert code in (0, 1)
    summary = json.loads((camp / "summary.json").read_text())
    assert summary["flight_day"]["n"] + summary["flight_day"]["scrubbed"] == 2
    assert set(summary["availability"]) == {"1", "2"}
    row = json.loads((camp / "samples" / "000001.json").read_text())
    assert row["month"] == 2 and "passed_allowable" in row and "lcc_go" in row
    capsys.readouterr()
    code = cli.main(["mc", "rerun", str(camp), "--sample", "1", "--out", str(tmp_path / "r")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "every metric of the campaign row identical" in out
    flown = (tmp_path / "r" / "nominal_mc_short_fd1.yaml").read_text()
    assert str((camp / "flight_day" / "000001_guidance.npz").resolve()) in flown


@pytest.mark.slow
def test_rerun_bad_input(reference, tmp_path, capsys):
    assert cli.main(["mc", "rerun", str(reference), "--sample", str(RUNS)]) == 2
    assert "the campaign has samples 0-5" in capsys.readouterr().err
    assert cli.main(["mc", "rerun", str(tmp_path), "--sample", "0"]) == 2
    assert "not a campaign directory" in capsys.readouterr().err


@pytest.mark.slow
def test_margins_campaign_is_the_margins_of_the_sampled_plants(tmp_path, capsys):
    """`vega mc margins`: each row holds the margins vega margins computes for the plant of that
    sample (its deviations as sample_scenario draws them), and the same rows on 1 and 2
    workers."""
    from vega_loops import margins as mg
    from vega_campaign.campaign import load_dispersions, sample_scenario
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_model.parameters import default_context
    from vega_sim.scenario import load_scenario

    rows = {}
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        code = cli.main(["mc", "margins", "--runs", "4", "--at", "50", "--seed", "2",
                         "--workers", str(workers), "--out", str(out)])
        assert code in (0, 1)
        rows[workers] = _rows(out)
    assert rows[1] == rows[2]
    row = json.loads(rows[1])[3]
    disp = load_dispersions()
    _, values = sample_scenario(load_scenario("nominal"), disp, 2, 3)
    deviations = {k: values[k] for k, _ in disp.uncertainty}
    assert {k: row[k] for k in deviations} == deviations
    ctx = default_context()
    (want,) = mg.analyse_time(load_controller_table(default_table_path()), ctx, 50.0,
                              [(0, deviations)], nyquist=False)
    assert row["pm_deg@50"] == want["pm_deg"] and row["b1_peak_db@50"] == want["b1_peak_db"]
    assert row["n_unstable@50"] == want["n_unstable"]
    assert row["verdict"] == ("fail" if want["n_unstable"] else "pass")
    summary = json.loads((tmp_path / "w1" / "summary.json").read_text())
    assert summary["kind"] == "margins" and summary["runs"] == 4
