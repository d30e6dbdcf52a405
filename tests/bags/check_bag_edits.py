"""In-memory edits of a loaded run bag, for the `vega check` tests (vega_bags.bagcheck).

One short in-process flight (thesis scenario, 20.0 … 20.5 s, PD fixture table) is written to a
bag and read back once (:func:`short_run_bag`, flown once per set of inputs:
tests/bags/cached_bags.py); a test injects its faults into the columns of that loaded bag in
memory (no flight, no bag written per test), so that each check is exercised on its own.
:data:`TIMING` is the loop timing of vehicle.yaml the schedule of that run follows.
"""

from __future__ import annotations

import dataclasses

from cached_bags import cached_short_run
from vega_bags import bagio
from vega_bus import topics
from vega_bus.timing import LoopTiming

MS = 1_000_000  # ns
TIMING = LoopTiming(physics_dt_ms=1, frame_ms=10, controller_period_ms=20, sensor_latency_ms=12,
                    computing_latency_ms=12, actuator_latency_ms=15)
TRUTH, INS, CMD, ACT, DIAG, CLOCK = (t.name for t in (
    topics.TRUTH, topics.INS, topics.TVC_CMD, topics.ACTUATOR, topics.DIAGNOSTICS,
    topics.CLOCK))


def short_run_bag():
    """(the in-process run, its bag directory, the loaded bag) of the 20.0 … 20.5 s flight."""
    run, path = cached_short_run((20.0, 20.5))
    return run, path, bagio.read_run_bag(path)


def _edit(bag, topic, log_time_ns=None, **columns):
    """The bag with some columns (and/or the log times) of one topic replaced."""
    cols = bag[topic]
    new = dataclasses.replace(cols, columns={**cols.columns, **columns},
                              log_time_ns=cols.log_time_ns if log_time_ns is None
                              else log_time_ns)
    return dataclasses.replace(bag, topics={**bag.topics, topic: new})


def _take(bag, topic, n):
    """The bag with only the first ``n`` messages of a topic of fixed-size fields."""
    cols = bag[topic]
    assert not cols.counts
    new = dataclasses.replace(cols, log_time_ns=cols.log_time_ns[:n],
                              columns={k: v[:n] for k, v in cols.columns.items()})
    return dataclasses.replace(bag, topics={**bag.topics, topic: new})


def _without(bag, topic):
    """The bag without one topic."""
    return dataclasses.replace(bag, topics={k: v for k, v in bag.topics.items() if k != topic})


def _meta(bag, **changes):
    """The bag with run-metadata entries replaced (key: the name of a bagio.META_* constant;
    value None: the entry removed)."""
    meta = dict(bag.metadata)
    for k, v in changes.items():
        key = getattr(bagio, k)
        if v is None:
            meta.pop(key, None)
        else:
            meta[key] = v
    return dataclasses.replace(bag, metadata=meta)


def _stamps_ms(bag, topic, field="stamp_ns"):
    """A topic's stamps (or another ns field) in whole ms."""
    return (bag[topic][field] // MS).tolist()
