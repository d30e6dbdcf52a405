"""``vega replay --check-controller`` never says IDENTICAL when the numbers of commands differ.

Two levels, no ROS participant started:

* the pure comparison :func:`vega_bags.replay.first_difference` on TvcCommand bytes
  (serialised here with the bag's own typestore, as the bag stores them): more commands
  replayed than recorded, fewer, none, and a field difference inside the common prefix;
* the whole check, ``vega replay BAG --check-controller`` through ``vega_cli.cli.main``, on a
  real run bag (in-process simulation, tests/fixture_bags.py) with only the ROS plumbing of
  ``check_controller`` replaced (the node, the controller process, the start barrier and the
  feeding loop): the fake controller "answers" with the bag's own recorded commands plus or
  minus some, so the verdict must come from the length check alone.
"""

from contextlib import contextmanager
from types import SimpleNamespace

import pytest

from vega_bags import bagio, replay
from vega_bus import topics


# ----------------------------------------------------------------------------- pure comparison
def _cmd(seq, deflection=0.01, status=0):
    store = bagio.vega_typestore()
    T = store.types[topics.TVC_CMD.type_name]
    Time = store.types["builtin_interfaces/msg/Time"]
    Header = store.types["std_msgs/msg/Header"]
    stamp = Time(sec=20, nanosec=seq * 20_000_000 + 12_000_000)
    msg = T(header=Header(stamp=stamp, frame_id=""),
            sample_stamp=Time(sec=20, nanosec=seq * 20_000_000), seq=seq,
            deflection_cmd_rad=deflection, scheduling_velocity_mps=300.0, status=status)
    return bytes(store.serialize_cdr(msg, topics.TVC_CMD.type_name))


RECORDED = [_cmd(k, deflection=0.001 * k) for k in range(5)]


def test_same_commands_are_identical():
    assert replay.first_difference(RECORDED, list(RECORDED)) == (5, None)


@pytest.mark.parametrize("extra", [1, 3])
def test_more_commands_than_the_bag_are_a_difference(extra):
    """The controller sent every recorded command and then more."""
    replayed = RECORDED + [_cmd(5 + k) for k in range(extra)]
    compared, diff = replay.first_difference(RECORDED, replayed)
    assert compared == 5
    assert diff == f"the controller sent {5 + extra} commands, the bag holds 5"


def test_a_repeated_last_command_is_a_difference():
    """An extra command identical to the last one (a duplicate) is still one too many."""
    compared, diff = replay.first_difference(RECORDED, RECORDED + [RECORDED[-1]])
    assert compared == 5 and diff == "the controller sent 6 commands, the bag holds 5"


@pytest.mark.parametrize("kept", [4, 1, 0])
def test_fewer_commands_than_the_bag_are_a_difference(kept):
    compared, diff = replay.first_difference(RECORDED, RECORDED[:kept])
    assert compared == kept
    assert diff == f"the controller sent {kept} commands, the bag holds 5"


def test_commands_when_the_bag_holds_none_are_a_difference():
    compared, diff = replay.first_difference([], RECORDED[:2])
    assert compared == 0 and diff == "the controller sent 2 commands, the bag holds 0"


def test_a_field_difference_in_the_common_part_is_named_first():
    """A difference inside the compared prefix is reported (not the length), at its index."""
    replayed = RECORDED[:2] + [_cmd(2, deflection=0.5)] + RECORDED[3:] + [_cmd(5)]
    compared, diff = replay.first_difference(RECORDED, replayed)
    assert compared == 3
    assert diff.startswith("command #2 (recorded seq 2, stamp 20.052 s): deflection_cmd_rad")


@pytest.mark.parametrize("recorded, replayed", [(5, 6), (5, 4), (0, 1), (5, 0)])
def test_verdict_of_a_length_mismatch(recorded, replayed):
    """The ControllerCheck built from such a comparison says DIFFERENT, exit status 1."""
    rec = RECORDED[:recorded]
    rep = (RECORDED + [_cmd(5)])[:replayed]
    compared, diff = replay.first_difference(rec, rep)
    check = replay.ControllerCheck(recorded, replayed, compared, diff, "t.npz")
    assert not check.identical and check.exit_code == 1
    assert "IDENTICAL" not in check.summary() and "DIFFERENT" in check.summary()


# ----------------------------------------------------------------------------- the whole check
@pytest.fixture(scope="module")
def bag():
    from cached_bags import cached_short_run   # flown once per set of inputs (read-only)

    return cached_short_run((20.0, 20.5))[1]


class _FakeNode:
    def create_publisher(self, *args, **kwargs):
        return SimpleNamespace(publish=lambda msg: None)

    def create_subscription(self, *args, **kwargs):
        return SimpleNamespace()


@contextmanager
def _fake_ros_node(name):
    yield _FakeNode(), SimpleNamespace()


class _FakeController:
    def __init__(self, params, workdir, env):
        self.params = params

    def stop(self):
        pass


def _check(monkeypatch, capsys, bag, answer, failure=None):
    """Run ``vega replay BAG --check-controller`` with the ROS plumbing faked: the "controller"
    answers ``answer(recorded)`` (a list of TvcCommand bytes)."""
    import vega_bus.barrier
    from vega_cli import cli

    recorded = [bytes(d) for _, _, d in bagio.iter_raw_messages(bag, {topics.TVC_CMD.name})]
    assert len(recorded) >= 10

    def fake_feed(controller, barrier, executor, ins_pub, ins_raw, samples_ms, period_ms,
                  received, barrier_timeout_s, say):
        received.extend(answer(recorded))
        return failure

    monkeypatch.setattr(replay, "_ros_node", _fake_ros_node)
    monkeypatch.setattr(replay, "_ControllerProcess", _FakeController)
    monkeypatch.setattr(replay, "_feed", fake_feed)
    monkeypatch.setattr(vega_bus.barrier, "StartBarrier", lambda *a, **k: SimpleNamespace())
    code = cli.main(["replay", str(bag), "--check-controller"])
    out = capsys.readouterr().out
    return code, out, recorded


@pytest.mark.slow
def test_check_of_the_recorded_commands_is_identical(monkeypatch, capsys, bag):
    """Control case: the faked plumbing gives IDENTICAL when the answer is the recording."""
    code, out, recorded = _check(monkeypatch, capsys, bag, lambda rec: list(rec))
    assert code == 0
    assert "verdict: IDENTICAL" in out
    assert f"{len(recorded)} commands replayed, {len(recorded)} recorded" in out


@pytest.mark.parametrize("extra", [1, 2])
def test_check_with_more_commands_than_the_bag_is_different(monkeypatch, capsys, bag, extra):
    code, out, recorded = _check(monkeypatch, capsys, bag,
                                 lambda rec: list(rec) + [rec[-1]] * extra)
    n = len(recorded)
    assert code == 1
    assert "IDENTICAL" not in out
    assert (f"verdict: DIFFERENT: the controller sent {n + extra} commands, the bag holds {n}"
            in out)
    assert f"{n + extra} commands replayed, {n} recorded, {n} compared" in out


@pytest.mark.slow
@pytest.mark.parametrize("missing", [1, 5])
def test_check_with_fewer_commands_than_the_bag_is_different(monkeypatch, capsys, bag, missing):
    code, out, recorded = _check(monkeypatch, capsys, bag, lambda rec: list(rec)[:-missing])
    n = len(recorded)
    assert code == 1
    assert "IDENTICAL" not in out
    assert (f"verdict: DIFFERENT: the controller sent {n - missing} commands, the bag holds {n}"
            in out)


def test_check_of_a_controller_that_stopped_early_names_both(monkeypatch, capsys, bag):
    """The feeding loop reports a stall (exit 1) and the commands are short: both are named."""
    failure = replay._Failed(1, "no command for measurement #7 (sample 20.140 s) within 20 s")
    code, out, recorded = _check(monkeypatch, capsys, bag, lambda rec: list(rec)[:3], failure)
    assert code == 1 and "IDENTICAL" not in out
    assert "no command for measurement #7" in out
    assert f"the controller sent 3 commands, the bag holds {len(recorded)}" in out
