"""The truth-side SIL nodes: ``plant``, ``ins_sensor``, ``tvc_actuator`` (thin ROS shells).

Each node builds its step object exactly as the in-process simulation does
(:mod:`vega_sim.assembly`) and only moves values between it and the messages
(:mod:`vega_bus.topics`), in the lockstep of :mod:`vega_bus.schedule`:

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

Parameters (one YAML for all nodes, ``/**: ros__parameters:``; unused keys are ignored):
``scenario`` (name or YAML path, default "nominal"), ``seed`` (−1: the scenario's), ``realtime``
(plant), ``participants``, ``barrier_timeout_s``, ``stall_timeout_s``. Exit codes:
:mod:`vega_bus.shell`.
"""

from __future__ import annotations

import sys
import time

from vega_bus import topics
from vega_bus.schedule import RECORDER_WINDOW_FRAMES
from vega_bus.shell import (EXIT_BAD_INPUT, EXIT_RUN_FAILURE, NodeExit, SeqCheck, Shell,
                            run_node)
from vega_bus.timing import ms_to_stamp, stamp_to_ms
from vega_sim.run import load_run as run_of

__all__ = ["load_run", "plant_main", "ins_main", "actuator_main"]


def load_run(shell: Shell):
    """The ``scenario`` and ``seed`` parameters → (Scenario, seed, RunInfo)
    (:func:`vega_sim.run.load_run`); :class:`NodeExit` (2) on bad input."""
    try:
        return run_of(*shell.run_params())
    except (ValueError, OSError) as exc:
        raise NodeExit(EXIT_BAD_INPUT, " ".join(str(exc).split())) from None


def _stamp(header_stamp, t_ms: int) -> None:
    header_stamp.sec, header_stamp.nanosec = ms_to_stamp(t_ms)


def _ms(stamp, topic: str) -> int:
    try:
        return stamp_to_ms(stamp.sec, stamp.nanosec)
    except ValueError as exc:
        raise NodeExit(EXIT_RUN_FAILURE, f"{topic}: {exc}") from None


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
    realtime = shell.param("realtime", False)
    participants, barrier_timeout = shell.common_params()
    try:
        plant = make_plant(scenario, seed=seed)
    except ValueError as exc:
        raise NodeExit(EXIT_BAD_INPUT, " ".join(str(exc).split())) from None

    run_pub = node.create_publisher(String, topics.RUN.name, topics.control_qos())
    run_pub.publish(String(data=info.to_json()))
    truth_pub = node.create_publisher(VehicleState, topics.TRUTH.name, topics.data_qos())
    clock_pub = node.create_publisher(Clock, topics.CLOCK.name, topics.clock_qos())
    frames = shell.inbox(ActuatorState, topics.ACTUATOR.name, topics.data_qos())
    recorded = shell.recorder_progress(participants)   # back-pressure (vega_bus.schedule)
    shell.barrier(participants, [truth_pub, clock_pub], barrier_timeout)
    startup_s = _process_age_s()

    msg, clock = VehicleState(), Clock()
    msg.header.frame_id = "base_link"
    n, frame_ms = info.n_frames, info.timing.frame_ms
    ticks = set(info.clock_frames())
    wall0 = time.monotonic()
    for k in range(n + 1):
        if k - recorded.count >= RECORDER_WINDOW_FRAMES and recorded.linked():
            shell.wait_until(lambda: k - recorded.count < RECORDER_WINDOW_FRAMES,
                             lambda: f"the recorder (it reported {recorded.count} of {k} "
                                     f"frames)")
        t = plant.output()
        _stamp(msg.header.stamp, t.stamp_ms)
        msg.seq = t.seq
        (msg.pitch_rad, msg.pitch_rate_radps, msg.drift_m, msg.drift_rate_mps, msg.aoa_rad,
         msg.q_alpha_pa_rad, msg.dynamic_pressure_pa, msg.mach, msg.velocity_mps,
         msg.altitude_m, msg.wind_mps) = t[2:13]
        msg.bending_q = t.bending_q
        msg.bending_qdot = t.bending_qdot
        truth_pub.publish(msg)
        if k in ticks:
            _stamp(clock.clock, t.stamp_ms)
            clock_pub.publish(clock)
        if k == n:
            break
        shell.wait_until(lambda: bool(frames),
                         lambda: f"{topics.ACTUATOR.name} frame {k} (seq {k})")
        act = frames.pop(0)
        _expect_stamp(topics.ACTUATOR.name, _ms(act.header.stamp, topics.ACTUATOR.name),
                      t.stamp_ms + frame_ms)
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
    from vega_sim.plant_step import TruthOut, parameter_track
    from vega_sim.assembly import make_ins

    node = shell.node
    scenario, seed, info = load_run(shell)
    participants, barrier_timeout = shell.common_params()
    ins = make_ins(scenario, seed=seed)
    # the parameters at every frame start, as the plant and the in-process run hold them
    # (evaluated before the barrier, ≈ 0.2 s, instead of ≈ 20 µs per frame in flight)
    t = info.timing
    params_at = parameter_track(default_context(), info.t_start_ms, info.t_end_ms,
                                frame_ms=t.frame_ms, refresh_ms=t.frame_ms,
                                dt_ms=t.physics_dt_ms, deviations=scenario.deviations).at_ms
    pub = node.create_publisher(InsMeasurement, topics.INS.name, topics.data_qos())
    truths = shell.inbox(VehicleState, topics.TRUTH.name, topics.data_qos())
    recorded = shell.recorder_progress(participants)
    shell.barrier(participants, [pub], barrier_timeout)

    out = InsMeasurement()
    out.header.frame_id = "base_link"
    for k in range(info.n_frames):
        shell.wait_until(lambda: bool(truths), lambda: f"{topics.TRUTH.name} seq {k}")
        m = truths.pop(0)
        t_ms = _ms(m.header.stamp, topics.TRUTH.name)
        _expect_stamp(topics.TRUTH.name, t_ms, info.frame_start(k))
        truth = TruthOut(t_ms, m.seq, m.pitch_rad, m.pitch_rate_radps, m.drift_m,
                         m.drift_rate_mps, m.aoa_rad, m.q_alpha_pa_rad, m.dynamic_pressure_pa,
                         m.mach, m.velocity_mps, m.altitude_m, m.wind_mps,
                         (float(m.bending_q[0]), float(m.bending_q[1])),
                         (float(m.bending_qdot[0]), float(m.bending_qdot[1])))
        s = ins.sample(truth, params_at(t_ms))
        _stamp(out.header.stamp, s.stamp_ms)
        _stamp(out.sample_stamp, s.sample_ms)
        out.seq = s.seq
        (out.pitch_rad, out.pitch_rate_radps, out.drift_m, out.drift_rate_mps,
         out.velocity_mps, out.valid) = s[3:9]
        pub.publish(out)
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
    pub = node.create_publisher(ActuatorState, topics.ACTUATOR.name, topics.data_qos())
    seq = SeqCheck(topics.TVC_CMD.name)
    received = [0]

    def on_command(msg):
        seq(msg.seq)
        stamp = _ms(msg.header.stamp, topics.TVC_CMD.name)
        if stamp + lat < act.t_ms:
            raise NodeExit(EXIT_RUN_FAILURE,
                           f"{topics.TVC_CMD.name}: command seq {msg.seq} applies at "
                           f"{stamp + lat} ms, but the actuator is already at {act.t_ms} ms")
        act.receive(_Command(stamp, msg.seq, msg.deflection_cmd_rad))
        received[0] += 1

    node.create_subscription(TvcCommand, topics.TVC_CMD.name, shell.guard(on_command),
                             topics.data_qos())
    recorded = shell.recorder_progress(participants)
    shell.barrier(participants, [pub], barrier_timeout)

    out = ActuatorState()
    for k in range(info.n_frames):
        need = info.commands_needed(k)
        shell.wait_until(lambda: received[0] >= need,
                         lambda: f"{topics.TVC_CMD.name} seq {need - 1} (frame {k})")
        f = act.advance(info.frame_start(k))
        _stamp(out.header.stamp, f.stamp_ms)
        out.seq = f.seq
        out.deflection_rad, out.rate_radps, out.accel_radps2 = (
            f.deflection_rad, f.rate_radps, f.accel_radps2)
        out.deflection_samples_rad = f.deflection_samples_rad
        out.rate_samples_radps = f.rate_samples_radps
        out.accel_samples_radps2 = f.accel_samples_radps2
        out.sample_period_s = f.sample_period_s
        pub.publish(out)
    shell.finish([pub], recorded, info.n_frames + 1)


class _Command:
    """A received command as :meth:`ActuatorStep.receive` reads it."""

    __slots__ = ("stamp_ms", "seq", "deflection_cmd_rad")

    def __init__(self, stamp_ms, seq, deflection_cmd_rad):
        self.stamp_ms, self.seq, self.deflection_cmd_rad = stamp_ms, seq, deflection_cmd_rad


def actuator_main(argv=None) -> None:
    """Console script ``vega_plant tvc_actuator``."""
    sys.exit(run_node("tvc_actuator", _actuator, argv))
