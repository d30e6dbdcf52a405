"""The ``recorder`` node: one rosbag2 (MCAP, version 9) per run, raw CDR bytes as received.

Parameters (the run's shared YAML; :mod:`vega_bus.parameters`): ``bag_path`` (output
directory, must not exist), ``scenario``, ``seed``, ``controller_table`` (for the metadata and
the expected message counts), ``participants``, ``barrier_timeout_s``, ``stall_timeout_s``.

* subscribes to every topic of :data:`vega_bus.topics.ALL_TOPICS` with ``raw=True`` and writes
  the bytes unchanged (:class:`vega_bags.bagio.RunBagWriter`): no re-serialisation, so two runs
  of one scenario and seed give byte-identical payloads on every data topic (only
  ``/vega/diagnostics``, the controller's wall-clock step time, differs);
* writes them in (log time, :data:`vega_bus.topics.RECORD_ORDER`, seq) order, whatever order
  they arrived in (:class:`Reorder`): the file order of two such runs is the same too;
* log time = the message's sim-time stamp (``header.stamp``; ``clock`` of /clock), read
  from the CDR bytes at the offsets of the computed layout (:class:`RawFields`);
* checks ``seq`` of every data topic (a gap → exit 1, bag closed and readable);
* reports its progress on ``/vega/recorded``: the frames it holds on every topic, each time
  they have grown by RECORDER_REPORT_FRAMES (:class:`FramesRecorded`; the plant's back-pressure,
  :data:`vega_bus.schedule.RECORDER_WINDOW_FRAMES`); takes its messages in batches
  (:data:`RECORDER_BATCH_S`);
* knows the run's message counts (:meth:`vega_bus.schedule.RunInfo.expected_counts`); once it
  has them all it closes the bag, publishes its final report (the other nodes exit on it,
  :meth:`vega_bus.shell.Shell.finish`), waits until they have left and exits 0;
* SIGINT/SIGTERM: closes the bag (readable, holding what arrived) and exits 0.

The bag is opened before the start barrier (a path that exists → exit 2 before anything flies).
"""

from __future__ import annotations

import heapq
import math
import struct
import sys
import time

from vega_core.documents import read_text
from vega_core.errors import BadInput, one_line

from vega_bus import qos, topics
from vega_bus.schedule import RECORDER_REPORT_FRAMES
from vega_bus.shell import EXIT_BAD_INPUT, EXIT_RUN_FAILURE, NodeExit, Shell, run_node
from vega_bus.timing import NS_PER_MS, NS_PER_S

__all__ = ["FramesRecorded", "RawFields", "Reorder", "main"]

# The recorder is off the lockstep's critical path (the plant may run
# RECORDER_WINDOW_FRAMES ahead of it): it sleeps this long after each wake-up, so that one
# wake-up drains ≈ 10 ms of traffic (≈ 40 messages at 1000 frames/s) instead of one message.
# Measured on the 100 s flight (A/B, load 4.5-5): recorder CPU 2.4 → 1.55 s, flight 17 → 18.5×.
# 10 ms is ≈ 10-30 frames of the 60-frame window and ≈ 3 % of the DDS history depth.
RECORDER_BATCH_S = 0.01

_TIME = struct.Struct("<iI")
_U32 = struct.Struct("<I")


def _check_le(data) -> None:
    if len(data) < 12 or data[1] != 1:   # encapsulation CDR_LE = 00 01
        raise ValueError("not a little-endian CDR message")


class RawFields:
    """The stamp and ``seq`` of one message type's raw CDR bytes, at the offsets of the layout
    :func:`vega_bags.bagio.cdr_offsets` computes (the one the bag reader uses).

    In every message of the graph the only variable-size part before these fields is
    ``header.frame_id``, whose length word sits at a fixed place (after the fixed-size
    stamp): the offsets are computed for the first message of each frame_id length and
    cached, so a message costs three struct reads (tests/sil/test_sil_nodes.py checks them for
    every topic and several frame_id lengths).

    Parameters
    ----------
    type_name
        rosidl type of the topic (``vega_msgs/msg/VehicleState``, ``rosgraph_msgs/msg/Clock``).

    Examples
    --------
    >>> stamp_ns, seq = RawFields("vega_msgs/msg/InsMeasurement")(data)   # doctest: +SKIP

    ``seq`` is None for a type without one (``/clock``).
    """

    def __init__(self, type_name: str):
        self.type_name = type_name
        self._length_at: int | None = None   # offset of frame_id's length word, once known
        self._known: dict[int | None, tuple[int, int | None]] = {}

    def _learn(self, data) -> tuple[int, int | None]:
        from vega_bags import bagio

        at = bagio.cdr_offsets(self.type_name, data)
        key = None
        if "header.frame_id" in at:
            self._length_at = at["header.frame_id"]
            key = _U32.unpack_from(data, self._length_at)[0]
        self._known[key] = found = (at["stamp_ns"], at.get("seq"))
        return found

    def __call__(self, data) -> tuple[int, int | None]:
        """(stamp [ns], seq or None) of one raw message.

        Raises
        ------
        ValueError
            If ``data`` is not little-endian CDR.
        """
        _check_le(data)
        key = None if self._length_at is None else _U32.unpack_from(data, self._length_at)[0]
        found = self._known.get(key)
        stamp_at, seq_at = found if found is not None else self._learn(data)
        sec, nsec = _TIME.unpack_from(data, stamp_at)
        seq = None if seq_at is None else _U32.unpack_from(data, seq_at)[0]
        return sec * NS_PER_S + nsec, seq


class Reorder:
    """Holds received messages until nothing that sorts before them can still arrive, then
    hands them to ``write`` in (log time, :data:`vega_bus.topics.RECORD_ORDER` rank, arrival)
    order: equal-time messages of different topics get one order whatever order the
    executor delivered them in, and log times never go backwards in the file.

    Each topic's stamps strictly increase (the lockstep; :mod:`vega_bags.bagcheck` checks it),
    so the next message of a topic that is still to send has a log time above the last one it
    sent: every held message with a log time ≤ the smallest such last log time can go. A
    topic that has sent all its messages (``expected``) holds nothing back; one that has sent
    none yet holds everything. The buffer so holds at most about one period of the slowest
    topic still running (/clock: 100 ms of traffic). :meth:`drain` writes the rest (the run's
    end, or a stop).

    Parameters
    ----------
    write
        ``write(topic, log_time_ns, data)``, e.g. :meth:`vega_bags.bagio.RunBagWriter.write`.
    expected
        Topic name → number of messages of the complete run
        (:meth:`vega_bus.schedule.RunInfo.expected_counts`).
    """

    def __init__(self, write, expected: dict[str, int]):
        self._write = write
        self._heap: list = []
        self._n = 0
        self._rank = topics.RECORD_ORDER
        self._left = dict(expected)
        self._last: dict[str, float] = {name: -math.inf for name in expected}

    def __len__(self) -> int:
        return len(self._heap)

    def add(self, topic: str, log_time_ns: int, data) -> None:
        """Take one message; write every held message that can no longer be preceded."""
        heapq.heappush(self._heap, (log_time_ns, self._rank[topic], self._n, topic, data))
        self._n += 1
        self._last[topic] = log_time_ns
        self._left[topic] -= 1
        horizon = min((self._last[name] for name, left in self._left.items() if left > 0),
                      default=math.inf)
        heap = self._heap
        while heap and heap[0][0] <= horizon:
            t, _, _, name, payload = heapq.heappop(heap)
            self._write(name, t, payload)

    def drain(self) -> None:
        """Write every held message, in order."""
        while self._heap:
            t, _, _, name, payload = heapq.heappop(self._heap)
            self._write(name, t, payload)


class FramesRecorded:
    """The recorder's back-pressure report (/vega/recorded): how many frames of the run the
    recorder holds on EVERY topic still running — the smallest, over those topics, of the
    frame of its last message + 1 (frame = (stamp − t_start) // frame length); a topic that has
    sent all its messages no longer counts; 0 before a topic's first message.

    The plant does not run more than :data:`vega_bus.schedule.RECORDER_WINDOW_FRAMES` frames
    beyond this report. Why every topic: counting only the truth messages lets the plant run
    on while another writer's deliveries to the recorder are held up: in a soak of the
    test suite (two copies on two cores) the recorder lost /vega/ins samples 8 153–9 000 — 848
    frames — while truth kept arriving, more than the INS writer's KEEP_LAST history of 1 000
    samples could still repair in time. With every topic in the report, a writer whose
    messages do not arrive stops the plant within the window, and its unacknowledged samples
    (≤ window + report interval frames) stay in its history until the reliable protocol
    repairs them. The topics sent less often than every frame (commands and diagnostics
    every controller period, /clock every 10 frames) lag the truth by up to their period: the
    effective window is a few frames shorter.

    It cannot hold the run: a plant waiting at frame k (k − last report ≥ window) has sent
    everything of the frames before k, and the other nodes send theirs without the recorder,
    so the report reaches at least k − 11 (the /clock period, and one frame) ≥ last report +
    window − 11, more than RECORDER_REPORT_FRAMES further: a report is always due
    (tests/sim/test_recorder_window.py runs the protocol over a whole flight's schedule).

    Parameters
    ----------
    expected
        Topic name → messages of the complete run (:meth:`vega_bus.schedule.RunInfo.
        expected_counts`).
    t_start_ns, frame_ns
        The run's first frame time and frame length [ns].
    """

    def __init__(self, expected: dict[str, int], t_start_ns: int, frame_ns: int):
        self._t0, self._frame = int(t_start_ns), int(frame_ns)
        self._left = dict(expected)
        self._reached = {name: 0 for name in expected}
        self._total = max(expected.values(), default=0)
        self._reported = 0

    def add(self, topic: str, stamp_ns: int) -> int | None:
        """One message of ``topic`` (stamped ``stamp_ns``) received; returns :meth:`frames`
        when it has grown by :data:`~vega_bus.schedule.RECORDER_REPORT_FRAMES` or more since
        the last value returned (the report to publish), else None.

        Checked on every message of every topic, not on the truth's alone: the executor
        takes a batch topic by topic, so when a truth message arrives the other topics'
        messages of the same frames may still wait in their queues — a report made only then
        could lag the truth by the whole window and leave the plant waiting for a report that
        no further truth message would trigger."""
        self._left[topic] -= 1
        self._reached[topic] = (int(stamp_ns) - self._t0) // self._frame + 1
        # never the truth count itself: that value is the recorder's final report, sent once
        # the bag is closed, on which the other nodes end (vega_bus.shell.Shell.finish); a
        # progress report reaching it let them end while the recorder was still in its start
        # barrier (a 1 s flight, fresh-clone CI under load), which then never completed
        now = min(self.frames(), self._total - 1)
        if now >= self._reported + RECORDER_REPORT_FRAMES:
            self._reported = now
            return now
        return None

    def frames(self) -> int:
        """Frames held on every running topic (all of them, the truth's count, when done)."""
        running = [self._reached[name] for name, left in self._left.items() if left > 0]
        return max(0, min(running)) if running else self._total


def _recorder(shell: Shell) -> None:
    from pathlib import Path

    from std_msgs.msg import UInt32
    from vega_sim.run import load_run

    from vega_bags import bagio

    node = shell.node
    bag_path = shell.param("bag_path")
    table = shell.param("controller_table")
    try:
        scenario, seed, info = load_run(*shell.run_params())
    except (BadInput, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, one_line(exc)) from None
    participants, barrier_timeout = shell.common_params()
    if Path(bag_path).exists():
        raise NodeExit(EXIT_BAD_INPUT, f"bag {bag_path}: exists already, not overwriting")

    # entities first (subscriptions, progress, the barrier's), then the bag is opened while
    # discovery runs; no message arrives before the barrier, so the writer is there by then
    expected = info.expected_counts()
    counts = {name: 0 for name in expected}
    progress = node.create_publisher(UInt32, topics.RECORDED.name, qos.data_qos())
    writer = None
    reorder = Reorder(lambda topic, t, data: writer.write(topic, t, data), expected)
    held = FramesRecorded(expected, info.t_start_ms * NS_PER_MS,
                          info.timing.frame_ms * NS_PER_MS)
    for topic in topics.ALL_TOPICS:
        profile = qos.clock_qos() if topic is topics.CLOCK else qos.data_qos()
        callback = _writer_callback(reorder, topic.name, topic.type_name, counts, held,
                                    progress)
        shell.checked_subscription(topics.message_class(topic.type_name), topic.name,
                                   callback, profile, raw=True)
    barrier = shell.open_barrier(participants, [progress])
    try:
        if not table:
            from vega_gnc.controller_table import default_table_path
            table = default_table_path()
        from vega_sim.scenario import scenario_file
        source = scenario_file(shell.node.get_parameter("scenario").value)
        from vega_gnc.guidance_reference import reference_path
        guidance = reference_path(scenario.guidance)
        meta = bagio.run_metadata(scenario.name, read_text(source, "scenario"), seed, table,
                                  guidance_reference=guidance,
                                  extra={"vega.plant": scenario.plant,
                                         "vega.t_start_s": repr(scenario.t_start_s),
                                         "vega.t_end_s": repr(scenario.t_end_s)})
        writer = bagio.RunBagWriter(bag_path, meta).open()
    except (BadInput, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, one_line(exc)) from None

    try:
        shell.barrier(participants, [progress], barrier_timeout, opened=barrier)
        shell.batch_s = RECORDER_BATCH_S
        shell.wait_until(lambda: counts == expected,
                         lambda: "messages " + ", ".join(
                             f"{k} {counts[k]}/{n}" for k, n in expected.items()
                             if counts[k] < n),
                         progress=lambda: sum(counts.values()))
    finally:
        try:
            reorder.drain()
        finally:
            writer.close()
    # the final report ends the run for everyone; wait until they have left (they exit on it)
    final = UInt32(data=counts[topics.TRUTH.name])
    progress.publish(final)
    deadline = time.monotonic() + shell.stall_timeout_s
    while progress.get_subscription_count() > 0 and time.monotonic() < deadline:
        shell.spin_once(0.01)   # a graph change does not wake the wait: poll (the run waits)


def _writer_callback(reorder: Reorder, name: str, type_name: str, counts: dict,
                     held: FramesRecorded, progress):
    """Callback handing the raw messages of topic ``name`` (type ``type_name``) to the
    :class:`Reorder` buffer in front of the bag and to ``held``, and publishing on
    ``progress`` (/vega/recorded) the report ``held`` returns."""
    from std_msgs.msg import UInt32

    fields = RawFields(type_name)
    report = UInt32()

    def on_message(data):
        stamp, seq = fields(data)
        if seq is not None and seq != counts[name]:
            raise NodeExit(EXIT_RUN_FAILURE, f"sequence gap on {name}: expected seq "
                                             f"{counts[name]}, got {seq}")
        reorder.add(name, stamp, data)
        counts[name] += 1
        frames = held.add(name, stamp)
        if frames is not None:
            report.data = frames
            progress.publish(report)

    return on_message


def main(argv=None) -> None:
    """Console script ``vega_bags recorder``."""
    sys.exit(run_node("recorder", _recorder, argv))
