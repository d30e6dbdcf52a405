"""``vega replay``: republishing a run bag, and the controller regression check.

Real ROS 2: the replay runs as its own process (``vega replay``) or starts the installed
``tvc_controller`` executable as a child; the test process subscribes in its own rclpy
context. Bags come from the in-process simulation (tests/fixture_bags.py).
"""

import subprocess
import sys
import time
from dataclasses import replace

import pytest

from fixture_bags import messages_on, short_run, write_bag
from vega_bus import qos, topics
from vega_bags import bagio, replay
from vega_cli import cli

pytestmark = pytest.mark.ros

DELIVERY_TIMEOUT_S = 90.0
"""Upper bound for discovery plus delivery (a failure guard, not a synchronisation)."""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return short_run(tmp_path_factory.mktemp("run"), span_s=(20.0, 22.0))


@pytest.fixture(scope="module")
def bag(run, tmp_path_factory):
    return write_bag(tmp_path_factory.mktemp("bag") / "bag", run)


def _receive_replay(bag_path, env, argv=()):
    """Run ``vega replay BAG --rate 0 --wait-subscribers …`` and receive every topic raw."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    expected = {}
    for topic, _, data in bagio.iter_raw_messages(bag_path):
        expected.setdefault(topic, []).append(bytes(data))
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("replay_listener", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    got = {name: [] for name in expected}
    for t in topics.ALL_TOPICS:
        node.create_subscription(topics.message_class(t.type_name), t.name,
                                 got[t.name].append, qos.data_qos(), raw=True)
    child = subprocess.Popen(
        [sys.executable, "-m", "vega_cli.cli", "replay", str(bag_path), "--rate", "0",
         "--wait-subscribers", str(DELIVERY_TIMEOUT_S), *argv],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + DELIVERY_TIMEOUT_S
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
            done = all(len(got[n]) == len(expected[n]) for n in expected)
            if done and child.poll() is not None:
                break
        executor.spin_once(timeout_sec=0.1)
    finally:
        if child.poll() is None:
            child.terminate()
        _, stderr = child.communicate(timeout=30)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return expected, got, child.returncode, stderr


def _unpadded(wire, recorded):
    """``wire`` without the zero padding Fast DDS adds up to a multiple of 4 bytes (the bag
    holds rclpy's unpadded serialisation; a bag recorded off the wire is padded already)."""
    pad = wire[len(recorded):]
    assert len(pad) < 4 and not any(pad) and len(wire) % 4 == 0
    return wire[:len(recorded)]


@pytest.mark.slow
def test_replay_republishes_the_recorded_bytes(bag, ros_env):
    """Every message, /clock included, arrives in order with the bytes recorded."""
    expected, got, status, stderr = _receive_replay(bag, ros_env)
    assert status == 0, stderr
    for t in topics.ALL_TOPICS:
        assert len(got[t.name]) == len(expected[t.name]), t.name
        assert [_unpadded(w, r) for w, r in zip(got[t.name], expected[t.name])] == \
            expected[t.name], t.name
    assert "published" in stderr and "Traceback" not in stderr


def test_replay_rejects_bad_input(tmp_path, capsys):
    assert cli.main(["replay", str(tmp_path / "missing")]) == 2
    assert "no such file or directory" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["replay", str(tmp_path), "--rate", "-1"])
    assert "must be a finite number >= 0" in capsys.readouterr().err


# ----------------------------------------------------------------------------- controller check
@pytest.mark.slow
def test_controller_reproduces_the_recorded_commands(bag, run, capsys):
    """The installed controller node, fed the recorded INS, sends the recorded commands."""
    status = cli.main(["replay", str(bag), "--check-controller"])
    out = capsys.readouterr().out
    n = len(run.result.cmd_rad)
    assert status == 0, out
    assert f"{n} commands replayed, {n} recorded, {n} compared" in out
    assert "verdict: IDENTICAL" in out


@pytest.mark.slow
def test_a_changed_command_is_found(run, tmp_path):
    """A recorded command that the controller does not reproduce: verdict 1, first one named."""
    def mutate(messages):
        i = messages_on(messages, topics.TVC_CMD.name)[37]
        messages[i][2].deflection_cmd_rad += 1e-12
    bag = write_bag(tmp_path / "bag", run, mutate)
    result = replay.check_controller(bag)
    assert result.exit_code == 1 and result.compared == 38
    assert result.difference.startswith("command #37 (recorded seq 37, stamp 20.764 s): "
                                        "deflection_cmd_rad: recorded ")
    assert result.replayed == result.recorded == len(run.result.cmd_rad)


def test_bad_table_is_bad_input(bag, tmp_path, capsys):
    table = tmp_path / "broken.npz"
    table.write_bytes(b"not a table")
    assert cli.main(["replay", str(bag), "--check-controller", "--table", str(table)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "broken.npz" in err


def test_first_difference_compares_all_fields():
    from rclpy.serialization import serialize_message
    from vega_msgs.msg import TvcCommand

    def cmd(**fields):
        m = TvcCommand()
        m.seq, m.deflection_cmd_rad, m.status = 3, 0.25, 0
        for k, v in fields.items():
            setattr(m, k, v)
        return serialize_message(m)

    assert replay.first_difference([cmd()], [cmd()]) == (1, None)
    n, diff = replay.first_difference([cmd()], [cmd(status=1)])
    assert n == 1 and diff.endswith("status: recorded 0, replayed 1")
    _, diff = replay.first_difference([cmd(deflection_cmd_rad=0.0)],
                                      [cmd(deflection_cmd_rad=-0.0)])
    assert "deflection_cmd_rad" in diff  # bit for bit: -0.0 is not 0.0
    assert replay.first_difference([cmd(), cmd()], [cmd()]) == \
        (1, "the controller sent 1 commands, the bag holds 2")


@pytest.mark.slow
def test_controller_replay_of_a_real_sil_run(run, tmp_path, capsys):
    """End to end: a short `vega sil run` (five processes), then the controller replay of
    its bag reproduces every command the SIL controller sent (the SIL regression check)."""
    from sil_flights import run_layout_in, vega_sil_run, write_short_scenario

    scenario = write_short_scenario(tmp_path, "thesis", "thesis_replay", 20.0, 21.0)
    flight = vega_sil_run(["--scenario", scenario, "--table", run.table_path,
                           "--out", tmp_path / "out"])
    assert flight.returncode == 0, flight.stderr
    bag = run_layout_in(tmp_path / "out").bag_dir
    status = cli.main(["replay", str(bag), "--check-controller"])
    out = capsys.readouterr().out
    assert status == 0, out
    assert "50 commands replayed, 50 recorded, 50 compared" in out


@pytest.mark.slow
def test_controller_replay_flies_the_recorded_guidance_reference(run, tmp_path, capsys):
    """A bag of a run with the wind-biased reference (nominal cut to 40–41 s, where the
    reference is far from 0): the replayed controller tracks the reference the metadata names
    and reproduces every command; the same bag claiming no reference does not."""
    from vega_bags import simbag
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import load_scenario

    scenario = replace(load_scenario("nominal"), t_start_s=40.0, t_end_s=41.0)
    result = run_scenario(scenario, run.table_path)
    good = simbag.write_simulation_bag(tmp_path / "good", result, run.table_path, git_rev="t")
    meta = bagio.read_run_bag(good).metadata
    assert meta[bagio.META_GUIDANCE_REFERENCE].endswith("guidance_reference.npz")
    status = cli.main(["replay", str(good), "--check-controller"])
    out = capsys.readouterr().out
    assert status == 0 and "50 commands replayed, 50 recorded, 50 compared" in out, out

    lying = dict(meta, **{bagio.META_GUIDANCE_REFERENCE: "none"})
    lying.pop(bagio.META_GUIDANCE_REFERENCE_SHA256)
    bad = simbag.write_messages(tmp_path / "bad", simbag.simulation_messages(result), lying)
    assert cli.main(["replay", str(bad), "--check-controller"]) == 1
    assert "DIFFERENT" in capsys.readouterr().out
