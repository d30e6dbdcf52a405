"""``vega replay`` without the CLI: :func:`vega_bags.replay.play` and the controller child
process (``_ControllerProcess``), tested for the "no tests" mutants of
`make mutation MODULE=replay`. Each test takes well under 3 s.

Real parts: ``play`` runs its own rclpy node and publishes on loopback (the test run's
ROS_DOMAIN_ID, LOCALHOST discovery, tests/conftest.py); a listener node in a second rclpy
context of the test process receives every topic raw. ``_ControllerProcess`` starts a tiny
shell script found through a real ament index prefix (the real ``find_executable``), and once
the installed ``tvc_controller`` itself.

Independent references:

* a hand-written bag (:data:`TINY`: six messages with log times, bytes and order typed out
  here, no /clock) — the expected counts, the synthesised /clock stamps (one per distinct log
  time, decoded with the bag's typestore), the span and the pacing bounds (log time / rate)
  are worked out by hand from that list;
* a real run bag (tests/cached_bags.py: a 0.3 s in-process flight with /clock), compared
  byte for byte with what ``bagio.iter_raw_messages`` reads from its file;
* vega_bus.topics and qos for names, types and profiles; the ROS graph of the listener
  (node name and QoS of the publishers);
* for the child process: what the script itself records (argv, working directory,
  environment, the parameters file read with PyYAML against hand-typed values), the exit
  status and the log line it was told to print.
"""

from __future__ import annotations

import os
import signal
import stat
import threading
import time
from contextlib import contextmanager
from functools import partial
from pathlib import Path

import pytest
import yaml

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


# ----------------------------------------------------------------------------- helpers
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
    """Fail with TimeoutError instead of hanging (a mutant's endless sleep): SIGALRM in the
    main thread; a no-op elsewhere."""
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


# ----------------------------------------------------------------------------- play
@pytest.mark.parametrize("rate", [-1.0, -1e-9, float("nan"), float("inf"), float("-inf")])
def test_bad_rate_is_refused_before_the_bag_is_read(rate, tmp_path):
    with pytest.raises(BadArgument, match="must be a finite number >= 0"):
        replay.play(tmp_path / "no_bag", rate)


@pytest.mark.ros
def test_everything_in_order_at_full_speed(tiny_bag, tiny_raw, listener):
    """rate 0: after waiting for the listener, every message on its topic, in order, bytes as
    recorded; a /clock per distinct log time (none lost: publishing before the subscribers
    matched would lose them)."""
    ear = listener([INS, CMD, CLOCK])
    lines = []
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
    assert result.wall_s < TINY_SPAN_S           # not paced
    for name in (INS, CMD):
        got = [data for _, data in ear.got[name]]
        assert [_unpadded(w, r) for w, r in zip(got, tiny_raw[name])] == tiny_raw[name]
        assert len(got) == len(tiny_raw[name])
    store = bagio.vega_typestore()
    clocks = [store.deserialize_cdr(data, topics.CLOCK.type_name).clock
              for _, data in ear.got[CLOCK]]
    assert [c.sec * 1_000_000_000 + c.nanosec for c in clocks] == TINY_CLOCKS_NS


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
    assert TINY_SPAN_S / rate <= result.wall_s <= TINY_SPAN_S / rate + 1.0
    due = {name: [(ns - T0_NS) / 1e9 / rate for topic, ns, _ in TINY if topic == name]
           for name in (INS, CMD)}
    due[CLOCK] = [(ns - T0_NS) / 1e9 / rate for ns in TINY_CLOCKS_NS]
    for name, offsets in due.items():
        arrived = [t - t_call for t, _ in ear.got[name]]
        assert len(arrived) == len(offsets)
        for k, (at, when) in enumerate(zip(arrived, offsets)):
            assert at >= when, (name, k, at, when)


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
    assert TINY_SPAN_S <= result.wall_s <= TINY_SPAN_S + 1.0
    # one stop poll per message, each after the previous message's due time
    assert len(polls.times) == len(TINY)
    for k in range(1, len(TINY)):
        assert polls.times[k] - t_call >= (TINY[k - 1][1] - T0_NS) / 1e9


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
    assert [line for _, line, _ in said] == [
        f"no subscriber on {CMD}, {CLOCK} after 0.4 s; publishing anyway"]
    at, _, polled = said[0]
    assert at - polls.times[0] >= 0.4 - 0.01
    assert polled >= 3                                      # polled while waiting
    waiting = polls.times[:polled]
    assert max(b - a for a, b in zip(waiting, waiting[1:])) < 0.5
    assert result.counts == TINY_COUNTS and result.span_s == TINY_SPAN_S
    assert len(polls.times) == polled + len(TINY)           # then once per message
    ear.wait_for({INS: 4}, timeout_s=2.0)


def test_missing_subscribers_without_progress_callback(tiny_bag):
    with _deadline(20):
        result = replay.play(tiny_bag, 0.0, wait_subscribers_s=0.1)
    assert result.counts == TINY_COUNTS


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


# ----------------------------------------------------------------------------- controller process
FAKE_NODE = """#!/bin/sh
rec="$VEGA_FAKE_RECORD"
printf '%s\\n' "$0" "$@" > "$rec/argv"
pwd > "$rec/cwd"
cp "$3" "$rec/params.yaml"
printf '%s\\n' "${VEGA_FAKE_MARK-unset}" "${VEGA_ONLY_IN_PARENT-unset}" > "$rec/env"
if [ -n "$VEGA_FAKE_SAY" ]; then printf 'first line\\n%s\\n\\n' "$VEGA_FAKE_SAY"; fi
if [ -n "$VEGA_FAKE_SLEEP" ]; then exec sleep "$VEGA_FAKE_SLEEP"; fi
exit "${VEGA_FAKE_EXIT-0}"
"""


@pytest.fixture
def fake_controller(tmp_path, monkeypatch):
    """An ament prefix whose vega_gnc has a ``tvc_controller`` script (:data:`FAKE_NODE`),
    searched first; returns (the script's path, its record directory, env maker)."""
    from vega_bringup import rosenv

    prefix = tmp_path / "prefix"
    index = prefix / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True)
    (index / "vega_gnc").write_text("")
    exe = prefix / "lib" / "vega_gnc" / "tvc_controller"
    exe.parent.mkdir(parents=True)
    exe.write_text(FAKE_NODE)
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("AMENT_PREFIX_PATH",
                       os.pathsep.join([str(prefix), os.environ.get("AMENT_PREFIX_PATH", "")]))
    monkeypatch.setenv("VEGA_ONLY_IN_PARENT", "yes")
    record = tmp_path / "record"
    record.mkdir()

    def env(**extra):
        out = rosenv.ros_environment()
        out.pop("VEGA_ONLY_IN_PARENT", None)
        out.update(VEGA_FAKE_RECORD=str(record), VEGA_FAKE_MARK="passed", **extra)
        return out

    return exe, record, env


def _params(barrier_timeout_s=7.5, table="/x/t.npz"):
    from vega_bringup import orchestrate

    return orchestrate.RunParameters(
        scenario="thesis", seed=42, realtime=False, controller_table=table, bag_path="",
        participants=("tvc_controller", "recorder"), barrier_timeout_s=barrier_timeout_s)


@contextmanager
def _started(params, workdir, env):
    controller = replay._ControllerProcess(params, workdir, env)
    try:
        yield controller
    finally:
        controller.stop()


def test_controller_command_line_directory_environment(fake_controller, tmp_path):
    """A fresh nested work directory: the executable of vega_gnc/tvc_controller from the
    ament index, ``--ros-args --params-file WORKDIR/params.yaml`` holding the run's
    parameters, started in WORKDIR with exactly the given environment, its output in
    WORKDIR/logs/tvc_controller.log."""
    exe, record, env = fake_controller
    workdir = tmp_path / "new" / "work"
    with _started(_params(), workdir, env(VEGA_FAKE_SAY="said")) as controller:
        assert controller.wait(10.0) == 0
        assert controller.returncode == 0
        sup = controller.supervisor
        assert sup.participants == ("tvc_controller", "recorder")
        assert sup.barrier_timeout_s == 7.5
        assert not sup.watch_barrier          # the checker watches the barrier, not this
        assert controller.process is sup.processes[0] and len(sup.processes) == 1
    params_file = workdir / "params.yaml"
    assert (record / "argv").read_text().splitlines() == [
        str(exe), "--ros-args", "--params-file", str(params_file)]
    assert Path((record / "cwd").read_text().strip()).resolve() == workdir.resolve()
    assert (record / "env").read_text().splitlines() == ["passed", "unset"]
    assert yaml.safe_load((record / "params.yaml").read_text()) == {"/**": {"ros__parameters": {
        "scenario": "thesis", "seed": 42, "realtime": False, "controller_table": "/x/t.npz",
        "bag_path": "", "participants": ["tvc_controller", "recorder"],
        "barrier_timeout_s": 7.5}}}
    assert (workdir / "logs" / "tvc_controller.log").read_text() == "first line\nsaid\n\n"


def test_controller_in_an_existing_directory(fake_controller, tmp_path):
    """check_controller hands it a directory mkdtemp made already."""
    _, record, env = fake_controller
    workdir = tmp_path / "exists"
    workdir.mkdir()
    with _started(_params(), workdir, env()) as controller:
        assert controller.wait(10.0) == 0
    assert (record / "argv").read_text().splitlines()[-1] == str(workdir / "params.yaml")


@pytest.mark.parametrize("status, say, text", [
    (2, "tvc_controller: bad input", "tvc_controller ended with exit status 2: "
                                     "tvc_controller: bad input"),
    (1, "", "tvc_controller ended with exit status 1"),
])
def test_controller_failure_names_status_and_last_line(fake_controller, tmp_path, status,
                                                       say, text):
    _, _, env = fake_controller
    with _started(_params(), tmp_path / "w", env(VEGA_FAKE_EXIT=str(status),
                                                 VEGA_FAKE_SAY=say)) as controller:
        assert controller.wait(10.0) == status
        assert controller.returncode == status
        assert controller.failure() == text


def test_controller_wait_gives_up_and_stop_ends_it(fake_controller, tmp_path):
    """A node that keeps running: wait(0.2) returns None after about 0.2 s; stop() ends it
    (SIGTERM), and the failure says so."""
    _, _, env = fake_controller
    with _started(_params(), tmp_path / "w", env(VEGA_FAKE_SLEEP="60")) as controller:
        out = []
        waiter = threading.Thread(target=lambda: out.append(controller.wait(0.2)), daemon=True)
        t = time.monotonic()
        waiter.start()
        waiter.join(5.0)
        assert out == [None] and time.monotonic() - t >= 0.2
        assert controller.returncode is None
        controller.stop()
        assert controller.returncode == -signal.SIGTERM
        assert controller.failure() == "tvc_controller ended with killed by SIGTERM"


@pytest.mark.ros
def test_installed_controller_reads_its_parameters(tmp_path):
    """The real tvc_controller, nobody publishing /vega/run: it gives up after the barrier
    timeout of the parameters file (0.5 s) and exits 1 saying so (its installed table)."""
    from vega_bringup import rosenv

    with _started(_params(barrier_timeout_s=0.5, table=""), tmp_path / "w",
                  rosenv.ros_environment()) as controller:
        assert controller.wait(30.0) == 1
        text = controller.failure()
    assert text.startswith("tvc_controller ended with exit status 1: tvc_controller: ")
    assert "waited 0.5 s for the run description on /vega/run" in text
