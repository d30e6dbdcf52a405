"""The ROS shell of ``vega replay --check-controller`` (vega_bags.replay.check_controller):
what it asks of ROS, tested for the survivors of `make mutation MODULE=replay`.

No ROS participant is started: the node, the start barrier, the controller process and the
feeding loop are replaced by recorders of what check_controller hands them, and the
"controller" answers through the command subscription's own callback (as DDS would call it).

Independent references: the topic names, message types, QoS profiles and ``raw`` flags of
vega_bus (topics.py, qos.py) — the same the nodes use; the start-barrier seats of the SIL
(docs: the checker sits where the recorder sits); a run bag written from a short in-process
flight (tests/fixture_bags.py) with hand-written metadata.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import pytest

from vega_bags import bagio, replay
from vega_bus import qos, topics

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config" / "guidance_reference.npz"


@pytest.fixture(scope="module")
def run_and_bag():
    from cached_bags import cached_short_run

    return cached_short_run((20.0, 20.3))


@pytest.fixture(scope="module")
def run(run_and_bag):
    return run_and_bag[0]


@pytest.fixture(scope="module")
def bag(run_and_bag):
    return run_and_bag[1]


class _Shell:
    """Recorders of the ROS plumbing; the controller answers ``answer`` via the callback."""

    def __init__(self, answer=None, failure=None, remove_workdir=False):
        self.answer, self.failure, self.remove_workdir = answer, failure, remove_workdir
        self.publishers, self.subscriptions = [], []
        self.barrier_call = self.controller = self.feed = None
        self.node = self.executor = None

    def install(self, monkeypatch):
        import vega_bus.barrier

        cap = self

        class Node:
            def create_publisher(self, *args, **kwargs):
                pub = SimpleNamespace(sent=[])
                pub.publish = pub.sent.append
                cap.publishers.append((args, kwargs, pub))
                return pub

            def create_subscription(self, *args, **kwargs):
                sub = SimpleNamespace()
                cap.subscriptions.append((args, kwargs, sub))
                return sub

        @contextmanager
        def ros_node(name):
            assert name == "recorder"
            cap.node, cap.executor = Node(), SimpleNamespace()
            yield cap.node, cap.executor

        class Controller:
            def __init__(self, params, workdir, env):
                cap.controller = self
                self.params, self.workdir, self.env = params, workdir, env
                self.workdir_existed = isinstance(workdir, Path) and workdir.is_dir()
                self.stopped = False

            def stop(self):
                self.stopped = True
                if cap.remove_workdir:
                    shutil.rmtree(self.workdir)

        def start_barrier(*args, **kwargs):
            cap.barrier_call = (args, kwargs)
            return SimpleNamespace(name="barrier")

        def feed(controller, barrier, executor, ins_pub, ins_raw, samples_ms, period_ms,
                 received, barrier_timeout_s, say):
            cap.feed = SimpleNamespace(controller=controller, barrier=barrier,
                                       executor=executor, ins_pub=ins_pub, received=received)
            (args, _, _), = [s for s in cap.subscriptions if topics.TVC_CMD.name in s[0]]
            deliver = args[2]
            for data in cap.answer or []:
                deliver(data)            # as the executor would call the subscription
            return cap.failure

        monkeypatch.setattr(replay, "_ros_node", ros_node)
        monkeypatch.setattr(replay, "_ControllerProcess", Controller)
        monkeypatch.setattr(replay, "_feed", feed)
        monkeypatch.setattr(vega_bus.barrier, "StartBarrier", start_barrier)
        return self


def _recorded(path):
    return [bytes(d) for _, _, d in bagio.iter_raw_messages(path, {topics.TVC_CMD.name})]


def test_publishers_and_subscriptions_of_the_checker(monkeypatch, bag):
    from std_msgs.msg import String

    recorded = _recorded(bag)
    shell = _Shell(answer=recorded).install(monkeypatch)
    check = replay.check_controller(bag)
    # the commands came in through the subscription's callback, into the compared list
    assert check.identical and check.replayed == len(recorded) == check.compared
    assert shell.feed.received == recorded
    (run_args, run_kw, run_pub), (ins_args, ins_kw, ins_pub) = shell.publishers
    assert run_args == (String, "/vega/run", qos.control_qos()) and run_kw == {}
    assert ins_args == (topics.message_class("vega_msgs/msg/InsMeasurement"), "/vega/ins",
                        qos.data_qos()) and ins_kw == {}
    (cmd_args, cmd_kw, cmd_sub), (diag_args, diag_kw, diag_sub) = shell.subscriptions
    assert cmd_args[:2] == (topics.message_class("vega_msgs/msg/TvcCommand"), "/vega/tvc_cmd")
    assert cmd_args[3:] == (qos.data_qos(),) and cmd_kw == {"raw": True}
    assert diag_args[:2] == (topics.message_class("vega_msgs/msg/StepDiagnostics"),
                             "/vega/diagnostics")
    assert diag_args[3:] == (qos.data_qos(),) and diag_kw == {"raw": True}
    diag_args[2](b"\x00\x01\x00\x00")    # the diagnostics are heard and dropped
    # the run description went out on /vega/run, as the plant's
    (msg,) = run_pub.sent
    assert isinstance(msg, String) and json.loads(msg.data)["scenario"] == "thesis"
    # the barrier: the checker in the recorder's seat, matched both ways
    args, kwargs = shell.barrier_call
    assert args == (shell.node, ("tvc_controller", "recorder"))
    assert kwargs == {"publishers": [ins_pub], "subscriptions": [cmd_sub, diag_sub],
                      "subscribers": {"/vega/ins": ("tvc_controller",)}}
    # the feeding loop gets that barrier, the node's executor, the INS publisher, the process
    f = shell.feed
    assert f.barrier is not None and f.barrier.name == "barrier"
    assert f.executor is shell.executor and f.ins_pub is ins_pub
    assert f.controller is shell.controller


def test_the_controller_process_gets_a_scratch_directory_and_the_ros_environment(
        monkeypatch, bag):
    shell = _Shell(answer=_recorded(bag)).install(monkeypatch)
    replay.check_controller(bag)
    c = shell.controller
    assert c.workdir_existed and c.workdir.name.startswith("vega-replay-")
    assert c.workdir.parent == Path(tempfile.gettempdir())
    assert c.stopped and not c.workdir.exists()          # removed after the check
    assert isinstance(c.env, dict) and c.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "ROS_LOCALHOST_ONLY" not in c.env


def test_a_scratch_directory_already_gone_does_not_fail_the_check(monkeypatch, bag):
    """Cleaning up is best effort: the verdict stands if the directory is already gone."""
    shell = _Shell(answer=_recorded(bag), remove_workdir=True).install(monkeypatch)
    check = replay.check_controller(bag)
    assert check.identical and not shell.controller.workdir.exists()


def test_the_bags_guidance_reference_is_flown(monkeypatch, run, tmp_path):
    """The run description carries the guidance the bag was recorded with, not the
    scenario's."""
    from vega_bags import simbag

    sha = hashlib.sha256(GUIDE.read_bytes()).hexdigest()
    meta = bagio.run_metadata(run.result.scenario.name,
                              simbag.scenario_yaml(run.result.scenario), run.result.seed,
                              run.table_path, git_rev="test")
    meta[bagio.META_GUIDANCE_REFERENCE] = str(GUIDE)
    meta[bagio.META_GUIDANCE_REFERENCE_SHA256] = sha
    path = simbag.write_messages(tmp_path / "bag", simbag.simulation_messages(run.result), meta)
    assert run.result.scenario.guidance != str(GUIDE)
    shell = _Shell(answer=_recorded(path)).install(monkeypatch)
    check = replay.check_controller(path)
    assert check.identical and check.notes == ()
    info = json.loads(shell.publishers[0][2].sent[0].data)
    assert info["guidance"] == str(GUIDE)


def test_a_failure_of_the_loop_with_identical_commands_is_named_alone(monkeypatch, bag):
    recorded = _recorded(bag)
    _Shell(answer=recorded, failure=replay._Failed(1, "stalled")).install(monkeypatch)
    check = replay.check_controller(bag)
    assert check.difference == "stalled" and check.exit_code == 1
    _Shell(answer=recorded[:-1], failure=replay._Failed(1, "stalled")).install(monkeypatch)
    check = replay.check_controller(bag)
    assert check.difference == (f"stalled; the controller sent {len(recorded) - 1} commands, "
                                f"the bag holds {len(recorded)}")


def test_a_bag_without_ins_messages_is_a_bag_error(monkeypatch, run, tmp_path):
    from fixture_bags import write_bag

    path = write_bag(tmp_path / "bag", run,
                     lambda m: [x for x in m if x[0] != topics.INS.name])
    shell = _Shell(answer=[]).install(monkeypatch)
    with pytest.raises(bagio.BagError, match="no /vega/ins messages to replay$"):
        replay.check_controller(path)
    # and without the topic at all (a bag that never had the INS connection)
    read = bagio.read_run_bag

    def without_ins(p):
        b = read(p)
        return bagio.RunBag(b.path, {k: v for k, v in b.topics.items()
                                     if k != topics.INS.name}, b.metadata, b.other_topics)

    monkeypatch.setattr(bagio, "read_run_bag", without_ins)
    with pytest.raises(bagio.BagError, match="no /vega/ins messages to replay$"):
        replay.check_controller(path)
    assert shell.controller is None                       # refused before anything started


def test_one_ins_message_is_enough_to_start(monkeypatch, run, tmp_path):
    from fixture_bags import messages_on, write_bag

    def keep_first(messages):
        drop = set(messages_on(messages, topics.INS.name)[1:])
        return [x for i, x in enumerate(messages) if i not in drop]

    path = write_bag(tmp_path / "bag", run, keep_first)
    shell = _Shell(answer=_recorded(path)).install(monkeypatch)
    check = replay.check_controller(path)
    assert check.identical and len(shell.feed.received) == check.recorded


def test_clock_bytes_by_hand():
    """A rosgraph_msgs/Clock at 20.012 s: sec 20, nanosec 12 000 000 (the bag's typestore)."""
    store = bagio.vega_typestore()
    msg = store.deserialize_cdr(replay._clock_bytes(20_012_000_000), "rosgraph_msgs/msg/Clock")
    assert (msg.clock.sec, msg.clock.nanosec) == (20, 12_000_000)
    msg = store.deserialize_cdr(replay._clock_bytes(999_999_999), "rosgraph_msgs/msg/Clock")
    assert (msg.clock.sec, msg.clock.nanosec) == (0, 999_999_999)
    assert isinstance(replay._clock_bytes(0), bytes)


# ----------------------------------------------------------------------------- the feeding loop
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


def test_flush_shares_one_deadline():
    acked = []
    pubs = [SimpleNamespace(wait_for_all_acked=lambda d: acked.append(d.nanoseconds))
            for _ in range(3)]
    replay._flush(pubs, 2.0)
    assert len(acked) == 3 and 1.9e9 < acked[0] <= 2e9
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
