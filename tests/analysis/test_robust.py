"""Robust analysis (vega_analysis.robust): disk margins checked on
textbook loops with known answers and against python-control; the worst-case search and the
destabilising scale checked on the shipped table against independent evaluations."""

import math

import control as ct
import numpy as np
import pytest

from vega_loops import margins as M
from vega_analysis import robust as R
from vega_gnc.controller_table import default_table_path, load_controller_table


# ------------------------------------------------------------------------ disk margins
def test_disk_margin_of_a_static_gain_is_closed_form():
    # L = k: S − 1/2 = (1 − k)/(2(1 + k)), so α = 2(1 + k)/|1 − k|; k = 3 → α = 4
    alpha, _ = R.disk_margin(np.full(5, 3.0 + 0j))
    assert alpha == pytest.approx(4.0, rel=1e-12)
    # α ≥ 2: every gain change is tolerated (DGM infinite), DPM = 2·atan(2) = 126.87°
    gm, pm = R.disk_gm_pm(4.0)
    assert math.isinf(gm) and pm == pytest.approx(math.degrees(2 * math.atan(2.0)))


def test_disk_margin_matches_python_control_and_seiler_example():
    # Seiler, Packard & Gahinet 2020, L = 25/(s³ + 10 s² + 10 s + 10): α ≈ 0.46, DGM ≈ 4.05 dB,
    # DPM ≈ 25.8°, within the classical margins (GM 11.1 dB, PM 29.1°)
    L = ct.tf([25], [1, 10, 10, 10])
    w = np.logspace(-2, 2, 4001)
    alpha, k = R.disk_margin(L(1j * w))
    gm, pm = R.disk_gm_pm(alpha)
    dm_ref, dgm_ref, dpm_ref = ct.disk_margins(L, w)
    assert alpha == pytest.approx(dm_ref, rel=1e-9)
    assert gm == pytest.approx(dgm_ref, rel=1e-9) and pm == pytest.approx(dpm_ref, rel=1e-9)
    assert alpha == pytest.approx(0.46, abs=0.005) and pm == pytest.approx(25.8, abs=0.1)
    gm_classic, pm_classic, _, _ = ct.margin(L)
    assert gm < 20 * math.log10(gm_classic) and pm < pm_classic
    assert w[k] == pytest.approx(1.96, rel=0.02)


def test_disk_gain_margin_is_a_true_gain_margin():
    # every gain in (1/DGM, DGM) keeps the loop stable, and the disk is not conservative by
    # more than the classical gain margin: scaling L by the classical GM destabilises it
    L = ct.tf([25], [1, 10, 10, 10])
    w = np.logspace(-2, 2, 4001)
    gm_db, _ = R.disk_gm_pm(R.disk_margin(L(1j * w))[0])
    for g in (10 ** (0.99 * gm_db / 20), 10 ** (-0.99 * gm_db / 20)):
        assert np.all(ct.poles(ct.feedback(g * L)).real < 0)
    assert np.any(ct.poles(ct.feedback(3.61 * L)).real > 0)


def test_disk_margin_is_zero_where_the_loop_passes_through_minus_one():
    L = np.array([0.5, -1.0 + 0j, 0.3])
    assert R.disk_margin(L)[0] == 0.0


# --------------------------------------------------------------- worst case on the table
@pytest.fixture(scope="module")
def point():
    from vega_model.parameters import default_context

    table = load_controller_table(default_table_path())
    return R.robust_point(table, default_context(), 50.0)


@pytest.fixture(scope="module")
def worst(point):
    return R.worst_case(point, seed=0, search={**R.SEARCH, "maxiter": 30})


def _alpha_of(point, dev):
    return R._evaluate(point, dev)


@pytest.mark.slow
def test_worst_case_is_no_better_than_any_corner_or_random_plant(point, worst):
    w = worst["worst"]
    assert w["alpha"] <= worst["corner_worst"]["alpha"]
    # re-evaluated independently, the reported deviations give the reported figures
    r, a = _alpha_of(point, w["deviations"])
    assert a == pytest.approx(w["alpha"], rel=1e-12) and r == pytest.approx(w["radius"])
    # every deviation lies inside the set's bounds
    for p in point.uset:
        assert p.lower - 1e-12 <= w["deviations"][p.name] <= p.upper + 1e-12
    # 150 random plants of the set: none has a smaller disk margin than the one found
    rng = np.random.default_rng(7)
    alphas = [_alpha_of(point, point.uset.sample(rng))[1] for _ in range(150)]
    assert w["alpha"] <= min(alphas)
    nominal = _alpha_of(point, point.uset.nominal())[1]
    assert w["alpha"] < nominal
    # the worst plant's margins each name their crossover: the frequencies of its exact
    # sampled-data loop recomputed here, the PM the distance from −180° at or above the floor
    row = R._fine(point, w["deviations"])
    loop = M.frozen_loop(point.data, *M.corner_plant(point.context, 50.0, w["deviations"]))
    ref = M.extract_margins(point.data.w_radps, loop.L_d, loop.omega_modes)
    for key in ("gm_low_db", "gm_high_db", "pm_deg"):
        assert row[M.FREQUENCY_OF[key]] == pytest.approx(ref[M.FREQUENCY_OF[key]], rel=1e-12)
    assert row["pm_deg"] == pytest.approx(abs(row["pm_signed_deg"]))
    assert row["w_pm_radps"] >= M.PM_FLOOR_RADPS


@pytest.mark.slow
def test_destabilising_scale_brackets_the_stability_boundary(point, worst):
    u = np.array(worst["worst"]["u"])
    ray = R.destabilising_scale(point, u)
    assert ray["s_star"] is not None and 1.0 < ray["s_star"] <= ray["s_limit"]
    assert ray["mu_lower"] == pytest.approx(1.0 / ray["s_star"])
    tol = ray["s_limit"] / 12 / 2 ** 10 * 1.01
    r_in, _ = _alpha_of(point, R._deviations(point, (ray["s_star"] - tol) * u))
    r_out, _ = _alpha_of(point, R._deviations(point, ray["s_star"] * u))
    assert r_in <= 1.0 + 1e-6 < r_out


def test_scale_limit_keeps_parameters_physical(point, monkeypatch):
    i = point.names.index("psi_mode_2")                      # ±50 %: centre 0, half 0.5
    u = np.zeros(len(point.names))
    u[i] = -1.0
    assert R._scale_limit(point, u) == pytest.approx(0.9 / 0.5)   # shapes −90 %, not below
    u[i] = 1.0
    assert R._scale_limit(point, u) == R.S_MAX                    # nothing bounds it but S_MAX
    j = point.names.index("delay_s")                          # ±10 ms around 39 ms
    u[:] = 0.0
    u[j] = -1.0
    assert R._scale_limit(point, u) == R.S_MAX                    # 3.9 > 3: capped
    monkeypatch.setattr(R, "S_MAX", 10.0)
    assert R._scale_limit(point, u) == pytest.approx(0.039 / 0.010)   # total delay ≥ 0


def test_fine_analysis_of_the_nominal_plant_agrees_with_vega_margins(point):
    row = R._fine(point, point.uset.nominal())
    ref = M.analyse_loop(point.data, *M.corner_plant(point.context, 50.0,
                                                     point.uset.nominal()), nyquist=False)
    for key in ("gm_low_db", "gm_high_db", "pm_deg"):
        assert row[key] == pytest.approx(ref[f"sd_{key}"], abs=1e-9)
        # and the crossover each belongs to
        assert row[M.FREQUENCY_OF[key]] == pytest.approx(ref[f"sd_{M.FREQUENCY_OF[key]}"],
                                                          rel=1e-12)
    assert set(R._FINE_KEYS) <= set(row)
    assert row["n_unstable"] == 0 and 0.0 < row["disk_alpha"] < 2.0
    assert row["disk_gm_db"] <= min(row["gm_low_db"], row["gm_high_db"]) + 1e-9
    assert row["disk_pm_deg"] <= row["pm_deg"] + 1e-9


def _row(t_s, **figures):
    """A hand-made row of :func:`R.analyse_time` (only what :func:`R.summarise` reads)."""
    row = {"t_s": t_s, "max_radius": 0.999, "worst_bending_1_ok": True,
           "worst_bending_2_ok": True, "mu_lower": 0.8, "mu_centre_stable": True,
           "mu_fit_loop_rel": 0.1, "mu_upper_w_radps": 0.4}
    for key in R.SUMMARY_KEYS:
        row.setdefault(key, 1.0)
    row.update(figures)
    return row


def test_summary_names_the_crossover_of_each_worst_margin_and_counts_whole_calls():
    rows = [_row(46.0, worst_pm_deg=20.2, worst_w_pm_radps=0.96, worst_gm_low_db=2.0,
                 worst_w_gm_low_radps=0.3, mu_upper=1.10, mu_whole_calls=6, mu_whole_won=0,
                 mu_whole_stopped=0, mu_whole_time_s=7.3),
            _row(48.0, worst_pm_deg=14.9, worst_w_pm_radps=8.25, worst_gm_low_db=3.0,
                 worst_w_gm_low_radps=0.5, mu_upper=0.91, mu_whole_calls=18, mu_whole_won=3,
                 mu_whole_stopped=2, mu_whole_time_s=31.0)]
    s = R.summarise(rows)
    assert s["worst_pm_deg"] == {"value": 14.9, "t_s": 48.0, "w_radps": 8.25}
    assert s["worst_gm_low_db"] == {"value": 2.0, "t_s": 46.0, "w_radps": 0.3}
    assert "w_radps" not in s["max_radius"]
    assert (s["mu_whole_calls"], s["mu_whole_won"], s["mu_whole_stopped"]) == (24, 3, 2)
    assert s["mu_whole_time_s"] == pytest.approx(38.3)
    assert s["mu_whole_stopped_times_s"] == [48.0]
