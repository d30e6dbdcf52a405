"""Run bags from the in-process simulation: the real message types, serialised by rclpy.

:func:`simulation_messages` turns a :class:`~vega_sim.closed_loop.SimulationResult` into the
messages the SIL nodes publish for the same run — ``VehicleState`` at every frame time
t_start … t_end and ``/clock`` at those of :func:`vega_bus.schedule.clock_frames`,
``InsMeasurement`` per frame, ``TvcCommand`` and ``StepDiagnostics`` per controller step,
``ActuatorState`` per frame with its physics-rate samples — as (topic, log time [ns], rclpy
message) in the recorder's file order ((log time, :data:`vega_bus.topics.RECORD_ORDER`)),
each filled from its record (:mod:`vega_bus.records`) by :func:`vega_bus.wire.to_msg`, as
the nodes fill theirs. Tests may alter them (a NaN, a dropped message, a stalled stamp)
before :func:`write_messages` serialises them with ``rclpy.serialization.serialize_message``
into a run bag through :class:`vega_bags.bagio.RunBagWriter`.

Used by the bag tests and ``bench/bench_check.py`` (bags without starting the SIL), and as
the reference for comparing a SIL bag with the in-process run. The controller's wall-clock
step time is not simulated: every ``/vega/diagnostics`` message carries ``compute_time_s``
(default 50 µs, the order of the measured controller step).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Mapping

from vega_bus import topics, wire
from vega_bus.records import ActuatorOut, CommandOut, InsOut, TruthOut
from vega_bus.schedule import clock_frames
from vega_bus.timing import NS_PER_MS, ms_to_stamp

from vega_bags import bagio

__all__ = ["scenario_yaml", "simulation_messages", "write_messages", "write_simulation_bag"]



def scenario_yaml(scenario) -> str:
    """YAML text of a scenario that :func:`vega_sim.scenario.parse_scenario` reads back
    (:func:`vega_sim.scenario.dump_scenario`)."""
    from vega_sim.scenario import dump_scenario

    return dump_scenario(scenario)


def _stamp(msg_time, t_ms: int) -> None:
    msg_time.sec, msg_time.nanosec = ms_to_stamp(int(t_ms))


def simulation_messages(result, *, compute_time_s: float = 5e-5
                        ) -> list[tuple[str, int, Any]]:
    """The messages of an in-process run, as the SIL publishes them.

    Parameters
    ----------
    result
        :class:`vega_sim.closed_loop.SimulationResult`.
    compute_time_s
        ``StepDiagnostics.compute_time_s`` of every command's diagnostics [s].

    Returns
    -------
    list of (topic, log time [ns], rclpy message)
        Sorted by log time, then in :data:`vega_bus.topics.RECORD_ORDER` (the recorder's
        file order).
    """
    from rosgraph_msgs.msg import Clock
    from vega_msgs.msg import (ActuatorState, InsMeasurement, StepDiagnostics, TvcCommand,
                               VehicleState)

    out: list[tuple[str, int, Any]] = []
    r = result
    ticks = set(clock_frames(len(r.t_ms) - 1))
    for i, t_ms in enumerate(r.t_ms.tolist()):
        m = wire.to_msg(TruthOut(
            stamp_ms=t_ms, seq=i, pitch_rad=float(r.theta_rad[i]),
            pitch_rate_radps=float(r.theta_dot_radps[i]), drift_m=float(r.z_m[i]),
            drift_rate_mps=float(r.z_dot_mps[i]), aoa_rad=float(r.alpha_rad[i]),
            q_alpha_pa_rad=float(r.q_alpha_pa_rad[i]), dynamic_pressure_pa=float(r.q_pa[i]),
            mach=float(r.mach[i]), velocity_mps=float(r.v_mps[i]), altitude_m=float(r.h_m[i]),
            wind_mps=float(r.wind_mps[i]), bending_q=tuple(r.bending_q[i].tolist()),
            bending_qdot=tuple(r.bending_qdot[i].tolist())), VehicleState())
        out.append((topics.TRUTH.name, t_ms * NS_PER_MS, m))
        if i in ticks:
            c = Clock()
            _stamp(c.clock, t_ms)
            out.append((topics.CLOCK.name, t_ms * NS_PER_MS, c))
    for i, t_ms in enumerate(r.ins_stamp_ms.tolist()):
        m = wire.to_msg(InsOut(
            stamp_ms=t_ms, sample_ms=int(r.ins_sample_ms[i]), seq=i,
            pitch_rad=float(r.ins_theta_rad[i]), pitch_rate_radps=float(r.ins_theta_dot_radps[i]),
            drift_m=float(r.ins_z_m[i]), drift_rate_mps=float(r.ins_z_dot_mps[i]),
            velocity_mps=float(r.ins_v_mps[i]), valid=True), InsMeasurement())
        out.append((topics.INS.name, t_ms * NS_PER_MS, m))
    for i, t_ms in enumerate(r.cmd_stamp_ms.tolist()):
        m = wire.to_msg(CommandOut(
            stamp_ms=t_ms, sample_ms=int(r.cmd_sample_ms[i]), seq=i,
            deflection_cmd_rad=float(r.cmd_rad[i]), scheduling_velocity_mps=float(r.cmd_v_mps[i]),
            status=int(r.cmd_status[i])), TvcCommand())
        out.append((topics.TVC_CMD.name, t_ms * NS_PER_MS, m))
        d = StepDiagnostics(seq=i, compute_time_s=float(compute_time_s))
        d.header.stamp = m.header.stamp
        d.header.frame_id = topics.DIAGNOSTICS.publisher
        out.append((topics.DIAGNOSTICS.name, t_ms * NS_PER_MS, d))
    dt_ms = int(r.act_t_ms[1] - r.act_t_ms[0])
    per_frame = int(r.ins_stamp_ms.size and (r.act_t_ms.size - 1) // r.ins_stamp_ms.size)
    for f in range(per_frame and (r.act_t_ms.size - 1) // per_frame):
        lo, hi = 1 + f * per_frame, 1 + (f + 1) * per_frame
        t_ms = int(r.act_t_ms[hi - 1])
        m = wire.to_msg(ActuatorOut(
            stamp_ms=t_ms, seq=f, deflection_samples_rad=tuple(r.beta_rad[lo:hi].tolist()),
            rate_samples_radps=tuple(r.beta_dot_radps[lo:hi].tolist()),
            accel_samples_radps2=tuple(r.beta_ddot_radps2[lo:hi].tolist()),
            command_samples_rad=(), sample_period_s=dt_ms / 1000.0), ActuatorState())
        out.append((topics.ACTUATOR.name, t_ms * NS_PER_MS, m))
    out.sort(key=lambda item: (item[1], topics.RECORD_ORDER[item[0]]))
    return out


def write_messages(path: str | Path, messages: Iterable[tuple[str, int, Any]],
                   metadata: Mapping[str, str]) -> Path:
    """Serialise ``messages`` (topic, log time [ns], rclpy message) with rclpy into a new
    run bag at ``path`` with ``metadata``; returns the path."""
    from rclpy.serialization import serialize_message

    with bagio.RunBagWriter(path, metadata) as bag:
        for topic, t_ns, message in messages:
            bag.write(topic, t_ns, serialize_message(message))
    return Path(path)


def write_simulation_bag(path: str | Path, result, table_path: str | Path, *,
                         compute_time_s: float = 5e-5, git_rev: str | None = None) -> Path:
    """Write the run bag of an in-process run (metadata: its scenario, seed, table and the
    guidance reference the scenario names)."""
    from vega_gnc.guidance_reference import reference_path

    meta = bagio.run_metadata(result.scenario.name, scenario_yaml(result.scenario),
                              result.seed, table_path, git_rev=git_rev,
                              guidance_reference=reference_path(result.scenario.guidance))
    return write_messages(path, simulation_messages(result, compute_time_s=compute_time_s),
                          meta)
