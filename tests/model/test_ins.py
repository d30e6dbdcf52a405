"""INS sensor model: kinematics from the plant module, Eq. 4.18 noise, seeding, timing, and
the parameter checks.

The noise is also held to its documented law sample by sample (module and class docstrings: a
numpy PCG64 generator seeded with ``seed``, five standard-normal draws per sample in the
channel order θ, θ̇, z, ż, v, added as truth + σ·n), rebuilt here with numpy alone on the hand
kinematics of an undeformed vehicle (θ_INS = θ, z_INS = z − l sin θ; thesis Eqs. 2.33–2.36).
"""

import math

import numpy as np
import pytest

from vega_model.dynamics import ins_outputs
from vega_model.ins import InsParams, InsSensor, sample_schedule
from vega_model.parameters import model_parameters
from vega_model.vehicle_data import load_vehicle_data

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def params():
    return InsParams.from_vehicle(load_vehicle_data())


def _state(rng):
    """A plausible perturbation state [θ, θ̇, z, ż, q1, q2, q̇1, q̇2]."""
    return rng.normal(0.0, [2 * DEG, 1 * DEG, 5.0, 2.0, 0.5, 0.3, 5.0, 5.0])


def test_params_from_vehicle(params):
    assert params.rate_hz == 100.0
    assert params.latency_s == pytest.approx(0.012)               # thesis §2.12.4 sensors
    assert params.sigma_theta_rad == pytest.approx(0.02 * DEG)     # thesis Eq. 4.18
    assert params.sigma_theta_dot_radps == pytest.approx(0.01 * DEG)
    assert params.sigma_z_m == pytest.approx(0.01)
    assert params.sigma_z_dot_mps == pytest.approx(0.001)
    assert params.sigma_velocity_mps == pytest.approx(0.05)


@pytest.mark.parametrize("t", (10.0, 50.0, 90.0))
def test_noise_free_measurement_is_the_ins_kinematics(params, t):
    p = model_parameters(t)
    sensor = InsSensor(params, noise=False)
    rng = np.random.default_rng(int(t))
    for _ in range(5):
        x = _state(rng)
        m = sensor.measure(x, p, p.v_mps)
        np.testing.assert_array_equal(m[:4], ins_outputs(p, x))
        assert m.velocity_mps == p.v_mps
    # a bent vehicle at rest: θ_INS = −Σ Ψr q (Eq. 2.33), z_INS = Σ Ψt q (Eq. 2.35)
    x = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    m = sensor.measure(x, p, 0.0)
    assert m.theta_rad == pytest.approx(-p.psi_r_ins[0]) and m.z_m == pytest.approx(p.psi_t_ins[0])


@pytest.mark.slow
def test_noise_std_matches_eq_4_18(params):
    p = model_parameters(50.0)
    sensor = InsSensor(params, seed=21)
    x = np.zeros(8)
    truth = np.concatenate((ins_outputs(p, x), [p.v_mps]))
    samples = np.array([sensor.measure(x, p, p.v_mps) for _ in range(20000)]) - truth
    sig = [params.sigma_theta_rad, params.sigma_theta_dot_radps, params.sigma_z_m,
           params.sigma_z_dot_mps, params.sigma_velocity_mps]
    # std of a std estimate from 20000 samples: 0.5 %; 4 % tolerance
    np.testing.assert_allclose(samples.std(axis=0), sig, rtol=0.04)
    assert np.all(np.abs(samples.mean(axis=0)) < 4.0 * np.array(sig) / math.sqrt(20000))
    # channels independent
    corr = np.corrcoef(samples.T)
    assert np.max(np.abs(corr - np.eye(5))) < 0.05


def test_seeded_determinism(params):
    p = model_parameters(30.0)
    x = _state(np.random.default_rng(0))
    s1, s2, s3 = InsSensor(params, seed=7), InsSensor(params, seed=7), InsSensor(params, seed=8)
    run1 = [s1.measure(x, p, 400.0) for _ in range(50)]
    run2 = [s2.measure(x, p, 400.0) for _ in range(50)]
    run3 = [s3.measure(x, p, 400.0) for _ in range(50)]
    assert run1 == run2 and run1 != run3
    s1.reset()
    assert s1.measure(x, p, 400.0) == run1[0]


def test_sample_schedule(params):
    t, avail = sample_schedule(params, 0.1)
    np.testing.assert_allclose(t, np.arange(11) * 0.01)          # 100 Hz, ends included
    np.testing.assert_allclose(avail - t, 0.012)                 # 12 ms sensor latency
    t2, _ = sample_schedule(params, 1.0, t_start_s=0.955)
    np.testing.assert_allclose(t2, [0.96, 0.97, 0.98, 0.99, 1.0])


def _kw(**over):
    kw = dict(rate_hz=100.0, latency_s=0.012, sigma_theta_rad=1e-4,
              sigma_theta_dot_radps=1e-4, sigma_z_m=0.01, sigma_z_dot_mps=1e-3,
              sigma_velocity_mps=0.05)
    kw.update(over)
    return kw


def test_rate_must_be_finite_and_positive():
    assert InsParams(**_kw(rate_hz=0.5)).rate_hz == 0.5          # below 1 Hz is still valid
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="rate_hz"):
            InsParams(**_kw(rate_hz=bad))


@pytest.mark.parametrize("name", ("latency_s", "sigma_theta_rad", "sigma_theta_dot_radps",
                                  "sigma_z_m", "sigma_z_dot_mps", "sigma_velocity_mps"))
def test_latency_and_noise_levels_zero_allowed_negative_or_non_finite_refused(name):
    assert getattr(InsParams(**_kw(**{name: 0.0})), name) == 0.0
    for bad in (-1e-6, math.nan, math.inf):
        with pytest.raises(ValueError, match=name):
            InsParams(**_kw(**{name: bad}))


def test_sensor_keeps_its_parameters_and_defaults(params):
    s = InsSensor(params)
    assert s.params is params and s.seed == 0 and s.noise is True


@pytest.mark.parametrize("seed", (None, 0, 42))
def test_noise_is_the_documented_sequence_channel_by_channel(params, seed):
    """600 samples (more than one internal block of draws): each equals truth + σ·n with n the
    k-th group of five draws of PCG64(seed), in the order θ, θ̇, z, ż, v."""
    p = model_parameters(40.0)
    theta, z = 1.5 * DEG, 3.0
    x = np.array([theta, 0.5 * DEG, z, 1.0, 0.0, 0.0, 0.0, 0.0])
    li = p.l_ins_m
    truth = np.array([theta, 0.5 * DEG, z - li * math.sin(theta),
                      1.0 - li * math.cos(theta) * 0.5 * DEG, 420.0])
    sensor = InsSensor(params) if seed is None else InsSensor(params, seed=seed)
    rng = np.random.Generator(np.random.PCG64(0 if seed is None else seed))
    sig = np.array([params.sigma_theta_rad, params.sigma_theta_dot_radps, params.sigma_z_m,
                    params.sigma_z_dot_mps, params.sigma_velocity_mps])
    assert np.all(sig > 0.0)
    for k in range(600):
        m = np.array(sensor.measure(x, p, 420.0))
        n = rng.standard_normal(5)
        np.testing.assert_allclose(m, truth + sig * n, rtol=1e-12, atol=0,
                                   err_msg=f"sample {k}")
