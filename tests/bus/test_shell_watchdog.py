"""A node whose middleware teardown hangs still ends, with the exit code its run had
(vega_bus.shell: Fast DDS was seen hanging in rmw_destroy_node once in ~20 runs under load)."""

import os
import re
import select
import subprocess
import sys
import textwrap
import time

import pytest

from load_scaling import budget_s


def _stop_flag_process(function: str, after: str = ""):
    """A Python process with the nodes' stop flag installed that, inside a function named
    ``function`` (whose name its stacks must show), prints "ready" and waits until its stdin
    is closed (:func:`_release`) — "ready" from inside, so that a signal sent on it finds the
    process in the function, however late the signal comes or is handled."""
    script = textwrap.dedent(f"""
        import sys
        from vega_bus.shell import StopFlag
        StopFlag()
        def {function}():
            print("ready", flush=True)
            sys.stdin.read()
        {function}()
        {after}
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline() == "ready\n"
    return proc


def _stderr_until(proc, text: str, timeout_s: float) -> str:
    """Read ``proc``'s stderr until it holds ``text`` (or it ends, or ``timeout_s`` passes);
    what was read. (The limit only bounds a hang: the test waits for the event.)"""
    got = b""
    deadline = time.monotonic() + timeout_s
    fd = proc.stderr.fileno()
    while text.encode() not in got:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            break
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            break
        got += chunk
    return got.decode()


def _release(proc):
    """Close the stdin of a :func:`_stop_flag_process`: its function returns; (out, rest of
    stderr) once it has ended."""
    return proc.communicate(input="", timeout=budget_s(30.0))


@pytest.mark.slow
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


@pytest.mark.slow
@pytest.mark.parametrize("short", [False, True])
def test_normal_teardown_is_not_cut_short(short):
    """A close of 0.1 s: neither the watchdog thread nor the GIL-free exit timer ends the
    process (the timer is disarmed when the teardown ends in time). Short limits: the
    watchdog's grace scaled by the load (the close must end within it, or the watchdog would
    rightly end the process), the exit timer due 1 s after it, and the process living on 1 s
    past that due time."""
    if short:
        grace_s = budget_s(0.5)
        limits = f"shell.SHUTDOWN_GRACE_S = {grace_s!r}; shell.HARD_SHUTDOWN_MARGIN_S = 0.5"
        code, after_s, line = 0, grace_s + 0.5 + 0.5 + 1.0, "after the due time"
    else:
        limits, code, after_s, line = "shell.SHUTDOWN_GRACE_S = 5.0", 1, 0.2, "after close"
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


@pytest.mark.slow
@pytest.mark.parametrize("code, status", [(0, 0), (1, 1), (2, 2)])
def test_teardown_hanging_with_the_gil_held_still_ends_with_its_stacks(code, status):
    """The watchdog thread needs the GIL; a teardown blocked in C holding it (here: a long
    builtin sum) is ended without it: faulthandler writes the stacks, then the C library's
    POSIX timer ends the process with the run's own exit code — 0 for a complete run (the INS
    and the actuator were seen hanging so in rmw_destroy_node under load; a complete run must
    not end as a failure, status -14 of SIGALRM). The watchdog's grace is scaled by the load:
    the main thread must be inside the sum before it passes, or the watchdog would (rightly)
    end the process itself."""
    grace_s = budget_s(0.5)
    script = textwrap.dedent(f"""
        import vega_bus.shell as shell
        shell.SHUTDOWN_GRACE_S = {grace_s!r}
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
    # faulthandler.dump_traceback_later's header: the grace plus the margin, h:mm:ss[.us]
    assert re.search(r"^Timeout \(0:00:\d\d(\.\d{6})?\)!$", result.stderr, re.M), result.stderr
    assert "in close" in result.stderr and "middleware shutdown hung" not in result.stderr


@pytest.mark.slow
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
    and the node keeps running (vega_bus.shell.StopFlag): released only once its stacks are
    out, it leaves the function and goes on."""
    import signal

    proc = _stop_flag_process("waiting_for_the_final_report",
                              after='print("went on", flush=True)')
    try:
        proc.send_signal(signal.SIGUSR1)
        err = _stderr_until(proc, "in waiting_for_the_final_report", budget_s(30.0))
        out, rest = _release(proc)
    finally:
        proc.kill()
    err += rest
    assert proc.returncode == 0 and out == "went on\n", (proc.returncode, out, err)
    assert "Current thread" in err and "in waiting_for_the_final_report" in err, err


@pytest.mark.slow
def test_the_orchestrator_asks_a_hung_node_for_its_stacks():
    """vega_bringup.orchestrate: a node still running long after the others is asked for its
    stacks (SIGUSR1) before it is stopped, so that its log says where it hung. (The test ends
    the process only once the stacks are out: a SIGKILL pending beside the SIGUSR1 of a
    process not yet scheduled would discard both.)"""
    from types import SimpleNamespace

    from vega_bringup.orchestrate import Supervisor

    proc = _stop_flag_process("hung_in_teardown")
    try:
        assert Supervisor._dump_stacks([SimpleNamespace(popen=proc)]) is True
        err = _stderr_until(proc, "in hung_in_teardown", budget_s(30.0))
        err += _release(proc)[1]
    finally:
        proc.kill()
    assert "in hung_in_teardown" in err, err
