"""The truth side's per-run fast paths give exactly the numbers of the code they replace:
the kernel constants from the track's columns, the wind of the whole track, the INS' finiteness
check, the actuator's held-command frames; and a run leaves the garbage collector as it was.
"""

import dataclasses
import gc
import math

import numpy as np
import pytest

from vega_bus.records import CommandOut
from vega_model.actuator import ActuatorParams, TvcActuator
from vega_model.nonlinear_kernel import entry_constants
from vega_model.parameters import default_context
from vega_model.wind import GustProfile, ProfileChange, WindModel
from vega_sim.assembly import loop_timing, make_actuator
from vega_sim.closed_loop import run_scenario
from vega_sim.device_steps import _all_finite
from vega_sim.plant_step import ParameterTrack, PlantWind
from vega_sim.scenario import load_scenario
from vega_gnc.controller_table import default_table_path

DEVIATIONS = {"thrust": 0.05, "velocity": 0.02, "density": -0.1, "x_cp": 0.1, "x_cg": 0.01,
              "mass": -0.03, "jyy": 0.1, "bending_frequency_1": -0.2,
              "bending_frequency_2": 0.2, "psi_mode_1": 0.3, "psi_mode_2": -0.5}


def _bits(values):
    return np.asarray(values, dtype=float).view(np.uint64).tolist()


@pytest.mark.parametrize("deviations", [{}, DEVIATIONS])
def test_kernel_constants_from_columns_equal_entry_constants(deviations):
    track = ParameterTrack(default_context(), 20000, 30000, refresh_ms=5, deviations=deviations)
    consts, _ = track.kernel_inputs()
    want = np.array([entry_constants(p) for p in track.params])
    assert consts.shape == want.shape
    assert _bits(consts.ravel()) == _bits(want.ravel())


def _frames_reference(data, track, frames, **kw):
    """The wind frame by frame as PlantWind drew it before the whole-track draw: one
    WindModel.steps per run of steps with one parameter entry."""
    model = WindModel(data, **kw)
    out = []
    t0, refresh, dt = track.t_start_ms, track.refresh_ms, track.dt_ms
    for f in range(frames):
        t_ms = t0 + f * track.frame_ms
        k, n = 0, track.frame_ms // dt
        while k < n:
            e = (t_ms + k * dt - t0) // refresh
            j = min(n, (t0 + (e + 1) * refresh - t_ms + dt - 1) // dt)
            p = track.params[e]
            out += model.steps([(t_ms + i * dt) / 1000.0 for i in range(k, j)], p.h_m, p.v_mps)
            k = j
    return out


@pytest.mark.parametrize("refresh_ms", [10, 5, 1])
def test_plant_wind_frames_equal_frame_by_frame_draws(refresh_ms):
    ctx = default_context()
    gust = GustProfile(31.2345, 2.0, 9.0)
    track = ParameterTrack(ctx, 30000, 34000, refresh_ms=refresh_ms, deviations=DEVIATIONS)
    wind = PlantWind(ctx.vehicle, track, profile=True, turbulence="moderate", gust=gust, seed=8,
                     change=ProfileChange(1.2, 300.0))
    frames = (track.t_end_ms - track.t_start_ms) // track.frame_ms + 1
    got = []
    for f in range(frames):
        got += wind.frame(track.t_start_ms + f * track.frame_ms, 10)
    want = _frames_reference(ctx.vehicle, track, frames, profile=True, turbulence="moderate",
                             gust=gust, seed=8, dt_s=0.001, change=ProfileChange(1.2, 300.0))
    assert len(got) == len(want) == frames * 10
    assert _bits(got) == _bits(want)


def test_all_finite_fast_path_agrees_with_the_value_by_value_check():
    cases = [((1.0, -2.0, 3.5), 0.0), ((1e308, 1e308), 0.0),        # finite, the sum overflows
             ((-1e308, -1e308, 1.0), 1e308), ((math.inf, -math.inf), 0.0),
             ((math.nan, 1.0), 0.0), ((1.0, 2.0), math.nan), ((1.0, 2.0), -math.inf),
             ((0.0,) * 8, 0.0)]
    for values, extra in cases:
        want = all(math.isfinite(x) for x in values) and math.isfinite(extra)
        assert _all_finite(values, extra) is want, (values, extra)


def test_actuator_frames_equal_the_step_by_step_law():
    """Commands applying at every position inside a frame (first and last step included), on
    frame boundaries, several in one frame, and none for frames on end: the samples equal
    TvcActuator.step with the command held from its stamp + latency."""
    scenario = load_scenario("nominal")
    timing = loop_timing(scenario)
    step = make_actuator(scenario)
    ref = TvcActuator(ActuatorParams.from_vehicle(default_context().vehicle),
                      scenario.initial_state.beta_rad)
    lat, dt, n = timing.actuator_latency_ms, timing.physics_dt_ms, timing.steps_per_frame
    t0 = scenario.t_start_ms
    rng = np.random.default_rng(4)
    applies = sorted({int(a) for a in rng.integers(0, 600, 40)} | {9, 10, 19, 20, 21, 599})
    commands = [CommandOut(t0 + a - lat, 0, seq, float(rng.normal() * 0.2), 0.0, 0)
                for seq, a in enumerate(applies)]
    for cmd in commands:
        step.receive(cmd)
    got, held = [], ref.command_rad
    for f in range(70):
        got += step.advance(t0 + f * n * dt).deflection_samples_rad
    want = []
    for k in range(70 * n):
        for a, cmd in zip(applies, commands):
            if a == k:
                held = cmd.deflection_cmd_rad
        want.append(ref.step(held)[0])
    assert _bits(got) == _bits(want)


@pytest.mark.parametrize("enabled", [True, False])
def test_a_run_leaves_the_garbage_collector_as_it_was(enabled):
    was = gc.isenabled()
    try:
        (gc.enable if enabled else gc.disable)()
        run_scenario(dataclasses.replace(load_scenario("nominal"), t_end_s=0.2),
                     default_table_path())
        assert gc.isenabled() is enabled
    finally:
        (gc.enable if was else gc.disable)()


@pytest.mark.slow
@pytest.mark.parametrize("deviations", [{}, DEVIATIONS])
def test_lazy_parameter_sets_equal_the_bulk_build(deviations):
    ctx = default_context()
    track = ParameterTrack(ctx, 40000, 45000, refresh_ms=5, deviations=deviations)
    times = (40000 + 5 * np.arange(len(track.params))) / 1000.0
    bulk = ctx.parameters_at_times(times, deviations)
    assert len(track.params) == len(bulk) == 1002
    order = [1001, 0, 500, -1, -1002] + list(range(len(bulk)))   # first access anywhere
    for e in order:
        assert track.params[e] == bulk[e] and repr(track.params[e]) == repr(bulk[e])
    assert track.params[-1] is track.params[1001]                   # built once, kept
    assert track.params[3:6] == bulk[3:6] and list(track.params) == bulk
    with pytest.raises(IndexError):
        track.params[1002]


@pytest.mark.parametrize("deviations", [{}, DEVIATIONS])
def test_parameter_views_are_the_parameter_sets_fields(deviations):
    track = ParameterTrack(default_context(), 60000, 62000, deviations=deviations)
    assert len(track.views) == len(track.params)
    for e, (view, p) in enumerate(zip(track.views, track.params)):
        want = (p.v_mps, p.q_pa, p.mach, p.h_m, p.rho_kgpm3, p.l_cp_m, *p.psi_t_ins,
                *p.psi_r_ins, p.l_ins_m)
        got = (*view[:6], *view.psi_t_ins, *view.psi_r_ins, view.l_ins_m)
        assert _bits(got) == _bits(want), e
        t_ms = track.t_start_ms + e * track.refresh_ms
        assert track.view_ms(t_ms) is view and track.at_ms(t_ms) is p


@pytest.mark.slow
def test_actuator_run_tuples_equal_single_steps_at_every_limit():
    """Random commands (repeated objects, NaN, ±inf among them) that drive the nozzle onto both
    stops and both rate limits: run_tuples gives step's numbers, and each limit is reached."""
    params = ActuatorParams.from_vehicle(default_context().vehicle)
    a, b = TvcActuator(params, -0.02), TvcActuator(params, -0.02)
    rng = np.random.default_rng(12)
    levels = (rng.normal(size=60) * 0.3).tolist() + [math.nan, math.inf, -math.inf]
    commands = [levels[int(i)] for i in rng.integers(0, len(levels), 80) for _ in range(400)]
    got = a.run_tuples(commands)
    want = [b.step(u) + (b.command_rad,) for u in commands]
    assert [_bits(g) for g in got] == [_bits(w) for w in zip(*want)]
    assert a.state == b.state and a.command_rad == b.command_rad
    beta, rate = np.array(got[0]), np.array(got[1])
    pos, slew = params.position_limit_rad, params.rate_limit_radps
    assert (beta == pos).any() and (beta == -pos).any()
    assert (rate == slew).any() and (rate == -slew).any()
