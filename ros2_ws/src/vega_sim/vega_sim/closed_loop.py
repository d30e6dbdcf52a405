"""The in-process closed-loop simulation: the SIL's node step functions, called in lockstep.

:func:`run_scenario` flies a :class:`~vega_sim.scenario.Scenario` with a controller table
through the same classes the SIL nodes wrap (:mod:`vega_sim.plant_step`,
:mod:`vega_sim.device_steps`, :mod:`vega_gnc.controller_step`), one frame (10 ms) at a time,
in the order the lockstep SIL runs them::

    truth(t_f) ──► INS.sample ──► controller.step (every 2nd sample) ──► actuator.receive
         ▲                                                                    │
         └──────────── plant.advance(samples) ◄── actuator.advance(t_f) ◄─────┘

All times are integer milliseconds (:mod:`vega_bus.timing`); the latencies are carried
by the stamps (INS +12 ms, controller +12 ms, actuator +15 ms), not by the call order, so the
result does not depend on when within a frame a node is called. Same scenario and seed →
identical arrays. The SIL must reproduce this run (same scenario, seed and table).

The run covers the frames [t_start, t_end): the INS samples at their starts, the plant's truth
is recorded at every frame time up to and including t_end, the actuator at every physics step.

A SIL node builds its part with the factory the in-process run uses
(:mod:`vega_sim.assembly`: ``make_plant``, ``make_ins`` — its model parameters at a sample
time are :func:`vega_sim.plant_step.parameters_at` —, ``make_actuator``; the controller:
:class:`vega_gnc.controller_step.ControllerStep` from the table and the loop timing) and
converts stamps with :mod:`vega_bus.timing`; tests/sim/test_closed_loop.py checks that
nodes built and driven that way reproduce :func:`run_scenario` bit for bit.

Test hook (off by default, no SIL counterpart): ``run_scenario(..., perturbation=
LoopPerturbation(...))`` inserts a gain and/or a delay at the actuator input inside a time
window (:class:`LoopPerturbation`; the time-domain margins of
:mod:`vega_analysis.time_margins`). Without it the run is the one above, bit for bit.
"""

from __future__ import annotations

import bisect
import gc
import math
from contextlib import contextmanager
from dataclasses import dataclass, fields
from pathlib import Path
from typing import NamedTuple

import numpy as np

from vega_bus.records import CommandOut
from vega_bus.timing import LoopTiming
from vega_gnc.controller_runtime import RuntimeLimits
from vega_gnc.controller_table import ControllerTable, load_controller_table
from vega_gnc.controller_step import ControllerStep
from vega_gnc.guidance_reference import GuidanceReference, resolve_reference
from vega_model.parameters import ModelContext, default_context
from vega_sim.scenario import Scenario, load_scenario
from vega_sim.device_steps import ActuatorStep, InsStep
from vega_sim.plant_step import PlantStep
from vega_sim.assembly import loop_timing, make_actuator, make_ins, make_plant

from vega_sim.requirements import RequirementReport, RequirementSpec, evaluate_requirements

__all__ = ["FROM_SCENARIO", "make_controller", "scenario_reference", "LoopSteps", "build_steps",
           "SimulationResult", "LoopPerturbation", "run_scenario"]

FROM_SCENARIO = "from scenario"
"""``reference`` of :func:`make_controller`: the guidance reference the scenario names."""


def make_controller(scenario: Scenario, table: ControllerTable, *,
                    context: ModelContext | None = None,
                    limits: RuntimeLimits = RuntimeLimits(),
                    reference: GuidanceReference | None | str = FROM_SCENARIO
                    ) -> ControllerStep:
    """The controller node of a scenario with a controller table, tracking a guidance
    reference (``reference``: a loaded one, None for none, or :data:`FROM_SCENARIO`: the one
    the scenario names, :func:`scenario_reference`)."""
    if isinstance(reference, str):
        reference = scenario_reference(scenario)
    return ControllerStep(table, loop_timing(scenario, context), limits, reference=reference)


def scenario_reference(scenario: Scenario) -> GuidanceReference | None:
    """The guidance reference a scenario flies (None for ``guidance: none``).

    Raises
    ------
    BadInput
        A reference file that does not load (one line naming it).
    """
    return resolve_reference(scenario.guidance)


@dataclass(frozen=True)
class LoopSteps:
    """The nodes of one run, built from a scenario as the SIL nodes build theirs."""

    timing: LoopTiming
    plant: PlantStep
    ins: InsStep
    controller: ControllerStep
    actuator: ActuatorStep


def build_steps(scenario: Scenario, table: ControllerTable, *, seed: int | None = None,
                context: ModelContext | None = None, parameter_refresh_ms: int | None = None,
                limits: RuntimeLimits = RuntimeLimits()) -> LoopSteps:
    """All four nodes of a scenario, ready at t_start (:func:`make_plant`, :func:`make_ins`,
    :func:`make_controller`, :func:`make_actuator` with the same arguments)."""
    context = context if context is not None else default_context()
    return LoopSteps(
        timing=loop_timing(scenario, context),
        plant=make_plant(scenario, seed=seed, context=context,
                         parameter_refresh_ms=parameter_refresh_ms),
        ins=make_ins(scenario, seed=seed, context=context),
        controller=make_controller(scenario, table, context=context, limits=limits),
        actuator=make_actuator(scenario, context=context))


@dataclass(frozen=True)
class SimulationResult:
    """Time histories of one closed-loop run (SI units; times as integer ms and seconds).

    Truth, at every frame time t_start … t_end (``t_ms``): ``theta_rad``, ``theta_dot_radps``,
    ``z_m``, ``z_dot_mps``, ``alpha_rad``, ``q_alpha_pa_rad``, ``q_pa``, ``mach``, ``v_mps``,
    ``h_m``, ``wind_mps``, ``bending_q`` and ``bending_qdot`` (N×2).
    Actuator, at every physics step t_start … t_end (``act_t_ms``; index 0 = initial state):
    ``beta_rad``, ``beta_dot_radps``, ``beta_ddot_radps2`` and ``beta_cmd_rad`` (the command
    held over the step ending at the sample).
    INS, one per frame (sample ``ins_sample_ms``, stamp ``ins_stamp_ms``): ``ins_theta_rad``,
    ``ins_theta_dot_radps``, ``ins_z_m``, ``ins_z_dot_mps``, ``ins_v_mps``.
    Controller, one per command (``cmd_stamp_ms``, from the sample ``cmd_sample_ms``):
    ``cmd_rad``, ``cmd_v_mps`` (scheduling velocity), ``cmd_status`` (TvcCommand STATUS_*).
    """

    scenario: Scenario
    seed: int
    t_ms: np.ndarray
    theta_rad: np.ndarray
    theta_dot_radps: np.ndarray
    z_m: np.ndarray
    z_dot_mps: np.ndarray
    alpha_rad: np.ndarray
    q_alpha_pa_rad: np.ndarray
    q_pa: np.ndarray
    mach: np.ndarray
    v_mps: np.ndarray
    h_m: np.ndarray
    wind_mps: np.ndarray
    bending_q: np.ndarray
    bending_qdot: np.ndarray
    act_t_ms: np.ndarray
    beta_rad: np.ndarray
    beta_dot_radps: np.ndarray
    beta_ddot_radps2: np.ndarray
    beta_cmd_rad: np.ndarray
    ins_sample_ms: np.ndarray
    ins_stamp_ms: np.ndarray
    ins_theta_rad: np.ndarray
    ins_theta_dot_radps: np.ndarray
    ins_z_m: np.ndarray
    ins_z_dot_mps: np.ndarray
    ins_v_mps: np.ndarray
    cmd_sample_ms: np.ndarray
    cmd_stamp_ms: np.ndarray
    cmd_rad: np.ndarray
    cmd_v_mps: np.ndarray
    cmd_status: np.ndarray

    @property
    def t_s(self) -> np.ndarray:
        """Truth times [s]."""
        return self.t_ms / 1000.0

    @property
    def act_t_s(self) -> np.ndarray:
        """Actuator sample times [s]."""
        return self.act_t_ms / 1000.0

    def arrays(self) -> dict[str, np.ndarray]:
        """Every time history by field name (for comparisons and saving)."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if isinstance(getattr(self, f.name), np.ndarray)}

    def metrics(self, spec: RequirementSpec | None = None) -> RequirementReport:
        """Requirement metrics, margins and pass/fail (thesis Table 3.1), with the thesis'
        Table 5.1 figures side by side (:func:`vega_sim.requirements.evaluate_requirements`)."""
        return evaluate_requirements(self.t_s, self.q_alpha_pa_rad, self.mach, self.z_m,
                                     self.z_dot_mps, self.act_t_s, self.beta_rad,
                                     beta_cmd_rad=self.beta_cmd_rad, spec=spec)


@dataclass(frozen=True)
class LoopPerturbation:
    """A perturbation of the loop at the actuator input inside a time window (a test hook).

    Without it the actuator holds, from time t on, the newest command whose stamp + actuator
    latency is ≤ t: call that β_c(t). With it, the actuator's input is

    * k·β_c(t − Δ) for t in [``t0_ms``, ``t1_ms``) (k = ``gain``, Δ = ``delay_ms``),
    * β_c(t) elsewhere,

    switched at t0 and t1 exactly (1 ms grid): a gain and a transport delay inserted at the
    actuator input, the loop broken where the frequency-domain margins break it
    (:mod:`vega_loops.margins`). At t0 the nozzle goes back to the command of Δ
    earlier; at t1 it returns to the newest one. The controller is not told (``cmd_rad``
    records what it computed, ``beta_cmd_rad`` what the actuator held); the actuator's
    position and rate limits stay as they are (the saturation is part of the nonlinear loop).

    Attributes
    ----------
    t0_ms, t1_ms
        Window on the actuator's time [ms], t0_ms <= t1_ms (whole ms, vega_bus.timing).
    gain
        Finite factor on the command [1].
    delay_ms
        Extra delay >= 0 [ms] on the 1 ms grid of the loop.
    """

    t0_ms: int
    t1_ms: int
    gain: float = 1.0
    delay_ms: int = 0

    def __post_init__(self):
        for name in ("t0_ms", "t1_ms", "delay_ms"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ValueError(f"LoopPerturbation.{name} must be a whole number of ms, "
                               f"got {value!r}")
        if not self.t0_ms <= self.t1_ms:
            raise ValueError(f"LoopPerturbation window [{self.t0_ms}, {self.t1_ms}) ms: need "
                           "t0_ms <= t1_ms")
        if self.delay_ms < 0:
            raise ValueError(f"LoopPerturbation.delay_ms must be >= 0, got {self.delay_ms!r}")
        if isinstance(self.gain, bool) or not math.isfinite(self.gain):
            raise ValueError(f"LoopPerturbation.gain must be a finite number, got {self.gain!r}")


class _Held(NamedTuple):
    """A command as :meth:`ActuatorStep.receive` takes it."""

    stamp_ms: int
    seq: int
    deflection_cmd_rad: float


class _PerturbedActuator:
    """The actuator node behind a :class:`LoopPerturbation`.

    It keeps the controller's commands (application time = stamp + latency, deflection) and,
    before each frame, hands the actuator one command per change of its perturbed input in the
    frame (a command's application, shifted by Δ inside the window, and the window's edges),
    stamped so that the actuator applies it at that time."""

    def __init__(self, perturbation: LoopPerturbation, actuator: ActuatorStep,
                 timing: LoopTiming):
        self._p, self._actuator = perturbation, actuator
        self._latency_ms, self._frame_ms = timing.actuator_latency_ms, timing.frame_ms
        self._times: list[int] = []                # application times, increasing
        self._values: list[float] = []
        self._seq = 0

    def receive(self, cmd: CommandOut) -> None:
        """Keep ``cmd`` (commands come in stamp order)."""
        self._times.append(cmd.stamp_ms + self._latency_ms)
        self._values.append(cmd.deflection_cmd_rad)

    def _input(self, t_ms: int) -> float | None:
        """The perturbed actuator input from ``t_ms`` on (None: no command yet)."""
        p = self._p
        inside = p.t0_ms <= t_ms < p.t1_ms
        k = bisect.bisect_right(self._times, t_ms - p.delay_ms if inside else t_ms) - 1
        if k < 0:
            return None
        return p.gain * self._values[k] if inside else self._values[k]

    def advance(self, t_ms: int):
        """Hand the actuator the input changes in [t_ms, t_ms + frame), then
        :meth:`ActuatorStep.advance`."""
        p, times, end = self._p, self._times, t_ms + self._frame_ms

        def applied(shift):               # application times + shift that fall in the frame
            return (a + shift for a in times[bisect.bisect_left(times, t_ms - shift):
                                             bisect.bisect_left(times, end - shift)])

        changes = {t for t in (p.t0_ms, p.t1_ms) if t_ms <= t < end}
        changes.update(t for t in applied(0) if not p.t0_ms <= t < p.t1_ms)
        changes.update(t for t in applied(p.delay_ms) if p.t0_ms <= t < p.t1_ms)
        for t in sorted(changes):
            value = self._input(t)
            if value is not None:
                self._actuator.receive(_Held(t - self._latency_ms, self._seq, value))
                self._seq += 1
        return self._actuator.advance(t_ms)


def _columns(values: list, n_fields: int) -> np.ndarray:
    """Records of ``n_fields`` numbers, concatenated, as a (n_fields, n_records) float array
    with contiguous rows."""
    return np.array(values, dtype=float).reshape(-1, n_fields).T.copy()


def run_scenario(scenario: Scenario | str | Path, table: ControllerTable | str | Path,
                 seed: int | None = None, *, context: ModelContext | None = None,
                 parameter_refresh_ms: int | None = None,
                 limits: RuntimeLimits = RuntimeLimits(),
                 perturbation: LoopPerturbation | None = None) -> SimulationResult:
    """Fly a scenario in process and return its time histories.

    Parameters
    ----------
    scenario
        A :class:`Scenario`, or a shipped scenario name / YAML path (:func:`load_scenario`).
    table
        A :class:`ControllerTable` or the path of a controller table file.
    seed
        Overrides the scenario's seed.
    context, parameter_refresh_ms, limits
        See :func:`build_steps`.
    perturbation
        Scale and/or delay the commands of a window at the actuator input (a test hook,
        :class:`LoopPerturbation`); None (default): the flight as the SIL flies it.

    Raises
    ------
    BadInput
        Bad scenario or table (one line), a span outside the flight-condition table, or a
        table whose sample time is not the controller period
        (:class:`vega_core.errors.BadInput`).
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if not isinstance(table, ControllerTable):
        table = load_controller_table(table)
    with _collector_paused():
        return _run(scenario, table, seed, context, parameter_refresh_ms, limits, perturbation)


@contextmanager
def _collector_paused():
    """Python's cyclic garbage collector off for the duration (the reference counts still free
    everything at once: a run makes no reference cycles).

    A run allocates ≈ 0.3 million objects (the parameter track's 10 001 sets, a record per node
    and frame); with the collector on they trigger full collections, which traverse every object
    of the process (the memoised tracks included): ≈ 60 ms of CPU per Monte Carlo flight,
    ≈ 13 % (docs/MONTE_CARLO.md §8). Only the speed changes, never a number. The collector's state
    is restored on exit (left off if it was off)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _run(scenario: Scenario, table: ControllerTable, seed, context, parameter_refresh_ms,
         limits, perturbation) -> SimulationResult:
    """:func:`run_scenario` once its scenario and table are loaded."""
    nodes = build_steps(scenario, table, seed=seed, context=context,
                        parameter_refresh_ms=parameter_refresh_ms, limits=limits)
    plant, ins, controller, actuator = nodes.plant, nodes.ins, nodes.controller, nodes.actuator
    if perturbation is not None:
        actuator = _PerturbedActuator(perturbation, actuator, nodes.timing)
    # the INS reads its lever arm and mode shapes from the track's views (the same numbers as
    # the parameter sets the SIL's INS node reads, ParameterTrack.at_ms)
    at_ms = plant.track.view_ms
    # flat lists of numbers (the per-step objects die at once: no garbage-collector load)
    truths, bending, measurements, commands = [], [], [], []
    beta, rate, accel, held = [], [], [], []
    truth = plant.output()
    for _ in range(plant.track.n_frames):
        truths += truth[:13]
        bending += truth.bending_q + truth.bending_qdot
        t = truth.stamp_ms
        meas = ins.sample(truth, at_ms(t))
        measurements += meas
        cmd = controller.step(meas)
        if cmd is not None:
            actuator.receive(cmd)
            commands += cmd
        frame = actuator.advance(t)
        beta += frame.deflection_samples_rad
        rate += frame.rate_samples_radps
        accel += frame.accel_samples_radps2
        held += frame.command_samples_rad
        truth = plant.advance(frame.deflection_samples_rad, frame.rate_samples_radps)
    truths += truth[:13]
    bending += truth.bending_q + truth.bending_qdot

    (t_ms, _seq, theta, theta_dot, z, z_dot, alpha, q_alpha, q_pa, mach, v,
     h, wind) = _columns(truths, 13)
    bending = _columns(bending, 4).T
    (ins_stamp, ins_sample, _iseq, i_theta, i_theta_dot, i_z, i_z_dot, i_v,
     _valid) = _columns(measurements, 9)
    c_stamp, c_sample, _cseq, c_rad, c_v, c_status = _columns(commands, 6)
    dt = nodes.timing.physics_dt_ms
    beta0 = scenario.initial_state.beta_rad

    def stacked(samples, first):
        return np.array([first] + samples, dtype=float)

    return SimulationResult(
        scenario=scenario, seed=scenario.seed if seed is None else int(seed),
        t_ms=t_ms.astype(np.int64), theta_rad=theta, theta_dot_radps=theta_dot, z_m=z,
        z_dot_mps=z_dot, alpha_rad=alpha, q_alpha_pa_rad=q_alpha, q_pa=q_pa, mach=mach,
        v_mps=v, h_m=h, wind_mps=wind, bending_q=bending[:, :2].copy(),
        bending_qdot=bending[:, 2:].copy(),
        act_t_ms=scenario.t_start_ms + dt * np.arange(len(beta) + 1, dtype=np.int64),
        beta_rad=stacked(beta, beta0), beta_dot_radps=stacked(rate, 0.0),
        beta_ddot_radps2=stacked(accel, 0.0), beta_cmd_rad=stacked(held, beta0),
        ins_sample_ms=ins_sample.astype(np.int64), ins_stamp_ms=ins_stamp.astype(np.int64),
        ins_theta_rad=i_theta, ins_theta_dot_radps=i_theta_dot, ins_z_m=i_z,
        ins_z_dot_mps=i_z_dot, ins_v_mps=i_v,
        cmd_sample_ms=c_sample.astype(np.int64), cmd_stamp_ms=c_stamp.astype(np.int64),
        cmd_rad=c_rad.copy(), cmd_v_mps=c_v.copy(), cmd_status=c_status.astype(np.int64))
