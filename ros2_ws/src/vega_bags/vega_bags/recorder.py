"""The ``recorder`` node: one rosbag2 (MCAP, version 9) per run, raw CDR bytes as received.

Parameters (the run's shared YAML): ``bag_path`` (output directory, must not exist),
``scenario``, ``seed``, ``controller_table`` (for the metadata and the expected message
counts), ``participants``, ``barrier_timeout_s``, ``stall_timeout_s``.

* subscribes to every topic of :data:`vega_bus.topics.ALL_TOPICS` with ``raw=True`` and writes
  the bytes unchanged (:class:`vega_bags.bagio.RunBagWriter`): no re-serialisation, so two runs
  of one scenario and seed give byte-identical payloads (except ``compute_time_s``);
* log time = the message's sim-time stamp (``header.stamp``; ``clock`` of /clock), read
  from the CDR bytes (:func:`stamp_ns`);
* checks ``seq`` of every data topic (a gap → exit 1, bag closed and readable);
* reports its progress on ``/vega/recorded`` (the plant's back-pressure,
  :data:`vega_bus.schedule.RECORDER_WINDOW_FRAMES`); takes its messages in batches
  (:data:`RECORDER_BATCH_S`);
* knows the run's message counts (:meth:`vega_bus.schedule.RunInfo.expected_counts`); once it
  has them all it closes the bag, publishes its final report (the other nodes exit on it,
  :meth:`vega_bus.shell.Shell.finish`), waits until they have left and exits 0;
* SIGINT/SIGTERM: closes the bag (readable, holding what arrived) and exits 0.

The bag is opened before the start barrier (a path that exists → exit 2 before anything flies).
"""

from __future__ import annotations

import struct
import sys
import time

from vega_bus import topics
from vega_bus.schedule import RECORDER_REPORT_FRAMES
from vega_bus.shell import EXIT_BAD_INPUT, EXIT_RUN_FAILURE, NodeExit, Shell, run_node

__all__ = ["stamp_ns", "seq_of", "main"]

# The recorder is off the lockstep's critical path (the plant may run
# RECORDER_WINDOW_FRAMES ahead of it): it sleeps this long after each wake-up, so that one
# wake-up drains ≈ 10 ms of traffic (≈ 40 messages at 1000 frames/s) instead of one message.
# Measured on the 100 s flight (A/B, load 4.5-5): recorder CPU 2.4 → 1.55 s, flight 17 → 18.5×.
# 10 ms is ≈ 10-20 frames of the 100-frame window and ≈ 2 % of the DDS history depth.
RECORDER_BATCH_S = 0.01

_TIME = struct.Struct("<iI")
_U32 = struct.Struct("<I")
# CDR offset of ``seq`` after the header's frame_id: VehicleState and ActuatorState have it
# right after the header, InsMeasurement and TvcCommand after an 8-byte sample_stamp.
_SEQ_AFTER_HEADER = {topics.TRUTH.name: 0, topics.ACTUATOR.name: 0, topics.INS.name: 8,
                     topics.TVC_CMD.name: 8}


def _check_le(data) -> None:
    if len(data) < 12 or data[1] != 1:   # encapsulation CDR_LE = 00 01
        raise ValueError("not a little-endian CDR message")


def stamp_ns(data) -> int:
    """Nanoseconds of the first field (``header.stamp`` / ``clock``) of a raw CDR message."""
    _check_le(data)
    sec, nsec = _TIME.unpack_from(data, 4)
    return sec * 1_000_000_000 + nsec


def seq_of(data, offset_after_header: int) -> int:
    """``seq`` of a raw vega_msgs message (uint32 after the header and ``offset`` bytes)."""
    _check_le(data)
    (length,) = _U32.unpack_from(data, 12)       # frame_id: uint32 length (with NUL), bytes
    pos = 16 + length - 4                         # CDR positions count from byte 4
    pos = (pos + 3) // 4 * 4 + offset_after_header
    return _U32.unpack_from(data, pos + 4)[0]


def _recorder(shell: Shell) -> None:
    from pathlib import Path

    from std_msgs.msg import UInt32
    from vega_sim.run import load_run

    from vega_bags import bagio

    node = shell.node
    bag_path = shell.param("bag_path", "", lambda v: None if v else "must be set")
    table = shell.param("controller_table", "")
    try:
        scenario, seed, info = load_run(*shell.run_params())
    except (ValueError, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, " ".join(str(exc).split())) from None
    participants, barrier_timeout = shell.common_params()
    if Path(bag_path).exists():
        raise NodeExit(EXIT_BAD_INPUT, f"bag {bag_path}: exists already, not overwriting")
    try:
        if not table:
            from vega_gnc.controller_table import default_table_path
            table = default_table_path()
        from vega_sim.scenario import scenario_file
        source = scenario_file(shell.node.get_parameter("scenario").value)
        meta = bagio.run_metadata(scenario.name, source.read_text(encoding="utf-8"), seed, table,
                                  extra={"vega.plant": scenario.plant,
                                         "vega.t_start_s": repr(scenario.t_start_s),
                                         "vega.t_end_s": repr(scenario.t_end_s)})
        writer = bagio.RunBagWriter(bag_path, meta).open()
    except (ValueError, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, " ".join(str(exc).split())) from None

    expected = info.expected_counts()
    counts = {name: 0 for name in expected}
    progress = node.create_publisher(UInt32, topics.RECORDED.name, topics.data_qos())
    try:
        for topic in topics.ALL_TOPICS:
            qos = topics.clock_qos() if topic is topics.CLOCK else topics.data_qos()
            callback = _writer_callback(writer, topic.name, counts,
                                        progress if topic is topics.TRUTH else None)
            node.create_subscription(topics.message_class(topic.type_name), topic.name,
                                     shell.guard(callback), qos, raw=True)
        shell.barrier(participants, [progress], barrier_timeout)
        shell.batch_s = RECORDER_BATCH_S
        shell.wait_until(lambda: counts == expected,
                         lambda: "messages " + ", ".join(
                             f"{k} {counts[k]}/{n}" for k, n in expected.items()
                             if counts[k] < n),
                         progress=lambda: sum(counts.values()))
    finally:
        writer.close()
    # the final report ends the run for everyone; wait until they have left (they exit on it)
    final = UInt32(data=counts[topics.TRUTH.name])
    progress.publish(final)
    deadline = time.monotonic() + shell.stall_timeout_s
    while progress.get_subscription_count() > 0 and time.monotonic() < deadline:
        shell.spin_once(0.05)


def _writer_callback(writer, name: str, counts: dict, progress=None):
    """Callback writing the raw messages of topic ``name``; with ``progress`` (the truth
    topic), it reports the count on /vega/recorded every RECORDER_REPORT_FRAMES messages."""
    from std_msgs.msg import UInt32

    offset = _SEQ_AFTER_HEADER.get(name)
    report = UInt32()

    def on_message(data):
        if offset is not None:
            seq = seq_of(data, offset)
            if seq != counts[name]:
                raise NodeExit(EXIT_RUN_FAILURE, f"sequence gap on {name}: expected seq "
                                                 f"{counts[name]}, got {seq}")
        writer.write(name, stamp_ns(data), data)
        counts[name] += 1
        if progress is not None and counts[name] % RECORDER_REPORT_FRAMES == 0:
            report.data = counts[name]
            progress.publish(report)

    return on_message


def main(argv=None) -> None:
    """Console script ``vega_bags recorder``."""
    sys.exit(run_node("recorder", _recorder, argv))
