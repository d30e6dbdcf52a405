"""SIGTERM at random points of a node's life ends it cleanly.

The node contract (vega_bus/shell.py): SIGINT/SIGTERM → one line ``NODE: stopped by SIGTERM``,
exit 0, the bag closed — never a traceback (rclpy's own handler would shut the context down
under a running wait: ``RCLError: context is not valid``). The one window where that cannot
hold is before the node's code runs at all (interpreter start, import of the node's module):
there SIGTERM's default action ends the process, status −15, nothing written.
The test tells the two apart from the process's caught-signal mask (``SigCgt`` in
/proc/PID/status) read just before the signal is sent.

Real executables, real DDS; the points are random (seeded: the seed is in the assertion
messages) over the start-up, the start barrier and the flight.
"""

import random
import signal
import subprocess
import time
from pathlib import Path

import pytest

from load_scaling import budget_s
from sil_flights import flight_env, wait_for_sim_time, write_node_params, write_short_scenario
from vega_bags import bagio
from vega_bringup import orchestrate
from vega_bringup.executables import find_executable
from vega_bus import topics

pytestmark = pytest.mark.ros

SEED = 15_4
STARTS = 20
MAX_DELAY_S = 2.0
FLIGHT_END_S = 18.0
"""End of the mid-flight runs [s] (they start at 10 s, flown in real time)."""


def _handles_sigterm(pid: int) -> bool:
    """True if process ``pid`` has a handler for SIGTERM installed (SigCgt bit)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigCgt:"):
            return bool(int(line.split()[1], 16) & (1 << (signal.SIGTERM - 1)))
    raise AssertionError(f"no SigCgt in /proc/{pid}/status")


def _params(path: Path, **values) -> Path:
    return write_node_params(path, **values)


def _start(spec, params_file):
    exe = find_executable(spec.package, spec.executable)
    return subprocess.Popen(orchestrate.node_command(exe, params_file), env=flight_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _reap(procs):
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def _until_flag(proc, timeout_s):
    """Wait until ``proc`` handles SIGTERM (its stop flag is installed); False on timeout."""
    deadline = time.monotonic() + timeout_s
    while proc.poll() is None and time.monotonic() < deadline:
        if _handles_sigterm(proc.pid):
            return True
        time.sleep(0.005)
    return False


@pytest.mark.slow
def test_sigterm_at_random_points_of_a_start(tmp_path):
    """20 starts of the five node executables in turn, each alone (it waits at the start
    barrier for the other participants); SIGTERM after a random 0–2 s, counted from the
    process start for even starts (the interpreter start, imports, rclpy.init, parameters,
    scenario and table loading, the barrier's spin) and from the moment its stop flag is
    installed for odd ones (so that half the signals surely land in the node's own code).
    Signal handled → exit 0 and exactly the line ``NODE: stopped by SIGTERM``; signal before
    the flag → status −15 and nothing written; never a traceback."""
    rng = random.Random(SEED)
    handled = 0
    specs = orchestrate.PARTICIPANTS
    for i in range(STARTS):
        spec = specs[i % len(specs)]
        name = spec.executable
        params = _params(tmp_path / f"p{i}.yaml", bag_path=str(tmp_path / f"bag{i}"),
                         barrier_timeout_s=budget_s(60.0))
        delay = rng.uniform(0.0, MAX_DELAY_S)
        proc = _start(spec, params)
        try:
            if i % 2 and not _until_flag(proc, budget_s(20.0)):
                raise AssertionError(f"{name}: no SIGTERM handler after {budget_s(20.0):g} s "
                                     f"(exit {proc.poll()})")
            time.sleep(delay)
            assert proc.poll() is None, f"{name} ended by itself: {proc.communicate()}"
            caught = _handles_sigterm(proc.pid)
            proc.send_signal(signal.SIGTERM)
            out, err = proc.communicate(timeout=budget_s(30.0))
        finally:
            _reap([proc])
        where = f"start {i} ({name}, seed {SEED}, delay {delay:.3f} s, handler {caught})"
        assert "Traceback" not in err and "RCLError" not in err, f"{where}:\n{err}"
        if proc.returncode == 0:
            assert err == f"{name}: stopped by SIGTERM\n", f"{where}: {err!r}"
            handled += 1
        else:
            assert not caught, f"{where}: exit {proc.returncode} with the flag set: {err!r}"
            assert proc.returncode == -signal.SIGTERM and err == "" and out == "", \
                f"{where}: exit {proc.returncode}: {err!r}"
    assert handled >= STARTS // 2, f"only {handled} of {STARTS} signals reached a node's code"


@pytest.fixture(scope="module")
def short_scenario(tmp_path_factory):
    # 8 s flown in real time: the test's /clock watcher may see its first message seconds after
    # the flight began (DDS discovery under load), and the signals must still find it running
    # (a 3 s flight can be over before the signals come: "nobody was stopped")
    return write_short_scenario(tmp_path_factory.mktemp("scenario"), "thesis",
                                "thesis_sigterm", 10.0, FLIGHT_END_S)


@pytest.mark.slow
@pytest.mark.parametrize("flight", range(4))
def test_sigterm_to_every_node_mid_flight(tmp_path, short_scenario, flight):
    """Five nodes fly the thesis scenario cut to 10–13 s, paced to real time; at a random
    point after /clock reached 10 s (0–2 s later) every node gets SIGTERM at once, in a random
    order, as the supervisor's stop sends it: each ends with exit 0 and its one line
    ``NODE: stopped by SIGTERM`` (or, if it had already finished, exit 0 and nothing), no
    traceback, and the recorder's bag is closed and readable."""
    rng = random.Random(SEED * 100 + flight)
    bag = tmp_path / "bag"
    params = _params(tmp_path / "p.yaml", scenario=str(short_scenario), realtime=True,
                     bag_path=str(bag), barrier_timeout_s=budget_s(60.0))
    specs = list(orchestrate.PARTICIPANTS)
    procs = {spec.executable: _start(spec, params) for spec in reversed(specs)}
    try:
        assert wait_for_sim_time(10.0, timeout_s=budget_s(60.0),
                                 still_running=lambda: all(p.poll() is None
                                                           for p in procs.values())), \
            {name: p.poll() for name, p in procs.items()}
        delay = rng.uniform(0.0, MAX_DELAY_S)
        time.sleep(delay)
        order = list(procs)
        rng.shuffle(order)
        for name in order:
            if procs[name].poll() is None:
                procs[name].send_signal(signal.SIGTERM)
        results = {name: (*proc.communicate(timeout=budget_s(30.0)), proc.returncode)
                   for name, proc in procs.items()}
    finally:
        _reap(procs.values())
    where = f"flight {flight} (seed {SEED}, delay {delay:.3f} s, order {order})"
    for name, (_out, err, code) in results.items():
        assert "Traceback" not in err and "RCLError" not in err, f"{where} {name}:\n{err}"
        assert code == 0, f"{where} {name}: exit {code}: {err!r}"
        assert err in ("", f"{name}: stopped by SIGTERM\n"), f"{where} {name}: {err!r}"
    assert any(err for _out, err, _code in results.values()), f"{where}: nobody was stopped"
    truth = bagio.read_run_bag(bag)[topics.TRUTH.name]
    assert 0 < len(truth) <= round((FLIGHT_END_S - 10.0) * 100) + 1, where
