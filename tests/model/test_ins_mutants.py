"""INS sensor model: tests written for the survivors of `make mutation MODULE=ins`.

Independent references: the documented noise law (module and class docstrings: a numpy PCG64
generator seeded with ``seed``, five standard-normal draws per sample in the channel order
θ, θ̇, z, ż, v, added as truth + σ·n) rebuilt here with numpy alone, and the hand kinematics
of an undeformed vehicle (θ_INS = θ, z_INS = z − l sin θ; thesis Eqs. 2.33–2.36).
"""

import math

import numpy as np
import pytest

from vega_model.ins import InsParams, InsSensor
from vega_model.parameters import model_parameters
from vega_model.vehicle_data import load_vehicle_data

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def params():
    return InsParams.from_vehicle(load_vehicle_data())


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
