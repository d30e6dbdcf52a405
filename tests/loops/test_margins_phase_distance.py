"""The phase margin as the distance of a crossover's phase from −180° (either side), the
frozen-time floor below which a gain crossover is reported apart, and the worst-corner
ranking by that distance (``vega_loops.margins``).

The loops are closed forms whose crossovers are known by hand:

* L(s) = k·e^{−sτ}/s (integrator and pure delay): |L(jω)| = k/ω, so the one gain crossover
  is ω = k, with phase −90° − kτ·180°/π; the distance from −180° is |90° − kτ·180°/π| (taken
  mod 360°). τ is chosen for the phase wanted: τ = (φ_target − (−90°))·(−π/180°)/k.
  On a log grid the magnitude k/ω is linear in log ω, so the interpolated crossover is exact
  to rounding; the phase, linear in ω, is interpolated in log ω with an error below
  (Δ ln ω)²·ωτ/8 (≈ 1e-6° here);
* sums of such samples given by hand where two crossovers are wanted (see
  test_margins_extraction.py for the interpolation rule).

The floor's number is re-derived from the flight-condition table: the time the rigid-body
loop parameters stay within 10 % of their max-Q values.
"""

import math

import numpy as np
import pytest

from vega_loops import margins as M

W = np.geomspace(1e-3, 1e2, 40001)
"""Frequency grid [rad/s] (Δ ln ω = 2.9e-4)."""


def _delay_integrator(k, phase_deg):
    """k·e^{−sτ}/s with τ ≥ 0 chosen so that the phase at ω = k is ``phase_deg`` (≤ −90°)."""
    tau = math.radians(-90.0 - phase_deg) / k
    return k * np.exp(-1j * W * tau) / (1j * W)


# ------------------------------------------------------------------------ the distance
@pytest.mark.parametrize("phase, distance, signed", [
    (-150.0, 30.0, 30.0),       # 30° above −180°
    (-196.0, 16.0, -16.0),      # 16° beyond −180°: 16, not −16
    (-164.0, 16.0, 16.0),       # the mirror: as close
    (-250.0, 70.0, -70.0),
    (-530.0, 10.0, 10.0),       # beyond a full turn: −530° = −170° (mod 360°)
])
def test_distance_of_a_delay_integrator_crossover(phase, distance, signed):
    k = 2.0
    got = M.extract_margins(W, _delay_integrator(k, phase))
    assert got["w_pm_radps"] == pytest.approx(k, rel=1e-9)
    assert got["pm_deg"] == pytest.approx(distance, abs=1e-4)
    assert got["pm_signed_deg"] == pytest.approx(signed, abs=1e-4)
    assert got["n_gain_crossovers"] == 1 and got["n_low_gain_crossovers"] == 0
    assert got["pm_low_deg"] == math.inf and math.isnan(got["w_pm_low_radps"])


def test_distance_of_a_delay_integrator_from_its_delay():
    """L = k e^{−sτ}/s with k = 3 rad/s, τ = 0.2 s: phase −90° − 0.6 rad = −124.38°, 55.62°."""
    k, tau = 3.0, 0.2
    got = M.extract_margins(W, k * np.exp(-1j * W * tau) / (1j * W))
    assert got["pm_deg"] == pytest.approx(90.0 - math.degrees(k * tau), abs=1e-4)
    assert got["w_pm_radps"] == pytest.approx(k, rel=1e-9)


# ----------------------------------------------------------------------------- the floor
def test_a_crossover_below_the_floor_is_reported_apart():
    """k = 0.025 rad/s (the drift loop's crossover in the dispersed sweep, a 250 s period):
    not in pm_deg (no other crossover: inf), reported in pm_low_deg with its frequency."""
    k = 0.025
    assert k < M.PM_FLOOR_RADPS
    got = M.extract_margins(W, _delay_integrator(k, -213.0))
    assert got["pm_deg"] == math.inf and math.isnan(got["w_pm_radps"])
    assert math.isnan(got["pm_signed_deg"])
    assert got["pm_low_deg"] == pytest.approx(33.0, abs=1e-4)
    assert got["w_pm_low_radps"] == pytest.approx(k, rel=1e-9)
    assert got["n_gain_crossovers"] == 1 and got["n_low_gain_crossovers"] == 1
    # the same loop with the floor below its crossover: counted
    counted = M.extract_margins(W, _delay_integrator(k, -213.0), pm_floor_radps=0.02)
    assert counted["pm_deg"] == pytest.approx(33.0, abs=1e-4)
    assert counted["n_low_gain_crossovers"] == 0


def _two_crossovers():
    """By hand (linear in log ω between samples): 0 dB at the geometric midpoints of
    0.01–0.04 (ω = 0.02, phase midway −210/−216: −213°, 33° beyond −180°) and of 1–4 rad/s
    (ω = 2, phase midway −150/−160: −155°, 25°); 0 dB … 40 dB between."""
    w = [0.01, 0.04, 0.1, 1.0, 4.0, 10.0]
    m = [-6.0, 6.0, 40.0, 6.0, -6.0, -20.0]
    ph = [-210.0, -216.0, -200.0, -150.0, -160.0, -170.0]
    return w, 10.0 ** (np.array(m) / 20.0) * np.exp(1j * np.radians(ph))


def test_the_rigid_pm_leaves_out_the_crossover_below_the_floor():
    w, L = _two_crossovers()
    got = M.extract_margins(w, L)
    assert got["pm_deg"] == pytest.approx(25.0, abs=1e-9)
    assert got["w_pm_radps"] == pytest.approx(2.0, rel=1e-12)
    assert got["pm_low_deg"] == pytest.approx(33.0, abs=1e-9)
    assert got["w_pm_low_radps"] == pytest.approx(0.02, rel=1e-12)
    assert got["n_gain_crossovers"] == 2 and got["n_low_gain_crossovers"] == 1


def test_a_crossover_exactly_on_the_floor_counts():
    w, L = _two_crossovers()
    w_low = M.extract_margins(w, L)["w_pm_low_radps"]
    on = M.extract_margins(w, L, pm_floor_radps=w_low)
    assert on["pm_deg"] == pytest.approx(25.0, abs=1e-9)        # both count: 25 < 33
    assert on["n_low_gain_crossovers"] == 0 and on["pm_low_deg"] == math.inf
    above = M.extract_margins(w, L, pm_floor_radps=np.nextafter(w_low, np.inf))
    assert above["n_low_gain_crossovers"] == 1


def test_gain_margins_keep_every_phase_crossover_with_its_frequency():
    """k e^{−sτ}/s: phase crossovers where ωτ = π/2 + 2πn, |L| = k/ω there. k = 0.2, τ = 20 s:
    the first at ω = π/40 = 0.0785 rad/s (below the floor), |L| = 8/π (gain reduction 8.12
    dB); the next at 5π/40, |L| = 1.6/π (gain increase 5.86 dB)."""
    k, tau = 0.2, 20.0
    got = M.extract_margins(W, k * np.exp(-1j * W * tau) / (1j * W))
    assert got["w_gm_low_radps"] == pytest.approx(math.pi / 40.0, rel=1e-6)
    assert got["gm_low_db"] == pytest.approx(20 * math.log10(8.0 / math.pi), abs=1e-4)
    assert got["w_gm_high_radps"] == pytest.approx(5 * math.pi / 40.0, rel=1e-6)
    assert got["gm_high_db"] == pytest.approx(-20 * math.log10(1.6 / math.pi), abs=1e-4)


@pytest.mark.slow
def test_the_floor_from_the_flight_condition_table():
    """PM_FLOOR_RADPS = 1/T, T the time after (and before) max-Q within which the aerodynamic
    stiffness μ_α = Q·S·C_Nα·l_CP/J_yy and the control effectiveness μ_c = T·l_CG-PVP/J_yy
    stay within 10 % of their max-Q values (module docstring of vega_loops.margins)."""
    from vega_model.parameters import default_context

    context = default_context()
    t_q = M.max_q_time(context)
    t = np.round(np.arange(t_q - 15.0, t_q + 15.0 + 1e-9, 0.1), 6)
    ps = [context.parameters(float(x)) for x in t]
    mu_a = np.array([p.q_pa * p.s_ref_m2 * p.cn_alpha_per_rad * p.l_cp_m / p.jyy_kgm2
                     for p in ps])
    mu_c = np.array([p.thrust_n * p.l_cg_pvp_m / p.jyy_kgm2 for p in ps])
    k_q = int(np.argmin(np.abs(t - t_q)))

    def within(x):
        """Shortest time from max-Q, on either side, to a 10 % change of x."""
        off = np.abs(x / x[k_q] - 1.0) >= 0.10
        after = t[k_q:][off[k_q:]][0] - t_q
        before = t_q - t[:k_q + 1][off[:k_q + 1]][-1]
        return min(after, before)

    frozen = min(within(mu_a), within(mu_c))
    assert 6.0 < frozen < 7.5
    assert 1.0 / frozen == pytest.approx(M.PM_FLOOR_RADPS, rel=0.1)


# --------------------------------------------------------------- the worst-corner ranking
def _corner_rows(t_s=48.0):
    """Three corners at one time, signed PMs −33° (at 0.025 rad/s, below the floor), −16°
    (8.2 rad/s) and +25° (2 rad/s): the delay-integrator loop of each, margins extracted."""
    rows = []
    for corner, (k, phase) in enumerate(((0.025, -213.0), (8.2, -196.0), (2.0, -155.0)),
                                        start=1):
        row = M.extract_margins(W, _delay_integrator(k, phase), (1e3, 2e3))
        row.update(t_s=t_s, corner=corner, n_unstable=0)
        rows.append(row)
    return rows


def test_the_worst_corner_is_the_closest_crossover_at_its_frequency():
    worst = M.worst_per_time(_corner_rows())[0]
    assert worst["pm_deg_corner"] == 2
    assert worst["pm_deg"] == pytest.approx(16.0, abs=1e-4)
    assert worst["pm_deg_freq_radps"] == pytest.approx(8.2, rel=1e-9)
    # the drift-like crossover below the floor: reported apart, with its frequency
    assert worst["pm_low_deg_corner"] == 1
    assert worst["pm_low_deg"] == pytest.approx(33.0, abs=1e-4)
    assert worst["pm_low_deg_freq_radps"] == pytest.approx(0.025, rel=1e-9)


def test_verdicts_rank_by_the_distance_and_name_the_crossover():
    v = M.verdicts(_corner_rows(), [{}, {"a": -0.1}, {"a": 0.2}, {"a": 0.3}],
                   M.DISPERSED_CRITERION)
    pm = v["pm_deg"]
    assert pm["corner"] == 2 and pm["pass"] is False            # 16° < 20°
    assert pm["worst"] == pytest.approx(16.0, abs=1e-4)
    assert pm["w_radps"] == pytest.approx(8.2, rel=1e-9)
    low = v["pm_below_floor"]
    assert low["corner"] == 1 and low["n_loops"] == 1
    assert low["worst"] == pytest.approx(33.0, abs=1e-4)
    assert low["w_radps"] == pytest.approx(0.025, rel=1e-9)
    assert "pass" not in low
