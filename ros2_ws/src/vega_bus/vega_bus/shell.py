"""The ROS shell every VEGA node shares: start-up, parameters, waiting, exit codes, signals.

Exit codes of every node (the contract the orchestrator relies on):

* 0 — the run finished (the node sent or received its last message of the run), or a stop
  was requested with SIGINT/SIGTERM (one line on stderr says so; the recorder closes its bag
  first, so it stays readable);
* 1 — run failure: start-barrier timeout (the line names the missing participants), a
  sequence gap, a stamp out of the lockstep schedule, a lockstep stall (no expected input for
  ``stall_timeout_s``);
* 2 — bad input: a parameter of the wrong type or value, an unknown scenario, a malformed
  controller table (:class:`vega_core.errors.BadInput`), or a file that cannot be read or
  written (``OSError``); reported before the barrier.

Every failure is one line on stderr, ``<node>: <what>``. An exception of any other type is a
defect of the node: its traceback, then the one line ``<node>: <type>: <message>``, exit 1.

No executor: :meth:`Shell.spin_once` waits on one rcl wait set holding the node's
subscriptions and then *drains* every ready subscription (takes until empty), calling its
callback per message, so one wake-up handles everything that arrived. Measured on the
5-process 100 s SIL flight (A/B, same loaded machine): the same CPU time and speed as rclpy's
EventsExecutor driven by ``spin_once`` (docs/ENVIRONMENT_SETUP.md: its ``spin()`` is
broken in the PyPI wheels), without depending on rclpy's experimental API. rclpy's own
signal handlers are replaced by a flag that the wait loops poll, so that a stop never
interrupts a bag write halfway.

Parameters: :meth:`Shell.param` declares a parameter of :mod:`vega_bus.parameters` (default,
check, read-only descriptor). From the first one until the start barrier is complete, each
:meth:`Shell.spin_once` also lets rclpy's public executor answer the node's parameter
services once (no wait), so ``ros2 param describe`` works on a node waiting for its peers;
in flight nothing but the wait set runs.
"""

from __future__ import annotations

import faulthandler
import math
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any, Callable

from vega_core.errors import BadInput, one_line

from vega_bus import network, parameters

__all__ = ["EXIT_OK", "EXIT_RUN_FAILURE", "EXIT_BAD_INPUT", "DUMP_STACKS_SIGNAL",
           "TEARDOWN_WATCHDOG_SIGNAL", "NodeExit",
           "Stopped", "StopFlag", "Shell", "RecorderProgress", "run_node", "SeqCheck",
           "decoded"]

EXIT_OK = 0
EXIT_RUN_FAILURE = 1
EXIT_BAD_INPUT = 2

DEFAULT_STALL_TIMEOUT_S = parameters.STALL_TIMEOUT_S.default

DUMP_STACKS_SIGNAL = signal.SIGUSR1
"""Signal on which a node writes the Python stacks of all its threads to stderr (its log) and
goes on (:mod:`faulthandler`)."""


class NodeExit(Exception):
    """Leave the node with ``code`` and the one-line ``message``."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code
        self.message = message


class Stopped(Exception):
    """A stop was requested (SIGINT/SIGTERM)."""


class SeqCheck:
    """Sequence-number check of one input topic: seq must run 0, 1, 2, … without a gap."""

    def __init__(self, topic: str):
        self.topic = topic
        self.next = 0

    def __call__(self, seq: int) -> None:
        """Accept ``seq`` or raise :class:`NodeExit` (1) naming the gap."""
        if seq != self.next:
            raise NodeExit(EXIT_RUN_FAILURE,
                           f"sequence gap on {self.topic}: expected seq {self.next}, got {seq}")
        self.next += 1


NODE_UMASK = 0o077
"""File-mode creation mask of every node: files it creates are readable and writable by its
user only (Fast DDS sets its shared-memory segments' mode itself:
:func:`restrict_shared_memory`)."""


def _params_section_problem(tree, where: str) -> str | None:
    """Why a node-parameters YAML mapping is not one rcl reads (None if it is): every entry a
    node name/pattern holding ``ros__parameters`` (a mapping) or further such entries."""
    if not isinstance(tree, dict) or not tree:
        return f"{where or 'the top level'} must be a mapping of node names"
    for key, value in tree.items():
        here = f"{where}/{key}" if where else str(key)
        if not isinstance(value, dict):
            return f"'{here}' must hold 'ros__parameters' (a mapping), got {value!r}"
        if "ros__parameters" in value:
            if not isinstance(value["ros__parameters"], dict) or len(value) != 1:
                return f"'{here}' must hold only 'ros__parameters', a mapping"
            continue
        problem = _params_section_problem(value, here)
        if problem:
            return problem
    return None


def check_params_files(argv: list[str]) -> None:
    """Read every ``--params-file FILE`` of the ROS arguments before rcl does, so that a
    missing, oversized (1 MiB) or malformed file is one line (:class:`BadInput`, exit 2)
    instead of rcl's error line and a traceback."""
    from vega_core.documents import load_yaml
    from vega_core.errors import BadFile

    for i, arg in enumerate(argv[:-1]):
        if arg == "--params-file":
            path = argv[i + 1]
            problem = _params_section_problem(load_yaml(path, "node parameters"), "")
            if problem:
                raise BadFile(f"{path}: node parameters file: {problem}")


def restrict_shared_memory() -> int:
    """Make the shared-memory files this process has mapped (Fast DDS's segments in
    /dev/shm, created 0644) and owns readable and writable by its user only; the number
    changed. The run's other nodes run as the same user and keep their access."""
    changed = 0
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return 0
    uid = os.getuid()
    for path in {line.split(None, 5)[-1] for line in maps.splitlines()
                 if " /dev/shm/fastrtps_" in line}:
        try:
            if os.stat(path).st_uid == uid:
                os.chmod(path, 0o600)
                changed += 1
        except OSError:
            continue
    return changed


class StreamCheck:
    """An input topic of the run has one publisher, and its messages come in that publisher's
    order: a message is refused (:class:`NodeExit` (1), never handed on) if the subscription
    matches more than one publisher, or if its publication sequence number (rclpy's
    MessageInfo, set by the sending DDS writer: 1, 2, 3, … per writer) is not the next one.
    A foreign publisher on the topic (another process on the host, docs/SECURITY.md) so fails
    the run before any of its messages is used: its own numbers restart at 1, and it is a
    second matched publisher from its match on. A message taken outside :meth:`Shell.spin_once`
    (rclpy's executor answering parameter requests before the barrier) carries no
    MessageInfo and is checked for the publisher count only.

    Call it from the subscription's callback, before using the message."""

    def __init__(self, shell: "Shell", topic: str):
        self.shell = shell
        self.topic = topic
        self.subscription = None
        self.taken = 0

    def __call__(self) -> None:
        """Accept the message being handled or raise :class:`NodeExit` (1) naming why not."""
        subscription = self.subscription
        if subscription is not None:
            count = subscription.get_publisher_count()     # public rclpy API
            if count > 1:
                raise NodeExit(EXIT_RUN_FAILURE,
                               f"refused a message on {self.topic}: {count} publishers match "
                               f"this subscription, the run has one: a foreign publisher is "
                               f"on the bus")
        number = self.shell.publication_number
        expected = self.taken + 1
        if number is not None and number != expected:
            raise NodeExit(EXIT_RUN_FAILURE,
                           f"refused a message on {self.topic}: publication sequence number "
                           f"{number}, expected {expected}: not the stream of the run's "
                           f"publisher (a foreign or restarted publisher)")
        self.taken = expected


def decoded(decode: Callable[[bytes], Any], data, topic: str):
    """``decode(data)``; a message it refuses (``ValueError``, e.g. a stamp off the millisecond
    grid or bytes of another layout) fails the run: :class:`NodeExit` (1) ``<topic>: <why>``."""
    try:
        return decode(data)
    except ValueError as exc:
        raise NodeExit(EXIT_RUN_FAILURE, f"{topic}: {exc}") from None


class StopFlag:
    """SIGINT and SIGTERM set a flag (the signal's name) instead of acting at once.

    Installed before anything slow happens (:class:`Shell` installs it before it imports
    rclpy), so that a stop at any point of a node's life is polled by its wait loops
    (:meth:`Shell.spin_once` raises :class:`Stopped`) and ends it cleanly, exit 0: never
    rclpy's handler, which shuts the context down under a running wait (``RCLError: context
    is not valid``), and never Python's default SIGTERM action (the process dies without
    closing its bag) once the flag is in place. Before it — the interpreter's start and the
    import of the node's module, ≈ 0.1–0.5 s (docs/TESTING.md, "Flaky tests") — SIGTERM still
    ends the process by the default action, status −15, nothing written.
    """

    def __init__(self):
        self.signal_name: str | None = None
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._on_signal)
        # a hung node's Python stacks on request (the orchestrator sends SIGUSR1 before it
        # stops a node that did not end): faulthandler writes them from its C handler, so
        # they come out even when the main thread is blocked in C holding the GIL
        stream = _fault_stream()
        if stream is not None:
            faulthandler.register(DUMP_STACKS_SIGNAL, file=stream, all_threads=True)

    def _on_signal(self, signum, _frame) -> None:
        self.signal_name = signal.Signals(signum).name


class Shell:
    """rclpy context, one node and its wait set, with a stop flag (:class:`StopFlag`).

    Parameters
    ----------
    name
        Node name (= executable name).
    argv
        Command line (``--ros-args …`` is handed to rclpy).
    """

    def __init__(self, name: str, argv: list[str]):
        # the flag first, before rclpy is imported: a signal from here on is a clean stop
        self._stop = StopFlag()
        import rclpy
        from rclpy.impl.implementation_singleton import rclpy_implementation
        from rclpy.signals import SignalHandlerOptions

        self.name = name
        self.failure: NodeExit | None = None
        # what the node creates (the recorder's bag, logs) is for the user who runs it only;
        # Fast DDS's shared-memory segments ignore the mask: restrict_shared_memory
        os.umask(NODE_UMASK)
        if network.enforce():
            print(f"{name}: ROS_DOMAIN_ID was not set; using {network.HAND_START_DOMAIN_ID}, "
                  f"the default for nodes started by hand", file=sys.stderr)
        check_params_files(argv)
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name)
        self._rclpy = rclpy_implementation
        # answers ros2 param requests from the first declared parameter until the barrier
        self._parameter_services: _ParameterServices | None = None
        self._barrier_passed = False
        self._wait_set = None
        self._waited: tuple = ()
        self.stall_timeout_s = DEFAULT_STALL_TIMEOUT_S
        # > 0: wait_until sleeps this long after each wake-up, so that the next one takes many
        # messages at once (for a node off the lockstep's critical path: the recorder)
        self.batch_s = 0.0
        # publication sequence number of the message being handled (StreamCheck); None
        # outside spin_once
        self.publication_number: int | None = None

    @property
    def signal_name(self) -> str | None:
        """The name of the stop signal received (SIGINT, SIGTERM), or None."""
        return self._stop.signal_name

    @property
    def stopping(self) -> bool:
        """True once SIGINT or SIGTERM arrived."""
        return self._stop.signal_name is not None

    def spin_once(self, timeout_s: float) -> None:
        """Wait (at most ``timeout_s``) until a subscription holds messages, then take every
        message of every ready subscription and call its callback; re-raise a callback's
        failure (:meth:`guard`) and :class:`Stopped` on a signal."""
        subs = tuple(self.node.subscriptions)
        if subs != self._waited:
            self._wait_set = self._rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0,
                                                 self.node.context.handle)
            self._waited = subs
        ws = self._wait_set
        ws.clear_entities()
        for sub in subs:
            ws.add_subscription(sub.handle)
        ws.wait(int(timeout_s * 1e9))
        ready = ws.get_ready_entities("subscription")
        if ready:
            for sub in subs:
                if sub.handle.pointer in ready:
                    take, msg_type, raw, callback = (sub.handle.take_message, sub.msg_type,
                                                     sub.raw, sub.callback)
                    while self.failure is None:
                        got = take(msg_type, raw)
                        if got is None:
                            break
                        self.publication_number = got[1]["publication_sequence_number"]
                        callback(got[0])
                        self.publication_number = None
        if self._parameter_services is not None:
            self._parameter_services.serve()
        if self.failure is not None:
            raise self.failure
        if self.signal_name is not None:
            raise Stopped()

    def guard(self, callback: Callable) -> Callable:
        """Wrap a subscription callback: a :class:`NodeExit` it raises is stored and raised
        by the next :meth:`spin_once` (never raised through rclpy)."""
        def wrapped(msg):
            if self.failure is not None:
                return
            try:
                callback(msg)
            except NodeExit as exc:
                self.failure = exc
        return wrapped

    def wait_until(self, done: Callable[[], bool], what: Callable[[], str] | str,
                   timeout_s: float | None = None, failure: str = "lockstep stall",
                   progress: Callable[[], Any] | None = None) -> None:
        """Spin until ``done()``.

        Raises :class:`NodeExit` (1) ``<failure>: waited … for <what>`` after ``timeout_s``
        (default: the stall timeout); with ``progress``, the time counts from the last change
        of ``progress()`` (a long wait that keeps advancing, like the recorder's, is no stall).
        """
        if done():
            return
        limit = self.stall_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + limit
        last = progress() if progress is not None else None
        while True:
            self.spin_once(0.1)
            if done():
                return
            if self.batch_s:
                time.sleep(self.batch_s)
            if progress is not None:
                now = progress()
                if now != last:
                    last = now
                    deadline = time.monotonic() + limit
            if time.monotonic() >= deadline:
                text = what() if callable(what) else what
                raise NodeExit(EXIT_RUN_FAILURE, f"{failure}: waited {limit:g} s for {text}")

    def record_inbox(self, msg_type, topic: str, qos, decode: Callable[[bytes], Any]) -> list:
        """Subscribe to ``topic`` taking the serialised bytes (``raw=True``); return the list
        that receives ``decode(bytes)`` — a record of :mod:`vega_bus.records`
        (:func:`vega_bus.cdr.decoder`: no message object is built, docs/SIL_SPEED.md) — in
        arrival order, after the stream check (:class:`StreamCheck`: one publisher, its
        publication order) and the sequence check (:class:`SeqCheck`; a gap fails the run).
        A message ``decode`` refuses fails the run (:func:`decoded`)."""
        box: list = []
        check = SeqCheck(topic)
        stream = StreamCheck(self, topic)

        def on_message(data):
            stream()
            record = decoded(decode, data, topic)
            check(record.seq)
            box.append(record)

        stream.subscription = self.node.create_subscription(
            msg_type, topic, self.guard(on_message), qos, raw=True)
        return box

    def checked_subscription(self, msg_type, topic: str, callback: Callable, qos,
                             raw: bool = False):
        """A subscription whose callback runs only for messages that pass the
        :class:`StreamCheck` (guarded: :meth:`guard`)."""
        stream = StreamCheck(self, topic)

        def on_message(msg):
            stream()
            callback(msg)

        stream.subscription = self.node.create_subscription(
            msg_type, topic, self.guard(on_message), qos, raw=raw)
        return stream.subscription

    # -------------------------------------------------------------------- parameters
    def param(self, name: str) -> Any:
        """Declare node parameter ``name`` as :data:`vega_bus.parameters.PARAMETERS` defines
        it (its default, and a read-only descriptor with its description, unit, constraints
        and range) and return its value.

        Raises
        ------
        NodeExit
            (2) one line if the value has the wrong type (rclpy's reason) or is outside its
            domain (``parameter '<name>': <problem> (got <value>)``, the table's check).
        KeyError
            If ``name`` is not in the table (a programming error).
        """
        spec = parameters.spec(name)
        if self._parameter_services is None and not self._barrier_passed:
            self._parameter_services = _ParameterServices(self.node)
        try:
            value = self.node.declare_parameter(name, spec.default, _descriptor(spec)).value
        except Exception as exc:  # noqa: BLE001 - rclpy raises several types for bad values
            value = self._out_of_range(spec, exc)
        problem = spec.problem(value)
        if problem:
            raise NodeExit(EXIT_BAD_INPUT, f"parameter '{name}': {problem} (got {value!r})")
        return value

    def _out_of_range(self, spec: parameters.ParameterSpec, exc: Exception) -> Any:
        """The value rclpy rejected, if only the descriptor's range rejected it (then the
        table's check words the one line); else :class:`NodeExit` (2) with rclpy's reason."""
        if spec.integer_range is not None:
            try:
                value = self.node.declare_parameter(
                    spec.name, spec.default, _descriptor(spec, ranged=False)).value
            except Exception:  # noqa: BLE001 - the type is wrong too: rclpy's reason below
                pass
            else:
                if spec.problem(value):
                    return value
        raise NodeExit(EXIT_BAD_INPUT, f"parameter '{spec.name}': {one_line(exc)}") from None

    def run_params(self) -> tuple[str, int]:
        """The ``scenario`` (name or YAML path) and ``seed`` (−1: the scenario's) parameters."""
        return self.param("scenario"), self.param("seed")

    def common_params(self) -> tuple[tuple[str, ...], float]:
        """The ``participants`` and ``barrier_timeout_s`` parameters (and ``stall_timeout_s``,
        which sets :attr:`stall_timeout_s`)."""
        participants = tuple(self.param("participants"))
        timeout = self.param("barrier_timeout_s")
        self.stall_timeout_s = self.param("stall_timeout_s")
        return participants, timeout

    def open_barrier(self, participants, publishers):
        """Create the start barrier's entities (:class:`vega_bus.barrier.StartBarrier`) for
        ``publishers`` and every subscription of the node, without waiting: a node that
        creates its publishers, subscriptions and this first, then does its slow set-up
        (parameter tracks, the plant), lets DDS discovery run meanwhile in the middleware's
        threads (docs/SIL_SPEED.md); :meth:`barrier` with ``opened=`` then waits."""
        from vega_bus.barrier import StartBarrier

        return StartBarrier(self.node, participants, publishers,
                            [s for s in self.node.subscriptions])

    def barrier(self, participants, publishers, timeout_s: float, opened=None):
        """Run the start barrier (:class:`vega_bus.barrier.StartBarrier`) for ``publishers``
        and every subscription of the node (or the one :meth:`open_barrier` created:
        ``opened``); :class:`NodeExit` (1) naming the missing participants on timeout."""
        barrier = opened if opened is not None else self.open_barrier(participants, publishers)
        if not barrier.wait(self.spin_once, timeout_s):
            raise NodeExit(EXIT_RUN_FAILURE, barrier.describe_missing())
        self._barrier_passed = True
        self._stop_parameter_services()
        restrict_shared_memory()   # every segment of the run exists once the barrier passed
        return barrier

    def _stop_parameter_services(self) -> None:
        if self._parameter_services is not None:
            self._parameter_services.close()
            self._parameter_services = None

    def recorder_progress(self, participants) -> "RecorderProgress":
        """Subscribe to the recorder's progress (if "recorder" is a participant)."""
        return RecorderProgress(self, participants)

    def finish(self, publishers, progress: "RecorderProgress", final: int) -> None:
        """End of the run, after this node's last message: with a recorder, wait until it
        reports ``final`` truth messages written (then every message of the run has reached
        it, and every node has had its last input, since each node's last output follows its
        last input); without one, :meth:`flush`. Waiting for the report instead of the DDS
        acknowledgements saves ≈ 2.3 s per run: Fast DDS acknowledges on its heartbeat.
        A participant in the recorder's seat that publishes no progress (the controller check
        of ``vega replay``), or a recorder that left, means :meth:`flush` instead."""
        if progress.linked():
            self.wait_until(lambda: progress.count >= final or not progress.linked(),
                            lambda: f"the recorder's final report ({progress.count}/{final} "
                                    f"truth messages written)",
                            progress=lambda: progress.count)
        if progress.count < final:
            self.flush(publishers)

    def flush(self, publishers, timeout_s: float | None = None) -> None:
        """Wait until every subscriber acknowledged what ``publishers`` sent, so that exiting
        right after the last message loses nothing (a lagging recorder may still be a few
        hundred messages behind, and Fast DDS repairs a lost sample only at its next heartbeat,
        every few seconds). Gives up after ``timeout_s`` (default: the stall timeout)."""
        from rclpy.duration import Duration

        limit = self.stall_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + limit
        for pub in publishers:
            left = max(0.0, deadline - time.monotonic())
            pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))

    def close(self) -> None:
        """Destroy the node and shut rclpy down (idempotent)."""
        import rclpy

        try:
            self._wait_set = None
            self._stop_parameter_services()
            self.node.destroy_node()
        finally:
            rclpy.try_shutdown()


class RecorderProgress:
    """The latest count the recorder reported on ``/vega/recorded`` (:mod:`vega_bus.schedule`).

    Subscribed only when "recorder" is a participant; :meth:`linked` tells whether a
    publisher of the reports is matched (the real recorder is; a tool in its seat may not be).
    """

    def __init__(self, shell: Shell, participants):
        from std_msgs.msg import UInt32

        from vega_bus.qos import data_qos
        from vega_bus.topics import RECORDED

        self.count = 0
        self._sub = None
        if "recorder" in participants:
            # stream-checked: a forged report could let the plant run ahead of the recorder
            self._sub = shell.checked_subscription(UInt32, RECORDED.name, self._on_report,
                                                   data_qos())

    def _on_report(self, msg) -> None:
        self.count = max(self.count, int(msg.data))

    def linked(self) -> bool:
        """True while a publisher of ``/vega/recorded`` is matched."""
        return self._sub is not None and self._sub.get_publisher_count() > 0


def _descriptor(spec: parameters.ParameterSpec, ranged: bool = True):
    """The rclpy ``ParameterDescriptor`` of a table entry (:mod:`vega_bus.parameters`):
    description with unit and default, additional constraints, integer range, read-only (a
    node reads its parameters once, at start-up)."""
    from rcl_interfaces.msg import IntegerRange, ParameterDescriptor

    descriptor = ParameterDescriptor(description=spec.full_description,
                                     additional_constraints=spec.constraints, read_only=True)
    if ranged and spec.integer_range is not None:
        low, high = spec.integer_range
        descriptor.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
    return descriptor


class _ParameterServices:
    """Answers the node's parameter services (``ros2 param list/get/describe``) from its
    first declared parameter until the start barrier is complete.

    The shell has no executor (:meth:`Shell.spin_once`), so nothing would answer them: this
    runs rclpy's public ``SingleThreadedExecutor.spin_once`` (no wait) after each of the
    shell's own waits, from the first :meth:`Shell.param` until the start barrier is
    complete — a node started by hand waits there for its peers. It never runs in flight (no
    cost in the lockstep); a request that arrives then is not answered. A subscription
    message it takes goes to the same callback as in :meth:`Shell.spin_once`.
    """

    def __init__(self, node):
        from rclpy.executors import SingleThreadedExecutor

        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)
        self._node = node

    def serve(self) -> None:
        """Handle what is ready now (one request or message), without waiting."""
        self._executor.spin_once(timeout_sec=0.0)

    def close(self) -> None:
        """Detach the node from the executor and shut the executor down."""
        self._executor.remove_node(self._node)
        self._executor.shutdown(timeout_sec=0.0)


def run_node(name: str, body: Callable[[Shell], int | None], argv: list[str] | None = None
             ) -> int:
    """Run ``body(shell)`` as node ``name`` and exit with the contract's code.

    ``body`` returns normally when the run is finished (exit 0). :class:`NodeExit`,
    :class:`Stopped` (SIGINT/SIGTERM: exit 0), KeyboardInterrupt and rclpy's
    ExternalShutdownException are turned into one line on stderr and the exit code;
    :class:`~vega_core.errors.BadInput` and ``OSError`` into one line and exit 2. Any other
    exception is a defect: its traceback, then one line naming its type, exit 1 (the last
    line is what the orchestrator reports).

    Without ``argv`` (the node's executable: its ``main`` passes none) the process ends here,
    with the code, once stdout and stderr are flushed (:func:`os._exit`): the interpreter's
    own teardown — finalising every module, numba's LLVM, rclpy — takes 0.3–0.7 s and holds
    nothing of the run (the bag is closed, the middleware shut down), while the run waits for
    the last node to exit (docs/SIL_SPEED.md). With ``argv`` (a test, in-process), the code
    is returned.
    """
    entry_point = argv is None
    argv = sys.argv if argv is None else argv
    shell = None
    code = EXIT_OK
    try:
        shell = Shell(name, argv)
        result = body(shell)
        code = EXIT_OK if result is None else int(result)
    except NodeExit as exc:
        print(f"{name}: {exc.message}", file=sys.stderr)
        code = exc.code
    except (BadInput, OSError) as exc:
        print(f"{name}: {one_line(exc)}", file=sys.stderr)
        code = EXIT_BAD_INPUT
    except (Stopped, KeyboardInterrupt):
        why = shell.signal_name if shell is not None and shell.signal_name else "SIGINT"
        print(f"{name}: stopped by {why}", file=sys.stderr)
        code = EXIT_OK
    except Exception as exc:  # noqa: BLE001 - ExternalShutdownException, and defects
        if type(exc).__name__ == "ExternalShutdownException":
            print(f"{name}: stopped (ROS shutdown)", file=sys.stderr)
            code = EXIT_OK
        else:
            traceback.print_exc()
            print(f"{name}: {type(exc).__name__}: {one_line(exc)}", file=sys.stderr)
            code = EXIT_RUN_FAILURE
    finally:
        if shell is not None:
            _close_with_watchdog(name, shell, code)
    sys.stdout.flush()
    sys.stderr.flush()
    if entry_point:
        os._exit(code)
    return code


SHUTDOWN_GRACE_S = 10.0
"""How long a node may spend destroying its middleware entities after its work is done (s).

Measured: rmw shutdown normally takes well under 1 s; once in about 20 runs on a loaded
machine Fast DDS hung in ``rmw_destroy_node`` (``DomainParticipant::set_listener``) for
minutes. Everything of the run is delivered and the bag closed before this point, so the
process then ends without finishing the teardown, with the exit code it already had."""

HARD_SHUTDOWN_MARGIN_S = 3.0
"""The backstop of :data:`SHUTDOWN_GRACE_S` that needs no GIL comes this much later (s).

A teardown blocked in C code that holds the GIL starves the watchdog thread: seen in CI,
``ins_sensor`` silent for 30 s after a complete run (its bag complete), and in a soak of the
test suite (two copies on two cores) the INS and the actuator with their main thread in
rclpy's ``Node.destroy_node`` → ``destroy_when_not_in_use()`` (rmw_destroy_node) for more than
13 s. Then :func:`faulthandler.dump_traceback_later` (a C thread) writes the Python stacks to
stderr and, :data:`EXIT_AFTER_STACKS_S` later, a POSIX timer of the C library
(:func:`_exit_timer`) ends the process with the exit code the run already had — 0 for a
complete run. Where POSIX timers cannot be used, a failed node is ended by faulthandler (exit
1) and a complete one by :data:`TEARDOWN_WATCHDOG_SIGNAL`'s default action, which the
orchestrator reads as "finished, teardown hung" (status 0 with a warning)."""

TEARDOWN_WATCHDOG_SIGNAL = signal.SIGALRM
"""The signal that ends a node whose middleware teardown hung with the GIL held after a
complete run where no POSIX timer could be armed (:data:`HARD_SHUTDOWN_MARGIN_S`)."""


def _fault_stream():
    """The stream :mod:`faulthandler` writes to: stderr if it is a real file (a node's log),
    else the process's original stderr (in-process use with stderr captured), else None (no
    stacks, and a failed node has no GIL-free backstop; a finished one still has SIGALRM's)."""
    for stream in (sys.stderr, sys.__stderr__):
        try:
            if stream is not None:
                stream.fileno()
                return stream
        except (AttributeError, OSError, ValueError):
            continue
    return None


def _close_with_watchdog(name: str, shell: Shell, code: int) -> None:
    """``shell.close()``, but exit the process with ``code`` if it hangs (see above)."""
    def give_up():
        print(f"{name}: middleware shutdown hung for {SHUTDOWN_GRACE_S:g} s; exiting "
              f"without it", file=sys.stderr)
        sys.stderr.flush()
        sys.stdout.flush()
        os._exit(code)

    watchdog = threading.Timer(SHUTDOWN_GRACE_S, give_up)
    watchdog.daemon = True
    watchdog.start()
    hard_s = SHUTDOWN_GRACE_S + HARD_SHUTDOWN_MARGIN_S
    stream = _fault_stream()
    try:
        cancel_exit = _exit_timer(hard_s + EXIT_AFTER_STACKS_S, code)
    except (OSError, AttributeError, TypeError, ValueError):
        cancel_exit = None          # no POSIX timers here: the signal / faulthandler backstop
    if stream is not None:
        faulthandler.dump_traceback_later(hard_s, exit=cancel_exit is None and code != EXIT_OK,
                                          file=stream)
    # signal dispositions can be set from the main thread only (a node's body runs there)
    alarm = cancel_exit is None and code == EXIT_OK and \
        threading.current_thread() is threading.main_thread()
    if alarm:
        signal.signal(TEARDOWN_WATCHDOG_SIGNAL, signal.SIG_DFL)
        signal.alarm(math.ceil(hard_s) + 1)
    try:
        shell.close()
    except Exception:  # noqa: BLE001 - best effort at exit
        pass
    finally:
        if cancel_exit is not None:
            cancel_exit()
        if alarm:
            signal.alarm(0)
        faulthandler.cancel_dump_traceback_later()
        watchdog.cancel()


EXIT_AFTER_STACKS_S = 0.5
"""How long after the GIL-free stack dump the GIL-free exit comes (s): time for the dump."""


def _exit_timer(seconds: float, code: int) -> Callable[[], None]:
    """Arm a POSIX timer (``timer_create`` with SIGEV_THREAD, CLOCK_MONOTONIC) whose expiry
    calls the C library's ``_exit(code)`` in a thread of the C library's own: it ends the
    process with ``code`` even while the main thread holds the GIL in C code (the middleware
    teardown hang of :data:`HARD_SHUTDOWN_MARGIN_S`), where no Python code can run. Returns
    the function that disarms it.

    Raises
    ------
    OSError
        If the timer cannot be created or armed (AttributeError/TypeError where the C
        library has no such functions: the caller falls back to the signal backstop).
    """
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)

    class Sigval(ctypes.Union):
        _fields_ = [("sival_int", ctypes.c_int), ("sival_ptr", ctypes.c_void_p)]

    class SigevThread(ctypes.Structure):
        _fields_ = [("function", ctypes.c_void_p), ("attribute", ctypes.c_void_p)]

    class SigevUnion(ctypes.Union):
        _fields_ = [("pad", ctypes.c_int * 12), ("tid", ctypes.c_int), ("thread", SigevThread)]

    class Sigevent(ctypes.Structure):           # Linux struct sigevent (64 bytes)
        _fields_ = [("sigev_value", Sigval), ("sigev_signo", ctypes.c_int),
                    ("sigev_notify", ctypes.c_int), ("un", SigevUnion)]

    class Timespec(ctypes.Structure):
        _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]

    class Itimerspec(ctypes.Structure):
        _fields_ = [("it_interval", Timespec), ("it_value", Timespec)]

    if ctypes.sizeof(Sigevent) != 64:
        raise OSError(f"struct sigevent is not 64 bytes here ({ctypes.sizeof(Sigevent)})")
    event = Sigevent()
    event.sigev_notify = 2                      # SIGEV_THREAD: call the function in a thread
    event.sigev_value.sival_ptr = int(code)     # the argument: _exit(code), the whole word set
    event.un.thread.function = ctypes.cast(libc._exit, ctypes.c_void_p).value
    timer = ctypes.c_void_p()
    if libc.timer_create(1, ctypes.byref(event), ctypes.byref(timer)) != 0:   # MONOTONIC
        raise OSError(ctypes.get_errno(), "timer_create failed")
    spec = Itimerspec()
    spec.it_value.tv_sec = int(seconds)
    spec.it_value.tv_nsec = int(round((seconds - int(seconds)) * 1e9))
    if libc.timer_settime(timer, 0, ctypes.byref(spec), None) != 0:
        libc.timer_delete(timer)
        raise OSError(ctypes.get_errno(), "timer_settime failed")
    return lambda: libc.timer_delete(timer)
