"""A node whose middleware teardown hangs still ends, with the exit code its run had
(vega_bus.shell: Fast DDS was seen hanging in rmw_destroy_node once in ~20 runs under load)."""

import subprocess
import sys
import textwrap

import pytest

from load_scaling import budget_s


def _stop_flag_process(function: str, sleep_s: float, after: str = ""):
    """A Python process with the nodes' stop flag installed that, inside a function named
    ``function`` (whose name its stacks must show), prints "ready" and sleeps ``sleep_s`` —
    "ready" from inside, so that a signal sent on it finds the process in the function."""
    script = textwrap.dedent(f"""
        import time
        from vega_bus.shell import StopFlag
        StopFlag()
        def {function}():
            print("ready", flush=True)
            time.sleep({sleep_s})
        {function}()
        {after}
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline() == "ready\n"
    return proc


@pytest.mark.parametrize("code", [0, 1])
def test_hanging_teardown_exits_with_the_runs_code(code):
    script = textwrap.dedent(f"""
        import time
        import vega_bus.shell as shell
        shell.SHUTDOWN_GRACE_S = 0.5

        class Hangs:
            def close(self):
                time.sleep(60)

        shell._close_with_watchdog("plant", Hangs(), {code})
        print("not reached")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=budget_s(30.0), check=False)
    assert result.returncode == code
    assert result.stdout == ""
    assert result.stderr == "plant: middleware shutdown hung for 0.5 s; exiting without it\n"


@pytest.mark.parametrize("limits, code, after_s, line", [
    ("shell.SHUTDOWN_GRACE_S = 5.0", 1, 0.2, "after close"),
    # the exit timer due 1.5 s after close starts: the process lives on past its due time
    ("shell.SHUTDOWN_GRACE_S = 0.5; shell.HARD_SHUTDOWN_MARGIN_S = 0.5", 0, 2.5,
     "after the due time"),
])
def test_normal_teardown_is_not_cut_short(limits, code, after_s, line):
    """A close of 0.1 s: neither the watchdog thread nor the GIL-free exit timer ends the
    process (the timer is disarmed when the teardown ends in time)."""
    script = textwrap.dedent(f"""
        import time
        import vega_bus.shell as shell
        {limits}

        class Quick:
            def close(self):
                time.sleep(0.1)

        shell._close_with_watchdog("plant", Quick(), {code})
        time.sleep({after_s})
        print("{line}")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=budget_s(30.0), check=False)
    assert result.returncode == 0 and result.stdout == line + "\n" and result.stderr == ""


@pytest.mark.parametrize("code, status", [(0, 0), (1, 1), (2, 2)])
def test_teardown_hanging_with_the_gil_held_still_ends_with_its_stacks(code, status):
    """The watchdog thread needs the GIL; a teardown blocked in C holding it (here: a long
    builtin sum) is ended without it: faulthandler writes the stacks, then the C library's
    POSIX timer ends the process with the run's own exit code — 0 for a complete run (the soak
    of 2026-11-27 saw the INS and the actuator hang so in rmw_destroy_node; they used to die
    of SIGALRM, -14)."""
    script = textwrap.dedent(f"""
        import vega_bus.shell as shell
        shell.SHUTDOWN_GRACE_S = 0.5
        shell.HARD_SHUTDOWN_MARGIN_S = 0.5

        class HoldsTheGil:
            def close(self):
                sum(range(10**13))

        shell._close_with_watchdog("plant", HoldsTheGil(), {code})
        print("not reached")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=budget_s(30.0), check=False)
    assert result.returncode == status
    assert result.stdout == ""
    assert "Timeout (0:00:01)!" in result.stderr
    assert "in close" in result.stderr and "middleware shutdown hung" not in result.stderr


def test_the_exit_timer_ends_the_process_with_its_code_while_the_gil_is_held():
    script = textwrap.dedent("""
        import vega_bus.shell as shell
        shell._exit_timer(0.3, 5)
        sum(range(10**13))
        print("not reached")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=budget_s(30.0), check=False)
    assert result.returncode == 5 and result.stdout == ""


def test_the_orchestrator_counts_a_teardown_watchdog_end_as_finished(tmp_path):
    """vega_bringup.orchestrate.NodeProcess: status -SIGALRM (the node's own teardown
    watchdog after a complete run) → returncode 0 and teardown_hung; another signal stays
    a failure."""
    import signal

    from vega_bringup.orchestrate import NodeProcess

    ended = {}
    for sig in (signal.SIGALRM, signal.SIGTERM):
        proc = subprocess.Popen([sys.executable, "-c",
                                 f"import os, signal; os.kill(os.getpid(), {int(sig)})"])
        node = NodeProcess(spec=None, command=[], log_path=tmp_path / "log", popen=proc)
        node.reap(block=True)
        ended[sig] = (node.returncode, node.teardown_hung)
    assert ended == {signal.SIGALRM: (0, True), signal.SIGTERM: (-15, False)}


def test_a_node_writes_its_stacks_on_request_and_goes_on():
    """SIGUSR1 (the orchestrator's request to a hung node) → every thread's stack on stderr,
    and the node keeps running (vega_bus.shell.StopFlag)."""
    import signal
    import time

    proc = _stop_flag_process("waiting_for_the_final_report", 1.5,
                              after='print("went on", flush=True)')
    try:
        time.sleep(0.3)
        proc.send_signal(signal.SIGUSR1)
        out, err = proc.communicate(timeout=budget_s(30.0))
    finally:
        proc.kill()
    assert proc.returncode == 0 and out == "went on\n"
    assert "Current thread" in err and "in waiting_for_the_final_report" in err


def test_the_orchestrator_asks_a_hung_node_for_its_stacks():
    """vega_bringup.orchestrate: a node still running long after the others is asked for its
    stacks (SIGUSR1) before it is stopped, so that its log says where it hung."""
    import time
    from types import SimpleNamespace

    from vega_bringup.orchestrate import Supervisor

    proc = _stop_flag_process("hung_in_teardown", 30)
    try:
        assert Supervisor._dump_stacks([SimpleNamespace(popen=proc)]) is True
        time.sleep(0.2)
    finally:
        proc.kill()
    _, err = proc.communicate(timeout=budget_s(30.0))
    assert "in hung_in_teardown" in err
