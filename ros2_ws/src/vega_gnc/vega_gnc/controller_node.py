"""The ``tvc_controller`` node: the flight controller as a thin ROS shell.

Start-up, before the start barrier (bad input → one line, exit 2):

1. parameter ``controller_table`` ("" = the installed
   ``share/vega_gnc/config/lpv_controller.npz``) → :func:`load_controller_table` (a malformed
   table is rejected here);
2. the run description from the time master on ``/vega/run``
   (:class:`vega_bus.schedule.RunInfo`: span and loop timing; the flight side reads no
   scenario), waited for up to ``barrier_timeout_s`` (exit 1 if it never comes); the table's
   ``dt_s`` must be the controller period.

Loop: every ``/vega/ins`` measurement is checked (sequence without gap, else exit 1) and
handed to :class:`vega_gnc.controller_step.ControllerStep` — the same step the in-process
simulation runs. A measurement whose sample time is on the controller period (20 ms) yields
one ``/vega/tvc_cmd`` command, stamped arrival + computing latency. Input validation is the
runtime's (:mod:`vega_gnc.controller_runtime`): NaN/inf fields, ``valid = false``, a sample
stamp not later than the previous one (out of order), older than ``max_age_s`` at arrival
(stale) → ``STATUS_HOLD_LAST`` (the last command, for up to ``hold_limit_s``) then
``STATUS_SAFE_ZERO``; velocity outside the grid → ``STATUS_VELOCITY_CLAMPED``; command beyond
±6.5° → ``STATUS_LIMITED``. A stamp that is not on a whole millisecond makes the measurement
invalid (same flags). Nothing in the loop raises. ``compute_time_s`` is the measured wall-clock
time of the step (the only field that differs between two runs).

The node exits 0 after the run's last measurement (sample t_end − frame).
"""

from __future__ import annotations

import sys
import time
from vega_bus import topics
from vega_bus.records import InsOut
from vega_bus.schedule import RunInfo
from vega_bus.shell import EXIT_BAD_INPUT, NodeExit, Shell, run_node
from vega_bus.timing import ms_to_stamp

__all__ = ["to_sample", "main"]

_NS_PER_MS = 1_000_000


def _ms_floor(stamp) -> tuple[int, bool]:
    """(whole ms rounded down, exact?) of a builtin_interfaces/Time."""
    ms, rest = divmod(int(stamp.nanosec), _NS_PER_MS)
    return int(stamp.sec) * 1000 + ms, rest == 0


def to_sample(msg) -> InsOut:
    """An InsMeasurement as an :class:`vega_bus.records.InsOut`; stamps off the millisecond
    grid → invalid."""
    stamp, ok1 = _ms_floor(msg.header.stamp)
    sample, ok2 = _ms_floor(msg.sample_stamp)
    return InsOut(stamp, sample, msg.seq, msg.pitch_rad, msg.pitch_rate_radps, msg.drift_m,
                  msg.drift_rate_mps, msg.velocity_mps, bool(msg.valid) and ok1 and ok2)


def _controller(shell: Shell) -> None:
    from std_msgs.msg import String
    from vega_msgs.msg import InsMeasurement, TvcCommand

    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_gnc.controller_step import ControllerStep

    node = shell.node
    path = shell.param("controller_table", "")
    participants, barrier_timeout = shell.common_params()
    try:
        path = path or default_table_path()
        table = load_controller_table(path)
    except (ValueError, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, " ".join(str(exc).split())) from None

    infos = []

    def on_run(msg):
        try:
            infos.append(RunInfo.from_json(msg.data))
        except ValueError as exc:
            raise NodeExit(EXIT_BAD_INPUT, f"{topics.RUN.name}: {exc}") from None

    node.create_subscription(String, topics.RUN.name, shell.guard(on_run), topics.control_qos())
    shell.wait_until(lambda: bool(infos),
                     f"the run description on {topics.RUN.name} (is the plant running?)",
                     barrier_timeout, failure="start barrier timed out")
    info = infos[-1]
    try:
        ctrl = ControllerStep(table, info.timing)
    except ValueError as exc:
        raise NodeExit(EXIT_BAD_INPUT, f"{path}: {exc}") from None

    pub = node.create_publisher(TvcCommand, topics.TVC_CMD.name, topics.data_qos())
    queue = shell.inbox(InsMeasurement, topics.INS.name, topics.data_qos())
    recorded = shell.recorder_progress(participants)
    shell.barrier(participants, [pub], barrier_timeout)

    out = TvcCommand()
    clock = time.perf_counter
    for k in range(info.n_frames):
        shell.wait_until(lambda: bool(queue), lambda: f"{topics.INS.name} seq {k}")
        m = to_sample(queue.pop(0))
        t0 = clock()
        cmd = ctrl.step(m)
        elapsed = clock() - t0
        if cmd is None:
            continue
        out.header.stamp.sec, out.header.stamp.nanosec = ms_to_stamp(cmd.stamp_ms)
        out.sample_stamp.sec, out.sample_stamp.nanosec = ms_to_stamp(cmd.sample_ms)
        out.seq = cmd.seq
        out.deflection_cmd_rad = cmd.deflection_cmd_rad
        out.scheduling_velocity_mps = cmd.scheduling_velocity_mps
        out.status = cmd.status
        out.compute_time_s = elapsed
        pub.publish(out)
    shell.finish([pub], recorded, info.n_frames + 1)


def main(argv=None) -> None:
    """Console script ``vega_gnc tvc_controller``."""
    sys.exit(run_node("tvc_controller", _controller, argv))
