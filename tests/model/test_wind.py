"""Wind: Eq. 2.54 profile, Table 2.4 turbulence parameters, Dryden statistics, gust."""

import math

import numpy as np
import pytest
from scipy.linalg import solve_continuous_lyapunov

from vega_model.wind import (DrydenTurbulence, GustProfile, WindModel, dryden_ss,
                             turbulence_params, wind_profile_mps)
from vega_model.vehicle_data import load_vehicle_data


@pytest.fixture(scope="module")
def data():
    return load_vehicle_data()


@pytest.mark.parametrize("h, expected", [
    (-50.0, 0.0),
    (0.0, 0.0),
    (1000.0, 140.0 * (0.5 ** 0.9 - 0.45)),     # 12.024 m/s on the leading edge
    (2000.0, 14.0),
    (10000.0, 14.0),
    (17500.0, 14.0),
    (18750.0, 7.0),                             # mid trailing edge: A/2 (1 − cos(−π/2))
    (20000.0, 0.0),
    (20001.0, 0.0),
    (60000.0, 0.0),
])
def test_profile_values(data, h, expected):
    assert wind_profile_mps(h, data) == pytest.approx(expected, abs=1e-12)
    assert float(wind_profile_mps(np.array([h]), data)[0]) == pytest.approx(expected, abs=1e-12)


def test_profile_leading_edge_hand_value(data):
    assert wind_profile_mps(1000.0, data) == pytest.approx(12.0242, abs=1e-4)


@pytest.mark.parametrize("h", (2000.0, 17500.0, 20000.0))
def test_profile_continuous_at_breakpoints(data, h):
    eps = 1e-6
    lo, mid, hi = (wind_profile_mps(x, data) for x in (h - eps, h, h + eps))
    assert abs(lo - mid) < 1e-6 and abs(hi - mid) < 1e-6


def test_profile_vector_equals_scalar(data):
    h = np.linspace(-100.0, 25000.0, 2001)
    vec = wind_profile_mps(h, data)
    assert vec.shape == h.shape
    np.testing.assert_allclose(vec, [wind_profile_mps(float(x), data) for x in h], atol=1e-12)
    assert np.all(vec >= 0.0) and np.max(vec) == pytest.approx(14.0)
    assert math.isnan(wind_profile_mps(math.nan, data))


@pytest.mark.parametrize("h, intensity, sigma, length", [
    (500.0, "light", 0.17, 832.0),                       # below 1 km: 1 km row held
    (1500.0, "light", 0.17, 867.0),
    (3000.0, "moderate", (1.65 + 2.04) / 2, (902 + 1040) / 2),
    (12000.0, "severe", 7.89, 1800.0),
    (11000.0, "severe", (7.72 + 7.89) / 2, (1230 + 1800) / 2),
    (20000.0, "severe", 3.85, 8640.0),                   # last row, still on
    (20000.5, "severe", 0.0, 8640.0),                    # above 20 km: zero
    (35000.0, "moderate", 0.0, 8640.0),
    (8000.0, "none", 0.0, 1040.0),
])
def test_turbulence_params_table_2_4(data, h, intensity, sigma, length):
    s, ell = turbulence_params(h, data, intensity)
    assert s == pytest.approx(sigma, abs=1e-12) and ell == pytest.approx(length, abs=1e-9)
    s_arr, ell_arr = turbulence_params(np.array([h, h]), data, intensity)
    assert s_arr[1] == pytest.approx(sigma, abs=1e-12) and ell_arr[0] == pytest.approx(length)


def test_turbulence_rejects_unknown_intensity(data):
    with pytest.raises(ValueError):
        turbulence_params(1000.0, data, "extreme")
    with pytest.raises(ValueError):
        DrydenTurbulence(data, "Light")


def _run(turb, n, h, v):
    return np.array([turb.step(h, v) for _ in range(n)])


@pytest.mark.slow
def test_dryden_stationary_std_and_correlation_time(data):
    """Severe at 11 km (interpolated row): σ = 7.805 m/s, L = 1515 m; V = 1000 m/s."""
    dt, h, v = 0.05, 11000.0, 1000.0
    sigma, ell = turbulence_params(h, data, "severe")
    x = _run(DrydenTurbulence(data, "severe", seed=4, dt_s=dt), 200_000, h, v)
    assert np.std(x) == pytest.approx(sigma, rel=0.04)
    assert abs(np.mean(x)) < 0.1 * sigma
    # lag-1 correlation -> correlation time; and the correlation at lag L/V is 1/e
    xc = x - x.mean()
    rho1 = np.dot(xc[1:], xc[:-1]) / np.dot(xc, xc)
    assert -dt / math.log(rho1) == pytest.approx(ell / v, rel=0.05)
    lag = round(ell / v / dt)
    rho_tc = np.dot(xc[lag:], xc[:-lag]) / np.dot(xc, xc)
    assert rho_tc == pytest.approx(math.exp(-lag * dt * v / ell), abs=0.04)


def test_dryden_seeded(data):
    a = _run(DrydenTurbulence(data, "moderate", seed=11), 500, 5000.0, 300.0)
    b = _run(DrydenTurbulence(data, "moderate", seed=11), 500, 5000.0, 300.0)
    c = _run(DrydenTurbulence(data, "moderate", seed=12), 500, 5000.0, 300.0)
    np.testing.assert_array_equal(a, b)
    assert np.max(np.abs(a - c)) > 0.1
    turb = DrydenTurbulence(data, "moderate", seed=11)
    _run(turb, 123, 5000.0, 300.0)
    turb.reset()
    np.testing.assert_array_equal(_run(turb, 500, 5000.0, 300.0), a)


def test_dryden_zero_above_20km_and_for_none(data):
    turb = DrydenTurbulence(data, "severe", seed=1)
    assert np.all(_run(turb, 1000, 20500.0, 900.0) == 0.0)
    assert np.all(_run(DrydenTurbulence(data, "none", seed=1), 100, 10000.0, 500.0) == 0.0)
    with pytest.raises(ValueError):
        turb.step(math.nan, 500.0)


def test_dryden_ss_thesis_form_with_airspeed(data):
    h, v = 10000.0, 600.0
    sigma, ell = turbulence_params(h, data, "light")
    A, B, C, D = dryden_ss(h, v, data, "light")
    assert A[0, 0] == pytest.approx(-v / ell)
    assert B[0, 0] == pytest.approx(sigma * math.sqrt(2.0 * v / (math.pi * ell)))
    assert C[0, 0] == 1.0 and D[0, 0] == 0.0
    # white noise of two-sided intensity π -> variance σ² (MIL-HDBK-1797 convention)
    P = solve_continuous_lyapunov(A, -math.pi * B @ B.T)
    assert P[0, 0] == pytest.approx(sigma ** 2, rel=1e-12)
    with pytest.raises(ValueError):
        dryden_ss(h, 0.0, data)


def test_gust_shape(data):
    g = GustProfile.from_vehicle(data, t_start_s=40.0)
    amp, dur = 9.0, 2.0                     # vehicle.yaml wind.gust
    assert (g.amplitude_mps, g.duration_s) == (amp, dur)
    assert g.velocity_mps(39.999) == 0.0 and g.velocity_mps(42.001) == 0.0
    assert g.velocity_mps(40.0) == 0.0
    assert g.velocity_mps(41.0) == pytest.approx(amp)                  # peak at t0 + D/2
    assert g.velocity_mps(40.5) == pytest.approx(amp / 2)              # quarter: A/2
    assert g.velocity_mps(40.3) == pytest.approx(g.velocity_mps(41.7))  # symmetric
    t = np.linspace(39.0, 43.0, 4001)
    v = np.array([g.velocity_mps(x) for x in t])
    assert np.max(v) == pytest.approx(amp) and np.min(v) == 0.0
    with pytest.raises(ValueError):
        GustProfile(0.0, 0.0, 1.0)


def test_wind_model_sums_parts(data):
    gust = GustProfile(t_start_s=1.0, duration_s=1.0, amplitude_mps=-5.0)
    model = WindModel(data, profile=True, turbulence="light", gust=gust, seed=5)
    ref_turb = DrydenTurbulence(data, "light", seed=5)
    dt = model.turbulence.dt_s
    for k in range(2500):
        t = k * dt
        h, v = 1500.0 + 300.0 * t, 50.0 + 20.0 * t
        c = model.step_components(t, h, v)
        assert c.profile_mps == pytest.approx(wind_profile_mps(h, data), abs=1e-12)
        assert c.gust_mps == gust.velocity_mps(t)
        assert c.turbulence_mps == ref_turb.step(h, v)
        assert c.total_mps == c.profile_mps + c.turbulence_mps + c.gust_mps
    plain = WindModel(data, profile=False)
    assert plain.step(10.0, 10000.0, 500.0) == 0.0
