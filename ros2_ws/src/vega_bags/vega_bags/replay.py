"""Replay of run bags: republish the recorded topics, or re-run the controller on them.

* :func:`play` — ``vega replay BAG [--rate R]``: every graph topic of the bag is published
  again, raw CDR bytes as recorded (``Publisher.publish`` accepts serialised bytes), with the
  QoS of :mod:`vega_bus.topics`, in log-time order and paced by the log times at ``rate`` ×
  real time (0: as fast as possible). ``/clock`` is republished as recorded (or, for a bag
  without it, generated from the log times). Optionally it first waits until every topic has
  a subscriber, and it always waits until the subscribers acknowledged everything before it
  returns.
* :func:`check_controller` — ``vega replay BAG --check-controller [--table FILE]``: the SIL
  regression check for controller changes. A fresh ``tvc_controller`` node (the installed
  executable, as ``vega sil run`` starts it) gets the run description of the bag on
  ``/vega/run`` and the recorded INS measurements in order, flow-controlled: after a
  measurement whose sample falls on the controller period, the checker waits for the
  command before it sends the next one. Its commands are compared with the recorded ones,
  every field, floats bit for bit (the wall-clock step time is on ``/vega/diagnostics``,
  not compared).

The checker takes the recorder's place in the start barrier (node name ``recorder``,
participants ``tvc_controller`` and ``recorder``): the controller announces itself only when
its command publisher has matched the checker's subscription, so no command can be lost.

Verdict of the check (:class:`ControllerCheck`): exit status 0 identical, 1 different (the
first difference is named), 2 bad input (bag, table, scenario metadata; the controller
rejecting its input). A bad bag raises :class:`vega_bags.bagio.BagError`.
"""

from __future__ import annotations

import dataclasses

import math
import shutil
import struct
import subprocess
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from vega_core.errors import BadArgument, BadInput

from vega_bus import qos, topics
from vega_bus.timing import NS_PER_MS, NS_PER_S

from vega_bags import bagio

__all__ = ["PlayResult", "play", "ControllerCheck", "first_difference", "check_controller"]

CHECKER_NAME = "recorder"
"""Node name of the controller checker (it records the controller's commands)."""
STALL_TIMEOUT_S = 20.0
"""Longest wait for one expected command [s] before the controller counts as stalled."""


@contextmanager
def _ros_node(name: str):
    """(node, executor) in a fresh rclpy context without rclpy's signal handlers; shut down
    on exit."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(name, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _flush(publishers, timeout_s: float) -> None:
    """Wait until the subscribers acknowledged everything (or ``timeout_s`` passed)."""
    from rclpy.duration import Duration

    deadline = time.monotonic() + timeout_s
    for pub in publishers:
        left = max(0.0, deadline - time.monotonic())
        pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))


# ----------------------------------------------------------------------------- play
@dataclass(frozen=True)
class PlayResult:
    """What :func:`play` published: messages per topic, sim-time span [s], wall time [s]."""

    counts: dict
    span_s: float
    wall_s: float


def _clock_bytes(t_ns: int) -> bytes:
    """A serialised rosgraph_msgs/Clock at ``t_ns``."""
    store = bagio.vega_typestore()
    Clock = store.types[topics.CLOCK.type_name]
    Time = store.types["builtin_interfaces/msg/Time"]
    sec, nsec = divmod(int(t_ns), NS_PER_S)
    return bytes(store.serialize_cdr(Clock(clock=Time(sec=sec, nanosec=nsec)),
                                     topics.CLOCK.type_name))


def play(path: str | Path, rate: float = 1.0, *, wait_subscribers_s: float = 0.0,
         stop: Callable[[], bool] = lambda: False,
         progress: Callable[[str], None] | None = None) -> PlayResult:
    """Republish a run bag (module docstring).

    Parameters
    ----------
    path
        Run bag directory.
    rate
        Sim seconds per wall second (1: real time); 0: as fast as possible.
    wait_subscribers_s
        If > 0, first wait up to this long until every published topic has a subscriber.
    stop
        Polled between messages; True ends the replay early.
    progress
        Called with one-line status messages.

    Raises
    ------
    BagError
        Missing, corrupt or foreign bag.
    BadArgument
        Negative or non-finite rate.
    """
    if not (math.isfinite(rate) and rate >= 0.0):
        raise BadArgument(f"--rate {rate!r}: must be a finite number >= 0")
    say = progress or (lambda line: None)
    bag = bagio.read_run_bag(path)  # validates the whole bag before anything is published
    names = [t.name for t in topics.ALL_TOPICS if bag.has(t.name) and len(bag[t.name])]
    synth_clock = topics.CLOCK.name not in names
    with _ros_node("vega_replay") as (node, executor):
        pubs = {}
        for t in topics.ALL_TOPICS:
            if t.name in names or (t is topics.CLOCK and synth_clock):
                profile = qos.clock_qos() if t is topics.CLOCK else qos.data_qos()
                pubs[t.name] = node.create_publisher(topics.message_class(t.type_name),
                                                     t.name, profile)
        if wait_subscribers_s > 0:
            deadline = time.monotonic() + wait_subscribers_s
            while any(p.get_subscription_count() == 0 for p in pubs.values()):
                if time.monotonic() > deadline or stop():
                    lonely = [n for n, p in pubs.items() if p.get_subscription_count() == 0]
                    say(f"no subscriber on {', '.join(lonely)} after {wait_subscribers_s:g} s; "
                        f"publishing anyway")
                    break
                executor.spin_once(timeout_sec=0.05)
        counts = dict.fromkeys(pubs, 0)
        first = last = None
        wall0 = time.monotonic()
        last_clock = None
        for topic, t_ns, data in bagio.iter_raw_messages(path):
            if stop():
                break
            if first is None:
                first = t_ns
            if rate > 0:
                delay = wall0 + (t_ns - first) / 1e9 / rate - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            if synth_clock and t_ns != last_clock:
                pubs[topics.CLOCK.name].publish(_clock_bytes(t_ns))
                counts[topics.CLOCK.name] += 1
                last_clock = t_ns
            pubs[topic].publish(bytes(data))
            counts[topic] += 1
            last = t_ns
        wall = time.monotonic() - wall0
        _flush(pubs.values(), 10.0)
    span = 0.0 if first is None else (last - first) / 1e9
    return PlayResult(counts, span, wall)


# ----------------------------------------------------------------------------- controller check
@dataclass(frozen=True)
class ControllerCheck:
    """Verdict of :func:`check_controller`.

    ``recorded``/``replayed``: number of commands; ``compared``: commands compared field by
    field; ``difference``: the first difference (None: identical); ``notes``: remarks (e.g.
    a table whose SHA-256 differs from the recorded one).
    """

    recorded: int
    replayed: int
    compared: int
    difference: str | None
    table: str
    notes: tuple[str, ...] = ()

    @property
    def identical(self) -> bool:
        """True if every recorded command was reproduced exactly."""
        return self.difference is None

    @property
    def exit_code(self) -> int:
        """0 identical, 1 different."""
        return 0 if self.identical else 1

    def summary(self) -> str:
        """One or two lines for the console."""
        head = (f"controller replay with {self.table}: {self.replayed} commands replayed, "
                f"{self.recorded} recorded, {self.compared} compared")
        verdict = ("IDENTICAL (every field)" if self.identical
                   else f"DIFFERENT: {self.difference}")
        return "\n".join([*(f"note: {n}" for n in self.notes), head, f"verdict: {verdict}"])


def _same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return struct.pack("<d", float(a)) == struct.pack("<d", float(b))
    return a == b


def _diff(a, b, prefix: str = "") -> str | None:
    """First field (dotted path) where rosbags messages ``a`` and ``b`` differ, with values."""
    for f in fields(a):
        name = f.name
        if name == "__msgtype__" or name.isupper():
            continue
        x, y = getattr(a, name), getattr(b, name)
        if is_dataclass(x):
            found = _diff(x, y, f"{prefix}{name}.")
            if found:
                return found
        elif isinstance(x, np.ndarray):
            if x.shape != y.shape or x.tobytes() != y.tobytes():
                return f"{prefix}{name}: recorded {x.tolist()!r}, replayed {y.tolist()!r}"
        elif not _same(x, y):
            return f"{prefix}{name}: recorded {x!r}, replayed {y!r}"
    return None


def first_difference(recorded: list[bytes], replayed: list[bytes]) -> tuple[int, str | None]:
    """(commands compared, first difference or None) between two lists of TvcCommand bytes."""
    store = bagio.vega_typestore()
    name = topics.TVC_CMD.type_name
    n = min(len(recorded), len(replayed))
    for i in range(n):
        a = store.deserialize_cdr(recorded[i], name)
        b = store.deserialize_cdr(replayed[i], name)
        found = _diff(a, b)
        if found:
            t = a.header.stamp.sec + a.header.stamp.nanosec / 1e9
            return i + 1, f"command #{i} (recorded seq {a.seq}, stamp {t:.3f} s): {found}"
    if len(recorded) != len(replayed):
        return n, (f"the controller sent {len(replayed)} commands, the bag holds "
                   f"{len(recorded)}")
    return n, None


def _run_info(bag: bagio.RunBag):
    """The run description the plant published for this bag's run (from its metadata)."""
    from vega_bags.bagcheck import run_context

    ctx = run_context(bag)
    if ctx.info is None:
        raise bagio.BagError(f"bag {bag.path}: no usable scenario in the metadata "
                             f"({'; '.join(ctx.problems) or 'missing'}); cannot replay the "
                             f"controller")
    return ctx.info


def _table_path(bag: bagio.RunBag, table: str | Path | None) -> tuple[Path, list[str]]:
    """The table to replay with (given, else the recorded one) and remarks about it."""
    from vega_gnc.controller_table import load_controller_table

    notes = []
    if table is None:
        recorded = bag.metadata.get(bagio.META_CONTROLLER_TABLE)
        if not recorded:
            raise BadInput(f"bag {bag.path}: no controller table in the metadata; pass "
                           f"--table FILE")
        path = Path(recorded)
    else:
        path = Path(table)
    load_controller_table(path)  # a bad table: one line (BadInput), exit 2
    sha = bag.metadata.get(bagio.META_CONTROLLER_TABLE_SHA256)
    if sha and bagio.file_sha256(path) != sha:
        notes.append(f"{path} differs from the table the run was recorded with "
                     f"(SHA-256 {sha[:12]}…)")
    return path, notes


def _guidance_setting(bag: bagio.RunBag) -> tuple[str, list[str]]:
    """The ``guidance_reference`` parameter the recorded run flew ("none" for a bag recorded
    before the guidance existed) and remarks about it."""
    from vega_gnc.guidance_reference import NO_GUIDANCE, load_guidance_reference

    recorded = bag.metadata.get(bagio.META_GUIDANCE_REFERENCE, NO_GUIDANCE)
    if recorded == NO_GUIDANCE:
        return NO_GUIDANCE, []
    load_guidance_reference(recorded)  # a missing or bad file: one line (BadInput), exit 2
    sha = bag.metadata.get(bagio.META_GUIDANCE_REFERENCE_SHA256)
    if sha and bagio.file_sha256(recorded) != sha:
        return recorded, [f"{recorded} differs from the guidance reference the run was "
                          f"recorded with (SHA-256 {sha[:12]}…)"]
    return recorded, []


class _ControllerProcess:
    """The ``tvc_controller`` executable as a child process (the orchestrator's supervisor)."""

    def __init__(self, params, workdir: Path, env):
        from vega_bringup import orchestrate
        from vega_bringup.executables import find_executable

        workdir.mkdir(parents=True, exist_ok=True)
        params_file = workdir / "params.yaml"
        params_file.write_text(orchestrate.params_yaml(params), encoding="utf-8")
        spec = orchestrate.NodeSpec("vega_gnc", "tvc_controller")
        command = orchestrate.node_command(find_executable(spec.package, spec.executable),
                                           params_file)
        self.supervisor = orchestrate.Supervisor(
            [(spec, command)], orchestrate.RunLayout(workdir), env,
            participants=params.participants, barrier_timeout_s=params.barrier_timeout_s,
            watch_barrier=False)
        self.supervisor.start()
        self.process = self.supervisor.processes[0]

    @property
    def returncode(self):
        return self.process.returncode

    def failure(self) -> str:
        """The node's exit status and its last log line."""
        from vega_bringup.orchestrate import describe_status

        line = self.process.last_log_line()
        text = f"tvc_controller ended with {describe_status(self.returncode)}"
        return f"{text}: {line}" if line else text

    def wait(self, timeout_s: float) -> int | None:
        try:
            return self.process.popen.wait(timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def stop(self) -> None:
        self.supervisor.stop()


class _Failed(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def _feed(controller: _ControllerProcess, barrier, executor, ins_pub, ins_raw, samples_ms,
          period_ms: int, received: list, barrier_timeout_s: float, say) -> _Failed | None:
    """Start barrier, then the measurements in order, waiting for each expected command.

    Returns None when the controller answered every measurement on the controller period
    and ended normally, else the failure (code 2: it rejected its input; 1: it failed,
    stalled or ended early — the comparison then names what is missing).
    """
    def spin(timeout_s):
        executor.spin_once(timeout_sec=timeout_s)

    def failed():
        code = controller.returncode
        if code is not None and code != 0:
            return _Failed(2 if code == 2 else 1, controller.failure())
        return None

    say("controller started; waiting for the start barrier")
    if not barrier.wait(spin, barrier_timeout_s, stop=lambda: controller.returncode is not None):
        return failed() or _Failed(1, f"start barrier: {barrier.describe_missing()}")
    t0 = time.monotonic()
    expected = 0
    for k, data in enumerate(ins_raw):
        ins_pub.publish(bytes(data))
        if samples_ms[k] % period_ms:
            continue
        expected += 1
        deadline = time.monotonic() + STALL_TIMEOUT_S
        while len(received) < expected:
            if failed() or controller.returncode == 0 or time.monotonic() > deadline:
                break
            spin(0.05)
        if len(received) < expected:
            return failed() or _Failed(1, f"no command for measurement #{k} "
                                          f"(sample {samples_ms[k] / 1e3:.3f} s) within "
                                          f"{STALL_TIMEOUT_S:g} s")
    _flush([ins_pub], 5.0)
    controller.wait(10.0)
    say(f"{len(ins_raw)} measurements replayed in {time.monotonic() - t0:.2f} s")
    return failed()


def check_controller(path: str | Path, table: str | Path | None = None, *,
                     barrier_timeout_s: float = 60.0,
                     progress: Callable[[str], None] | None = None) -> ControllerCheck:
    """Feed a bag's INS measurements to a fresh controller node; compare its commands.

    Parameters
    ----------
    path
        Run bag directory.
    table
        Controller table (default: the one recorded in the bag's metadata).
    barrier_timeout_s
        Start-barrier timeout of the controller and of the checker [s].
    progress
        Called with one-line status messages.

    Returns
    -------
    ControllerCheck
        The verdict (``exit_code`` 0 identical, 1 different).

    Raises
    ------
    BadInput, OSError
        Bad bag (:class:`~vega_bags.bagio.BagError`), table or metadata, or the controller
        rejected its input (exit status 2).
    """
    from std_msgs.msg import String

    from vega_bus.barrier import StartBarrier

    from vega_bringup import orchestrate, rosenv

    say = progress or (lambda line: None)
    bag = bagio.read_run_bag(path)
    info = _run_info(bag)
    table_path, notes = _table_path(bag, table)
    guidance, guidance_notes = _guidance_setting(bag)
    notes += guidance_notes
    info = dataclasses.replace(info, guidance=guidance)   # the controller flies the bag's
    ins_raw = [d for _, _, d in bagio.iter_raw_messages(path, {topics.INS.name})]
    recorded = [d for _, _, d in bagio.iter_raw_messages(path, {topics.TVC_CMD.name})]
    samples_ms = (bag[topics.INS.name]["sample_stamp_ns"] // NS_PER_MS
                  if bag.has(topics.INS.name) else np.zeros(0, np.int64))
    if len(ins_raw) == 0:
        raise bagio.BagError(f"bag {bag.path}: no {topics.INS.name} messages to replay")
    participants = ("tvc_controller", CHECKER_NAME)
    params = orchestrate.RunParameters(
        scenario=info.scenario, seed=info.seed, realtime=False,
        controller_table=str(table_path.resolve()), bag_path="", participants=participants,
        barrier_timeout_s=float(barrier_timeout_s))
    received: list[bytes] = []
    with _ros_node(CHECKER_NAME) as (node, executor):
        run_pub = node.create_publisher(String, topics.RUN.name, qos.control_qos())
        ins_pub = node.create_publisher(topics.message_class(topics.INS.type_name),
                                        topics.INS.name, qos.data_qos())
        cmd_sub = node.create_subscription(topics.message_class(topics.TVC_CMD.type_name),
                                           topics.TVC_CMD.name, received.append,
                                           qos.data_qos(), raw=True)
        # the controller's barrier waits for the recorder's seat on its diagnostics too
        diag_sub = node.create_subscription(
            topics.message_class(topics.DIAGNOSTICS.type_name), topics.DIAGNOSTICS.name,
            lambda _: None, qos.data_qos(), raw=True)
        run_pub.publish(String(data=info.to_json()))
        # matched both ways before the run starts: the controller hears the measurements,
        # and this node hears the controller's commands from the first one
        barrier = StartBarrier(node, participants, publishers=[ins_pub],
                               subscriptions=[cmd_sub, diag_sub],
                               subscribers={topics.INS.name: ("tvc_controller",)})
        workdir = Path(tempfile.mkdtemp(prefix="vega-replay-"))
        controller = _ControllerProcess(params, workdir, rosenv.ros_environment())
        try:
            failure = _feed(controller, barrier, executor, ins_pub, ins_raw, samples_ms,
                            info.timing.controller_period_ms, received, barrier_timeout_s, say)
        finally:
            controller.stop()
            shutil.rmtree(workdir, ignore_errors=True)
    if failure is not None and failure.code == 2:
        raise BadInput(str(failure))
    compared, diff = first_difference(recorded, received)
    if failure is not None:
        diff = f"{failure}; {diff}" if diff else str(failure)
    return ControllerCheck(len(recorded), len(received), compared, diff, str(table_path),
                           tuple(notes))
