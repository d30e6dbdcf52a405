"""A node whose middleware teardown hangs still ends, with the exit code its run had
(vega_bus.shell: Fast DDS was seen hanging in rmw_destroy_node once in ~20 runs under load)."""

import subprocess
import sys
import textwrap

import pytest

from load_scaling import budget_s


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


def test_normal_teardown_is_not_cut_short():
    script = textwrap.dedent("""
        import time
        import vega_bus.shell as shell
        shell.SHUTDOWN_GRACE_S = 5.0

        class Quick:
            def close(self):
                time.sleep(0.1)

        shell._close_with_watchdog("plant", Quick(), 1)
        time.sleep(0.2)
        print("after close")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=budget_s(30.0), check=False)
    assert result.returncode == 0 and result.stdout == "after close\n" and result.stderr == ""
