"""Time limits of the tests that run real processes, scaled by the measured load.

A limit in a test is a backstop against a hang, never the thing tested: a process that works
must not hit it, however busy the machine. The limits are written as what the step takes on an
idle machine with a generous margin (``idle_s``), and :func:`budget_s` stretches them by the
load measured when the wait starts: the 1-minute load average per CPU, never below 1
(``os.getloadavg()`` / ``os.cpu_count()``; on the 2-core machine shared by several test runs it
was seen between 1 and 6). Where a test can wait for an event instead (a line on stderr, a
message on a topic, a process ending), it does, and the limit only bounds a hang
(docs/TESTING.md, "Flaky tests: root causes and fixes").
"""

import os

__all__ = ["load_factor", "budget_s"]

MAX_FACTOR = 8.0
"""Upper bound of the stretch (assumption: beyond 8 runnable processes per CPU a hang is more
likely than slowness, and a test should not wait for ever)."""


def load_factor() -> float:
    """The 1-minute load average per CPU now, clipped to [1, :data:`MAX_FACTOR`]."""
    try:
        load = os.getloadavg()[0]
    except OSError:                      # no load average on this system: assume busy
        return MAX_FACTOR
    return min(MAX_FACTOR, max(1.0, load / (os.cpu_count() or 1)))


def budget_s(idle_s: float) -> float:
    """``idle_s`` (what the step may take on an idle machine, margin included) times
    :func:`load_factor`."""
    return idle_s * load_factor()
