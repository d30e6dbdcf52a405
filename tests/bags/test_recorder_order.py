"""The recorder's reorder buffer: whatever order the executor delivers the
topics in (each topic in its own order), the bag gets (log time, topic rank) order, and the
same for every delivery order."""

import random

from vega_bags.recorder import Reorder
from vega_bus import topics
from vega_bus.schedule import RunInfo
from vega_bus.timing import NS_PER_MS, LoopTiming


def _streams(info):
    """Per topic, the (topic, log time) of a complete run, as the lockstep stamps them."""
    t, ms = info.timing, NS_PER_MS
    samples = list(info.command_samples())
    lag = t.sensor_latency_ms + t.computing_latency_ms
    return {
        topics.TRUTH.name: [info.frame_start(k) * ms for k in range(info.n_frames + 1)],
        topics.CLOCK.name: [info.frame_start(k) * ms for k in info.clock_frames()],
        topics.INS.name: [(info.frame_start(k) + t.sensor_latency_ms) * ms
                          for k in range(info.n_frames)],
        topics.TVC_CMD.name: [(s + lag) * ms for s in samples],
        topics.DIAGNOSTICS.name: [(s + lag) * ms for s in samples],
        topics.ACTUATOR.name: [(info.frame_start(k) + t.frame_ms) * ms
                               for k in range(info.n_frames)],
    }


def test_any_delivery_order_gives_one_file_order():
    info = RunInfo("x", 1, 10_000, 10_500, LoopTiming()).check()
    streams = _streams(info)
    assert {k: len(v) for k, v in streams.items()} == info.expected_counts()
    want = sorted(((n, topics.RECORD_ORDER[name], name) for name, ts in streams.items()
                   for n in ts))
    want = [(name, n) for n, _, name in want]
    for seed in range(20):
        rng = random.Random(seed)
        pending = {k: list(v) for k, v in streams.items()}
        written, held = [], []
        reorder = Reorder(lambda name, n, data: written.append((name, n)),
                          info.expected_counts())
        while any(pending.values()):
            name = rng.choice([k for k, v in pending.items() if v])
            reorder.add(name, pending[name].pop(0), b"")
            held.append(len(reorder))
        assert len(reorder) == 0            # the last message releases everything
        assert written == want, seed
        assert max(held) < 200              # a bounded buffer, not the whole run


def test_drain_writes_what_is_held_in_order():
    written = []
    reorder = Reorder(lambda name, n, data: written.append((name, n, data)),
                      {topics.TRUTH.name: 3, topics.INS.name: 3})
    reorder.add(topics.INS.name, 12, b"i0")
    reorder.add(topics.TRUTH.name, 10, b"t0")     # INS may still send ≤ 12: 10 goes
    reorder.add(topics.TRUTH.name, 20, b"t1")
    assert written == [(topics.TRUTH.name, 10, b"t0"), (topics.INS.name, 12, b"i0")]
    reorder.drain()                             # a stop: what is held, in order
    assert written[2:] == [(topics.TRUTH.name, 20, b"t1")] and len(reorder) == 0
