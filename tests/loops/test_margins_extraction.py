"""``vega_loops.margins.extract_margins`` on loops given sample by sample.

A loop is given by its samples: frequencies, magnitudes [dB] and phases [deg] picked by hand
(L = 10^(m/20)·e^{jφ}). Between samples the function interpolates linearly in log ω, so the
expected crossovers are worked out here by that rule written out with the hand-picked numbers
(level −180° + k·360° reached at the fraction f of the step, the magnitude and the frequency
e^{ln ω₀ + f (ln ω₁ − ln ω₀)} at that fraction). Where a magnitude is linear in log ω the
parabolic peak refinement has nothing to refine (the sample is the peak). Each documented
boundary (rigid band ω < 0.8 ω₁, bending bands 0.8 … 1.2 ω_i inclusive, phase-stabilised
above −6 dB) is checked with a crossover or a peak lying exactly on it.
"""

import math

import numpy as np
import pytest

from vega_loops import margins as M


def _loop(w, mag_db, phase_deg):
    return (10.0 ** (np.asarray(mag_db, float) / 20.0)
            * np.exp(1j * np.radians(np.asarray(phase_deg, float))))


def _at(w0, w1, f):
    return math.exp(math.log(w0) + f * (math.log(w1) - math.log(w0)))


# ------------------------------------------------------------------ crossovers and levels
def test_crossing_of_the_second_level_down():
    """Phase −100 … −600°: −180° crossed between 2 and 4 rad/s (f = ½, 20 dB) and −540°
    between 32 and 64 rad/s (f = ½, 2 dB): the gain reduction margin is the second, 2 dB;
    no crossover below 0 dB, so no gain-increase margin. One gain crossover, 64 … 128 rad/s."""
    w = [1, 2, 4, 8, 16, 32, 64, 128]
    ph = [-100, -170, -190, -350, -520, -539, -541, -600]
    m = [30, 25, 15, 5, 3, 2.5, 1.5, -10]
    got = M.extract_margins(w, _loop(w, m, ph))
    assert got["gm_low_db"] == pytest.approx(2.0, abs=1e-9)
    assert got["w_gm_low_radps"] == pytest.approx(_at(32, 64, 0.5), rel=1e-9)
    assert got["gm_high_db"] == math.inf and math.isnan(got["w_gm_high_radps"])
    f = 1.5 / 11.5                               # 0 dB between 64 (1.5 dB) and 128 (−10 dB)
    phase = -541 + f * (-600 + 541)              # −548.7°: 8.7° beyond −540°
    assert got["pm_deg"] == pytest.approx(-(phase + 540.0), abs=1e-9)
    assert got["pm_signed_deg"] == pytest.approx(phase + 540.0, abs=1e-9)
    assert got["w_pm_radps"] == pytest.approx(_at(64, 128, f), rel=1e-9)
    assert got["n_gain_crossovers"] == 1


def test_gain_increase_margin_is_the_smallest_not_the_first():
    """Two crossings below 0 dB (−180° at −20 dB, −540° at −5 dB): 5 dB, the second."""
    w = [1, 2, 4, 8, 16, 32, 64]
    ph = [-100, -170, -190, -350, -520, -530, -550]
    m = [-15, -18, -22, -12, -8, -6, -4]
    got = M.extract_margins(w, _loop(w, m, ph))
    assert got["gm_high_db"] == pytest.approx(5.0, abs=1e-9)      # −6 + ½ (−4 + 6)
    assert got["w_gm_high_radps"] == pytest.approx(_at(32, 64, 0.5), rel=1e-9)
    assert got["gm_low_db"] == math.inf
    assert got["pm_deg"] == math.inf and math.isnan(got["w_pm_radps"])
    assert got["n_gain_crossovers"] == 0


@pytest.mark.parametrize("phases, signed", [([-100, -120, -150, -170], 180 - 150 - 20 / 3),
                                            ([-100, -120, -150, -250], 180 - 150 - 100 / 3)])
def test_phase_margin_is_the_smallest_distance_from_minus_180(phases, signed):
    """Gain crossovers at 10 → −5 dB (f = ⅔), −5 → 5 (f = ½), 5 → −10 (f = ⅓): the third
    is the closest to −180° (23.3° above it; 3.3° beyond it); the margin is that distance,
    its side in pm_signed_deg."""
    w = [1, 2, 4, 8]
    m = [10, -5, 5, -10]
    got = M.extract_margins(w, _loop(w, m, phases))
    assert got["n_gain_crossovers"] == 3
    assert got["pm_deg"] == pytest.approx(abs(signed), abs=1e-9)
    assert got["pm_signed_deg"] == pytest.approx(signed, abs=1e-9)
    assert got["w_pm_radps"] == pytest.approx(_at(4, 8, 1 / 3), rel=1e-9)


@pytest.mark.parametrize("m0, m1, low, high", [(1.0, 0.0, 0.5, math.inf),
                                               (-1.0, 0.0, math.inf, 0.5),
                                               (3.0, -1.0, 1.0, math.inf)])
def test_a_crossover_just_above_or_below_0_db(m0, m1, low, high):
    """−170 → −190° at f = ½: the crossover at ½ (m0 + m1) dB is a gain reduction limit when
    above 0 dB, an increase limit when below."""
    w = [1.0, 2.0]
    got = M.extract_margins(w, _loop(w, [m0, m1], [-170, -190]))
    assert got["gm_low_db"] == pytest.approx(low, abs=1e-9)
    assert got["gm_high_db"] == pytest.approx(high, abs=1e-9)


# ------------------------------------------------------------------ bands and boundaries
def _exactly(factor, target, strict=True):
    """A float w0 with factor·w0 == target exactly (the product extract_margins forms)."""
    w0 = target / factor
    for _ in range(50):
        if factor * w0 == target:
            return w0
        w0 = np.nextafter(w0, np.inf if factor * w0 < target else -np.inf)
    if strict:
        raise AssertionError("no such float")
    return None


def _pc_loop():
    """One gain crossover (10 → −10 dB between 1 and 2 rad/s, f = ½, at −120°: PM 60°) and
    one phase crossover at −10.5 dB (−170 → −190° between 8 and 16 rad/s, f = ½)."""
    w = [1, 2, 4, 8, 16, 32]
    return w, _loop(w, [10, -10, -10, -10, -11, -12], [-120, -120, -140, -170, -190, -200])


def test_rigid_band_ends_just_below_0_8_omega_1():
    w, L = _pc_loop()
    free = M.extract_margins(w, L)
    wpc, wgc = free["w_gm_high_radps"], free["w_pm_radps"]
    assert free["gm_high_db"] == pytest.approx(10.5, abs=1e-9)
    assert free["pm_deg"] == pytest.approx(60.0, abs=1e-9)
    assert wpc == pytest.approx(_at(8, 16, 0.5), rel=1e-12)
    assert wgc == pytest.approx(_at(1, 2, 0.5), rel=1e-12)
    # a crossover exactly at 0.8 ω₁ is outside the rigid band (ω < 0.8 ω₁)
    at_edge = M.extract_margins(w, L, (_exactly(0.8, wpc), 1000.0))
    assert at_edge["gm_high_db"] == math.inf
    assert at_edge["pm_deg"] == pytest.approx(60.0, abs=1e-9)
    above = M.extract_margins(w, L, (np.nextafter(_exactly(0.8, wpc), np.inf), 1000.0))
    assert above["gm_high_db"] == pytest.approx(10.5, abs=1e-9)
    at_edge = M.extract_margins(w, L, (_exactly(0.8, wgc), 1000.0))
    assert at_edge["pm_deg"] == math.inf and at_edge["n_gain_crossovers"] == 0
    assert at_edge["gm_high_db"] == math.inf
    above = M.extract_margins(w, L, (np.nextafter(_exactly(0.8, wgc), np.inf), 1000.0))
    assert above["pm_deg"] == pytest.approx(60.0, abs=1e-9)
    assert above["n_gain_crossovers"] == 1


def test_band_crossovers_on_the_band_edges_are_in_the_band():
    """A bending band 0.8 … 1.2 ω₀ includes its edges: a crossover exactly on either edge
    gives the band's margins; just outside, none (inf)."""
    for factor, step in ((0.8, np.inf), (1.2, -np.inf)):
        # the same loop on a grid scaled by s: the first s for which both crossover
        # frequencies are factor·w0 for some float w0
        for s in 1.0 + 1e-3 * np.arange(100):
            w = [s * x for x in _pc_loop()[0]]
            L = _pc_loop()[1]
            free = M.extract_margins(w, L)
            wpc, wgc = free["w_gm_high_radps"], free["w_pm_radps"]
            if _exactly(factor, wpc, False) and _exactly(factor, wgc, False):
                break
        w0 = _exactly(factor, wpc)
        got = M.extract_margins(w, L, (0.01, w0))
        assert got["b2_gm_db"] == pytest.approx(10.5, abs=1e-9), factor
        out = M.extract_margins(w, L, (0.01, np.nextafter(w0, step)))
        assert out["b2_gm_db"] == math.inf, factor
        w0 = _exactly(factor, wgc)
        got = M.extract_margins(w, L, (0.01, w0))
        assert got["b2_pm_deg"] == pytest.approx(60.0, abs=1e-9), factor
        out = M.extract_margins(w, L, (0.01, np.nextafter(w0, step)))
        assert out["b2_pm_deg"] == math.inf, factor


def test_band_margins_only_from_crossovers_in_the_band():
    """Rigid band: phase crossovers at 1 dB and −2.6 dB, a gain crossover with −10° of
    margin; bending band 1 (ω₁ = 10, 8 … 12 rad/s): a phase crossover at −8 dB and gain
    crossovers with −33° and −30° (|·| reported). The band's margins are its own."""
    w = [1, 2, 3, 4, 8.5, 9, 10, 11, 11.5, 20]
    m = [5, 2, 0, -2, -5, -6, -10, 3, -3, -20]
    ph = [-150, -170, -190, -200, -100, -170, -190, -220, -200, -100]
    got = M.extract_margins(w, _loop(w, m, ph), (10.0, 100.0))
    # rigid: −180° between 2 and 3 (f = ½: 1 dB) and between 4 and 8.5 (f = 0.2: −2.6 dB),
    # 0 dB at 3 (phase −190°: 10° beyond −180°)
    assert got["gm_low_db"] == pytest.approx(1.0, abs=1e-9)
    assert got["gm_high_db"] == pytest.approx(2.6, abs=1e-9)
    assert got["pm_deg"] == pytest.approx(10.0, abs=1e-9)
    assert got["pm_signed_deg"] == pytest.approx(-10.0, abs=1e-9)
    assert got["b1_gm_db"] == pytest.approx(8.0, abs=1e-9)       # 9 → 10: f = ½, −8 dB
    # band 1 gain crossovers: 10 → 11 (f = 10/13, phase −190 − 30 f), 11 → 11.5 (f = ½)
    pm_a = 180 + (-190 - 30 * 10 / 13)
    pm_b = 180 + (-220 + 0.5 * 20)
    assert got["b1_pm_deg"] == pytest.approx(min(abs(pm_a), abs(pm_b)), abs=1e-9)
    assert got["b1_w_pm_radps"] == pytest.approx(_at(11, 11.5, 0.5), rel=1e-9)  # pm_b: 30°
    assert got["b1_w_gm_radps"] == pytest.approx(_at(9, 10, 0.5), rel=1e-9)
    assert got["b1_peak_db"] > 3.0 - 1e-9 and 8.0 <= got["b1_w_peak_radps"] <= 12.0


def test_band_peak_on_the_lower_and_upper_edges():
    """|L| ∝ 1/ω (and ∝ ω): the largest sample of a band is its lower (upper) edge, which the
    band includes: the peak is that sample (no refinement: the magnitude is linear in log ω)."""
    w1, w2 = 10.0, 50.0
    edges = [0.8 * w1, 1.2 * w1, 0.8 * w2, 1.2 * w2]
    w = np.array(sorted({1.0, 2.0, 5.0, 7.0, 9.0, 10.0, 11.0, 13.0, 20.0, 30.0, 45.0, 50.0,
                         55.0, 70.0, 100.0, *edges}))
    down = M.extract_margins(w, 1.0 / (1j * w), (w1, w2))
    up = M.extract_margins(w, 1j * w / 1000.0, (w1, w2))
    assert down["b1_peak_db"] == pytest.approx(-20 * math.log10(edges[0]), abs=1e-9)
    assert down["b1_w_peak_radps"] == pytest.approx(edges[0], rel=1e-12)
    assert down["b2_peak_db"] == pytest.approx(-20 * math.log10(edges[2]), abs=1e-9)
    assert up["b1_peak_db"] == pytest.approx(20 * math.log10(edges[1] / 1000), abs=1e-9)
    assert up["b1_w_peak_radps"] == pytest.approx(edges[1], rel=1e-12)
    assert up["b2_peak_db"] == pytest.approx(20 * math.log10(edges[3] / 1000), abs=1e-9)
    assert up["b2_w_peak_radps"] == pytest.approx(edges[3], rel=1e-12)
    # above the rigid band, outside both bands: 13, 20, 30 and 70, 100 rad/s
    assert down["hf_peak_db"] == pytest.approx(-20 * math.log10(13.0), abs=1e-9)
    assert up["hf_peak_db"] == pytest.approx(20 * math.log10(100.0 / 1000), abs=1e-9)


def test_hf_peak_leaves_out_the_rigid_band_and_both_bending_bands():
    w = [1, 2, 4, 6, 8, 9, 10, 11, 12, 13, 20, 30, 40, 45, 50, 55, 60, 70, 100]
    m = [40, 30, 20, 10, 2, 5, 10, 5, 2, -20, -15, -12, 1, 3, 5, 3, 1, -8, -30]
    got = M.extract_margins(w, _loop(w, m, [-90] * len(w)), (10.0, 50.0))
    assert got["hf_peak_db"] == pytest.approx(-8.0, abs=1e-9)
    # no bending data: the whole grid is rigid body, nothing above it
    assert M.extract_margins(w, _loop(w, m, [-90] * len(w)))["hf_peak_db"] == -math.inf


def test_a_band_beyond_the_grid_has_no_peak_and_no_margins():
    w = np.geomspace(1.0, 100.0, 50)
    got = M.extract_margins(w, 1.0 / (1j * w), (10.0, 500.0))
    assert got["b2_peak_db"] == -math.inf and math.isnan(got["b2_w_peak_radps"])
    assert got["b2_gm_db"] == math.inf and got["b2_pm_deg"] == math.inf
    assert got["b2_phase_stabilised"] is False
    assert got["b1_peak_db"] == pytest.approx(-20 * math.log10(w[w >= 8.0][0]), abs=1e-9)
    # rest: above 12 rad/s (band 2 starts at 400): the first sample above 12
    assert got["hf_peak_db"] == pytest.approx(-20 * math.log10(w[w > 12.0][0]), abs=1e-9)
    # nothing in the grid beyond 0.8 ω₁: no hf samples either
    far = M.extract_margins(w, 1.0 / (1j * w), (1000.0, 2000.0))
    assert far["hf_peak_db"] == -math.inf and far["b1_peak_db"] == -math.inf
    assert set(far) == set(got)


def test_phase_stabilised_strictly_above_minus_6_db():
    """A band peak of exactly −6 dB is gain-stabilised (≤ −6 dB); the next float above is
    phase-stabilised. The three samples around ω = 10 rad/s were found by bisection so that
    the refined peak is −6.0 to the last bit (checked first: the premise of the test)."""
    w = np.geomspace(1.0, 100.0, 61)

    def loop(mc):
        L = np.full(w.shape, 0.1, dtype=complex)
        L[29], L[30], L[31] = 0.49, mc, 0.48
        return L

    got = M.extract_margins(w, loop(0.5007719441961345), (10.0, 50.0))
    assert got["b1_peak_db"] == -6.0
    assert got["b1_phase_stabilised"] is False
    got = M.extract_margins(w, loop(0.5007719441961345 * (1 + 1e-12)), (10.0, 50.0))
    assert -6.0 < got["b1_peak_db"] < -5.99999
    assert got["b1_phase_stabilised"] is True


def test_a_phase_crossover_at_exactly_0_db_is_a_zero_gain_increase_margin():
    """|L| = 1 at −180° (the loop on the stability boundary): reported once, as a gain
    increase margin of 0 dB, not as a reduction margin. The two samples were found by
    bisection so that the interpolated magnitude is 0.0 to the last bit (checked)."""
    L = np.array([1.428571428571429 * np.exp(1j * np.radians(-170.0)),
                  0.7 * np.exp(1j * np.radians(-190.0))])
    got = M.extract_margins([1.0, 2.0], L)
    assert got["gm_high_db"] == 0.0 and got["w_gm_high_radps"] == pytest.approx(math.sqrt(2))
    assert got["gm_low_db"] == math.inf
