"""``vega replay --check-controller`` (:func:`vega_bags.replay.check_controller`) with its ROS
plumbing replaced: what it takes from the bag and what it asks of ROS.

No ROS participant is started: the node, the start barrier, the controller process and the
feeding loop are replaced by recorders of what check_controller hands them, and the
"controller" answers with commands (through the command subscription's own callback, as DDS
would call it, or straight into the list of received commands).

Independent references: the topic names, message types, QoS profiles and ``raw`` flags of
vega_bus (topics.py, qos.py) — the same the nodes use; the start-barrier seats of the SIL (the
checker sits where the recorder sits); the controller process's parameters (the recorded
scenario, seed and table, not real time, no bag) and the INS sample instants [ms] of the bag;
SHA-256 of the shipped controller table and guidance reference by hashlib (a file other than
the recorded one is noted, naming the first 12 digits of the recorded SHA-256); run bags
written from a short in-process flight (tests/fixture_bags.py, tests/bags/cached_bags.py) or
built in memory (:class:`vega_bags.bagio.RunBag`) with hand-written metadata.
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

from vega_core.errors import BadInput

from vega_bags import bagio, replay
from vega_bus import qos, topics

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config"
TABLE = CONFIG / "lpv_controller.npz"
GUIDE = CONFIG / "guidance_reference.npz"


# ------------------------------------------------- the controller and guidance recorded in the bag
def _bag(tmp_path, **meta):
    return bagio.RunBag(str(tmp_path / "bag"), {}, dict(meta))


def test_table_path_recorded_given_and_checked(tmp_path):
    sha = hashlib.sha256(TABLE.read_bytes()).hexdigest()
    bag = _bag(tmp_path, **{bagio.META_CONTROLLER_TABLE: str(TABLE),
                            bagio.META_CONTROLLER_TABLE_SHA256: sha})
    assert replay._table_path(bag, None) == (TABLE, [])
    # another copy with the same bytes: no note
    copy = tmp_path / "copy.npz"
    shutil.copyfile(TABLE, copy)
    assert replay._table_path(bag, str(copy)) == (copy, [])
    # a different table than recorded: a note naming the recorded SHA-256's first 12 digits
    other = CONFIG / "tvc_controller.npz"
    path, notes = replay._table_path(bag, other)
    assert path == other
    assert notes == [f"{other} differs from the table the run was recorded with "
                     f"(SHA-256 {sha[:12]}…)"]
    # no recorded SHA: nothing to compare
    assert replay._table_path(_bag(tmp_path, **{bagio.META_CONTROLLER_TABLE: str(other)}),
                              None) == (other, [])
    with pytest.raises(BadInput, match="no controller table in the metadata"):
        replay._table_path(_bag(tmp_path), None)
    with pytest.raises(BadInput, match="no controller table in the metadata"):
        replay._table_path(_bag(tmp_path, **{bagio.META_CONTROLLER_TABLE: ""}), None)


def test_guidance_setting(tmp_path):
    assert replay._guidance_setting(_bag(tmp_path)) == ("none", [])
    assert replay._guidance_setting(
        _bag(tmp_path, **{bagio.META_GUIDANCE_REFERENCE: "none"})) == ("none", [])
    sha = hashlib.sha256(GUIDE.read_bytes()).hexdigest()
    bag = _bag(tmp_path, **{bagio.META_GUIDANCE_REFERENCE: str(GUIDE),
                            bagio.META_GUIDANCE_REFERENCE_SHA256: sha})
    assert replay._guidance_setting(bag) == (str(GUIDE), [])
    wrong = "0123456789abcdef" * 4
    bag = _bag(tmp_path, **{bagio.META_GUIDANCE_REFERENCE: str(GUIDE),
                            bagio.META_GUIDANCE_REFERENCE_SHA256: wrong})
    assert replay._guidance_setting(bag) == (
        str(GUIDE), [f"{GUIDE} differs from the guidance reference the run was recorded with "
                     f"(SHA-256 0123456789ab…)"])
    assert replay._guidance_setting(
        _bag(tmp_path, **{bagio.META_GUIDANCE_REFERENCE: str(GUIDE)})) == (str(GUIDE), [])


def test_run_info_without_a_scenario_is_a_bag_error(tmp_path):
    with pytest.raises(bagio.BagError, match=r"no usable scenario in the metadata \(.+\); "
                                             r"cannot replay the controller"):
        replay._run_info(_bag(tmp_path))


# ------------------------------------------------------ what check_controller hands the controller
@pytest.fixture(scope="module")
def short_bag():
    from cached_bags import cached_short_run   # flown once per set of inputs (read-only)

    return cached_short_run((20.0, 20.5))[1]


class _Capture:
    """Fakes of the ROS plumbing that record what check_controller hands them."""

    def __init__(self, answer=None, failure=None):
        self.answer, self.failure = answer, failure
        self.published, self.params, self.feed = [], None, None

    def install(self, monkeypatch):
        from contextlib import contextmanager
        from types import SimpleNamespace

        import vega_bus.barrier

        cap = self

        class Node:
            def create_publisher(self, *args, **kwargs):
                return SimpleNamespace(publish=cap.published.append)

            def create_subscription(self, *args, **kwargs):
                return SimpleNamespace()

        @contextmanager
        def ros_node(name):
            assert name == replay.CHECKER_NAME
            yield Node(), SimpleNamespace()

        class Controller:
            def __init__(self, params, workdir, env):
                cap.params = params

            def stop(self):
                pass

        def feed(controller, barrier, executor, ins_pub, ins_raw, samples_ms, period_ms,
                 received, barrier_timeout_s, say):
            cap.feed = dict(ins_raw=ins_raw, samples_ms=samples_ms, period_ms=period_ms,
                            barrier_timeout_s=barrier_timeout_s, say=say)
            if cap.answer is not None:
                received.extend(cap.answer)
            return cap.failure

        monkeypatch.setattr(replay, "_ros_node", ros_node)
        monkeypatch.setattr(replay, "_ControllerProcess", Controller)
        monkeypatch.setattr(replay, "_feed", feed)
        monkeypatch.setattr(vega_bus.barrier, "StartBarrier", lambda *a, **k: SimpleNamespace())
        return self


def test_check_controller_hands_the_bag_to_the_controller(monkeypatch, short_bag):
    import json

    recorded = [bytes(d) for _, _, d in bagio.iter_raw_messages(short_bag,
                                                                {topics.TVC_CMD.name})]
    ins = [bytes(d) for _, _, d in bagio.iter_raw_messages(short_bag, {topics.INS.name})]
    bag = bagio.read_run_bag(short_bag)
    meta = bag.metadata
    cap = _Capture(answer=recorded).install(monkeypatch)
    said = []
    check = replay.check_controller(short_bag, progress=said.append)
    assert check.identical and check.recorded == check.replayed == len(recorded)
    # the controller process: the recorded scenario, seed and table, not real time, no bag
    p = cap.params
    assert p.scenario == meta[bagio.META_SCENARIO]
    assert p.seed == int(meta[bagio.META_SEED])
    assert p.realtime is False and p.bag_path == ""
    assert p.controller_table == str(Path(meta[bagio.META_CONTROLLER_TABLE]).resolve())
    assert p.participants == ("tvc_controller", "recorder")
    assert p.barrier_timeout_s == 60.0
    # the feeding loop: every INS message's bytes, its sample instants [ms], the period
    f = cap.feed
    assert [bytes(d) for d in f["ins_raw"]] == ins and len(ins) > 10
    want_ms = [int(s) // 1_000_000 for s in bag[topics.INS.name]["sample_stamp_ns"]]
    assert f["samples_ms"].dtype.kind == "i" and f["samples_ms"].tolist() == want_ms
    assert f["period_ms"] == 20          # vehicle.yaml controller.rate_hz 50 Hz
    assert f["barrier_timeout_s"] == 60.0
    f["say"]("hello")
    assert said == ["hello"]
    # the run description published first: the bag's scenario with the bag's guidance
    info = json.loads(cap.published[0].data)
    assert info["guidance"] == meta.get(bagio.META_GUIDANCE_REFERENCE, "none")


@pytest.mark.slow
def test_check_controller_defaults_and_options(monkeypatch, short_bag):
    recorded = [bytes(d) for _, _, d in bagio.iter_raw_messages(short_bag,
                                                                {topics.TVC_CMD.name})]
    cap = _Capture(answer=recorded).install(monkeypatch)
    other = CONFIG / "tvc_controller.npz"
    check = replay.check_controller(short_bag, table=other, barrier_timeout_s=7.5)
    assert cap.params.barrier_timeout_s == 7.5 and cap.feed["barrier_timeout_s"] == 7.5
    assert cap.params.controller_table == str(other.resolve())
    assert check.table == str(other)
    assert len(check.notes) == 1 and check.notes[0].startswith(
        f"{other} differs from the table the run was recorded with")
    # without a progress callback the loop still gets a callable that returns nothing
    cap = _Capture(answer=recorded).install(monkeypatch)
    replay.check_controller(short_bag)
    assert cap.feed["say"]("x") is None


def test_check_controller_bad_input_from_the_controller_is_bad_input(monkeypatch, short_bag):
    _Capture(answer=[], failure=replay._Failed(2, "controller: bad table")).install(monkeypatch)
    with pytest.raises(BadInput, match="^controller: bad table$"):
        replay.check_controller(short_bag)
    f = replay._Failed(1, "stalled")
    assert f.code == 1 and str(f) == "stalled"


# --------------------------------------------------------------- what check_controller asks of ROS
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


@pytest.mark.slow
def test_a_failure_of_the_loop_with_identical_commands_is_named_alone(monkeypatch, bag):
    recorded = _recorded(bag)
    _Shell(answer=recorded, failure=replay._Failed(1, "stalled")).install(monkeypatch)
    check = replay.check_controller(bag)
    assert check.difference == "stalled" and check.exit_code == 1
    _Shell(answer=recorded[:-1], failure=replay._Failed(1, "stalled")).install(monkeypatch)
    check = replay.check_controller(bag)
    assert check.difference == (f"stalled; the controller sent {len(recorded) - 1} commands, "
                                f"the bag holds {len(recorded)}")


@pytest.mark.slow
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
