"""The feeding loop of the controller replay (``vega_bags.replay._feed``) and the final flush
of the publishers (``_flush``).

The loop waits for the start barrier, publishes every INS measurement's recorded bytes and,
after each one on the controller period (20 ms), waits for its command before the next
measurement; it names a barrier that is not reached, a controller that stalls (no command
within STALL_TIMEOUT_S), ends early or dies (its own exit status and last line), and waits for
the controller to end. Independent reference: a fake controller, barrier, executor and INS
publisher (:class:`_Loop`) that answer by a rule stated here, so that every expected list,
count and message follows by hand; the flush shares one deadline between the publishers, in
nanoseconds.
"""

from types import SimpleNamespace

import pytest

from load_scaling import budget_s
from vega_bags import replay


class _Loop:
    """A controller, start barrier, executor and INS publisher for :func:`replay._feed`.

    The "controller" answers every INS sample on the 20 ms period with one command, delivered
    on the next ``spin_once`` (``answer_until``: it stops answering after that many);
    ``exit_after``: its exit status once that many commands were sent (None: it runs on).
    """

    def __init__(self, samples_ms, barrier_ok=True, answer_until=None, exit_after=None,
                 exit_code=0, code_at_barrier=None):
        self.samples_ms = samples_ms
        self.barrier_ok, self.answer_until = barrier_ok, answer_until
        self.exit_after, self.exit_code = exit_after, exit_code
        self.returncode = code_at_barrier
        self.published, self.received, self.said = [], [], []
        self.spins, self.barrier_args, self.waited, self.acked = [], None, [], []

    # the controller process
    def failure(self):
        return f"tvc_controller ended with status {self.returncode}: last line"

    def wait(self, timeout_s):
        self.waited.append(timeout_s)
        if self.returncode is None and self.exit_after is None:
            self.returncode = 0
        return self.returncode

    # the barrier
    def wait_barrier(self, spin, timeout_s, stop):
        self.barrier_args = (timeout_s, stop())
        spin(0.5)
        return self.barrier_ok

    def describe_missing(self):
        return "tvc_controller not seen"

    # the executor
    def spin_once(self, timeout_sec):
        self.spins.append(timeout_sec)
        due = sum(1 for s in self.samples_ms[:len(self.published)] if s % 20 == 0)
        limit = due if self.answer_until is None else min(due, self.answer_until)
        if len(self.received) < limit and self.returncode is None:
            self.received.append(b"cmd%d" % len(self.received))
            if self.exit_after is not None and len(self.received) >= self.exit_after:
                self.returncode = self.exit_code

    # the INS publisher
    def publish(self, data):
        self.published.append(data)

    def wait_for_all_acked(self, duration):
        self.acked.append(duration.nanoseconds)
        return True

    def feed(self, ins_raw, barrier_timeout_s=7.0):
        barrier = SimpleNamespace(wait=self.wait_barrier, describe_missing=self.describe_missing)
        return replay._feed(self, barrier, self, self, ins_raw, self.samples_ms, 20,
                            self.received, barrier_timeout_s, self.said.append)


def _ins(n):
    return [bytearray(b"ins%d" % k) for k in range(n)], [20000 + 10 * k for k in range(n)]


def test_feed_sends_every_measurement_and_waits_for_each_command():
    raw, samples = _ins(7)                     # samples 20000 … 20060: 4 on the 20 ms period
    loop = _Loop(samples)
    assert loop.feed(raw) is None
    assert loop.published == [bytes(r) for r in raw]
    assert all(type(p) is bytes for p in loop.published)
    assert loop.received == [b"cmd0", b"cmd1", b"cmd2", b"cmd3"]
    assert loop.barrier_args == (7.0, False)   # the barrier's stop: the controller has ended
    assert set(loop.spins) == {0.5, 0.05}
    assert loop.waited == [10.0]
    assert len(loop.acked) == 1 and 4.5e9 < loop.acked[0] <= 5e9
    assert loop.said[0] == "controller started; waiting for the start barrier"
    assert loop.said[1].startswith("7 measurements replayed in ") and loop.said[1].endswith(" s")
    assert len(loop.said) == 2


def test_feed_waits_for_the_command_before_the_next_measurement():
    """The measurement after one on the period goes out only once its command arrived."""
    raw, samples = _ins(5)
    loop = _Loop(samples)
    order = []
    pub, spin = loop.publish, loop.spin_once

    def publish(data):
        order.append(("ins", len(loop.received)))
        pub(data)

    def spin_once(timeout_sec):
        spin(timeout_sec)
        order.append(("spin", len(loop.received)))

    loop.publish, loop.spin_once = publish, spin_once
    assert loop.feed(raw) is None
    ins = [n for kind, n in order if kind == "ins"]
    assert ins == [0, 1, 1, 2, 2]              # commands seen before measurements 1 … 4


def test_feed_start_barrier_failures():
    raw, samples = _ins(3)
    loop = _Loop(samples, barrier_ok=False)
    f = loop.feed(raw)
    assert (f.code, str(f)) == (1, "start barrier: tvc_controller not seen")
    assert loop.published == []
    loop = _Loop(samples, barrier_ok=False, code_at_barrier=2)
    f = loop.feed(raw)
    assert loop.barrier_args == (7.0, True)
    assert (f.code, str(f)) == (2, "tvc_controller ended with status 2: last line")
    loop = _Loop(samples, barrier_ok=False, code_at_barrier=3)
    f = loop.feed(raw)
    assert (f.code, str(f)) == (1, "tvc_controller ended with status 3: last line")
    loop = _Loop(samples, barrier_ok=False, code_at_barrier=0)   # ended normally: not a cause
    assert str(loop.feed(raw)) == "start barrier: tvc_controller not seen"


@pytest.mark.slow
def test_feed_a_stalled_controller(monkeypatch):
    monkeypatch.setattr(replay, "STALL_TIMEOUT_S", 0.3)
    raw, samples = _ins(6)
    loop = _Loop(samples, answer_until=2)
    t0 = replay.time.monotonic()
    f = loop.feed(raw)
    waited = replay.time.monotonic() - t0
    assert (f.code, str(f)) == (1, "no command for measurement #4 (sample 20.040 s) within "
                                   "0.3 s")
    assert 0.3 <= waited < 5.0
    assert len(loop.published) == 5 and loop.waited == []


def test_feed_a_controller_that_ends_or_dies_early():
    raw, samples = _ins(8)
    # ended normally after 2 commands: the missing command is named at once, no stall wait
    loop = _Loop(samples, exit_after=2, exit_code=0)
    t0 = replay.time.monotonic()
    f = loop.feed(raw)
    assert replay.time.monotonic() - t0 < replay.STALL_TIMEOUT_S / 2
    assert (f.code, str(f)) == (1, "no command for measurement #4 (sample 20.040 s) within "
                                   "20 s")
    # died (status 1) or refused its input (2) after 2 commands: its own failure
    for code in (1, 2):
        loop = _Loop(samples, exit_after=2, exit_code=code)
        f = loop.feed(raw)
        assert (f.code, str(f)) == (code, f"tvc_controller ended with status {code}: last line")
    # ended with a failure after the last command: reported after the wait
    loop = _Loop(samples, exit_after=4, exit_code=1)
    f = loop.feed(raw)
    assert (f.code, str(f)) == (1, "tvc_controller ended with status 1: last line")
    assert loop.waited == [10.0] and len(loop.published) == 8


def test_feed_with_the_clock_standing_still(monkeypatch):
    """Stall limit 0 and a clock that does not move: the deadline is not passed (">"), so the
    loop still spins once and gets the command; the log line says 0.00 s."""
    monkeypatch.setattr(replay, "STALL_TIMEOUT_S", 0.0)
    monkeypatch.setattr(replay.time, "monotonic", lambda: 500.0)
    raw, samples = _ins(3)
    loop = _Loop(samples)
    assert loop.feed(raw) is None
    assert loop.received == [b"cmd0", b"cmd1"]
    assert loop.said[1] == "3 measurements replayed in 0.00 s"


# ------------------------------------------------------------------------------------------- flush
def test_flush_shares_one_deadline():
    acked = []
    pubs = [SimpleNamespace(wait_for_all_acked=lambda d: acked.append(d.nanoseconds))
            for _ in range(3)]
    replay._flush(pubs, 2.0)
    # the first publisher's share: 2 s less what elapsed before its call (load-scaled bound)
    assert len(acked) == 3 and 2e9 - budget_s(0.1) * 1e9 < acked[0] <= 2e9
    assert acked[0] >= acked[1] >= acked[2] >= 0
    acked.clear()
    replay._flush(pubs, 0.0)
    assert acked == [0, 0, 0]


def test_flush_waits_in_nanoseconds(monkeypatch):
    """With the clock standing still each publisher gets exactly 2 s = 2 000 000 000 ns."""
    acked = []
    pubs = [SimpleNamespace(wait_for_all_acked=lambda d: acked.append(d.nanoseconds))
            for _ in range(2)]
    monkeypatch.setattr(replay.time, "monotonic", lambda: 1000.0)
    replay._flush(pubs, 2.0)
    assert acked == [2_000_000_000, 2_000_000_000]
