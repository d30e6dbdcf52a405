"""``vega sil run`` refuses bad input while planning, before any node starts:
a seed beyond the int64 ``seed`` parameter, a ``--run-id`` with a control character, a scenario
whose span runs past the flight-condition table, a scenario "file" that never ends. One line
``vega: error: …``, exit status 2, no run directory, no process."""

import subprocess
import sys

import pytest

from fixture_tables import write_pd_table
from vega_bringup import orchestrate
from vega_bus import parameters
from vega_cli import cli
from vega_model.flight_conditions import FlightConditions
from vega_sim.scenario import scenario_path


@pytest.fixture(scope="module")
def pd_table(tmp_path_factory):
    """Path of the PD fixture table (tests/fixture_tables.py)."""
    return write_pd_table(tmp_path_factory.mktemp("pd") / "pd.npz").path


@pytest.fixture
def no_start(monkeypatch):
    """Fail the test if anything tries to start a node (as in tests/sil/test_sil_run.py)."""
    def _refuse(*args, **kwargs):
        raise AssertionError("a process was started")

    monkeypatch.setattr(orchestrate.Supervisor, "start", _refuse)
    monkeypatch.setattr(orchestrate.subprocess, "Popen", _refuse)


def _refused(tmp_path, capsys, *arguments):
    """Run ``vega sil run`` with ``arguments`` (--out under tmp_path): its stderr, after
    checking exit 2, one line, no output directory."""
    out = tmp_path / "runs"
    assert cli.main(["sil", "run", "--out", str(out), *arguments]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vega: error: ") and err.count("\n") == 1, err
    assert not out.exists()
    return err


def test_seed_beyond_the_int64_parameter_is_refused(tmp_path, capsys, no_start, pd_table):
    highest = parameters.SEED.integer_range[1]
    assert highest == 2**63 - 1
    for seed in (str(2**63), str(10**30)):
        err = _refused(tmp_path, capsys, "--scenario", "thesis", "--table", str(pd_table),
                       "--seed", seed)
        assert err == (f"vega: error: --seed must be <= {highest} (the int64 range of the node "
                       f"parameter 'seed'), got {seed}\n")


def test_seed_at_the_int64_maximum_is_planned(tmp_path, pd_table, no_start):
    from vega_bringup.planning import plan_run

    plan = plan_run("thesis", seed=str(2**63 - 1), out=tmp_path, table=pd_table, run_id="r")
    assert plan.seed == plan.params.seed == 2**63 - 1


@pytest.mark.parametrize("run_id", ["a\nb", "a\rb", "tab\there", "bell\x07", "nul\x00x",
                                    "esc\x1b[31m", "del\x7f", "line\u2028sep"])
def test_run_id_with_a_control_character_is_refused(tmp_path, capsys, no_start, pd_table,
                                                    run_id):
    err = _refused(tmp_path, capsys, "--scenario", "thesis", "--table", str(pd_table),
                   "--run-id", run_id)
    assert err == (f"vega: error: --run-id {run_id!r}: must be a plain directory name (no "
                   f"'/', no control or other non-printable characters)\n")


def test_scenario_beyond_the_flight_condition_table_is_refused(tmp_path, capsys, no_start,
                                                               pd_table):
    """Today's nominal scenario with t_end past the table's end (the nonlinear plant node
    would fail after start, exit 1): refused on loading, naming the file and the field."""
    end_s = float(FlightConditions.load().t_s[-1])
    text = scenario_path("nominal").read_text(encoding="utf-8")
    assert "t_end_s: 100.0" in text
    path = tmp_path / "nominal.yaml"
    path.write_text(text.replace("t_end_s: 100.0", f"t_end_s: {end_s + 10}"), encoding="utf-8")
    err = _refused(tmp_path, capsys, "--scenario", str(path), "--table", str(pd_table))
    assert err.startswith(f"vega: error: {path}: field 't_end_s': must be <= "), err
    assert "flight-condition table ends at" in err


_DEV_ZERO = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))  # reading it whole fails instead
from vega_bringup import orchestrate
def _refuse(*args, **kwargs):
    raise AssertionError("a process was started")
orchestrate.Supervisor.start = _refuse
orchestrate.subprocess.Popen = _refuse
from vega_cli import cli
sys.exit(cli.main(["sil", "run", "--scenario", "/dev/zero", "--out", sys.argv[1]]))
"""


@pytest.mark.slow
def test_dev_zero_scenario_is_refused_at_once(tmp_path):
    """``--scenario /dev/zero`` (size 0, endless): one line naming it, exit 2, quickly and
    without eating memory (a child process bounded to 2 GiB and 120 s)."""
    done = subprocess.run([sys.executable, "-c", _DEV_ZERO, str(tmp_path / "runs")],
                          capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stderr) == (
        2, "vega: error: /dev/zero: scenario file is over the 1 MiB (1048576 bytes) limit "
           "(more than 1048576 bytes read)\n"), done
    assert not (tmp_path / "runs").exists()


def test_the_report_preload_is_waited_for_before_the_process_ends():
    """``vega sil run`` starts the report's imports in a daemon thread when the flight begins;
    every exit path (a report written, a run that failed or was interrupted) waits for it
    (``finish``), because a daemon thread still importing C extensions while the interpreter
    finalizes aborts the process instead of exiting with the run's status."""
    import threading

    from vega_cli.commands import sil

    idle = sil._ReportPreload()
    idle.finish()                                   # never started: returns at once
    preload = sil._ReportPreload()
    preload.start()
    preload.finish()
    assert not any(t.name == "report-preload" and t.is_alive() for t in threading.enumerate())
    assert "matplotlib.pyplot" in sys.modules      # the imports ran to their end
