"""The controller replay's comparison (vega_bags.replay): recorded against replayed commands.

:func:`vega_bags.replay.first_difference` names the first differing field of the first
differing command, nested fields by their dotted path, with both values and the command's
recorded seq and stamp [s, 3 decimals, rounded from exact seconds]; floats are compared bit for
bit (NaN equals NaN, 0.0 differs from −0.0, an integer equals the float of the same value),
arrays by shape and bytes; the check's summary text. Independent references: TvcCommand and
ActuatorState messages built field by field with the bag's typestore, the console text typed
out by hand. No ROS participant is started.
"""

import math

from vega_bags import bagio, replay
from vega_bus import topics


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
