"""The SIL nodes as real processes: lockstep schedule, start barrier, controller input
validation over DDS, bad inputs, recorder bag of a short run.

Each ROS test starts the installed executables (``lib/PKG/EXE``, found like ``ros2 run``)
with the test run's ROS_DOMAIN_ID and LOCALHOST discovery (``ros_env`` fixture); every process
is reaped (SIGTERM, then SIGKILL) even when a test fails. Waits are on conditions with
deadlines, never fixed sleeps.
"""

import math
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from fixture_tables import write_pd_table
from load_scaling import budget_s
from sil_flights import write_node_params
from vega_bus import qos, topics
from vega_bus.barrier import PARTICIPANTS
from vega_bus.schedule import RunInfo
from vega_bus.timing import LoopTiming, ms_to_stamp
from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_OK, STATUS_SAFE_ZERO,
                                         STATUS_VELOCITY_CLAMPED)
from vega_sim.scenario import scenario_path
from vega_bringup.executables import find_executable
from vega_bags.recorder import RawFields

EXECUTABLES = {"plant": "vega_plant", "ins_sensor": "vega_plant", "tvc_actuator": "vega_plant",
               "tvc_controller": "vega_gnc", "recorder": "vega_bags"}
PROCESS_TIMEOUT_S = 60.0
"""What a node process may take to end by itself on an idle machine [s] (margin included),
scaled by the load when the wait starts (tests/load_scaling.py)."""


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def pd_table(tmp_path_factory):
    """The PD fixture table (tests/fixture_tables.py): (path, ControllerTable)."""
    path = tmp_path_factory.mktemp("pd") / "pd.npz"
    return path, write_pd_table(path)


@pytest.fixture
def nodes(ros_env):
    """Start SIL executables; every one is stopped and reaped at teardown."""
    procs = []

    def start(name, params_file, *extra):
        exe = find_executable(EXECUTABLES[name], name)
        proc = subprocess.Popen([exe, "--ros-args", "--params-file", str(params_file), *extra],
                                env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        procs.append(proc)
        return proc

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.terminate()
    for proc in procs:
        try:
            proc.communicate(timeout=budget_s(10.0))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()


def _finish(proc, timeout=None):
    out, err = proc.communicate(
        timeout=budget_s(PROCESS_TIMEOUT_S) if timeout is None else timeout)
    return proc.returncode, out, err


def _params(path: Path, **values) -> Path:
    values.setdefault("barrier_timeout_s", budget_s(60.0))  # unless the test sets its own
    return write_node_params(path, **values)


def _short_scenario(tmp_path, t_end_s=11.0) -> Path:
    """The thesis scenario cut to 10 s … ``t_end_s`` (a YAML file of its own)."""
    text = scenario_path("thesis").read_text()
    text = text.replace("name: thesis", "name: short").replace("t_end_s: 90.0",
                                                                f"t_end_s: {t_end_s}")
    path = tmp_path / "short.yaml"
    path.write_text(text)
    return path


# ----------------------------------------------------------------------------- schedule
def test_schedule_counts_and_actuator_needs():
    info = RunInfo("x", 1, 10_000, 11_000, LoopTiming()).check()
    assert info.n_frames == 100
    assert list(info.command_samples())[:3] == [10_000, 10_020, 10_040]
    assert info.expected_counts() == {"/vega/truth": 101, "/clock": 11, "/vega/ins": 100,
                                      "/vega/tvc_cmd": 50, "/vega/actuator": 100,
                                      "/vega/diagnostics": 50}
    assert info.clock_frames() == list(range(0, 101, 10))
    assert RunInfo("x", 1, 0, 1_050, LoopTiming()).clock_frames()[-3:] == [90, 100, 105]
    # command of sample s applies at s + 39 ms; frame k integrates steps t_k … t_k + 9 ms
    needed = [info.commands_needed(k) for k in range(info.n_frames)]
    for k, n in enumerate(needed):
        t_last_step = info.frame_start(k) + 9
        applying = [s for s in info.command_samples() if s + 39 <= t_last_step]
        assert n == len(applying)
    assert needed[:6] == [0, 0, 0, 1, 1, 2]      # the actuator runs 3 frames ahead
    # a span starting off the controller period: first command at the next multiple of 20
    assert RunInfo("x", 1, 10, 100, LoopTiming()).command_samples()[0] == 20
    assert RunInfo.from_json(info.to_json()) == info


@pytest.mark.parametrize("info, problem", [
    (RunInfo("x", 1, 10_005, 11_000, LoopTiming()), "whole 10 ms frames"),
    (RunInfo("x", 1, 11_000, 11_000, LoopTiming()), "whole 10 ms frames"),
    (RunInfo("x", 1, 0, 100, LoopTiming(sensor_latency_ms=0, computing_latency_ms=0,
                                        actuator_latency_ms=5)), "shorter than one frame"),
])
def test_schedule_rejects_bad_runs(info, problem):
    with pytest.raises(ValueError, match=problem):
        info.check()


def test_run_description_rejects_malformed_json():
    for text in ('{"scenario": "x"}', "not json", '{"scenario": "x", "seed": 1, '
                 '"t_start_ms": 0, "t_end_ms": 100, "timing": {"frame_ms": 0}}'):
        with pytest.raises(ValueError, match="malformed run description"):
            RunInfo.from_json(text)


def test_recorder_reads_stamp_and_seq_from_cdr():
    """The recorder's offsets (from bagio's computed layout, cached per frame_id length) read
    the right stamp and seq of every topic, whatever the frame_id and sample counts."""
    from rclpy.serialization import serialize_message

    for topic in topics.ALL_TOPICS:
        fields = RawFields(topic.type_name)
        cls = topics.message_class(topic.type_name)
        for k, frame_id in enumerate(("", "b", "base_link", "abc", "", "base_link")):
            m = cls()
            stamp = m.clock if topic is topics.CLOCK else m.header.stamp
            stamp.sec, stamp.nanosec = 12 + k, 345_000_000
            if topic is not topics.CLOCK:
                m.header.frame_id = frame_id
                m.seq = 4_000_000_001 + k
            if hasattr(m, "sample_stamp"):
                m.sample_stamp.sec = 99
            if topic is topics.ACTUATOR:
                m.deflection_samples_rad = [0.5] * k
            got = fields(serialize_message(m))
            assert got == ((12 + k) * 1_000_000_000 + 345_000_000,
                           None if topic is topics.CLOCK else 4_000_000_001 + k), topic.name


# ----------------------------------------------------------------------------- ROS: bad input
@pytest.mark.slow
@pytest.mark.ros
def test_malformed_controller_table_exits_2_with_one_line(nodes, tmp_path):
    bad = tmp_path / "broken.npz"
    bad.write_bytes(b"not a zip archive")
    proc = nodes("tvc_controller", _params(tmp_path / "p.yaml", controller_table=str(bad)))
    code, _out, err = _finish(proc)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("tvc_controller: ") and str(bad) in err


@pytest.mark.slow
@pytest.mark.ros
def test_malformed_guidance_reference_exits_2_with_one_line(nodes, tmp_path):
    bad = tmp_path / "broken_reference.npz"
    bad.write_bytes(b"not a zip archive")
    proc = nodes("tvc_controller", _params(tmp_path / "p.yaml", guidance_reference=str(bad)))
    code, _out, err = _finish(proc)
    assert code == 2
    assert err.count("\n") == 1 and str(bad) in err and "guidance reference" in err, err


@pytest.mark.slow
@pytest.mark.ros
def test_controller_refuses_a_guidance_reference_that_is_not_the_runs(nodes, tmp_path,
                                                                      pd_table):
    """A hand-started controller told 'none' in a run whose scenario flies the installed
    reference: one line naming both, exit 2, before the barrier."""
    info = RunInfo("driven", 0, 10_000, 10_100, LoopTiming(), "default").check()
    driver = _Driver(info)
    try:
        proc = nodes("tvc_controller", _params(tmp_path / "p.yaml", guidance_reference="none",
                                               controller_table=str(pd_table[0]),
                                               participants=["tvc_controller"]))
        driver.spin_until(lambda: proc.poll() is not None)
        code, _out, err = _finish(proc)
    finally:
        driver.close()
    assert code == 2 and err.count("\n") == 1, err
    assert "'guidance_reference' 'none' is not the run's guidance 'default'" in err, err


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.parametrize("name, key, value, text", [
    ("plant", "scenario", "no_such_scenario", "unknown scenario 'no_such_scenario'"),
    ("plant", "seed", -5, "parameter 'seed'"),
    ("tvc_actuator", "barrier_timeout_s", "ten", "parameter 'barrier_timeout_s'"),
])
def test_bad_parameters_exit_2_with_one_line(nodes, tmp_path, name, key, value, text):
    proc = nodes(name, _params(tmp_path / "p.yaml", **{key: value}))
    code, _out, err = _finish(proc)
    assert code == 2 and err.count("\n") == 1 and text in err, err


@pytest.mark.slow
@pytest.mark.ros
def test_barrier_timeout_names_the_missing_participant(nodes, tmp_path):
    proc = nodes("plant", _params(tmp_path / "p.yaml", scenario=str(_short_scenario(tmp_path)),
                                  participants=["plant", "ins_sensor"], barrier_timeout_s=1.0))
    code, _out, err = _finish(proc)
    assert code == 1
    assert err.count("\n") == 1 and "start barrier timed out" in err and "ins_sensor" in err
    assert "recorder" not in err    # not a participant of this run


# ----------------------------------------------------------------------------- ROS: controller
class _Driver:
    """The test process as the INS and the time master of a controller node."""

    def __init__(self, info: RunInfo):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import String
        from vega_msgs.msg import InsMeasurement, StepDiagnostics, TvcCommand

        self.context = rclpy.Context()
        rclpy.init(context=self.context,
                   signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.node = rclpy.create_node("test_driver", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.run = self.node.create_publisher(String, topics.RUN.name, qos.control_qos())
        self.run.publish(String(data=info.to_json()))
        self.ins = self.node.create_publisher(InsMeasurement, topics.INS.name,
                                              qos.data_qos())
        self.commands = []
        self.ready = set()
        self.node.create_subscription(TvcCommand, topics.TVC_CMD.name, self.commands.append,
                                      qos.data_qos())
        self.diagnostics = []
        self.node.create_subscription(StepDiagnostics, topics.DIAGNOSTICS.name,
                                      self.diagnostics.append, qos.data_qos())
        self.node.create_subscription(String, topics.READY.name,
                                      lambda m: self.ready.add(m.data), qos.control_qos())
        self._msg = InsMeasurement

    def spin_until(self, done, timeout_s=30.0):
        deadline = time.monotonic() + budget_s(timeout_s)
        while not done():
            assert time.monotonic() < deadline, "timed out waiting on the controller node"
            self.executor.spin_once(timeout_sec=0.05)

    def send(self, seq, sample_ms, stamp_ms, pitch=0.01, v=None, valid=True, nanosec_off=0):
        m = self._msg()
        m.header.stamp.sec, m.header.stamp.nanosec = ms_to_stamp(stamp_ms)
        m.sample_stamp.sec, ns = ms_to_stamp(sample_ms)
        m.sample_stamp.nanosec = ns + nanosec_off
        m.seq = seq
        m.pitch_rad, m.pitch_rate_radps, m.drift_m, m.drift_rate_mps = pitch, 0.0, 0.0, 0.0
        m.velocity_mps = v
        m.valid = valid
        self.ins.publish(m)

    def close(self):
        import rclpy

        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _controller_with_driver(nodes, tmp_path, table_path, n_frames, **params):
    """A controller node alone in its run (``params``: more of its parameters), and the
    driver it has matched and announced itself ready to."""
    info = RunInfo("driven", 0, 10_000, 10_000 + 10 * n_frames, LoopTiming(),
                   "none").check()
    driver = _Driver(info)
    proc = nodes("tvc_controller", _params(tmp_path / "p.yaml", controller_table=str(table_path),
                                           participants=["tvc_controller"], **params))
    driver.spin_until(lambda: "tvc_controller" in driver.ready
                      and driver.ins.get_subscription_count() >= 1)
    return driver, proc


@pytest.mark.slow
@pytest.mark.ros
def test_controller_flags_bad_measurements_and_never_crashes(nodes, tmp_path, pd_table):
    """NaN, stale, out-of-order, off-grid stamps and velocities over real DDS → the
    documented status flags; the node finishes its run and exits 0."""
    path, table = pd_table
    v_in = float(np.mean(table.grid_v_mps[:2]))
    v_out = float(table.grid_v_mps[-1]) + 500.0
    driver, proc = _controller_with_driver(nodes, tmp_path, path, n_frames=14)
    try:
        # (seq, sample ms, header stamp ms, kwargs); odd seqs are off the 20 ms period
        plan = [
            (0, 10_000, 10_012, {}),                                  # fresh, valid → OK
            (1, 10_010, 10_022, {}),
            (2, 10_020, 10_032, {"pitch": math.nan}),                 # NaN → hold last
            (3, 10_030, 10_042, {}),
            (4, 10_040, 10_140, {}),                                  # 100 ms old → stale
            (5, 10_050, 10_062, {}),
            (6, 10_000, 10_072, {}),                                  # older sample → order
            (7, 10_070, 10_082, {}),
            (8, 10_080, 10_092, {"v": v_out}),                        # off the grid → clamp
            (9, 10_090, 10_102, {}),
            (10, 10_100, 10_112, {"nanosec_off": 5}),                 # not on a ms → invalid
            (11, 10_110, 10_122, {}),
            (12, 10_400, 10_412, {"valid": False}),                   # invalid > 0.2 s → zero
            (13, 10_410, 10_422, {}),
        ]
        for seq, sample, stamp, kw in plan:
            driver.send(seq, sample, stamp, **{"v": v_in, **kw})
        driver.spin_until(lambda: len(driver.commands) == 7 and len(driver.diagnostics) == 7)
        code, _out, err = _finish(proc)
    finally:
        driver.close()
    assert code == 0 and err == ""
    c = driver.commands
    assert [m.seq for m in c] == list(range(7))
    assert [m.status for m in c] == [STATUS_OK, STATUS_HOLD_LAST, STATUS_HOLD_LAST,
                                     STATUS_HOLD_LAST, STATUS_VELOCITY_CLAMPED,
                                     STATUS_HOLD_LAST, STATUS_SAFE_ZERO]
    assert c[0].deflection_cmd_rad != 0.0
    assert all(m.deflection_cmd_rad == c[0].deflection_cmd_rad for m in c[1:4])
    assert c[5].deflection_cmd_rad == c[4].deflection_cmd_rad and c[6].deflection_cmd_rad == 0.0
    # stamps: arrival + 12 ms; sample stamp carried over
    assert (c[0].header.stamp.sec, c[0].header.stamp.nanosec) == ms_to_stamp(10_024)
    assert (c[4].sample_stamp.sec, c[4].sample_stamp.nanosec) == ms_to_stamp(10_080)
    # the wall-clock step time: on /vega/diagnostics, one per command, its stamp and seq
    d = driver.diagnostics
    assert [(m.seq, m.header.stamp.sec, m.header.stamp.nanosec) for m in d] == \
        [(m.seq, m.header.stamp.sec, m.header.stamp.nanosec) for m in c]
    assert all(0.0 < m.compute_time_s < 1.0 for m in d)
    assert {m.header.frame_id for m in d} == {"tvc_controller"}


@pytest.mark.slow
@pytest.mark.ros
def test_controller_sequence_gap_fails_the_run(nodes, tmp_path, pd_table):
    path, table = pd_table
    v = float(table.grid_v_mps[0])
    driver, proc = _controller_with_driver(nodes, tmp_path, path, n_frames=4)
    try:
        driver.send(0, 10_000, 10_012, v=v)
        driver.send(2, 10_020, 10_032, v=v)       # seq 1 lost
        code, _out, err = _finish(proc)
    finally:
        driver.close()
    assert code == 1 and err.count("\n") == 1
    assert "sequence gap on /vega/ins: expected seq 1, got 2" in err


@pytest.mark.slow
@pytest.mark.ros
def test_controller_stall_and_sigterm(nodes, tmp_path, pd_table):
    """No measurement for stall_timeout_s → exit 1 naming what it waited for; SIGTERM while
    waiting → one line, exit 0.

    The stalled controller's 0.5 s start when its barrier passes; measurement 0, sent once
    this process has seen the controller ready, arrives within them or not (a loaded machine,
    or the controller's reader matching the driver's writer only at the next heartbeat): the
    stall then names seq 1 or seq 0, both right. The stopped controller gets a stall timeout
    far beyond the test's own wait, so that SIGTERM, not a stall, ends it."""
    import signal

    path, table = pd_table
    info = RunInfo("driven", 0, 10_000, 10_100, LoopTiming(), "none").check()
    driver = _Driver(info)
    try:
        stalled = nodes("tvc_controller", _params(
            tmp_path / "a.yaml", controller_table=str(path), participants=["tvc_controller"],
            stall_timeout_s=0.5))
        driver.spin_until(lambda: "tvc_controller" in driver.ready
                          and driver.ins.get_subscription_count() >= 1)
        driver.send(0, 10_000, 10_012, v=float(table.grid_v_mps[0]))
        code, _out, err = _finish(stalled)
        assert code == 1, err
        assert err in (f"tvc_controller: lockstep stall: waited 0.5 s for /vega/ins seq {k}\n"
                       for k in (1, 0)), err

        driver.ready.clear()
        stopped = nodes("tvc_controller", _params(
            tmp_path / "b.yaml", controller_table=str(path), participants=["tvc_controller"],
            stall_timeout_s=budget_s(120.0)))
        driver.spin_until(lambda: "tvc_controller" in driver.ready)
        stopped.send_signal(signal.SIGTERM)
        code, _out, err = _finish(stopped)
    finally:
        driver.close()
    assert code == 0 and err == "tvc_controller: stopped by SIGTERM\n"


# ----------------------------------------------------------------------------- ROS: a short run
@pytest.mark.slow
@pytest.mark.ros
def test_short_run_records_a_complete_bag(nodes, tmp_path, pd_table):
    """Five processes started in reverse order fly 10–11 s in lockstep; the recorder's bag
    reads back with every expected message, gap-free sequences, log time = stamp, and the
    in-process simulation's numbers."""
    from vega_bags.bagio import META_SCENARIO, META_SEED, read_run_bag
    from vega_sim.closed_loop import run_scenario

    path, table = pd_table
    scenario = _short_scenario(tmp_path, t_end_s=11.0)
    bag = tmp_path / "bag"
    # the nodes' own limits (barrier, stall) end a hung run; the test's limit is a backstop
    # beyond them: both scaled by the load (a fixed 60 s is too short on a loaded machine)
    barrier_s = budget_s(60.0)
    params = _params(tmp_path / "p.yaml", scenario=str(scenario), controller_table=str(path),
                     bag_path=str(bag), barrier_timeout_s=barrier_s)
    procs = {name: nodes(name, params) for name in reversed(PARTICIPANTS)}
    results = {name: _finish(proc, barrier_s + budget_s(PROCESS_TIMEOUT_S))
               for name, proc in procs.items()}
    for name, (code, _out, err) in results.items():
        assert code == 0 and err == "", (name, err)
    assert "flew 1 s" in results["plant"][1]

    run = read_run_bag(bag)
    assert run.metadata[META_SCENARIO] == "short" and run.metadata[META_SEED] == "1"
    expected = RunInfo("short", 1, 10_000, 11_000, LoopTiming()).expected_counts()
    for name, count in expected.items():
        cols = run[name]
        assert len(cols) == count, name
        assert np.array_equal(cols.log_time_ns, cols["stamp_ns"]), name
        if name != topics.CLOCK.name:
            assert np.array_equal(cols["seq"], np.arange(count)), name
    ref = run_scenario(scenario, table)
    assert np.array_equal(run["/vega/truth"]["pitch_rad"], ref.theta_rad)
    assert np.array_equal(run["/vega/tvc_cmd"]["deflection_cmd_rad"], ref.cmd_rad)


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.parametrize("text, problem", [
    ("/**:\n  ros__parameters: [oops\n", "bad.yaml: not valid YAML (line 3)"),
    ("/**:\n  ros__parameters: 3\n",
     "bad.yaml: node parameters file: '/**' must hold only 'ros__parameters', a mapping"),
    ("plant:\n  seed: 1\n",
     "bad.yaml: node parameters file: 'plant/seed' must hold 'ros__parameters' (a mapping), "
     "got 1"),
    ("#" * (1 << 20) + "\n", "bad.yaml: node parameters file is 1048577 bytes, over the 1 MiB "
                             "(1048576 bytes) limit"),
])
def test_malformed_params_file_exits_2_with_one_line(nodes, tmp_path, text, problem):
    """A node given a malformed parameters file by hand says so in one line and exits 2 (not
    rcl's error line and a traceback)."""
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    code, _out, err = _finish(nodes("plant", path))
    assert code == 2
    lines = [line for line in err.splitlines() if "ROS_DOMAIN_ID" not in line]
    assert lines == [f"plant: {tmp_path}/{problem}"]
