"""``vega sil run`` without flying: parameters file, commands, argument validation, supervisor.

The supervisor tests use stand-in processes (small Python programs) to exercise its own
logic — failure detection, SIGCONT and SIGTERM, then SIGKILL, reaping, interrupt —
deterministically;
every SIL test with the real nodes is in tests/sil/test_sil_run_flight.py.
"""

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import yaml

from fixture_tables import write_pd_table
from load_scaling import budget_s
from sil_flights import alive
from vega_bringup import orchestrate
from vega_cli import cli
from vega_gnc import controller_table


@pytest.fixture(scope="module")
def pd_table(tmp_path_factory):
    """Path of the PD fixture table (tests/fixture_tables.py)."""
    return write_pd_table(tmp_path_factory.mktemp("pd") / "pd.npz").path


def _params(**changes):
    values = dict(scenario="thesis", seed=-1, realtime=False, controller_table="/t/pd.npz",
                  bag_path="/runs/x/bag")
    values.update(changes)
    return orchestrate.RunParameters(**values)


# ----------------------------------------------------------------------------- parameters
def test_params_yaml_is_one_wildcard_section_with_typed_values():
    """Every node reads the same ``/**`` section; types survive (ints, bools, floats, arrays)."""
    text = orchestrate.params_yaml(_params(seed=7, realtime=True, barrier_timeout_s=12))
    tree = yaml.safe_load(text)
    assert list(tree) == ["/**"]
    assert tree["/**"]["ros__parameters"] == {
        "scenario": "thesis", "seed": 7, "realtime": True, "controller_table": "/t/pd.npz",
        "bag_path": "/runs/x/bag",
        "participants": ["plant", "ins_sensor", "tvc_controller", "tvc_actuator", "recorder"],
        "barrier_timeout_s": 12.0}
    assert isinstance(tree["/**"]["ros__parameters"]["barrier_timeout_s"], float)


@pytest.mark.ros
def test_params_yaml_through_the_ros_parser(tmp_path):
    """A node started with ``--ros-args --params-file`` (rcl's own YAML parser) gets every
    parameter with the intended ROS type: strings that look like other types (``yes``,
    ``1``) stay strings."""
    import rclpy
    from rclpy.parameter import Parameter

    path = tmp_path / "params.yaml"
    path.write_text(orchestrate.params_yaml(_params(scenario="yes", bag_path="1",
                                                    controller_table="")))
    context = rclpy.Context()
    rclpy.init(args=["--ros-args", "--params-file", str(path)], context=context,
               signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node("plant", context=context,
                                 automatically_declare_parameters_from_overrides=True)
        got = {name: (p.type_, p.value) for name, p in node.get_parameters_by_prefix("").items()
               if name in orchestrate.RunParameters.__dataclass_fields__}
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    assert got == {
        "scenario": (Parameter.Type.STRING, "yes"), "seed": (Parameter.Type.INTEGER, -1),
        "realtime": (Parameter.Type.BOOL, False), "controller_table": (Parameter.Type.STRING, ""),
        "bag_path": (Parameter.Type.STRING, "1"),
        "participants": (Parameter.Type.STRING_ARRAY,
                         ["plant", "ins_sensor", "tvc_controller", "tvc_actuator", "recorder"]),
        "barrier_timeout_s": (Parameter.Type.DOUBLE, 60.0)}


def test_node_command_and_shell_line():
    """The exact ``ros2 run`` layout command, and its paste-ready line (env, domain id)."""
    command = orchestrate.node_command("/p/lib/vega_plant/plant", "/r un/params.yaml")
    assert command == ["/p/lib/vega_plant/plant", "--ros-args", "--params-file",
                       "/r un/params.yaml"]
    line = orchestrate.shell_line(command, 42, Path("/repo/tools/env.bash"))
    assert line == ("source /repo/tools/env.bash && export ROS_AUTOMATIC_DISCOVERY_RANGE="
                    "LOCALHOST ROS_DOMAIN_ID=42 && /p/lib/vega_plant/plant --ros-args "
                    "--params-file '/r un/params.yaml'")
    assert orchestrate.shell_line(command, 7, None).startswith(
        "export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=7 && /p/lib/")


def test_environment_script_is_the_projects():
    """The env script the dry run sources is this checkout's tools/env.bash."""
    assert orchestrate.environment_script() == (
        Path(__file__).resolve().parents[2] / "tools" / "env.bash")


def test_default_run_id():
    assert orchestrate.default_run_id("thesis", 3, now=0.0) == "19700101T000000Z-thesis-seed3"


@pytest.mark.parametrize("code, text", [(0, "exit status 0"), (2, "exit status 2"),
                                        (-9, "killed by SIGKILL"), (-15, "killed by SIGTERM")])
def test_describe_status(code, text):
    assert orchestrate.describe_status(code) == text


# ----------------------------------------------------------------------------- validation
@pytest.fixture
def no_start(monkeypatch):
    """Fail the test if anything tries to start a node."""
    def _refuse(*args, **kwargs):
        raise AssertionError("a process was started")

    monkeypatch.setattr(orchestrate.Supervisor, "start", _refuse)
    monkeypatch.setattr(orchestrate.subprocess, "Popen", _refuse)


@pytest.mark.parametrize("arguments, message", [
    (["--scenario", "no_such"], "vega: error: unknown scenario 'no_such' (shipped: "),
    (["--scenario", "missing/file.yaml"], "vega: error: "),
    (["--seed", "-1"], "vega: error: --seed must be an integer >= 0, got '-1'"),
    (["--seed", "x1"], "vega: error: --seed must be an integer >= 0, got 'x1'"),
    (["--table", "TABLE_DIR/missing.npz"], "vega: error: "),
])
def test_bad_arguments_one_line_exit_2_nothing_started(tmp_path, capsys, no_start, arguments,
                                                        message, pd_table):
    """Bad scenario, seed or table: one line on stderr, exit 2, no run directory, no process."""
    arguments = [a.replace("TABLE_DIR", str(tmp_path)) for a in arguments]
    if "--table" not in arguments:
        arguments += ["--table", str(pd_table)]
    out = tmp_path / "runs"
    assert cli.main(["sil", "run", "--out", str(out), *arguments]) == 2
    err = capsys.readouterr().err
    assert err.startswith(message), err
    assert err.count("\n") == 1
    assert not out.exists()


def test_malformed_table_is_rejected_before_start(tmp_path, capsys, no_start):
    """A malformed controller table: the loader's one-line error (the same the controller
    node gives), exit 2, nothing started."""
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"this is not a zip archive")
    assert cli.main(["sil", "run", "--scenario", "thesis", "--table", str(bad),
                     "--out", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vega: error: ") and str(bad) in err
    assert err.count("\n") == 1
    assert not (tmp_path / "runs").exists()


@pytest.mark.slow
@pytest.mark.parametrize("command, factor", [("sil", 5.0), ("mc", 5.0), ("sil", 1e300)])
def test_table_that_does_not_stabilise_is_refused_before_start(tmp_path, capsys, no_start,
                                                               command, factor):
    """The shipped table with every output gain ×5 (well formed, finite, each discrete
    controller as stable as before) — or ×1e300, absurd but finite: its nominal frozen loops
    are unstable inside the grid, so `vega sil run` and `vega mc run` refuse it in one line,
    exit 2, nothing written."""
    import numpy as np
    from vega_gnc.controller_table import default_table_path

    arrays = dict(np.load(default_table_path()))
    for key in ("C", "D", "Cd", "Dd"):
        arrays[key] = arrays[key] * factor
    bad = tmp_path / "gain5.npz"
    np.savez(bad, **arrays)
    extra = ["--runs", "2"] if command == "mc" else []
    assert cli.main([command, "run", "--scenario", "thesis", "--table", str(bad), *extra,
                     "--out", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vega: error: controller table {bad}: the nominal frozen closed loop "
                          f"is unstable inside its scheduling range at t = 10, 11"), err
    assert err.count("\n") == 1
    assert not (tmp_path / "runs").exists()


def test_existing_output_is_never_overwritten(tmp_path, capsys, no_start, pd_table):
    """An existing run directory, or an --out that is a file: one line, exit 2, untouched."""
    (tmp_path / "runs" / "r1").mkdir(parents=True)
    (tmp_path / "runs" / "r1" / "keep").write_text("x")
    assert cli.main(["sil", "run", "--scenario", "thesis", "--table", str(pd_table),
                     "--out", str(tmp_path / "runs"), "--run-id", "r1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vega: error: output {tmp_path / 'runs' / 'r1'} already exists")
    assert sorted(p.name for p in (tmp_path / "runs" / "r1").iterdir()) == ["keep"]
    (tmp_path / "file").write_text("x")
    assert cli.main(["sil", "run", "--scenario", "thesis", "--table", str(pd_table),
                     "--out", str(tmp_path / "file")]) == 2
    assert "exists and is not a directory" in capsys.readouterr().err


def test_missing_default_table_is_named(tmp_path, capsys, no_start, monkeypatch):
    """Without --table and without an installed table: one line naming the missing file and
    the way out, exit 2."""
    missing = tmp_path / "share" / "vega_gnc" / "config" / "lpv_controller.npz"
    monkeypatch.setattr(controller_table, "default_table_path", lambda: missing)
    assert cli.main(["sil", "run", "--scenario", "thesis", "--out", str(tmp_path / "r")]) == 2
    assert capsys.readouterr().err == (
        f"vega: error: no controller table: {missing} is not installed (the LPV synthesis "
        f"has not exported it); pass --table FILE\n")


def test_sil_without_action_is_a_usage_error(capsys):
    assert cli.main(["sil"]) == 2
    assert capsys.readouterr().err == (
        "vega: error: sil: an ACTION is required: run (see vega sil --help)\n")


# ----------------------------------------------------------------------------- supervisor
def _stand_in(name, body, tmp_path):
    """(spec, command) of a stand-in node running Python ``body``."""
    script = tmp_path / f"{name}.py"
    script.write_text(textwrap.dedent(body))
    return orchestrate.NodeSpec("stand_in", name), [sys.executable, str(script)]


_SLEEPER = """
    import signal, sys, time
    signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
    print("running", flush=True)
    while True:
        time.sleep(1)
"""
_STUBBORN = """
    import os, signal, time
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    open(os.environ["STUBBORN_READY"], "w").close()
    while True:
        time.sleep(1)
"""


def _supervisor(tmp_path, nodes, **kwargs):
    layout = orchestrate.RunLayout(tmp_path / "run")
    layout.run_dir.mkdir()
    return orchestrate.Supervisor(nodes, layout, os.environ, watch_barrier=False, **kwargs)


def test_supervisor_all_nodes_end_normally(tmp_path):
    """Every node exits 0 → ok, logs written, every status 0."""
    nodes = [_stand_in(f"n{i}", f"print('node {i} done')", tmp_path) for i in range(3)]
    sup = _supervisor(tmp_path, nodes)
    outcome = sup.run()
    assert outcome.ok and outcome.message == ""
    assert outcome.returncodes == {"n0": 0, "n1": 0, "n2": 0}
    assert all(cpu > 0.0 for cpu in outcome.cpu_s.values())  # a Python start-up costs CPU
    assert (tmp_path / "run" / "logs" / "n1.log").read_text() == "node 1 done\n"


def test_supervisor_failure_stops_the_others_and_names_the_node(tmp_path):
    """One node fails with its one-line error → the others are stopped (SIGTERM), the
    message names the node, its status and its last line; no process is left."""
    nodes = [_stand_in("sleeper", _SLEEPER, tmp_path),
             _stand_in("broken", f"""
                 import pathlib, sys, time
                 log = pathlib.Path({str(tmp_path / "run" / "logs" / "sleeper.log")!r})
                 while "running" not in log.read_text():  # the sleeper handles SIGTERM now
                     time.sleep(0.01)
                 print("broken: error: table.npz: not a controller table", file=sys.stderr)
                 sys.exit(2)
             """, tmp_path)]
    sup = _supervisor(tmp_path, nodes)
    outcome = sup.run()
    assert outcome.status == "bad_input"
    assert outcome.message == ("node 'broken' failed during the flight: exit status 2: "
                               "broken: error: table.npz: not a controller table")
    assert outcome.returncodes == {"sleeper": 0, "broken": 2}
    assert not any(alive(p.popen.pid) for p in sup.processes)


@pytest.mark.slow
def test_supervisor_kills_a_node_that_ignores_sigterm(tmp_path, monkeypatch):
    """A node that ignores SIGTERM is killed (SIGKILL) after the grace time; the run still
    ends and reaps it."""
    ready = tmp_path / "stubborn.ready"
    env = dict(os.environ, STUBBORN_READY=str(ready))
    nodes = [_stand_in("stubborn", _STUBBORN, tmp_path),
             _stand_in("dies", f"""
                 import os, sys, time
                 while not os.path.exists({str(ready)!r}):
                     time.sleep(0.01)
                 sys.exit(1)
             """, tmp_path)]
    layout = orchestrate.RunLayout(tmp_path / "run")
    layout.run_dir.mkdir()
    monkeypatch.setattr(orchestrate, "TERM_GRACE_S", 0.5)
    sup = orchestrate.Supervisor(nodes, layout, env, watch_barrier=False)
    outcome = sup.run()
    assert outcome.status == "failed"
    assert outcome.message == "node 'dies' failed during the flight: exit status 1"
    assert outcome.returncodes == {"stubborn": -signal.SIGKILL, "dies": 1}


def test_supervisor_node_killed_by_signal(tmp_path):
    """A node killed by a signal is named with the signal."""
    nodes = [_stand_in("sleeper", _SLEEPER, tmp_path),
             _stand_in("victim", "import os, signal; os.kill(os.getpid(), signal.SIGKILL)",
                       tmp_path)]
    outcome = _supervisor(tmp_path, nodes).run()
    assert outcome.message == "node 'victim' failed during the flight: killed by SIGKILL"


def _driver(tmp_path, tail):
    """A script that runs a Supervisor over two sleeper stand-ins (s0, s1) in its own
    process, the orchestrator's place: set-up, then ``tail`` (Python using ``sup``)."""
    sleeper = tmp_path / "sleeper.py"
    sleeper.write_text(textwrap.dedent(_SLEEPER))
    driver = tmp_path / "driver.py"
    driver.write_text(textwrap.dedent(f"""
        import os, sys
        from pathlib import Path
        from vega_bringup import orchestrate

        layout = orchestrate.RunLayout(Path({str(tmp_path / 'run')!r}))
        layout.run_dir.mkdir()
        nodes = [(orchestrate.NodeSpec("s", f"s{{i}}"), [sys.executable, {str(sleeper)!r}])
                 for i in range(2)]
        sup = orchestrate.Supervisor(nodes, layout, os.environ, watch_barrier=False)
    """) + textwrap.dedent(tail))
    return driver


@pytest.mark.slow
def test_supervisor_interrupt_stops_everything(tmp_path):
    """SIGINT or SIGTERM to the orchestrator (a separate process running the supervisor):
    every node is stopped, the orchestrator exits with the interrupted outcome and no node
    survives it."""
    pids = tmp_path / "pids"
    driver = _driver(tmp_path, f"""
        def progress(line):
            if line.startswith("started"):
                Path({str(pids)!r}).write_text(
                    " ".join(str(p.popen.pid) for p in sup.processes))
                print("started", flush=True)
        sup.progress = progress
        outcome = sup.run()
        print(outcome.status, outcome.returncodes["s0"], outcome.returncodes["s1"], flush=True)
    """)
    for sig in (signal.SIGINT, signal.SIGTERM):
        proc = subprocess.Popen([sys.executable, str(driver)], stdout=subprocess.PIPE,
                                text=True)
        assert proc.stdout.readline() == "started\n"
        node_pids = [int(p) for p in pids.read_text().split()]
        # wait until both stand-ins have installed their SIGTERM handler (they say so)
        deadline = time.monotonic() + budget_s(30.0)
        for name in ("s0", "s1"):
            log = tmp_path / "run" / "logs" / f"{name}.log"
            while "running" not in log.read_text() and time.monotonic() < deadline:
                time.sleep(0.01)
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=budget_s(30.0))
        assert out.split() == ["interrupted", "0", "0"]
        assert proc.returncode == 0
        assert not any(alive(pid) for pid in node_pids)
        shutil.rmtree(tmp_path / "run")


def test_killed_orchestrator_leaves_no_nodes(tmp_path):
    """Even SIGKILL on the orchestrator leaves no node behind: the kernel sends each node
    SIGTERM when its parent dies (PR_SET_PDEATHSIG)."""
    driver = _driver(tmp_path, """
        sup.progress = lambda line: print(
            " ".join(str(p.popen.pid) for p in sup.processes), flush=True)
        sup.run()
    """)
    proc = subprocess.Popen([sys.executable, str(driver)], stdout=subprocess.PIPE, text=True)
    node_pids = [int(p) for p in proc.stdout.readline().split()]
    assert len(node_pids) == 2
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + budget_s(30.0)
    while any(alive(pid) for pid in node_pids) and time.monotonic() < deadline:
        time.sleep(0.01)  # the orphans are reaped by init, not by us
    assert not any(alive(pid) for pid in node_pids)


def _in_small_fs(mount_point: Path, size: str, command: list[str]):
    """Run ``command`` in a private mount namespace with a tmpfs of ``size`` mounted on
    ``mount_point`` (``{fs}`` in the command is replaced by it): a real small file system,
    seen by that process only."""
    import shlex

    script = (f"mount -t tmpfs -o size={size} tmpfs {mount_point} && "
              + " ".join(shlex.quote(a.replace("{fs}", str(mount_point))) for a in command))
    return subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True,
                          text=True, timeout=budget_s(120.0))


@pytest.mark.slow
@pytest.mark.parametrize("size, code", [("4m", 2), ("64m", 0)])
def test_free_space_is_checked_before_start(tmp_path, size, code):
    """`vega sil run` into a file system too small for the run's bag, logs and report (80 s:
    about 10 MB) is refused in one line, exit 2, nothing written; with room it plans the run
    (--dry-run: nothing started either way). The file system is a real tmpfs of that size."""
    result = _in_small_fs(tmp_path, size, [sys.executable, "-m", "vega_cli.cli", "sil", "run",
                                 "--scenario", "thesis", "--out", "{fs}/runs", "--dry-run"])
    assert result.returncode == code, result.stderr
    if code == 2:
        assert result.stderr.count("\n") == 1, result.stderr
        assert "MB free on its file system; a 80 s run needs about 10.0 MB" in result.stderr
        assert "runs" not in result.stdout
