"""A bus only the run's nodes can write to, with real processes: a rogue rclpy publisher
(tests/sil/rogue_publisher.py, its own process) on loopback in this test run's own
ROS_DOMAIN_ID, against ``vega sil run`` and against a controller node.

* a domain with a participant on it is never picked, and an exported one is refused before
  anything starts (one line, exit 2);
* a foreign publisher on a run topic fails the run, named (node name and GID), and none of
  its messages is recorded;
* a node refuses a message from a second publisher, or one that breaks its publisher's
  stream (publication sequence number), and fails: the message is never flown.
"""

import subprocess
import sys
import time
from pathlib import Path

import pytest

from fixture_tables import write_pd_table
from load_scaling import budget_s
from sil_flights import (children_of, flight_env, start_vega_sil_run, vega_sil_run,
                         write_short_scenario)
import test_sil_nodes as sil_nodes
from vega_bags import bagio
from vega_bringup import rosenv
from vega_bus import topics

pytestmark = pytest.mark.ros

ROGUE = Path(__file__).with_name("rogue_publisher.py")
ROGUE_START_S = 30.0
"""How long a node under test waits for the next message (its ``stall_timeout_s``) while a
rogue process starts and is discovered, on an idle machine [s]: a backstop, scaled by the load
(:func:`load_scaling.budget_s`)."""
REFUSED_SECOND_PUBLISHER = (
    "tvc_controller: refused a message on /vega/ins: 2 publishers match this subscription, "
    "the run has one: a foreign publisher is on the bus")
"""The controller's refusal once its subscription has matched a second publisher."""
REFUSED_BROKEN_STREAM = (
    "tvc_controller: refused a message on /vega/ins: publication sequence number 1, expected "
    "2: not the stream of the run's publisher (a foreign or restarted publisher)")
"""The controller's refusal of a first message (publication sequence number 1) from a writer
other than the one whose message 1 it took."""
nodes = sil_nodes.nodes                 # the fixture starting single SIL executables
_controller_with_driver, _finish = sil_nodes._controller_with_driver, sil_nodes._finish


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    """The nominal flight cut to 10-60 s: flown in real time, it must still fly when the rogue
    process, started once the flight began, has come up (over 10 s on a loaded machine); the
    run ends when the rogue is found, so the length costs nothing otherwise."""
    return write_short_scenario(tmp_path_factory.mktemp("scenario"), "nominal", "sec", 10.0,
                                60.0)


@pytest.fixture(scope="module")
def pd_table(tmp_path_factory):
    """The PD fixture table: (path, ControllerTable)."""
    path = tmp_path_factory.mktemp("pd") / "pd.npz"
    return path, write_pd_table(path)


@pytest.fixture
def rogue():
    """Start rogue publishers (own processes, this run's domain); all stopped at teardown."""
    procs = []

    def start(*args):
        proc = subprocess.Popen([sys.executable, str(ROGUE), *map(str, args)],
                                env=flight_env(), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        procs.append(proc)
        return proc

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.terminate()
        proc.communicate(timeout=budget_s(30.0))


def _until(done, timeout_s=30.0):
    deadline = time.monotonic() + budget_s(timeout_s)
    while not done():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def _shm_modes(pid):
    """Mode bits of the Fast DDS shared-memory files process ``pid`` has mapped."""
    import os

    try:
        maps = Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return {}
    modes = {}
    for path in {line.split(None, 5)[-1] for line in maps.splitlines()
                 if " /dev/shm/fastrtps_" in line}:
        try:
            modes[path] = os.stat(path).st_mode & 0o777
        except OSError:
            continue
    return modes


@pytest.mark.slow
def test_a_busy_domain_is_found_and_never_picked(rogue, ros_domain_id, tmp_path):
    assert rosenv.domain_in_use(ros_domain_id) is None
    rogue("squatter", topics.INS.name, 0)
    assert _until(lambda: rosenv.domain_in_use(ros_domain_id) is not None)
    counter = tmp_path / "counter"
    counter.write_text(f"{ros_domain_id - 1 if ros_domain_id > 1 else 100}\n")
    picked = rosenv.pick_domain_id(counter)
    assert picked != ros_domain_id and rosenv.domain_in_use(picked) is None
    assert counter.read_text().strip() == str(picked)


@pytest.mark.slow
def test_an_exported_busy_domain_is_refused_before_anything_starts(rogue, ros_domain_id,
                                                                   tmp_path, scenario,
                                                                   pd_table):
    rogue("squatter", topics.INS.name, 0)
    assert _until(lambda: rosenv.domain_in_use(ros_domain_id) is not None)
    out = tmp_path / "out"
    result = vega_sil_run(["--scenario", scenario, "--table", pd_table[0], "--out", out])
    assert result.returncode == 2, result.stderr
    errors = [line for line in result.stderr.splitlines() if "error" in line]
    assert errors == [result.stderr.splitlines()[-1]]
    assert errors[0].startswith(f"vega: error: ROS_DOMAIN_ID={ros_domain_id} is in use: a DDS "
                                f"participant on this host holds its RTPS port ")
    assert not list(out.glob("*/params.yaml"))          # nothing written, nothing started


@pytest.mark.slow
def test_a_foreign_publisher_fails_the_run_naming_it(rogue, tmp_path, scenario, pd_table):
    """A rogue ``/vega/ins`` publisher joins a flying run (paced to real time): the run
    fails (exit 1) naming the rogue node and its GID; the bag holds none of its messages."""
    out = tmp_path / "out"
    proc = start_vega_sil_run(["--scenario", scenario, "--table", pd_table[0], "--out", out,
                               "--realtime"])
    try:
        stderr = []
        for line in proc.stderr:
            stderr.append(line)
            if "start barrier complete" in line:
                break
        assert proc.poll() is None, "".join(stderr)
        # the nodes' Fast DDS shared-memory segments: for the run's user only
        nodes = children_of(proc.pid)
        assert len(nodes) == 5
        assert _until(lambda: all(_shm_modes(pid) and not any(m & 0o077 for m in
                                                              _shm_modes(pid).values())
                                  for pid in nodes), 10.0), {p: _shm_modes(p) for p in nodes}
        rogue("rogue_ins", topics.INS.name, 50, "seq=1", "stamp_ms=10012",
              "velocity_mps=12345", "pitch_rad=0.5", "valid=1")
        stderr.append(proc.communicate(timeout=budget_s(120.0))[1])
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.communicate(timeout=budget_s(60.0))
    text = "".join(stderr)
    assert proc.returncode == 1, text
    assert "error: foreign publisher on /vega/ins: node '/rogue_ins' (GID 01.0f." in text, text
    assert "flew " not in text
    (bag,) = out.glob("*/bag")
    ins = bagio.read_run_bag(bag)[topics.INS.name]
    assert len(ins) > 0
    assert not (ins["velocity_mps"] == 12345.0).any()
    assert ins["seq"].tolist() == list(range(len(ins)))


@pytest.mark.slow
def test_a_node_refuses_a_second_publishers_message(nodes, rogue, tmp_path, pd_table):
    """A rogue process publishes one INS message (seq 1: the next the run expects) into a
    controller that has taken the driver's message 0: refused, exit 1, nothing computed from
    it. Which refusal depends on which of two events comes first in the controller: its
    subscription matching the rogue's writer (the graph's discovery: the publisher count
    becomes 2) or the rogue's message arriving (its publication sequence number is 1, the
    driver's stream is at 2). DDS does not order the two; either line is right, exactly one
    of them must be the node's only output. The controller's stall timeout is the test's
    limit on the rogue's start-up (a new Python process and its discovery: over 10 s, the
    default, on a loaded machine), so that a stall, not a refusal, can only mean that the
    rogue's message never came."""
    path, table = pd_table
    v = float(table.grid_v_mps[0])
    driver, proc = _controller_with_driver(nodes, tmp_path, path, n_frames=6,
                                           stall_timeout_s=budget_s(ROGUE_START_S))
    try:
        driver.send(0, 10_000, 10_012, v=v)
        driver.spin_until(lambda: len(driver.commands) == 1)
        rogue("rogue_ins", topics.INS.name, 1, "seq=1", "stamp_ms=10022",
              f"velocity_mps={v}", "pitch_rad=0.5", "valid=1")
        code, _out, err = _finish(proc)
        driver.executor.spin_once(timeout_sec=0.5)
    finally:
        driver.close()
    assert code == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0] in (REFUSED_SECOND_PUBLISHER, REFUSED_BROKEN_STREAM), err
    assert len(driver.commands) == 1                  # nothing computed from the rogue's


@pytest.mark.slow
def test_a_node_refuses_a_message_that_breaks_the_stream(nodes, tmp_path, pd_table):
    """A publisher replaced by another (its publication sequence numbers restart at 1):
    the next message is refused, not flown. (One refusal only: DDS announces the old writer's
    removal and the new writer on the driver participant's one reliable discovery stream, in
    that order, so the controller has unmatched the old writer before it matches the new one
    and takes its message; the pause below only keeps the two apart in time.)"""
    from vega_bus import qos

    path, table = pd_table
    v = float(table.grid_v_mps[0])
    # the pause and the new writer's matching must not outlast the controller's wait
    driver, proc = _controller_with_driver(nodes, tmp_path, path, n_frames=6,
                                           stall_timeout_s=budget_s(ROGUE_START_S))
    try:
        driver.send(0, 10_000, 10_012, v=v)
        driver.spin_until(lambda: len(driver.commands) == 1)
        driver.node.destroy_publisher(driver.ins)
        driver.executor.spin_once(timeout_sec=1.0)
        # the old writer unmatched on the controller's side (no event this process can see;
        # DDS announces the removal at once: well under 1 s idle)
        time.sleep(budget_s(1.0))
        driver.ins = driver.node.create_publisher(driver._msg, topics.INS.name,
                                                  qos.data_qos())
        driver.spin_until(lambda: driver.ins.get_subscription_count() >= 1)
        driver.send(1, 10_010, 10_022, v=v)
        code, _out, err = _finish(proc)
    finally:
        driver.close()
    assert code == 1, err
    assert err.strip().splitlines() == [REFUSED_BROKEN_STREAM]
    assert len(driver.commands) == 1


def test_foreign_publisher_rule():
    """The supervisor's rule on the graph's endpoints (pure function, endpoint records as rclpy
    gives them): the topic's node in the run's process, or an endpoint whose node name the
    graph does not know yet but whose GID is that process's; anything else is named."""
    from types import SimpleNamespace

    from vega_bringup.orchestrate import foreign_publisher

    def endpoint(name, pid, vendor=b"\x01\x0f"):
        gid = vendor + b"\x78\xfd" + (pid & 0xFFFF).to_bytes(2, "little") + bytes(10)
        return SimpleNamespace(node_name=name, node_namespace="/", endpoint_gid=list(gid))

    own = {"ins_sensor": 70_001, "plant": 70_002}
    participants = ("plant", "ins_sensor")
    ok = {topics.INS.name: [endpoint("ins_sensor", 70_001)],
          topics.READY.name: [endpoint("plant", 70_002), endpoint("ins_sensor", 70_001)],
          topics.TRUTH.name: [endpoint("_NODE_NAME_UNKNOWN_", 70_002)]}
    assert foreign_publisher(ok, own, participants) is None
    for name, pid, vendor in (("ins_sensor", 12_345, b"\x01\x0f"),   # the name, not the pid
                              ("rogue", 70_001, b"\x01\x0f"),        # the pid, not the name
                              ("plant", 70_002, b"\x01\x0f"),        # the wrong node
                              ("ins_sensor", 70_001, b"\x01\x10"),   # another DDS vendor
                              ("_NODE_NAME_UNKNOWN_", 12_345, b"\x01\x0f")):
        bad = {**ok, topics.INS.name: ok[topics.INS.name] + [endpoint(name, pid, vendor)]}
        found = foreign_publisher(bad, own, participants)
        assert found.startswith(f"foreign publisher on /vega/ins: node '/{name}' (GID "
                                f"{vendor[0]:02x}.{vendor[1]:02x}.78.fd."), found
