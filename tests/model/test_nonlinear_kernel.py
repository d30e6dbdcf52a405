"""The compiled plant (vega_model.nonlinear_kernel) and the per-frame fast paths of the model
give exactly the numbers of the plain-Python code they replace on the hot path.

Exact equality (no tolerance): the SIL is proven byte-equal to the in-process run, and both go
through these functions, so they must equal the reference implementations bit for bit.
"""

import math

import numpy as np
import pytest

from vega_model import nonlinear_kernel as nk
from vega_model.actuator import ActuatorParams, TvcActuator
from vega_model.dynamics import NonlinearModel, alpha_and_q_alpha, nonlinear_outputs
from vega_model.ins import InsParams, InsSensor
from vega_model.parameters import default_context
from vega_model.wind import GustProfile, WindModel


def _bits(values):
    return np.asarray(values, dtype=float).view(np.uint64).tolist()


@pytest.mark.slow
def test_hypot_is_cpythons_bit_for_bit():
    rng = np.random.default_rng(7)
    n = 20000
    scale = 10.0 ** rng.integers(-8, 8, size=(2, n))
    xs, ys = rng.normal(size=(2, n)) * scale
    sub_x, sub_y = rng.normal(size=(2, 200)) * 1e-310          # subnormal inputs
    pairs = list(zip(xs.tolist(), ys.tolist())) + list(zip(sub_x.tolist(), sub_y.tolist()))
    pairs += [(0.0, 0.0), (-0.0, 0.0), (3.0, -4.0), (math.inf, 1.0), (1.0, -math.inf),
              (math.nan, 1.0), (math.inf, math.nan), (1e308, 1e308), (5e-324, 0.0)]
    got = [nk._hypot(a, b) for a, b in pairs]
    want = [math.hypot(a, b) for a, b in pairs]
    assert _bits(got) == _bits(want)


@pytest.mark.slow
@pytest.mark.parametrize("t_s", [0.0, 12.5, 33.0, 58.7, 80.0, 100.0])
def test_rk4_step_equals_the_python_model(t_s):
    p = default_context().parameters(t_s)
    model = NonlinearModel(p)
    consts = np.array([nk.entry_constants(p)])
    tables = nk.mach_tables(p)
    rng = np.random.default_rng(int(t_s * 10))
    for _ in range(200):
        x = tuple((rng.normal(size=8) * [0.2, 0.2, 50, 20, 0.02, 0.02, 0.2, 0.2]).tolist())
        u = tuple((rng.normal(size=4) * [0.1, 5.0, 20.0, 0.3]).tolist())
        xa = np.array(x)
        nk._rk4_step(consts[0], *tables, xa, u[0], u[1], u[2], u[3], 0.001)
        assert _bits(xa) == _bits(model.rk4_step(x, u, 0.001))


@pytest.mark.slow
def test_rk4_frame_equals_the_python_steps_across_parameter_entries():
    """Ten steps over two parameter entries (a 5 ms refresh), inputs at the step means."""
    ctx = default_context()
    params = [ctx.parameters(40.0), ctx.parameters(40.005)]
    consts = np.array([nk.entry_constants(p) for p in params])
    rng = np.random.default_rng(3)
    beta = rng.normal(size=10) * 0.05
    rate = rng.normal(size=10) * 0.2
    wind = rng.normal(size=10) * 10.0
    x0 = (rng.normal(size=8) * 0.05).tolist()
    x = np.array(x0)
    nk.rk4_frame(x, consts, *nk.mach_tables(params[0]), beta, rate, wind, 0.01, -0.1, 1000.0,
                 0.001, 40000, 40000, 5, 1)
    want, b0, r0 = tuple(x0), 0.01, -0.1
    for k in range(10):
        model = NonlinearModel(params[k // 5])
        b1, r1 = float(beta[k]), float(rate[k])
        want = model.rk4_step(want, (0.5 * (b0 + b1), (r1 - r0) * 1000.0, float(wind[k]),
                                     0.5 * (r0 + r1)), 0.001)
        b0, r0 = b1, r1
    assert _bits(x) == _bits(want)


def test_entry_constants_are_the_models_products():
    """A model rebuilt from the constants' columns: the same derivative as NonlinearModel."""
    p = default_context().parameters(55.0)
    c = dict(zip(nk.CONSTANTS, nk.entry_constants(p)))
    assert c["d"] == p.x_cp_m - p.x_cg_m and c["lc"] == p.x_cg_m - p.x_pvp_m
    assert c["mode1_q"] == -(2.0 * math.pi * p.f1_hz) ** 2
    assert c["half_rho"] == 0.5 * p.rho_kgpm3 and c["T"] == p.thrust_n
    assert c["k_cf"] == p.aero.crossflow_coefficient


def test_alpha_and_q_alpha_is_the_first_nonlinear_output():
    p = default_context().parameters(45.0)
    x = (0.01, -0.02, 30.0, 4.0, 0.001, -0.002, 0.01, 0.02)
    alpha, q_alpha = alpha_and_q_alpha(p, x, 12.0)
    assert q_alpha == nonlinear_outputs(p, x, (0.0, 0.0, 12.0))[0]
    assert alpha != 0.0


def test_ins_block_noise_is_the_per_sample_draw():
    """The INS draws its noise in blocks: the same numbers as five draws per sample."""
    params = InsParams.from_vehicle(default_context().vehicle)
    sensor = InsSensor(params, seed=11)
    p = default_context().parameters(30.0)
    rng = np.random.Generator(np.random.PCG64(11))
    sigma = np.array([params.sigma_theta_rad, params.sigma_theta_dot_radps, params.sigma_z_m,
                      params.sigma_z_dot_mps, params.sigma_velocity_mps])
    x = (0.01, 0.002, 3.0, 0.4, 0.001, 0.0, 0.0, 0.01)
    for _ in range(600):                       # past two blocks
        y = np.empty(5)
        theta, theta_dot, z, z_dot, q1, q2, q1d, q2d = x
        ri, ti, li = p.psi_r_ins, p.psi_t_ins, p.l_ins_m
        y[:4] = [theta - ri[0] * q1 - ri[1] * q2, theta_dot - ri[0] * q1d - ri[1] * q2d,
                 z - li * math.sin(theta) + ti[0] * q1 + ti[1] * q2,
                 z_dot - li * math.cos(theta) * theta_dot + ti[0] * q1d + ti[1] * q2d]
        y[4] = 900.0
        y += sigma * rng.standard_normal(5)
        assert _bits(tuple(sensor.measure(x, p, 900.0))) == _bits(y)


@pytest.mark.parametrize("gust", [None, GustProfile(0.003, 0.01, 7.0)])
def test_wind_steps_equal_single_steps(gust):
    data = default_context().vehicle
    one = WindModel(data, turbulence="severe", gust=gust, seed=4, dt_s=0.001)
    many = WindModel(data, turbulence="severe", gust=gust, seed=4, dt_s=0.001)
    got, want = [], []
    for f in range(300):                        # 3000 steps: past two noise blocks
        h, v = 2000.0 + 30.0 * f, 100.0 + 2.0 * f
        times = [(10 * f + k) / 1000.0 for k in range(10)]
        got += many.steps(times, h, v)
        want += [one.step(t, h, v) for t in times]
    assert _bits(got) == _bits(want)


def test_actuator_run_equals_single_steps():
    params = ActuatorParams.from_vehicle(default_context().vehicle)
    a, b = TvcActuator(params, 0.01), TvcActuator(params, 0.01)
    rng = np.random.default_rng(5)
    commands = (rng.normal(size=2000) * 0.2).tolist()       # hits the rate and position limits
    commands[100:110] = [math.nan] * 5 + [math.inf] * 5
    got = a.run(commands)
    want = [b.step(u) + (b.command_rad,) for u in commands]
    assert [_bits(g) for g in got] == [_bits(w) for w in zip(*want)]
    assert a.state == b.state and a.command_rad == b.command_rad
