"""The wind sampler against its site table and its model: per-level moments and percentiles,
the correlation across altitude, the change's growth with the lag, the sounding's smoothing,
the small-scale shear law, and per-sample reproducibility."""

import math

import numpy as np
import pytest
from scipy.stats import norm

from vega_campaign.wind_environment import (FINE_STEP_M, change_rms_mps, climate_levels,
                                            in_plane_moments, level_moments, load_site,
                                            sample_profiles, small_scale_sigma_mps)

N_LEVELS = 4000            # samples for the level statistics (≈ 0.15 s a month)


@pytest.fixture(scope="module")
def site():
    return load_site()


@pytest.fixture(scope="module")
def levels(site):
    return {m: climate_levels(site, m, seed=11, n=N_LEVELS) for m in (1, 8)}


def _level(site, altitude_m):
    return int(np.argmin(np.abs(site.altitude_m - altitude_m)))


@pytest.mark.parametrize("month", [1, 8])
def test_level_means_spreads_and_correlation_are_the_tables(site, levels, month):
    """Every level: mean and spread of u and v and r(u, v) within 5 standard errors of n."""
    x = levels[month]
    mean, cov = level_moments(site, month)
    su, sv = np.sqrt(cov[:, 0, 0]), np.sqrt(cov[:, 1, 1])
    n = x.shape[0]
    assert np.all(np.abs(x.mean(axis=0) - mean) <= 5.0 * np.stack([su, sv], -1) / math.sqrt(n))
    sd = x.std(axis=0, ddof=1)
    assert np.all(np.abs(sd - np.stack([su, sv], -1))
                  <= 5.0 * np.stack([su, sv], -1) / math.sqrt(2 * n))
    r_table = cov[:, 0, 1] / (su * sv)
    r = np.array([np.corrcoef(x[:, k, 0], x[:, k, 1])[0, 1] for k in range(x.shape[1])])
    assert np.all(np.abs(r - r_table) <= 5.0 * (1.0 - r_table ** 2) / math.sqrt(n) + 1e-3)


@pytest.mark.parametrize("altitude_m", [1000, 5000, 10000, 12000, 15000, 20000])
def test_in_plane_percentiles_are_the_gaussian_ones(site, levels, altitude_m):
    """p50/p95/p99 of the in-plane component: the normal quantiles of the table's projected
    moments, within 5 standard errors of an n-sample quantile."""
    k = _level(site, altitude_m)
    m, s = in_plane_moments(site, 1)
    a = math.radians(site.flight_azimuth_deg)
    w = levels[1][:, k] @ np.array([math.sin(a), math.cos(a)])
    n = w.size
    for q in (0.50, 0.95, 0.99):
        want = m[k] + s[k] * norm.ppf(q)
        se = s[k] * math.sqrt(q * (1 - q) / n) / norm.pdf(norm.ppf(q))
        assert abs(np.quantile(w, q) - want) <= 5.0 * se


def _speed_quantile(mean, cov, q):
    """Quantile of |V|, V ~ N(mean, cov), by integrating the density on a polar grid (an
    independent route: no sampling). With V = r e(φ): (V − m)ᵀ A (V − m) =
    r² eᵀAe − 2r eᵀAm + mᵀAm, A = cov⁻¹."""
    from scipy.optimize import brentq

    a = np.linalg.inv(cov)
    phi = np.linspace(0.0, 2 * np.pi, 361)[:-1]
    e = np.stack([np.cos(phi), np.sin(phi)], -1)
    c2, c1, c0 = np.einsum("pi,ij,pj->p", e, a, e), e @ a @ mean, mean @ a @ mean
    norm_ = 2 * np.pi * math.sqrt(np.linalg.det(cov))

    def cdf(s):
        r = np.linspace(0.0, s, 401)[:, None]
        f = np.exp(-0.5 * (r * r * c2 - 2 * r * c1 + c0)) / norm_
        return np.trapezoid(f.mean(axis=1) * 2 * np.pi * r[:, 0], r[:, 0])

    top = np.linalg.norm(mean) + 8 * math.sqrt(np.trace(cov))
    return brentq(lambda s: cdf(s) - q, 1e-6, top, xtol=1e-3)


@pytest.mark.parametrize("altitude_m", [1000, 12000, 20000])
def test_speed_percentiles_are_those_of_the_vector_model(site, levels, altitude_m):
    """p50/p95/p99 of the sampled speed against the bivariate normal's, integrated."""
    k = _level(site, altitude_m)
    mean, cov = level_moments(site, 1)
    speed = np.linalg.norm(levels[1][:, k], axis=-1)
    n = speed.size
    for q in (0.50, 0.95, 0.99):
        want = _speed_quantile(mean[k], cov[k], q)
        density = max(np.mean(np.abs(speed - want) < 0.5), 1e-3)   # per m/s, near want
        se = math.sqrt(q * (1 - q) / n) / density
        assert abs(np.quantile(speed, q) - want) <= 5.0 * se + 0.05


@pytest.mark.parametrize("separation_m", [1000, 5000])
def test_inter_level_correlation_decays_as_the_model(site, levels, separation_m):
    """corr(u_i, u_j) = exp(−|Δh|/L) at two separations, averaged over level pairs."""
    x = levels[1][:, :, 0]
    step = int(round(separation_m / np.diff(site.altitude_m[1:3])[0]))
    pairs = range(1, site.altitude_m.size - step, 4)
    r = np.mean([np.corrcoef(x[:, i], x[:, i + step])[0, 1] for i in pairs])
    want = math.exp(-separation_m / site.vertical_correlation_m)
    assert r == pytest.approx(want, abs=5.0 * (1 - want ** 2) / math.sqrt(x.shape[0]))


@pytest.fixture(scope="module")
def changes(site):
    return {lag: sample_profiles(site, 1, n=1200, seed=5, lag_s=lag, mode="in_plane")
            for lag in (1800.0, 14400.0)}


def test_change_rms_grows_with_the_lag_as_cited(site, changes):
    """rms of the change at 0.5 h and 4 h: the model's per-component rms (in the plane an
    isotropic change keeps it), within 5 standard errors; the ratio is 8^(1/3) = 2 where the
    change is far from its climatological saturation."""
    k = np.arange(0, site.fine_altitude_m.size, 25)
    for lag, s in changes.items():
        rms = np.sqrt(np.mean(s.change_mps[:, k] ** 2, axis=0))
        want = change_rms_mps(site, 1, lag)[k]
        assert np.all(np.abs(rms - want) <= 5.0 * want / math.sqrt(2 * s.change_mps.shape[0]))
    short, long_ = change_rms_mps(site, 1, 1800.0), change_rms_mps(site, 1, 14400.0)
    h = site.fine_altitude_m
    band = (h >= 6000) & (h <= 17000)                        # Merceret's altitudes
    assert np.allclose(long_[band] / short[band], 2.0, rtol=0.08)
    assert np.all(long_ >= short)
    assert np.all(change_rms_mps(site, 1, 0.0) == 0.0)
    huge = change_rms_mps(site, 1, 1e9)                      # saturation: √2 σ_c
    _, cov = level_moments(site, 1)
    sat = np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])                 # √2 · √((σu² + σv²)/2)
    assert np.allclose(huge, np.interp(h, site.altitude_m, sat), rtol=1e-6)


def test_change_is_correlated_across_altitude(site, changes):
    c = changes[14400.0].change_mps
    step = int(round(site.change_vertical_correlation_m / FINE_STEP_M))
    r = np.mean([np.corrcoef(c[:, i], c[:, i + step])[0, 1] for i in range(20, 280, 20)])
    assert r == pytest.approx(math.exp(-1.0), abs=0.06)


def test_measured_is_the_running_mean_and_flown_the_sum(site, changes):
    """The sounding is the 600 m running mean of the true wind (checked with numpy's
    convolution in the interior); flown = climate + small scale + change, exactly."""
    s = changes[1800.0]
    true = s.climate_mps + s.small_scale_mps
    width = int(round(site.smoothing_window_m / FINE_STEP_M)) + 1
    kernel = np.ones(width) / width
    for i in (0, 7):
        want = np.convolve(true[i], kernel, mode="valid")
        half = width // 2
        assert np.allclose(s.measured_wind_mps[i, half:-half], want, atol=1e-12)
    assert np.allclose(s.flown_wind_mps, s.climate_mps + s.small_scale_mps + s.change_mps,
                       rtol=0.0, atol=1e-12)
    # the smoothing removes small scales: the second difference shrinks
    assert (np.std(np.diff(s.measured_wind_mps, 2, axis=1))
            < 0.5 * np.std(np.diff(true, 2, axis=1)))


def test_small_scale_shear_grows_as_the_layer_to_the_0_7(site, changes):
    """rms difference of the small-scale part over 100 and 300 m: σ_s √(2(1 − exp(−(Δh/L_r)^1.4)))
    (≈ σ_s √2 (Δh/L_r)^0.7 for thin layers, Fichtl 1972)."""
    s = changes[1800.0].small_scale_mps
    sigma = small_scale_sigma_mps(site, 1)
    k = slice(50, 250)                          # 5-25 km
    for dh in (100.0, 300.0):
        j = int(dh / FINE_STEP_M)
        d = (s[:, 50 + j:250 + j] - s[:, k]) / np.sqrt(sigma[k] * sigma[50 + j:250 + j])
        want = math.sqrt(2 * (1 - math.exp(-(dh / site.shear_resolved_m) ** 1.4)))
        assert np.sqrt(np.mean(d ** 2)) == pytest.approx(want, rel=0.05)


def test_sample_i_is_the_same_among_5_or_50_at_any_lag_and_mode(site):
    few = sample_profiles(site, 3, n=5, seed=9, lag_s=600.0)
    many = sample_profiles(site, 3, n=50, seed=9, lag_s=600.0)
    one = sample_profiles(site, 3, indices=[3], seed=9, lag_s=600.0)
    for name in ("measured_wind_mps", "flown_wind_mps"):
        assert np.array_equal(getattr(few, name)[3], getattr(many, name)[3])
        assert np.array_equal(getattr(few, name)[3], getattr(one, name)[0])
    other_lag = sample_profiles(site, 3, n=5, seed=9, lag_s=7200.0)
    assert np.array_equal(other_lag.measured_wind_mps, few.measured_wind_mps)
    assert np.allclose(other_lag.change_mps, few.change_mps * (
        change_rms_mps(site, 3, 7200.0) / change_rms_mps(site, 3, 600.0)))
    assert not np.array_equal(sample_profiles(site, 4, n=5, seed=9).measured_wind_mps,
                              few.measured_wind_mps)
    assert not np.array_equal(sample_profiles(site, 3, n=5, seed=10).measured_wind_mps,
                              few.measured_wind_mps)


def test_full_speed_puts_the_whole_measured_speed_in_the_plane(site):
    full = sample_profiles(site, 1, n=20, seed=2, mode="full_speed")
    plane = sample_profiles(site, 1, n=20, seed=2, mode="in_plane")
    assert np.all(full.measured_wind_mps >= 0.0)
    assert np.all(full.measured_wind_mps >= np.abs(plane.measured_wind_mps) - 1e-9)


@pytest.mark.slow
def test_a_sample_is_the_same_bits_whatever_the_blas_thread_count():
    """A Dask worker runs one BLAS thread, the command line two here: the site's factors and
    the samples are computed with one thread either way (vega_loops.blas), so a campaign's
    recorded profile is re-drawn bit for bit by `vega mc rerun`."""
    from threadpoolctl import threadpool_limits

    from vega_campaign.wind_environment import default_site_path, parse_site, sample_profiles

    text = default_site_path().read_text()
    out = []
    for threads in (1, 2):
        with threadpool_limits(limits=threads, user_api="blas"):
            site = parse_site(text, "kourou.yaml")
            s = sample_profiles(site, 7, n=40, seed=3)
        out.append((site._factors["small"], s.measured_wind_mps, s.flown_wind_mps))
    for a, b in zip(*out):
        assert a.tobytes() == b.tobytes()
