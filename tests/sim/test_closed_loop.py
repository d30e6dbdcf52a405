"""The in-process closed loop: timing, determinism, plants, wind and the per-node step classes.

The controller here is the hand-designed scheduled PD of tests/fixture_tables.py (a test
fixture, not the LPV synthesis), exported through vega_loops.export like the real
table.
"""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import cont2discrete

from fixture_tables import write_gain_table, write_pd_table
from vega_lpv.weights import THESIS
from vega_gnc.controller_runtime import STATUS_OK
from vega_model.dynamics import linear_model
from vega_model.ins import InsParams
from vega_model.actuator import ActuatorParams
from vega_model.parameters import default_context
from vega_model.wind import dryden_ss
from vega_bus.timing import LoopTiming, ms_to_stamp, seconds_to_ms, stamp_to_ms
from vega_gnc.controller_step import ControllerStep
from vega_sim import plant_step
from vega_sim.scenario import InitialState, Scenario, WindSettings, load_scenario
from vega_sim.device_steps import ActuatorStep, InsStep
from vega_sim.plant_step import (THESIS_DRYDEN_WEIGHT, ParameterTrack, TruthOut,
                                  _expm_batched, parameters_at, thesis_dryden_coefficients)
from vega_sim.assembly import derive_seeds, make_actuator, make_ins, make_plant
from vega_sim.closed_loop import build_steps, make_controller, run_scenario

QUIET = WindSettings(profile=False, turbulence="none", gust=None)


@pytest.fixture(scope="module")
def pd_table(tmp_path_factory):
    """The hand-designed scheduled PD controller (tests/fixture_tables.py)."""
    return write_pd_table(tmp_path_factory.mktemp("pd") / "pd.npz")


@pytest.fixture(scope="module")
def gain_table(tmp_path_factory):
    """A static gain β_cmd = 0.5·θ_INS (a first-order state that never feeds the output)."""
    return write_gain_table(tmp_path_factory.mktemp("gain") / "gain.npz")


def _scenario(**changes):
    base = Scenario(name="test", description="test", t_start_s=10.0, t_end_s=20.0,
                    plant="linear", initial_state=InitialState(theta_rad=math.radians(2.0)),
                    wind=QUIET, sensor_noise=False, seed=1, guidance="none")
    return replace(base, **changes)


# ----------------------------------------------------------------------------- numerics
def test_batched_expm_matches_scipy():
    """The batched exponential equals scipy's on the plant's own augmented matrices."""
    ctx = default_context()
    mats = []
    for t in (0.0, 10.0, 47.3, 90.0, 100.0):
        A, B, _, _ = linear_model(ctx.parameters(t))
        m = np.zeros((11, 11))
        m[:8, :8], m[:8, 8:] = A * 1e-3, B * 1e-3
        mats.append(m)
    rng = np.random.default_rng(0)
    mats += list(rng.standard_normal((5, 11, 11)) * 3.0)
    got = _expm_batched(np.array(mats))
    for m, e in zip(mats, got):
        ref = expm(m)
        assert np.max(np.abs(e - ref)) <= 1e-12 * np.max(np.abs(ref))


@pytest.mark.parametrize("refresh_ms", [10, 5, 1])
def test_linear_frame_map_equals_stepwise_zoh(refresh_ms):
    """H[f] = the product of the per-step exact ZOH maps with the parameters in force."""
    ctx = default_context()
    track = ParameterTrack(ctx, 47_000, 47_030, refresh_ms=refresh_ms)
    H = track.linear_frames().H
    rng = np.random.default_rng(1)
    x0, u = rng.standard_normal(8), rng.standard_normal(30)
    for f in range(track.n_frames):
        x = x0.copy()
        for k in range(10):
            A, B, _, _ = linear_model(track.at_ms(47_000 + 10 * f + k))
            aug = np.zeros((11, 11))
            aug[:8, :8], aug[:8, 8:] = A * 1e-3, B * 1e-3
            e = expm(aug)
            x = e[:8, :8] @ x + e[:8, 8:] @ u[3 * k:3 * k + 3]
        got = H[f] @ np.concatenate([x0, u])
        assert np.allclose(got, x, rtol=1e-10, atol=1e-12 * np.max(np.abs(x)))


def test_parameter_entries_are_held_per_refresh_interval():
    ctx = default_context()
    track = ParameterTrack(ctx, 10_000, 10_050, refresh_ms=5)
    assert len(track.params) == (50 + 10) // 5          # one frame past the end
    assert track.at_ms(10_004).t_s == 10.0 and track.at_ms(10_005).t_s == 10.005
    # what a separate INS node computes at a frame time is the plant's entry, bit for bit
    dev = {"thrust": 0.05, "x_cp": -0.1}
    perturbed = ParameterTrack(ctx, 10_000, 10_050, deviations=dev)
    for t in (10_000, 10_020, 10_050):
        assert track.at_ms(t) == parameters_at(ctx, t)
        assert perturbed.at_ms(t) == parameters_at(ctx, t, dev) != parameters_at(ctx, t)
    with pytest.raises(ValueError, match="flight-condition table"):
        ParameterTrack(ctx, 0, 110_000)
    with pytest.raises(ValueError, match="divide the frame"):
        ParameterTrack(ctx, 0, 1_000, refresh_ms=3)


def test_thesis_dryden_is_the_exact_zoh_of_the_dryden_filter():
    """One step equals cont2discrete(ZOH) of vega_model.wind.dryden_ss with input 1; it
    converges to W_w × the filter's DC gain; W_w is the synthesis' weight (§4.5.1)."""
    data = default_context().vehicle
    assert THESIS_DRYDEN_WEIGHT == THESIS.wind_sigmas == 3.0
    for h, v in ((1500.0, 180.0), (11_000.0, 580.0), (19_000.0, 1000.0)):
        A, B, C, D = dryden_ss(h, v, data, "light")
        Ad, Bd, *_ = cont2discrete((A, B, C, D), 1e-3, method="zoh")
        a, g = thesis_dryden_coefficients(h, v, data, "light", 1e-3)
        assert a == pytest.approx(Ad[0, 0], rel=1e-12)
        assert g == pytest.approx(Bd[0, 0], rel=1e-9)
        assert g / (1.0 - a) == pytest.approx(-B[0, 0] / A[0, 0], rel=1e-9)   # DC gain
    a, g = thesis_dryden_coefficients(0.0, 0.0, data, "light", 1e-3)           # at rest
    assert a == 1.0 and g == 0.0


@pytest.mark.slow
def test_thesis_wind_rises_to_three_times_the_dc_gain(pd_table):
    """The thesis scenario's wind: zero at t_start, then 3·σ_w√(2L_w/(πV)) (slowly varying)."""
    sc = replace(load_scenario("thesis"), t_end_s=40.0, sensor_noise=False)
    res = run_scenario(sc, pd_table)
    data = default_context().vehicle
    assert res.wind_mps[0] == 0.0
    a, g = thesis_dryden_coefficients(res.h_m[-1], res.v_mps[-1], data, "light", 1e-3)
    assert res.wind_mps[-1] == pytest.approx(3.0 * g / (1.0 - a), rel=0.02)
    assert np.all(np.diff(res.wind_mps[:200]) > 0.0)


# ----------------------------------------------------------------------------- timing
def test_stamp_conversions():
    assert ms_to_stamp(47_321) == (47, 321_000_000)
    assert stamp_to_ms(47, 321_000_000) == 47_321
    assert seconds_to_ms(0.012, "x") == 12
    with pytest.raises(ValueError, match="whole number of milliseconds"):
        seconds_to_ms(0.0125, "x")
    with pytest.raises(ValueError, match="whole millisecond"):
        stamp_to_ms(1, 500)
    timing = LoopTiming.from_vehicle(default_context().vehicle)
    assert (timing.physics_dt_ms, timing.frame_ms, timing.controller_period_ms) == (1, 10, 20)
    assert timing.total_latency_ms == 39


@pytest.mark.parametrize("t_start_s, delay_dev_s, first_motion_ms", [
    (10.0, 0.0, 39),     # sample at t_start is a controller sample: 12 + 12 + 15 ms
    (10.01, 0.0, 49),    # sample at t_start is skipped (decimation): + 10 ms
    (10.0, 0.01, 49),    # +10 ms delay deviation, applied to the actuator
])
def test_sensor_to_nozzle_latency(gain_table, t_start_s, delay_dev_s, first_motion_ms):
    """An attitude step at t_start moves the nozzle first in the physics step starting at
    t_start + 39 ms (+ decimation phase), not a millisecond earlier or later."""
    unc = (("delay_s", delay_dev_s),) if delay_dev_s else ()
    res = run_scenario(_scenario(t_start_s=t_start_s, t_end_s=t_start_s + 0.2,
                                 uncertainty=unc), gain_table)
    k = first_motion_ms                   # index of the sample at t_start + k ms
    assert np.all(res.beta_rad[:k + 1] == 0.0)
    assert res.beta_rad[k + 1] > 0.0      # β > 0 against θ > 0
    assert np.all(res.beta_cmd_rad[:k + 1] == 0.0)
    first = np.flatnonzero(res.ins_sample_ms == res.cmd_sample_ms[0])[0]
    assert res.cmd_rad[0] == pytest.approx(0.5 * res.ins_theta_rad[first], rel=1e-14)
    assert res.beta_cmd_rad[k + 1] == res.cmd_rad[0]
    assert res.ins_theta_rad[first] == pytest.approx(math.radians(2.0), rel=1e-4)
    assert np.all(res.ins_stamp_ms - res.ins_sample_ms == 12)
    assert np.all(res.cmd_stamp_ms - res.cmd_sample_ms == 24)
    assert np.all(res.cmd_sample_ms % 20 == 0)


@pytest.mark.parametrize("step_ms", [1000, 1001, 1003, 1010, 1011, 1019, 1020])
def test_latency_with_decimation_phase_at_node_level(gain_table, step_ms):
    """Step in the INS pitch at an arbitrary millisecond: the nozzle first moves at the next
    controller sample (multiple of 20 ms) at or after the step, + 39 ms."""
    ctx = default_context()
    data = ctx.vehicle
    timing = LoopTiming.from_vehicle(data)
    ins = InsStep(InsParams.from_vehicle(data), timing, seed=0, noise=False)
    ctrl = ControllerStep(gain_table, timing)
    act = ActuatorStep(ActuatorParams.from_vehicle(data), timing, t_start_ms=960)
    motion = None
    for t in range(960, 1200, 10):
        p = ctx.parameters(t / 1000.0)
        pitch = 0.01 if t >= step_ms else 0.0     # truth seen at the frame sample instants
        truth = TruthOut(t, 0, pitch, 0.0, 0.0, 0.0, 0.0, 0.0, p.q_pa, p.mach, p.v_mps,
                         p.h_m, 0.0, (0.0, 0.0), (0.0, 0.0))
        cmd = ctrl.step(ins.sample(truth, p))
        if cmd is not None:
            act.receive(cmd)
        out = act.advance(t)
        for k, beta in enumerate(out.deflection_samples_rad):
            if motion is None and beta != 0.0:
                motion = t + k                    # the step [t + k, t + k + 1] moved it
    expected = -(-step_ms // 20) * 20 + 39
    assert motion == expected


# ----------------------------------------------------------------------------- behaviour
@pytest.mark.slow
def test_theta0_decays_on_the_thesis_scenario(pd_table):
    """Thesis §5.2: θ0 = 2° is removed; the loop settles with the thesis' wind and noise."""
    res = run_scenario(replace(load_scenario("thesis"), t_end_s=30.0), pd_table)
    t = res.t_s
    assert math.degrees(res.theta_rad[0]) == pytest.approx(2.0)
    assert np.max(np.abs(res.theta_rad[t > 15.0])) < math.radians(0.2)
    assert np.max(np.abs(res.theta_rad[t > 25.0])) < math.radians(0.1)
    assert np.all(res.cmd_status == STATUS_OK)
    assert np.max(np.abs(res.beta_rad)) < math.radians(6.5)
    assert np.max(np.abs(res.bending_q[t > 15.0])) < 0.05     # no bending limit cycle
    report = res.metrics()
    assert report.passed
    assert "-14554.6" in report.table()


def test_nozzle_limits_apply(pd_table):
    """A 15° attitude error saturates the nozzle at the 6.5° stop and the 20°/s rate limit."""
    res = run_scenario(_scenario(initial_state=InitialState(theta_rad=math.radians(15.0)),
                                 t_end_s=11.0), pd_table)
    limit = ActuatorParams.from_vehicle(default_context().vehicle)
    assert np.max(np.abs(res.beta_rad)) == pytest.approx(limit.position_limit_rad, rel=1e-12)
    assert np.max(np.abs(res.beta_dot_radps)) <= limit.rate_limit_radps * (1 + 1e-12)
    assert np.max(np.abs(res.beta_cmd_rad)) > limit.position_limit_rad * 0.99


def test_same_seed_same_arrays(pd_table):
    """Deterministic: identical arrays run to run, also after the parameter cache is cleared."""
    sc = replace(load_scenario("nominal"), t_start_s=20.0, t_end_s=22.0)
    first = run_scenario(sc, pd_table).arrays()
    plant_step._cached_track.cache_clear()
    second = run_scenario(sc, pd_table).arrays()
    assert first.keys() == second.keys()
    for name in first:
        assert first[name].dtype == second[name].dtype
        assert np.array_equal(first[name], second[name]), name


def test_separately_built_nodes_reproduce_the_run(pd_table):
    """What the SIL does — each node built on its own from the scenario, stamps through ROS
    (sec, nanosec), INS parameters from parameters_at — gives the in-process run bit for bit."""
    sc = replace(load_scenario("gust"), plant="linear", t_start_s=46.0, t_end_s=47.0,
                 uncertainty=(("actuator", -0.05), ("thrust", 0.03)))
    ref = run_scenario(sc, pd_table)
    ctx = default_context()
    plant, ins = make_plant(sc), make_ins(sc)
    ctrl, act = make_controller(sc, pd_table), make_actuator(sc)
    truth = plant.output()
    theta, beta, commands = [truth.pitch_rad], [], []
    while truth.stamp_ms < sc.t_end_ms:
        t = stamp_to_ms(*ms_to_stamp(truth.stamp_ms))
        cmd = ctrl.step(ins.sample(truth, parameters_at(ctx, t, sc.deviations)))
        if cmd is not None:
            act.receive(cmd)
            commands.append(cmd.deflection_cmd_rad)
        frame = act.advance(t)
        beta += frame.deflection_samples_rad
        truth = plant.advance(list(frame.deflection_samples_rad),
                              list(frame.rate_samples_radps))
        theta.append(truth.pitch_rad)
    assert np.array_equal(theta, ref.theta_rad)
    assert np.array_equal(beta, ref.beta_rad[1:])
    assert np.array_equal(commands, ref.cmd_rad)


def test_other_seed_other_noise(pd_table):
    sc = replace(load_scenario("nominal"), plant="linear", t_start_s=20.0, t_end_s=22.0)
    a, b = run_scenario(sc, pd_table, seed=1), run_scenario(sc, pd_table, seed=2)
    assert a.seed == 1 and b.seed == 2
    assert a.theta_rad[0] == b.theta_rad[0]                   # same truth at t_start
    assert a.ins_theta_rad[0] != b.ins_theta_rad[0]           # INS noise
    assert a.wind_mps[0] != b.wind_mps[0]                     # turbulence
    assert not np.array_equal(a.beta_rad, b.beta_rad)
    wind_seed, ins_seed = derive_seeds(1)
    assert wind_seed != ins_seed and derive_seeds(1) == (wind_seed, ins_seed)
    assert derive_seeds(2) != (wind_seed, ins_seed)


@pytest.mark.slow
def test_linear_and_nonlinear_plants_agree_for_small_perturbations(pd_table):
    """Same closed loop on both plants (40–50 s, max-Q, no wind, no noise, θ0 = 0.1° and
    0.05°): the nonlinear model's Jacobian is the linear model, so the difference is second
    order — below 0.4 % of the peak at 0.1° (measured ≤ 0.29 %) and halved with the amplitude."""
    def relative_differences(theta0_deg):
        sc = _scenario(t_start_s=40.0, t_end_s=50.0,
                       initial_state=InitialState(theta_rad=math.radians(theta0_deg)))
        lin = run_scenario(sc, pd_table)
        non = run_scenario(replace(sc, plant="nonlinear"), pd_table)
        assert np.array_equal(lin.wind_mps, non.wind_mps)
        return np.array([np.max(np.abs(getattr(non, n) - getattr(lin, n)))
                         / np.max(np.abs(getattr(lin, n)))
                         for n in ("theta_rad", "z_m", "z_dot_mps", "beta_rad",
                                   "q_alpha_pa_rad")])

    big, small = relative_differences(0.1), relative_differences(0.05)
    assert np.all(big < 4e-3), big
    assert np.all((big / small > 1.8) & (big / small < 2.2)), big / small


@pytest.mark.slow
def test_parameter_refresh_interval_barely_matters(pd_table):
    """Refreshing the parameters every 1 ms instead of every 10 ms frame changes the histories
    by < 5e-4 of their peaks (measured here ≤ 1e-4; on the full runs ≤ 2e-4 for the thesis
    scenario, ≤ 9e-4 for the nonlinear nominal one, requirement values ≤ 1.5e-4 relative)."""
    sc = replace(load_scenario("thesis"), t_end_s=16.0)
    for plant in ("linear", "nonlinear"):
        a = run_scenario(replace(sc, plant=plant), pd_table)
        b = run_scenario(replace(sc, plant=plant), pd_table, parameter_refresh_ms=1)
        for name in ("theta_rad", "z_m", "z_dot_mps", "beta_rad", "q_alpha_pa_rad"):
            x, y = getattr(a, name), getattr(b, name)
            assert np.max(np.abs(x - y)) < 5e-4 * np.max(np.abs(x)), (plant, name)
        assert not np.array_equal(a.theta_rad, b.theta_rad)


def test_result_layout_and_metrics(pd_table):
    sc = _scenario(t_end_s=11.0)
    res = run_scenario(sc, pd_table)
    assert res.t_ms[0] == 10_000 and res.t_ms[-1] == 11_000 and res.t_ms.size == 101
    assert res.act_t_ms.size == 1001 and np.all(np.diff(res.act_t_ms) == 1)
    assert res.ins_sample_ms.size == 100 and res.cmd_stamp_ms.size == 50
    assert res.bending_q.shape == (101, 2)
    assert res.q_pa[0] == pytest.approx(default_context().parameters(10.0).q_pa)
    report = res.metrics()
    assert [r.key for r in report.results] == ["q_alpha", "drift", "drift_rate",
                                               "deflection", "deflection_integral"]
    assert report["deflection"].value == res.beta_rad[np.argmax(np.abs(res.beta_rad))]
    assert report["deflection_integral"].value == pytest.approx(
        np.trapezoid(np.abs(res.beta_rad), res.act_t_s))


def test_bad_inputs(pd_table, tmp_path):
    with pytest.raises(ValueError, match="controller table dt_s"):
        bad = write_gain_table(tmp_path / "slow.npz")
        ControllerStep(replace(bad, dt_s=0.01), LoopTiming())
    with pytest.raises(ValueError, match="flight-condition table"):
        run_scenario(_scenario(t_start_s=0.0, t_end_s=110.0), pd_table)
    with pytest.raises(ValueError, match="unknown scenario"):
        run_scenario("no_such_scenario", pd_table)
    nodes = build_steps(_scenario(t_end_s=10.01), pd_table)
    with pytest.raises(ValueError, match="expected 10000 ms"):
        nodes.actuator.advance(10_010)
    frame = nodes.actuator.advance(10_000)
    nodes.plant.advance(frame.deflection_samples_rad, frame.rate_samples_radps)
    with pytest.raises(ValueError, match="end of its span"):
        nodes.plant.advance(frame.deflection_samples_rad, frame.rate_samples_radps)
