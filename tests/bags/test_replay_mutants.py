"""Controller replay, pure parts: tests written for the survivors of
`make mutation MODULE=replay` (no ROS participant started).

Independent references: the console text typed out by hand; TvcCommand messages built field
by field with the bag's typestore; SHA-256 of the shipped files by hashlib; run bags built
in memory (:class:`vega_bags.bagio.RunBag`) with hand-written metadata.
"""

import hashlib
import math
import shutil
from pathlib import Path

import pytest

from vega_core.errors import BadInput

from vega_bags import bagio, replay
from vega_bus import topics

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config"
TABLE = CONFIG / "lpv_controller.npz"
GUIDE = CONFIG / "guidance_reference.npz"


def _cmd(seq=3, deflection=0.25, status=0, sec=20, nanosec=12_000_000, sample_ns=0,
         velocity=300.0):
    store = bagio.vega_typestore()
    T = store.types[topics.TVC_CMD.type_name]
    Time = store.types["builtin_interfaces/msg/Time"]
    Header = store.types["std_msgs/msg/Header"]
    msg = T(header=Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=""),
            sample_stamp=Time(sec=sec, nanosec=sample_ns), seq=seq,
            deflection_cmd_rad=deflection, scheduling_velocity_mps=velocity, status=status)
    return bytes(store.serialize_cdr(msg, topics.TVC_CMD.type_name))


def test_summary_text_identical_and_different():
    ok = replay.ControllerCheck(5, 5, 5, None, "t.npz")
    assert ok.identical and ok.exit_code == 0
    assert ok.summary() == ("controller replay with t.npz: 5 commands replayed, 5 recorded, "
                            "5 compared\nverdict: IDENTICAL (every field)")
    bad = replay.ControllerCheck(5, 6, 5, "x differs", "t.npz", notes=("n1", "n2"))
    assert not bad.identical and bad.exit_code == 1
    assert bad.summary() == ("note: n1\nnote: n2\n"
                             "controller replay with t.npz: 6 commands replayed, 5 recorded, "
                             "5 compared\nverdict: DIFFERENT: x differs")


def test_first_difference_names_nested_fields_with_values():
    n, diff = replay.first_difference([_cmd(), _cmd()], [_cmd(), _cmd(nanosec=13_000_000)])
    assert n == 2
    assert diff == ("command #1 (recorded seq 3, stamp 20.012 s): header.stamp.nanosec: "
                    "recorded 12000000, replayed 13000000")
    _, diff = replay.first_difference([_cmd(sample_ns=5)], [_cmd(sample_ns=6)])
    assert diff.endswith("sample_stamp.nanosec: recorded 5, replayed 6")
    _, diff = replay.first_difference([_cmd(velocity=300.0)], [_cmd(velocity=300.5)])
    assert diff.endswith("scheduling_velocity_mps: recorded 300.0, replayed 300.5")
    _, diff = replay.first_difference([_cmd(seq=3)], [_cmd(seq=4)])
    assert diff == "command #0 (recorded seq 3, stamp 20.012 s): seq: recorded 3, replayed 4"


def test_floats_are_compared_bit_for_bit():
    nan = float("nan")
    assert replay.first_difference([_cmd(deflection=nan)], [_cmd(deflection=nan)]) == (1, None)
    _, diff = replay.first_difference([_cmd(deflection=0.0)], [_cmd(deflection=-0.0)])
    assert diff.endswith("deflection_cmd_rad: recorded 0.0, replayed -0.0")
    assert replay._same(1, 1) and not replay._same(1, 2)
    assert replay._same(0.5, 0.5) and not replay._same(0.0, -0.0)
    assert replay._same(2, 2.0) and not replay._same(math.inf, -math.inf)


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


# ------------------------------------------- check_controller with the ROS plumbing replaced
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


def _actuator(samples):
    import numpy as np

    store = bagio.vega_typestore()
    T = store.types["vega_msgs/msg/ActuatorState"]
    Time = store.types["builtin_interfaces/msg/Time"]
    Header = store.types["std_msgs/msg/Header"]
    arr = np.array(samples, dtype=np.float64)
    return T(header=Header(stamp=Time(sec=1, nanosec=0), frame_id=""), seq=1,
             deflection_rad=0.0, rate_radps=0.0, accel_radps2=0.0, deflection_samples_rad=arr,
             rate_samples_radps=np.zeros(arr.size), accel_samples_radps2=np.zeros(arr.size),
             sample_period_s=0.001)


def test_array_fields_are_compared_by_shape_and_bytes():
    assert replay._diff(_actuator([0.1, 0.2]), _actuator([0.1, 0.2])) is None
    assert replay._diff(_actuator([0.1, 0.2]), _actuator([0.1, 0.3])) == (
        "deflection_samples_rad: recorded [0.1, 0.2], replayed [0.1, 0.3]")
    assert replay._diff(_actuator([0.1, 0.2]), _actuator([0.1, 0.2, 0.0])).startswith(
        "deflection_samples_rad: recorded [0.1, 0.2], replayed [0.1, 0.2, 0.0]")
    assert replay._diff(_actuator([0.0]), _actuator([-0.0])) is not None


def test_an_integer_and_a_float_are_compared_as_floats_bit_for_bit():
    assert not replay._same(0, -0.0) and not replay._same(-0.0, 0)
    assert replay._same(3, 3.0)


def test_stamp_of_a_difference_is_rounded_from_exact_seconds():
    """nanosec 13 500 000: 20.0135 s is printed 20.014 (3 decimals)."""
    _, diff = replay.first_difference([_cmd(nanosec=13_500_000)],
                                      [_cmd(nanosec=13_500_000, seq=4)])
    assert diff.startswith("command #0 (recorded seq 3, stamp 20.014 s): seq:")
