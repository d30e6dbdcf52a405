"""The ``tvc_controller`` node: the flight controller as a thin ROS shell.

Start-up, before the start barrier (bad input → one line, exit 2):

1. parameter ``controller_table`` ("" = the installed
   ``share/vega_gnc/config/tvc_controller.npz``) → :func:`load_controller_table` (a malformed
   table is rejected here);
2. the run description from the time master on ``/vega/run``
   (:class:`vega_bus.schedule.RunInfo`: span, loop timing and the guidance reference of the
   run; the flight side reads no scenario), waited for up to ``barrier_timeout_s`` (exit 1 if
   it never comes); the table's ``dt_s`` must be the controller period;
3. the guidance reference: the run's (``guidance`` of the run description: ``default`` = the
   installed ``share/vega_gnc/config/guidance_reference.npz``, ``none`` = zero references, or
   a file) → :func:`vega_gnc.guidance_reference.resolve_reference` (a malformed file is
   rejected here); a non-empty parameter ``guidance_reference`` must name the same.

Loop: every ``/vega/ins`` measurement is checked (sequence without gap, else exit 1) and
handed to :class:`vega_gnc.controller_step.ControllerStep` — the same step the in-process
simulation runs. A measurement whose sample time is on the controller period (20 ms) yields
one ``/vega/tvc_cmd`` command, stamped arrival + computing latency. Input validation is the
runtime's (:mod:`vega_gnc.controller_runtime`): NaN/inf fields, ``valid = false``, a sample
stamp not later than the previous one (out of order), older than ``max_age_s`` at arrival
(stale) → ``STATUS_HOLD_LAST`` (the last command, for up to ``hold_limit_s``) then
``STATUS_SAFE_ZERO``; velocity outside the grid → ``STATUS_VELOCITY_CLAMPED``; command beyond
±6.5° → ``STATUS_LIMITED``. A stamp that is not on a whole millisecond makes the measurement
invalid (same flags). Nothing in the loop raises. Every command is followed by a
``/vega/diagnostics`` message (``vega_msgs/StepDiagnostics``: the command's stamp and seq, and
``compute_time_s``, the measured wall-clock time of the step): the commands themselves hold
only what the flight determines, so two runs of one scenario and seed give the same bytes.

The node exits 0 after the run's last measurement (sample t_end − frame).
"""

from __future__ import annotations

import sys
import time

from vega_core.errors import BadInput, one_line

from vega_bus import cdr, qos, topics
from vega_bus.records import CommandOut, InsOut
from vega_bus.schedule import RunInfo
from vega_bus.shell import EXIT_BAD_INPUT, NodeExit, Shell, run_node
from vega_bus.timing import NS_PER_MS, ms_to_stamp

__all__ = ["sample_decoder", "main"]


def _ms_floor(sec: int, nanosec: int) -> int:
    """Whole ms, rounded down, of a builtin_interfaces/Time (sec, nanosec)."""
    return int(sec) * 1000 + int(nanosec) // NS_PER_MS


def sample_decoder():
    """``CDR bytes → InsOut`` (:func:`vega_bus.cdr.decoder`: no message object is built)
    with the controller's stamp policy: stamps rounded down to the ms, and a measurement with
    a stamp (``header.stamp`` or ``sample_stamp``) off the millisecond grid marked invalid —
    the runtime's input validation, never a node failure."""
    off_grid = [False]

    def floor_ms(sec: int, nanosec: int) -> int:
        if nanosec % NS_PER_MS:
            off_grid[0] = True
        return _ms_floor(sec, nanosec)

    decode = cdr.decoder(InsOut, floor_ms)

    def sample(data) -> InsOut:
        off_grid[0] = False
        measured = decode(data)
        return measured._replace(valid=False) if off_grid[0] else measured

    return sample


def _resolved(reference_path, setting: str) -> str:
    """A guidance setting as a comparable text: the absolute file path, or ``none``."""
    path = reference_path(setting)
    return "none" if path is None else str(path.resolve())


def _controller(shell: Shell) -> None:
    from std_msgs.msg import String
    from vega_msgs.msg import InsMeasurement, StepDiagnostics, TvcCommand

    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_gnc.controller_step import ControllerStep
    from vega_gnc.guidance_reference import reference_path, resolve_reference

    node = shell.node
    path = shell.param("controller_table")
    participants, barrier_timeout = shell.common_params()
    try:
        path = path or default_table_path()
        table = load_controller_table(path)
        guidance = shell.param("guidance_reference")
        if guidance:
            resolve_reference(guidance)     # a bad file: refused before waiting for the run
    except (BadInput, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, one_line(exc)) from None

    infos = []

    def on_run(msg):
        try:
            infos.append(RunInfo.from_json(msg.data))
        except BadInput as exc:
            raise NodeExit(EXIT_BAD_INPUT, f"{topics.RUN.name}: {exc}") from None

    node.create_subscription(String, topics.RUN.name, shell.guard(on_run), qos.control_qos())
    shell.wait_until(lambda: bool(infos),
                     f"the run description on {topics.RUN.name} (is the plant running?)",
                     barrier_timeout, failure="start barrier timed out")
    info = infos[-1]
    try:
        if guidance and _resolved(reference_path, guidance) != _resolved(reference_path,
                                                                         info.guidance):
            raise BadInput(f"parameter 'guidance_reference' {guidance!r} is not the run's "
                           f"guidance {info.guidance!r} (scenario {info.scenario!r})")
        reference = resolve_reference(info.guidance)
    except (BadInput, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, one_line(exc)) from None
    try:
        ctrl = ControllerStep(table, info.timing, reference=reference)
    except BadInput as exc:
        raise NodeExit(EXIT_BAD_INPUT, f"{path}: {exc}") from None

    pub = node.create_publisher(TvcCommand, topics.TVC_CMD.name, qos.data_qos())
    diag_pub = node.create_publisher(StepDiagnostics, topics.DIAGNOSTICS.name, qos.data_qos())
    queue = shell.record_inbox(InsMeasurement, topics.INS.name, qos.data_qos(),
                               sample_decoder())
    encode = cdr.encoder(CommandOut)
    recorded = shell.recorder_progress(participants)
    shell.barrier(participants, [pub, diag_pub], barrier_timeout)

    diag = StepDiagnostics()
    diag.header.frame_id = node.get_name()
    clock = time.perf_counter
    for k in range(info.n_frames):
        shell.wait_until(lambda: bool(queue), lambda: f"{topics.INS.name} seq {k}")
        m = queue.pop(0)
        t0 = clock()
        cmd = ctrl.step(m)
        elapsed = clock() - t0
        if cmd is None:
            continue
        pub.publish(encode(cmd))
        diag.header.stamp.sec, diag.header.stamp.nanosec = ms_to_stamp(cmd.stamp_ms)
        diag.seq = cmd.seq
        diag.compute_time_s = elapsed
        diag_pub.publish(diag)
    shell.finish([pub, diag_pub], recorded, info.n_frames + 1)


def main(argv=None) -> None:
    """Console script ``vega_gnc tvc_controller``."""
    sys.exit(run_node("tvc_controller", _controller, argv))
