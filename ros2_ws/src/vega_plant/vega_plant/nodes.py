"""The truth-side SIL nodes: ``plant``, ``ins_sensor``, ``tvc_actuator`` (thin ROS shells).

Each node builds its step object exactly as the in-process simulation does
(:mod:`vega_sim.assembly`) and only moves its records to and from the messages (serialised
directly by :mod:`vega_bus.cdr`, with :mod:`vega_bus.wire`'s field rule) on the topics of
:mod:`vega_bus.topics`, in the lockstep of :mod:`vega_bus.schedule`:

* ``plant`` (time master): publishes the run description on ``/vega/run``, waits for the start
  barrier, then for k = 0 … n: truth(t_k) on ``/vega/truth`` (and /clock = t_k on the frames
  of :meth:`RunInfo.clock_frames`), then waits for the actuator's frame k and integrates it
  (:class:`vega_sim.plant_step.PlantStep`).
  ``realtime: true`` paces the frames to the wall clock.
* ``ins_sensor``: each truth(t_k), k < n → one measurement
  (:class:`vega_sim.device_steps.InsStep`; model parameters of the run's
  :func:`vega_sim.plant_step.parameter_track`, as in the in-process run).
* ``tvc_actuator``: frame k as soon as it holds every command that applies within it
  (:meth:`vega_bus.schedule.RunInfo.commands_needed`; it runs up to three frames ahead of the
  plant) (:class:`vega_sim.device_steps.ActuatorStep`).

Parameters (one YAML for all nodes, ``/**: ros__parameters:``; unused keys are ignored;
meaning, unit, default and domain in :mod:`vega_bus.parameters`): ``scenario``, ``seed``,
``realtime`` (plant), ``participants``, ``barrier_timeout_s``, ``stall_timeout_s``. Exit
codes: :mod:`vega_bus.shell`.
"""

from __future__ import annotations

import sys
import time

from vega_core.errors import BadInput, one_line

from vega_bus import cdr, qos, topics
from vega_bus.records import ActuatorOut, CommandOut, InsOut, TruthOut
from vega_bus.schedule import RECORDER_WINDOW_FRAMES
from vega_bus.shell import (EXIT_BAD_INPUT, EXIT_RUN_FAILURE, NodeExit, SeqCheck, Shell,
                            decoded, run_node)
from vega_bus.timing import ms_to_stamp
from vega_sim.run import load_run as run_of

__all__ = ["load_run", "plant_main", "ins_main", "actuator_main"]


def load_run(shell: Shell):
    """The ``scenario`` and ``seed`` parameters → (Scenario, seed, RunInfo)
    (:func:`vega_sim.run.load_run`); :class:`NodeExit` (2) on bad input."""
    try:
        return run_of(*shell.run_params())
    except (BadInput, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, one_line(exc)) from None


def _stamp(header_stamp, t_ms: int) -> None:
    header_stamp.sec, header_stamp.nanosec = ms_to_stamp(t_ms)


def _expect_stamp(topic: str, got_ms: int, want_ms: int) -> None:
    if got_ms != want_ms:
        raise NodeExit(EXIT_RUN_FAILURE, f"{topic}: stamp {got_ms} ms out of the lockstep "
                                         f"schedule (expected {want_ms} ms)")


# ----------------------------------------------------------------------------- plant
def _plant(shell: Shell) -> None:
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String
    from vega_msgs.msg import ActuatorState, VehicleState

    from vega_sim.assembly import make_plant

    node = shell.node
    scenario, seed, info = load_run(shell)
    realtime = shell.param("realtime")
    participants, barrier_timeout = shell.common_params()

    # entities first, the plant's set-up (its parameter track) while discovery runs
    run_pub = node.create_publisher(String, topics.RUN.name, qos.control_qos())
    run_pub.publish(String(data=info.to_json()))
    truth_pub = node.create_publisher(VehicleState, topics.TRUTH.name, qos.data_qos())
    clock_pub = node.create_publisher(Clock, topics.CLOCK.name, qos.clock_qos())
    frames = shell.record_inbox(ActuatorState, topics.ACTUATOR.name, qos.data_qos(),
                                cdr.decoder(ActuatorOut))
    encode = cdr.encoder(TruthOut, "base_link")
    recorded = shell.recorder_progress(participants)   # back-pressure (vega_bus.schedule)
    barrier = shell.open_barrier(participants, [truth_pub, clock_pub])
    try:
        plant = make_plant(scenario, seed=seed)
    except BadInput as exc:
        raise NodeExit(EXIT_BAD_INPUT, one_line(exc)) from None
    shell.barrier(participants, [truth_pub, clock_pub], barrier_timeout, opened=barrier)
    startup_s = _process_age_s()

    clock = Clock()
    n, frame_ms = info.n_frames, info.timing.frame_ms
    ticks = set(info.clock_frames())
    wall0 = time.monotonic()
    for k in range(n + 1):
        if k - recorded.count >= RECORDER_WINDOW_FRAMES and recorded.linked():
            shell.wait_until(lambda: k - recorded.count < RECORDER_WINDOW_FRAMES,
                             lambda: f"{topics.RECORDED.name}: the recorder reported "
                                     f"{recorded.count} of {k} frames")
        t = plant.output()
        truth_pub.publish(encode(t))
        if k in ticks:
            _stamp(clock.clock, t.stamp_ms)
            clock_pub.publish(clock)
        if k == n:
            break
        shell.wait_until(lambda: bool(frames),
                         lambda: f"{topics.ACTUATOR.name} frame {k} (seq {k})")
        act = frames.pop(0)
        _expect_stamp(topics.ACTUATOR.name, act.stamp_ms, t.stamp_ms + frame_ms)
        plant.advance(act.deflection_samples_rad, act.rate_samples_radps)
        if realtime:
            ahead = wall0 + (k + 1) * frame_ms / 1000.0 - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
    shell.finish([truth_pub, clock_pub], recorded, n + 1)
    wall = time.monotonic() - wall0
    span_s = (info.t_end_ms - info.t_start_ms) / 1000.0
    print(f"plant: flew {span_s:g} s in {wall:.2f} s wall ({n / wall:.0f} frames/s, "
          f"{span_s / wall:.1f}x real time) after a {startup_s:.2f} s start-up", flush=True)


def _process_age_s() -> float:
    """Seconds since this process started (Linux /proc; NaN elsewhere)."""
    import os

    try:
        with open("/proc/self/stat") as f:
            start_ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return uptime - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return float("nan")


def plant_main(argv=None) -> None:
    """Console script ``vega_plant plant``."""
    sys.exit(run_node("plant", _plant, argv))


# ----------------------------------------------------------------------------- INS
def _ins(shell: Shell) -> None:
    from vega_msgs.msg import InsMeasurement, VehicleState

    from vega_model.parameters import default_context
    from vega_sim.plant_step import parameter_track
    from vega_sim.assembly import make_ins

    node = shell.node
    scenario, seed, info = load_run(shell)
    participants, barrier_timeout = shell.common_params()
    # entities first, the set-up below while discovery runs
    pub = node.create_publisher(InsMeasurement, topics.INS.name, qos.data_qos())
    truths = shell.record_inbox(VehicleState, topics.TRUTH.name, qos.data_qos(),
                                cdr.decoder(TruthOut))
    recorded = shell.recorder_progress(participants)
    barrier = shell.open_barrier(participants, [pub])
    ins = make_ins(scenario, seed=seed)
    # the parameters at every frame start, as the plant and the in-process run hold them: the
    # track's columns before the barrier, each frame's parameter set built from them on first
    # access in flight (≈ 6 µs; vega_sim.plant_step.parameter_track)
    t = info.timing
    params_at = parameter_track(default_context(), info.t_start_ms, info.t_end_ms,
                                frame_ms=t.frame_ms, refresh_ms=t.frame_ms,
                                dt_ms=t.physics_dt_ms, deviations=scenario.deviations).at_ms
    shell.barrier(participants, [pub], barrier_timeout, opened=barrier)

    encode = cdr.encoder(InsOut, "base_link")
    for k in range(info.n_frames):
        shell.wait_until(lambda: bool(truths), lambda: f"{topics.TRUTH.name} seq {k}")
        truth = truths.pop(0)
        _expect_stamp(topics.TRUTH.name, truth.stamp_ms, info.frame_start(k))
        pub.publish(encode(ins.sample(truth, params_at(truth.stamp_ms))))
    shell.finish([pub], recorded, info.n_frames + 1)


def ins_main(argv=None) -> None:
    """Console script ``vega_plant ins_sensor``."""
    sys.exit(run_node("ins_sensor", _ins, argv))


# ----------------------------------------------------------------------------- actuator
def _actuator(shell: Shell) -> None:
    from vega_msgs.msg import ActuatorState, TvcCommand

    from vega_sim.assembly import make_actuator

    node = shell.node
    scenario, _seed, info = load_run(shell)
    participants, barrier_timeout = shell.common_params()
    act = make_actuator(scenario)
    lat = info.timing.actuator_latency_ms
    pub = node.create_publisher(ActuatorState, topics.ACTUATOR.name, qos.data_qos())
    seq = SeqCheck(topics.TVC_CMD.name)
    received = [0]

    decode = cdr.decoder(CommandOut)

    def on_command(data):
        cmd = decoded(decode, data, topics.TVC_CMD.name)
        seq(cmd.seq)
        if cmd.stamp_ms + lat < act.t_ms:
            raise NodeExit(EXIT_RUN_FAILURE,
                           f"{topics.TVC_CMD.name}: command seq {cmd.seq} applies at "
                           f"{cmd.stamp_ms + lat} ms, but the actuator is already at "
                           f"{act.t_ms} ms")
        act.receive(cmd)
        received[0] += 1

    shell.checked_subscription(TvcCommand, topics.TVC_CMD.name, on_command, qos.data_qos(),
                               raw=True)
    recorded = shell.recorder_progress(participants)
    shell.barrier(participants, [pub], barrier_timeout)

    encode = cdr.encoder(ActuatorOut)
    for k in range(info.n_frames):
        need = info.commands_needed(k)
        shell.wait_until(lambda: received[0] >= need,
                         lambda: f"{topics.TVC_CMD.name} seq {need - 1} (frame {k})")
        pub.publish(encode(act.advance(info.frame_start(k))))
    shell.finish([pub], recorded, info.n_frames + 1)


def actuator_main(argv=None) -> None:
    """Console script ``vega_plant tvc_actuator``."""
    sys.exit(run_node("tvc_actuator", _actuator, argv))
