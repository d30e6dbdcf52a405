"""The flight controller of the closed loop as a step function (the controller node's core).

Plain Python, no ROS: the in-process simulation (:mod:`vega_sim.closed_loop`) and the SIL node
``vega_gnc tvc_controller`` (:mod:`vega_gnc.controller_node`) call this same class, so both
produce the same numbers. Every measurement whose sample time is a multiple of the controller
period (20 ms) goes through :class:`vega_gnc.controller_runtime.ControllerRuntime` exactly as
flown, at its arrival; the command is stamped arrival + computing latency (12 ms)
(:mod:`vega_bus.timing`). → :class:`vega_bus.records.CommandOut` (``TvcCommand``)

A measurement is a :class:`vega_bus.records.InsOut` (the flight side never imports the truth
side, vega_sim). Both records live in :mod:`vega_bus.records` and are re-exported here.
"""

from __future__ import annotations

from vega_bus.records import CommandOut, InsOut
from vega_bus.timing import LoopTiming, check_ms

from vega_gnc.controller_runtime import ControllerRuntime, Measurement, RuntimeLimits
from vega_gnc.controller_table import ControllerTable
from vega_gnc.guidance_reference import GuidanceReference

__all__ = ["CommandOut", "ControllerStep"]


class ControllerStep:
    """Flight-controller node: the table-driven runtime at the controller rate.

    Parameters
    ----------
    table
        Validated controller table; its ``dt_s`` must be the controller period.
    timing
        Loop timing (controller period, computing latency).
    limits
        Runtime safety parameters.
    rate_mps2
        ρ̇ slice of a rate-dependent table (None: the runtime's default, the upper slice).
    reference
        Wind-biased guidance reference the controller tracks (None: zero references, no
        feed-forward).

    Notes
    -----
    The runtime receives ``Measurement(stamp_s = sample time, …)`` and is stepped at
    ``now_s`` = the measurement's arrival (its stamp), so its staleness check sees the sensor
    latency (12 ms ≤ ``max_age_s``).
    """

    def __init__(self, table: ControllerTable, timing: LoopTiming,
                 limits: RuntimeLimits = RuntimeLimits(), rate_mps2: float | None = None,
                 reference: GuidanceReference | None = None):
        check_ms(table.dt_s, timing.controller_period_ms, "controller table dt_s")
        self.runtime = ControllerRuntime(table, limits, rate_mps2, reference)
        self._period_ms = timing.controller_period_ms
        self._latency_ms = timing.computing_latency_ms
        self._seq = 0

    def step(self, meas: InsOut) -> CommandOut | None:
        """Process one measurement; None if its sample time is not on the controller period."""
        if meas.sample_ms % self._period_ms:
            return None
        cmd = self.runtime.step(
            Measurement(meas.sample_ms / 1000.0, meas.pitch_rad, meas.pitch_rate_radps,
                        meas.drift_m, meas.drift_rate_mps, meas.velocity_mps, meas.valid),
            now_s=meas.stamp_ms / 1000.0)
        out = CommandOut(meas.stamp_ms + self._latency_ms, meas.sample_ms, self._seq,
                         cmd.deflection_cmd_rad, cmd.scheduling_velocity_mps, cmd.status)
        self._seq += 1
        return out
