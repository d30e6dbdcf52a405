"""Build the truth-side step objects of a scenario: the one recipe the in-process simulation
(:func:`vega_sim.closed_loop.build_steps`) and the SIL nodes (:mod:`vega_plant.nodes`) share.

* :func:`derive_seeds` — the (wind, INS) generator seeds of a scenario seed;
* :func:`loop_timing` — the loop timing of a scenario (vehicle.yaml + the ``delay_s``
  deviation on the actuator delay);
* :func:`make_plant`, :func:`make_ins`, :func:`make_actuator` — the step objects at t_start.

The controller's step object is built from the table and the timing alone
(:class:`vega_gnc.controller_step.ControllerStep`): the flight side needs no scenario.
"""

from __future__ import annotations

import numpy as np

from vega_bus.timing import LoopTiming

from vega_model.actuator import ActuatorParams
from vega_model.ins import InsParams
from vega_model.parameters import ModelContext, default_context
from vega_sim.scenario import Scenario
from vega_sim.device_steps import ActuatorStep, InsStep
from vega_sim.plant_step import PlantStep, PlantWind, parameter_track
from vega_model.wind import GustProfile, ProfileChange

__all__ = ["derive_seeds", "loop_timing", "make_plant", "initial_plant_state", "make_ins",
           "make_actuator", "FROM_SCENARIO"]

FROM_SCENARIO = object()
"""Default of the ``reference`` arguments: load the guidance reference the scenario names."""


def derive_seeds(seed: int) -> tuple[int, int]:
    """Independent (wind, INS) generator seeds from a scenario seed.

    ``numpy.random.SeedSequence(seed).spawn(2)``, one 64-bit state word each: the two noise
    streams are independent, and the SIL nodes derive the same seeds from the same number.
    """
    children = np.random.SeedSequence(int(seed)).spawn(2)
    wind, ins = (int(c.generate_state(1, np.uint64)[0]) for c in children)
    return wind, ins


def loop_timing(scenario: Scenario, context: ModelContext | None = None) -> LoopTiming:
    """The loop timing of a scenario (its ``delay_s`` deviation goes to the actuator delay)."""
    context = context if context is not None else default_context()
    return LoopTiming.from_vehicle(context.vehicle, scenario.deviations.get("delay_s", 0.0))


def make_plant(scenario: Scenario, *, seed: int | None = None,
               context: ModelContext | None = None,
               parameter_refresh_ms: int | None = None,
               reference=FROM_SCENARIO) -> PlantStep:
    """The plant node of a scenario (with its wind), at t_start.

    Parameters
    ----------
    scenario
        Span, plant model, initial state, wind and deviations.
    seed
        Overrides ``scenario.seed`` (the wind seed comes from :func:`derive_seeds`).
    context
        Model data sources (default: the shipped vehicle data and flight conditions).
    parameter_refresh_ms
        Model-parameter refresh interval (a divisor of the 10 ms frame; default: the frame).
    reference
        As :func:`initial_plant_state`.
    """
    context = context if context is not None else default_context()
    timing = loop_timing(scenario, context)
    refresh = timing.frame_ms if parameter_refresh_ms is None else int(parameter_refresh_ms)
    track = parameter_track(context, scenario.t_start_ms, scenario.t_end_ms,
                            frame_ms=timing.frame_ms, refresh_ms=refresh,
                            dt_ms=timing.physics_dt_ms, deviations=scenario.deviations)
    w = scenario.wind
    gust = None if w.gust is None else GustProfile(w.gust.start_s, w.gust.duration_s,
                                                   w.gust.amplitude_mps)
    wind = PlantWind(context.vehicle, track, profile=w.profile, turbulence=w.turbulence,
                     gust=gust, seed=derive_seeds(scenario.seed if seed is None else seed)[0],
                     thesis_constant_dryden=w.thesis_constant_dryden,
                     dt_ms=timing.physics_dt_ms,
                     change=ProfileChange(w.profile_scale, w.profile_shift_m))
    return PlantStep(track, wind, scenario.plant,
                     initial_plant_state(scenario, context, reference=reference),
                     scenario.initial_state.beta_rad)


def initial_plant_state(scenario: Scenario, context: ModelContext | None = None, *,
                        reference=FROM_SCENARIO) -> tuple[float, ...]:
    """The plant state at t_start: the scenario's ``initial_state`` taken as deviations from
    the flight its guidance reference describes (docs/GUIDANCE.md §5), so that a scenario cut
    to start mid-flight starts on the reference; with ``guidance: none`` (or a reference that
    is 0 there, as at lift-off) it is ``initial_state`` itself.

    The reference holds what the INS measures on the reference flight; the rigid states are
    recovered by the INS kinematics of thesis Eqs. 2.33-2.36 with the bending coordinates 0:
    θ = θ_INS, θ̇ = θ̇_INS, z = z_INS + l·θ, ż = ż_INS + l·θ̇, l = x_INS − x_CG at t_start.

    ``reference``: the loaded reference the scenario's ``guidance`` names (a
    :class:`vega_gnc.guidance_reference.GuidanceReference`, or None for ``none``), passed by
    a caller that already holds it — the batched engine loads the file once for all its
    samples; by default the file is loaded here."""
    from vega_gnc.guidance_reference import resolve_reference

    x0 = list(scenario.initial_state.plant_state())
    if reference is FROM_SCENARIO:
        reference = resolve_reference(scenario.guidance)
    if reference is None:
        return tuple(x0)
    context = context if context is not None else default_context()
    th, thd, z_ins, zd_ins, _ = reference.at(scenario.t_start_s)
    if th == thd == z_ins == zd_ins == 0.0:
        return tuple(x0)
    lever = context.parameters(scenario.t_start_s).l_ins_m
    for i, value in enumerate((th, thd, z_ins + lever * th, zd_ins + lever * thd)):
        x0[i] += float(value)
    return tuple(x0)


def make_ins(scenario: Scenario, *, seed: int | None = None,
             context: ModelContext | None = None) -> InsStep:
    """The INS node of a scenario (noise seed from :func:`derive_seeds`). Its model parameters
    at a sample time are :func:`vega_sim.plant_step.parameters_at` with the scenario's
    deviations."""
    context = context if context is not None else default_context()
    return InsStep(InsParams.from_vehicle(context.vehicle), loop_timing(scenario, context),
                   derive_seeds(scenario.seed if seed is None else seed)[1],
                   scenario.sensor_noise)


def make_actuator(scenario: Scenario, *, context: ModelContext | None = None) -> ActuatorStep:
    """The actuator node of a scenario (its ``actuator`` deviation scales the bandwidth)."""
    context = context if context is not None else default_context()
    params = ActuatorParams.from_vehicle(
        context.vehicle, bandwidth_scale=1.0 + scenario.deviations.get("actuator", 0.0))
    return ActuatorStep(params, loop_timing(scenario, context), scenario.t_start_ms,
                        scenario.initial_state.beta_rad)
