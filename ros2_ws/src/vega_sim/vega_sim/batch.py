"""The batched in-process flight engine: N dispersed flights of one campaign flown at once.

:func:`fly_batch` flies N scenarios (typically the dispersed samples of one base scenario,
``vega_campaign.campaign.sample_scenario``) through the same closed loop as
:func:`vega_sim.closed_loop.run_scenario`, frame by frame in the lockstep order, but with the
state of every sample in arrays:

* the truth side of all samples — actuator node, nonlinear plant, truth outputs, INS — is
  advanced by one compiled call between two controller steps
  (:func:`vega_model.batch_kernel.advance_frames`, the per-flight step classes' operations);
* the controller of all samples is stepped at once by
  :class:`vega_gnc.controller_runtime.ControllerBatch`, the runtime's step element-wise over
  the samples, built from the same table and limits, each sample with its own guidance
  reference (a flight-day campaign re-biases every sample's).

Every input that differs between samples is an array over samples, built per sample by the
per-flight factories themselves (:mod:`vega_sim.assembly`): the parameter track of the
sample's deviations (its kernel constants and per-entry views), its whole wind sequence
(profile change, turbulence seed, gust), its INS noise stream (the INS seed's generator, in
the order :class:`vega_model.ins.InsSensor` draws it), initial state, actuator bandwidth and
latency. So each flight is the per-flight one: tests/sim/test_batch.py compares every
recorded array of dispersed samples (gusts and the worst of a campaign included) with
:func:`run_scenario` bit for bit, and the requirement verdicts.

What a batch shares: the span, the plant model (nonlinear only), whether a guidance
reference is flown (each sample may fly its own), the loop's frame, physics step and
controller period, and the controller table; no ``thesis_constant_dryden`` wind and no
:class:`vega_sim.closed_loop.LoopPerturbation` (those runs stay on the per-flight path).
:func:`fly_batch` refuses anything else (:class:`vega_core.errors.BadInput`).

Memory: ≈ 9 MB per 100 s sample while the batch flies (parameter constants, wind, records);
callers bound it by the batch size. The results' float records are views of the batch's record
arrays, which live as long as any result of the batch does.
"""

from __future__ import annotations

import gc
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vega_core.errors import BadInput
from vega_gnc.controller_runtime import ControllerBatch, RuntimeLimits
from vega_gnc.controller_table import ControllerTable, load_controller_table
from vega_model.actuator import ActuatorParams, TvcActuator
from vega_model.ins import InsParams
from vega_model.parameters import ModelContext, default_context
from vega_sim.assembly import FROM_SCENARIO, derive_seeds, loop_timing, make_plant
from vega_sim.closed_loop import SimulationResult, scenario_reference
from vega_sim.scenario import Scenario

__all__ = ["fly_batch", "batch_refusal"]

# Samples' worth of INS noise InsSensor draws from its generator at a time (vega_model.ins).
_INS_BLOCK = 256


@dataclass
class _Sample:
    """The per-sample inputs of one flight, as the per-flight nodes hold them."""

    x0: np.ndarray                # plant state at t_start (8,)
    beta0: float                  # scenario's initial nozzle angle (the plant's; unclamped)
    consts: np.ndarray | None     # kernel constants of every parameter entry (entries, 24)
    tables: tuple                 # Mach tables (6 arrays)
    views: np.ndarray | None      # ParameterView fields of every entry (entries, 11)
    wind: np.ndarray | None       # wind over every physics step of the track [m/s]
    noise: np.ndarray | None      # the INS's standard normal draws
    noise_on: bool                # the scenario's sensor_noise
    sigma: tuple                  # INS noise σ of the five channels (InsSensor's order)
    act_par: tuple                # TvcActuator constants (batch_kernel.ACTUATOR_PARAMS)
    act_beta: float               # actuator's initial β (clamped to the stops) = held command
    latency_ms: tuple             # (sensor, computing, actuator) [ms]


def _sample_inputs(scenario: Scenario, seed: int, context: ModelContext,
                   n_frames: int, reference=FROM_SCENARIO) -> _Sample:
    """One sample's inputs (flight seed ``seed``), from the factories the per-flight run
    uses; ``reference``: the scenario's guidance reference, loaded once for the batch (as
    :func:`vega_sim.assembly.initial_plant_state`)."""
    plant = make_plant(scenario, seed=seed, context=context, reference=reference)
    track = plant.track
    consts, tables = track.kernel_inputs()
    views = track.view_array()
    n_steps = views.shape[0] * (track.refresh_ms // track.dt_ms)
    # PlantWind: the whole track's sequence (the same numbers frame by frame)
    _, wind = plant.wind.frame_and_array(track.t_start_ms, n_steps)
    timing = loop_timing(scenario, context)
    ins = InsParams.from_vehicle(context.vehicle)
    sigma = (ins.sigma_theta_rad, ins.sigma_theta_dot_radps, ins.sigma_z_m, ins.sigma_z_dot_mps,
             ins.sigma_velocity_mps)
    blocks = -(-(n_frames + 1) // _INS_BLOCK)
    rng = np.random.Generator(np.random.PCG64(derive_seeds(seed)[1]))
    noise = (rng.standard_normal(5 * _INS_BLOCK * blocks) if scenario.sensor_noise
             else np.zeros(5))
    params = ActuatorParams.from_vehicle(
        context.vehicle, bandwidth_scale=1.0 + scenario.deviations.get("actuator", 0.0))
    act = TvcActuator(params, scenario.initial_state.beta_rad)
    act_par = (act._p11, act._p12, act._p21, act._p22, act._w2, act._c, act._half_dt,
               act._pos, act._rate, act._max_step)
    return _Sample(
        x0=plant.state, beta0=float(scenario.initial_state.beta_rad),
        consts=consts, tables=tuple(tables), views=views, wind=np.asarray(wind, dtype=float),
        noise=noise, noise_on=bool(scenario.sensor_noise), sigma=sigma, act_par=act_par,
        act_beta=act.beta_rad,
        latency_ms=(timing.sensor_latency_ms, timing.computing_latency_ms,
                    timing.actuator_latency_ms))


def batch_refusal(scenario: Scenario, first: Scenario,
                  context: ModelContext | None = None) -> str | None:
    """Why :func:`fly_batch` would not fly ``scenario`` in a batch led by ``first`` (None:
    it would). ``batch_refusal(s, s)`` says whether ``s`` can be batched at all; a campaign
    flies the samples refused here through :func:`vega_sim.closed_loop.run_scenario`."""
    context = context if context is not None else default_context()
    if scenario.plant != "nonlinear":
        return f"plant {scenario.plant!r} (the batch flies the nonlinear plant)"
    if scenario.wind.thesis_constant_dryden:
        return "thesis_constant_dryden wind"
    if (scenario.t_start_ms, scenario.t_end_ms) != (first.t_start_ms, first.t_end_ms):
        return "a span other than the first scenario's"
    if (scenario.guidance == "none") != (first.guidance == "none"):
        return "guidance 'none' beside references (all fly a reference or none does)"
    t, t0 = loop_timing(scenario, context), loop_timing(first, context)
    if (t.physics_dt_ms, t.frame_ms, t.controller_period_ms) != (
            t0.physics_dt_ms, t0.frame_ms, t0.controller_period_ms):
        return "a loop timing other than the first scenario's"
    return None


def _check_batch(scenarios: Sequence[Scenario], context: ModelContext) -> None:
    """Refuse a batch that does not share what the engine shares (module docstring)."""
    for s in scenarios:
        why = batch_refusal(s, scenarios[0], context)
        if why is not None:
            raise BadInput(f"fly_batch: scenario {s.name!r} has {why}; fly it with "
                           "run_scenario")


def _stack(arrays) -> np.ndarray:
    return np.ascontiguousarray(np.stack(arrays))


def fly_batch(scenarios: Sequence[Scenario], table: ControllerTable | str | Path,
              seeds: Sequence[int | None] | None = None, *,
              context: ModelContext | None = None,
              limits: RuntimeLimits = RuntimeLimits()) -> list[SimulationResult]:
    """Fly N scenarios at once; the result of each is :func:`run_scenario`'s, bit for bit.

    Parameters
    ----------
    scenarios
        The flights (:class:`Scenario`; see the module docstring for what they must share).
    table
        A :class:`ControllerTable` or the path of a controller table file.
    seeds
        Per scenario, a seed overriding its own (None: the scenario's), as ``run_scenario``'s
        ``seed``.
    context, limits
        As :func:`run_scenario`.

    Returns
    -------
    list of SimulationResult
        One per scenario, in order.

    Raises
    ------
    BadInput
        An empty batch, seeds of another length, or scenarios that do not share the span,
        plant, guidance and loop timing (or with a thesis constant-driven Dryden wind).
    """
    scenarios = list(scenarios)
    if not scenarios:
        raise BadInput("fly_batch: no scenarios")
    if seeds is not None:
        if len(seeds) != len(scenarios):
            raise BadInput(f"fly_batch: {len(seeds)} seeds for {len(scenarios)} scenarios")
    if not isinstance(table, ControllerTable):
        table = load_controller_table(table)
    context = context if context is not None else default_context()
    _check_batch(scenarios, context)
    enabled = gc.isenabled()
    gc.disable()                    # as run_scenario: no reference cycles, no collector load
    try:
        flight_seeds = [s.seed if seed is None else int(seed)
                        for s, seed in zip(scenarios, seeds or [None] * len(scenarios))]
        return _fly(scenarios, flight_seeds, table, context, limits)
    finally:
        if enabled:
            gc.enable()


def _fly(scenarios: list[Scenario], seeds: list[int], table: ControllerTable,
         context: ModelContext, limits: RuntimeLimits) -> list[SimulationResult]:
    """:func:`fly_batch` once its inputs are checked."""
    from vega_model import batch_kernel as bk

    first = scenarios[0]
    timing = loop_timing(first, context)
    t0, frame, dt = first.t_start_ms, timing.frame_ms, timing.physics_dt_ms
    period = timing.controller_period_ms
    n_frames = (first.t_end_ms - t0) // frame
    steps = frame // dt
    n = len(scenarios)
    loaded: dict = {}                                 # each guidance file loaded once
    for s in scenarios:
        if s.guidance not in loaded:
            loaded[s.guidance] = scenario_reference(s)
    references = [loaded[s.guidance] for s in scenarios]
    # the per-sample inputs, each copied into the batch's arrays as soon as it is built (the
    # sample's own copy of the large ones is then dropped)
    samples, consts, views, wind, noise = [], None, None, None, None
    for i, (scenario, seed) in enumerate(zip(scenarios, seeds)):
        s = _sample_inputs(scenario, seed, context, n_frames, references[i])
        if consts is None:
            consts = np.empty((n, *s.consts.shape))
            views = np.empty((n, *s.views.shape))
            wind = np.empty((n, s.wind.size))
            noise = np.zeros((n, 5 * _INS_BLOCK * -(-(n_frames + 1) // _INS_BLOCK)))
        consts[i], views[i], wind[i] = s.consts, s.views, s.wind
        noise[i, :s.noise.size] = s.noise
        s.consts = s.views = s.wind = s.noise = None
        samples.append(s)
    refresh = frame                                   # the tracks' default refresh
    x = _stack([s.x0 for s in samples])
    plant_in = np.array([(s.beta0, 0.0) for s in samples])
    nx, ny, ns, ax, ay, asl = (_stack([s.tables[i] for s in samples]) for i in range(6))
    noise_on = np.array([s.noise_on for s in samples])
    sigma = np.array([s.sigma for s in samples], dtype=float)
    latency = np.array([s.latency_ms for s in samples], dtype=np.int64)
    sensor_lat = np.ascontiguousarray(latency[:, 0])
    act = np.array([(s.act_beta, 0.0, 0.0, s.act_beta, s.act_beta) for s in samples])
    act_par = np.array([s.act_par for s in samples], dtype=float)
    # pending commands: at most (total latency) / period + 2 at once
    depth = int(latency.sum(axis=1).max()) // period + 2
    queue_t = np.zeros((n, depth), dtype=np.int64)
    queue_v = np.zeros((n, depth))
    queue_n = np.zeros(n, dtype=np.int64)
    truth = np.empty((n, len(bk.TRUTH_FIELDS), n_frames + 1))
    ins = np.empty((n, len(bk.INS_FIELDS), n_frames + 1))
    act_out = np.empty((n, len(bk.ACTUATOR_FIELDS), n_frames * steps + 1))
    work_b, work_r = np.empty(steps), np.empty(steps)
    controller = ControllerBatch(
        n, table, limits, reference=None if references[0] is None else references)
    bk.observe(0, t0, t0, refresh, dt, x, views, wind, noise, noise_on, sigma, sensor_lat,
               truth, ins)
    cmd_frames, cmd_u, cmd_v, cmd_status = [], [], [], []
    no_push_t, no_push_v = np.zeros(n, dtype=np.int64), np.zeros(n)
    f = 0
    while f < n_frames:
        t = t0 + f * frame
        push, push_t, push_v = False, no_push_t, no_push_v
        if t % period == 0:                           # ControllerStep: on the period only
            meas = ins[:, :, f]
            stamp_ms = meas[:, 0].astype(np.int64)
            u, v_sched, status = controller.step(
                np.full(n, t / 1000.0), meas[:, 2:6], meas[:, 6], meas[:, 7] != 0.0,
                stamp_ms / 1000.0)
            cmd_frames.append(f)
            cmd_u.append(u)
            cmd_v.append(v_sched)
            cmd_status.append(status)
            push, push_t, push_v = True, stamp_ms + latency[:, 1] + latency[:, 2], u
        k = 1                                         # frames up to the next controller step
        while f + k < n_frames and (t0 + (f + k) * frame) % period:
            k += 1
        bk.advance_frames(f, k, t0, frame, refresh, dt, push, push_t, push_v, x, plant_in,
                          consts, nx, ny, ns, ax, ay, asl, views, wind, noise, noise_on, sigma,
                          sensor_lat, act, act_par, queue_t, queue_v, queue_n, truth, ins,
                          act_out, work_b, work_r)
        f += k
    cmd = (np.array(cmd_frames, dtype=np.int64), np.array(cmd_u).reshape(-1, n),
           np.array(cmd_v).reshape(-1, n), np.array(cmd_status, dtype=np.int64).reshape(-1, n))
    return [_result(scenarios[i], seeds[i], i, samples[i], truth[i], ins[i, :, :n_frames],
                    act_out[i], cmd, latency[i], t0, frame, dt) for i in range(n)]


def _result(scenario: Scenario, seed: int, i: int, sample: _Sample, truth: np.ndarray,
            ins: np.ndarray, act_out: np.ndarray, cmd, latency, t0: int, frame: int, dt: int
            ) -> SimulationResult:
    """Sample ``i``'s records as :func:`run_scenario` returns them: the same values, dtypes
    and shapes. The float records are views of the batch's arrays (one row per field; no
    copies), so they keep the batch's blocks alive while any result of it lives."""
    cmd_frames, cmd_u, cmd_v, cmd_status = cmd
    cmd_sample = t0 + frame * cmd_frames
    act_out[:, 0] = (sample.beta0, 0.0, 0.0, sample.beta0)     # the initial actuator state
    return SimulationResult(
        scenario=scenario, seed=int(seed),
        t_ms=truth[0].astype(np.int64), theta_rad=truth[1], theta_dot_radps=truth[2],
        z_m=truth[3], z_dot_mps=truth[4], alpha_rad=truth[5], q_alpha_pa_rad=truth[6],
        q_pa=truth[7], mach=truth[8], v_mps=truth[9], h_m=truth[10], wind_mps=truth[11],
        bending_q=truth[12:14].T, bending_qdot=truth[14:16].T,
        act_t_ms=t0 + dt * np.arange(act_out.shape[1], dtype=np.int64),
        beta_rad=act_out[0], beta_dot_radps=act_out[1], beta_ddot_radps2=act_out[2],
        beta_cmd_rad=act_out[3],
        ins_sample_ms=ins[1].astype(np.int64), ins_stamp_ms=ins[0].astype(np.int64),
        ins_theta_rad=ins[2], ins_theta_dot_radps=ins[3], ins_z_m=ins[4],
        ins_z_dot_mps=ins[5], ins_v_mps=ins[6],
        cmd_sample_ms=cmd_sample.astype(np.int64),
        cmd_stamp_ms=(cmd_sample + int(latency[0]) + int(latency[1])).astype(np.int64),
        cmd_rad=cmd_u[:, i].copy(), cmd_v_mps=cmd_v[:, i].copy(),
        cmd_status=cmd_status[:, i].astype(np.int64))
