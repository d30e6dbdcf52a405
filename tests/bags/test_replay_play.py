"""``vega replay`` without the CLI: :func:`vega_bags.replay.play` republishing a run bag.

Real parts: ``play`` runs its own rclpy node and publishes on loopback (the test run's
ROS_DOMAIN_ID, LOCALHOST discovery, tests/conftest.py); a listener node in a second rclpy
context of the test process receives every topic raw.

Independent references:

* a hand-written bag (:data:`TINY`: six messages with log times, bytes and order typed out
  here, no /clock) — the expected counts, the synthesised /clock stamps (one per distinct log
  time, decoded with the bag's typestore), the span and the pacing bounds (log time / rate)
  are worked out by hand from that list;
* a real run bag (tests/bags/cached_bags.py: a 0.3 s in-process flight with /clock), compared
  byte for byte with what ``bagio.iter_raw_messages`` reads from its file;
* vega_bus.topics and qos for names, types and profiles; the ROS graph of the listener
  (node name and QoS of the publishers);
* the /clock message bytes decoded with the bag's typestore.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from contextlib import contextmanager
from functools import partial

import pytest
from load_scaling import budget_s

from vega_core.errors import BadArgument

from vega_bags import bagio, replay, simbag
from vega_bus import qos, topics

INS, CMD, CLOCK = topics.INS.name, topics.TVC_CMD.name, topics.CLOCK.name
T0_NS = 5_000_000_000
"""Log time of the first message of :data:`TINY` [ns] (not 0: ``t + first`` ≠ ``t − first``)."""
TINY = [  # (topic, log time [ns], seq): equal log times in the bag's record order (INS first)
    (INS, T0_NS, 0),
    (CMD, T0_NS, 0),
    (INS, T0_NS + 100_000_000, 1),
    (INS, T0_NS + 250_000_000, 2),
    (CMD, T0_NS + 250_000_000, 1),
    (INS, T0_NS + 400_000_000, 3),
]
TINY_SPAN_S = 0.4
"""Last minus first log time of :data:`TINY` [s]."""
TINY_COUNTS = {INS: 4, CMD: 2, CLOCK: 4}
"""Messages ``play`` publishes for :data:`TINY`: 4 INS, 2 commands, one /clock per distinct
log time (5.0, 5.1, 5.25, 5.4 s)."""
TINY_CLOCKS_NS = [T0_NS, T0_NS + 100_000_000, T0_NS + 250_000_000, T0_NS + 400_000_000]
DELIVERY_S = 10.0
"""Upper bound for discovery plus delivery (a failure guard, not a synchronisation) [s]."""


# ----------------------------------------------------------------------------------------- helpers
def _message(topic, seq):
    from vega_msgs.msg import InsMeasurement, TvcCommand

    if topic == INS:
        m = InsMeasurement()
        m.seq, m.pitch_rad, m.velocity_mps, m.valid = seq, 0.001 * (seq + 1), 300.0 + seq, True
    else:
        m = TvcCommand()
        m.seq, m.deflection_cmd_rad, m.status = seq, -0.002 * (seq + 1), 0
    return m


@pytest.fixture(scope="module")
def tiny_bag(tmp_path_factory):
    """:data:`TINY` written as a run bag (placeholder metadata; no /clock)."""
    meta = {key: "test" for key in bagio.REQUIRED_METADATA}
    path = tmp_path_factory.mktemp("tiny") / "bag"
    return simbag.write_messages(path, [(t, ns, _message(t, s)) for t, ns, s in TINY], meta)


@pytest.fixture(scope="module")
def tiny_raw(tiny_bag):
    """{topic: [bytes]} of :data:`TINY` as the bag holds them."""
    out = {}
    for topic, _, data in bagio.iter_raw_messages(tiny_bag):
        out.setdefault(topic, []).append(bytes(data))
    return out


@pytest.fixture(scope="module")
def run_bag():
    from cached_bags import cached_short_run   # flown once per set of inputs (read-only)

    return cached_short_run((20.0, 20.3))[1]


@contextmanager
def _deadline(seconds):
    """Fail with TimeoutError instead of hanging (an endless sleep in the code under test):
    SIGALRM in the main thread; a no-op elsewhere."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _raise(signum, frame):
        raise TimeoutError(f"still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, _raise)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _unpadded(wire, recorded):
    """``wire`` without the zero padding Fast DDS may add up to a multiple of 4 bytes."""
    pad = wire[len(recorded):]
    assert len(pad) < 4 and not any(pad) and (not pad or len(wire) % 4 == 0)
    return wire[:len(recorded)]


class _Listener:
    """A node in its own rclpy context, spun in a thread: every message of ``names`` raw,
    with its arrival time (time.monotonic)."""

    def __init__(self, names):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("replay_test_listener", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.got = {name: [] for name in names}
        by_name = {t.name: t for t in topics.ALL_TOPICS}
        for name in names:
            t = by_name[name]
            profile = qos.clock_qos() if t is topics.CLOCK else qos.data_qos()
            self.node.create_subscription(topics.message_class(t.type_name), name,
                                          partial(self._on, name), profile, raw=True)
        self._running = True
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on(self, name, data):
        self.got[name].append((time.monotonic(), bytes(data)))

    def _spin(self):
        while self._running:
            self.executor.spin_once(timeout_sec=0.02)

    def wait_for(self, counts, timeout_s=DELIVERY_S):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(len(self.got[n]) >= k for n, k in counts.items()):
                break
            time.sleep(0.01)
        time.sleep(0.05)       # anything beyond the expected would show up now

    def publishers(self, name, node_name="vega_replay", timeout_s=5.0):
        """The graph's publishers of ``name`` that belong to node ``node_name`` (waits until
        there is one, at most ``timeout_s``)."""
        deadline = time.monotonic() + timeout_s
        while True:
            found = [p for p in self.node.get_publishers_info_by_topic(name)
                     if p.node_name == node_name]
            if found or time.monotonic() > deadline:
                return found
            time.sleep(0.02)

    def close(self):
        import rclpy

        self._running = False
        self.thread.join(5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def listener():
    made = []

    def make(names):
        made.append(_Listener(names))
        return made[-1]

    yield make
    for one in made:
        one.close()


class _Polls:
    """A ``stop`` callback that records when it is polled and says stop from poll
    ``stop_at`` (0-based) on, or once ``stop_after_s`` passed since its first poll."""

    def __init__(self, stop_at=None, stop_after_s=None, on_first=None):
        self.times, self.stop_at, self.stop_after_s = [], stop_at, stop_after_s
        self.on_first = on_first

    def __call__(self):
        if not self.times and self.on_first is not None:
            self.on_first()
        self.times.append(time.monotonic())
        if self.stop_at is not None and len(self.times) > self.stop_at:
            return True
        return self.stop_after_s is not None and \
            self.times[-1] - self.times[0] >= self.stop_after_s


# -------------------------------------------------------------------------------------------- play
@pytest.mark.parametrize("rate", [-1.0, -1e-9, float("nan"), float("inf"), float("-inf")])
def test_bad_rate_is_refused_before_the_bag_is_read(rate, tmp_path):
    with pytest.raises(BadArgument, match="must be a finite number >= 0"):
        replay.play(tmp_path / "no_bag", rate)


@pytest.mark.slow
@pytest.mark.ros
def test_everything_in_order_at_full_speed(tiny_bag, tiny_raw, listener, monkeypatch):
    """rate 0: after waiting for the listener, every message on its topic, in order, bytes as
    recorded; a /clock per distinct log time (none lost: publishing before the subscribers
    matched would lose them)."""
    ear = listener([INS, CMD, CLOCK])
    lines = []
    # pacing is replay's only sleep: at rate 0 it must never sleep (a wall-clock bound would
    # depend on the machine's load; this does not)
    paced, real_sleep = [], time.sleep

    def sleep(seconds):
        if sys._getframe(1).f_globals.get("__name__") == replay.__name__:
            paced.append(seconds)
        real_sleep(seconds)

    monkeypatch.setattr(replay.time, "sleep", sleep)
    t_call = time.monotonic()
    with _deadline(20):
        result = replay.play(tiny_bag, 0.0, wait_subscribers_s=DELIVERY_S,
                             progress=lines.append)
    outer = time.monotonic() - t_call
    ear.wait_for(TINY_COUNTS)
    assert lines == []
    assert isinstance(result, replay.PlayResult)
    assert result.counts == TINY_COUNTS
    assert result.span_s == TINY_SPAN_S
    assert 0.0 <= result.wall_s <= outer
    assert paced == []                           # not paced
    for name in (INS, CMD):
        got = [data for _, data in ear.got[name]]
        assert [_unpadded(w, r) for w, r in zip(got, tiny_raw[name])] == tiny_raw[name]
        assert len(got) == len(tiny_raw[name])
    store = bagio.vega_typestore()
    clocks = [store.deserialize_cdr(data, topics.CLOCK.type_name).clock
              for _, data in ear.got[CLOCK]]
    assert [c.sec * 1_000_000_000 + c.nanosec for c in clocks] == TINY_CLOCKS_NS


@pytest.mark.slow
@pytest.mark.ros
def test_publishers_are_node_vega_replay_with_the_topic_qos(tiny_bag, listener):
    """The graph while play runs (looked at from its first ``stop`` poll): node
    ``vega_replay`` publishes each topic of the bag (and /clock) with its type and the
    RELIABLE/VOLATILE profile of vega_bus.qos; nothing on topics the bag does not hold."""
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    ear = listener([])
    graph = {}

    def look():   # waits until the listener has discovered play's publishers
        graph.update({n: ear.publishers(n) for n in (INS, CMD, CLOCK)})
        graph.update({t.name: ear.publishers(t.name, timeout_s=0.0)
                      for t in (topics.TRUTH, topics.ACTUATOR, topics.DIAGNOSTICS)})

    with _deadline(20):
        replay.play(tiny_bag, 0.0, stop=_Polls(on_first=look))
    assert graph[topics.TRUTH.name] == graph[topics.ACTUATOR.name] == []
    assert graph[topics.DIAGNOSTICS.name] == []
    for name, t in ((INS, topics.INS), (CMD, topics.TVC_CMD), (CLOCK, topics.CLOCK)):
        assert len(graph[name]) == 1, name
        pub = graph[name][0]
        assert pub.topic_type == t.type_name
        assert pub.qos_profile.reliability == ReliabilityPolicy.RELIABLE
        assert pub.qos_profile.durability == DurabilityPolicy.VOLATILE


@pytest.mark.slow
@pytest.mark.ros
def test_paced_by_the_log_times(tiny_bag, listener):
    """rate 0.5: a message (and the /clock of its log time) arrives no earlier than
    (t_k − t_0) / 0.5 after the call; the whole replay takes at least span / rate."""
    rate = 0.5
    ear = listener([INS, CMD, CLOCK])
    lines = []
    t_call = time.monotonic()
    with _deadline(15):
        result = replay.play(tiny_bag, rate, wait_subscribers_s=DELIVERY_S,
                             progress=lines.append)
    ear.wait_for(TINY_COUNTS)
    assert lines == []
    assert result.counts == TINY_COUNTS and result.span_s == TINY_SPAN_S
    # the loop's own time: the span at this rate, plus scheduling slack (1 s, generous)
    assert TINY_SPAN_S / rate <= result.wall_s <= TINY_SPAN_S / rate + budget_s(1.0)
    due = {name: [(ns - T0_NS) / 1e9 / rate for topic, ns, _ in TINY if topic == name]
           for name in (INS, CMD)}
    due[CLOCK] = [(ns - T0_NS) / 1e9 / rate for ns in TINY_CLOCKS_NS]
    for name, offsets in due.items():
        arrived = [t - t_call for t, _ in ear.got[name]]
        assert len(arrived) == len(offsets)
        for k, (at, when) in enumerate(zip(arrived, offsets)):
            assert at >= when, (name, k, at, when)


@pytest.mark.slow
def test_default_rate_is_real_time_and_no_wait(tiny_bag):
    """Defaults: rate 1 (the replay lasts at least the span), no wait for subscribers (nothing
    said although nobody listens), publishers made without a subscriber are no error."""
    lines = []
    polls = _Polls()
    t_call = time.monotonic()
    with _deadline(15):
        result = replay.play(tiny_bag, progress=lines.append, stop=polls)
    assert lines == []
    assert result.counts == TINY_COUNTS and result.span_s == TINY_SPAN_S
    assert TINY_SPAN_S <= result.wall_s <= TINY_SPAN_S + budget_s(1.0)
    # one stop poll per message, each after the previous message's due time
    assert len(polls.times) == len(TINY)
    for k in range(1, len(TINY)):
        assert polls.times[k] - t_call >= (TINY[k - 1][1] - T0_NS) / 1e9


@pytest.mark.slow
@pytest.mark.ros
def test_missing_subscribers_are_named_after_the_wait(tiny_bag, listener):
    """wait_subscribers_s=0.4 with a subscriber on /vega/ins only: it waits 0.4 s, polling
    ``stop`` about every 0.05 s, names the topics without one and publishes anyway."""
    ear = listener([INS])
    said = []
    polls = _Polls()
    with _deadline(20):
        result = replay.play(tiny_bag, 0.0, wait_subscribers_s=0.4, stop=polls,
                             progress=lambda line: said.append((time.monotonic(), line,
                                                                len(polls.times))))
    # the listener's /vega/ins subscription is normally discovered within the 0.4 s; on a
    # loaded machine it may not be yet, and then /vega/ins is rightly named too
    assert [line for _, line, _ in said] in (
        [f"no subscriber on {CMD}, {CLOCK} after 0.4 s; publishing anyway"],
        [f"no subscriber on {INS}, {CMD}, {CLOCK} after 0.4 s; publishing anyway"])
    at, _, polled = said[0]
    assert at - polls.times[0] >= 0.4 - 0.01
    assert polled >= 2                                      # polled while waiting
    waiting = polls.times[:polled]
    assert max(b - a for a, b in zip(waiting, waiting[1:])) < budget_s(0.5)
    assert result.counts == TINY_COUNTS and result.span_s == TINY_SPAN_S
    assert len(polls.times) == polled + len(TINY)           # then once per message
    ear.wait_for({INS: 4}, timeout_s=2.0)


def test_missing_subscribers_without_progress_callback(tiny_bag):
    with _deadline(20):
        result = replay.play(tiny_bag, 0.0, wait_subscribers_s=0.1)
    assert result.counts == TINY_COUNTS


@pytest.mark.slow
def test_stop_ends_the_wait_for_subscribers(tiny_bag):
    """Nobody listens, 30 s allowed: ``stop`` turning True after 0.2 s ends the wait (and,
    still True, the replay before its first message)."""
    said = []
    polls = _Polls(stop_after_s=0.2)
    t_call = time.monotonic()
    with _deadline(10):
        result = replay.play(tiny_bag, 0.0, wait_subscribers_s=30.0, stop=polls,
                             progress=said.append)
    assert time.monotonic() - t_call < 5.0
    assert said == [f"no subscriber on {INS}, {CMD}, {CLOCK} after 30 s; publishing anyway"]
    assert result.counts == {INS: 0, CMD: 0, CLOCK: 0} and result.span_s == 0.0


@pytest.mark.parametrize("stop_at, counts, span_ns", [
    (0, {INS: 0, CMD: 0, CLOCK: 0}, None),
    (1, {INS: 1, CMD: 0, CLOCK: 1}, 0),
    (3, {INS: 2, CMD: 1, CLOCK: 2}, 100_000_000),
    (5, {INS: 3, CMD: 2, CLOCK: 3}, 250_000_000),
])
def test_stop_between_messages(tiny_bag, stop_at, counts, span_ns):
    """``stop`` True from its poll before message ``stop_at`` on: exactly the messages before
    it were published (a /clock per distinct log time among them), the span theirs."""
    with _deadline(20):
        result = replay.play(tiny_bag, 0.0, stop=_Polls(stop_at=stop_at))
    assert isinstance(result, replay.PlayResult)
    assert result.counts == counts
    assert result.span_s == (0.0 if span_ns is None else span_ns / 1e9)
    assert result.wall_s >= 0.0


@pytest.mark.slow
@pytest.mark.ros
def test_real_run_bag_is_republished_byte_for_byte(run_bag, listener):
    """A real run bag (with /clock): every topic, every message in order with the recorded
    bytes; /clock as recorded, none added."""
    expected, times = {}, []
    for topic, t_ns, data in bagio.iter_raw_messages(run_bag):
        expected.setdefault(topic, []).append(bytes(data))
        times.append(t_ns)
    assert set(expected) == {t.name for t in topics.ALL_TOPICS}
    ear = listener(list(expected))
    with _deadline(20):
        result = replay.play(run_bag, 0.0, wait_subscribers_s=DELIVERY_S)
    ear.wait_for({n: len(v) for n, v in expected.items()})
    assert result.counts == {n: len(v) for n, v in expected.items()}
    assert result.span_s == (times[-1] - times[0]) / 1e9
    for name, recorded in expected.items():
        got = [data for _, data in ear.got[name]]
        assert len(got) == len(recorded), name
        assert [_unpadded(w, r) for w, r in zip(got, recorded)] == recorded, name


def test_clock_bytes_by_hand():
    """A rosgraph_msgs/Clock at 20.012 s: sec 20, nanosec 12 000 000 (the bag's typestore)."""
    store = bagio.vega_typestore()
    msg = store.deserialize_cdr(replay._clock_bytes(20_012_000_000), "rosgraph_msgs/msg/Clock")
    assert (msg.clock.sec, msg.clock.nanosec) == (20, 12_000_000)
    msg = store.deserialize_cdr(replay._clock_bytes(999_999_999), "rosgraph_msgs/msg/Clock")
    assert (msg.clock.sec, msg.clock.nanosec) == (0, 999_999_999)
    assert isinstance(replay._clock_bytes(0), bytes)
