"""Property test of the bag writer (hypothesis): any sequence of messages on the graph's topics,
with non-decreasing log times and arbitrary payload bytes, written with RunBagWriter (chunk
flushes every second of log time included) reads back per topic in order, bit for bit."""

import itertools
import pytest

from hypothesis import given, settings
from hypothesis import strategies as st

from vega_bags import bagio
from vega_bus import topics

META = {k: "x" for k in bagio.REQUIRED_METADATA}

messages = st.lists(
    st.tuples(st.sampled_from([t.name for t in topics.ALL_TOPICS]),
              st.integers(0, 3_000_000_000),            # log-time step [ns], up to 3 s
              st.binary(min_size=0, max_size=64)),
    min_size=1, max_size=60)


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(batch=messages)
def test_write_then_read_gives_the_same_messages(tmp_path_factory, batch):
    path = tmp_path_factory.mktemp("rt") / "bag"
    times = list(itertools.accumulate(step for _, step, _ in batch))
    with bagio.RunBagWriter(path, META) as bag:
        for (topic, _, data), t in zip(batch, times):
            bag.write(topic, t, data)
    got = list(bagio.iter_raw_messages(path))
    want = [(topic, t, data) for (topic, _, data), t in zip(batch, times)]
    for name in {t for t, _, _ in want}:
        assert [(ts, bytes(d)) for tp, ts, d in got if tp == name] == \
               [(ts, d) for tp, ts, d in want if tp == name], name
    assert len(got) == len(want)
