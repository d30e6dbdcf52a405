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
