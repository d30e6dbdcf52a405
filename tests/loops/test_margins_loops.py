"""``vega_loops.margins``: the peak refinement, the sampled-data closed loop with a
fractional delay, the row of one frozen loop, and the Nyquist count with controller poles at
or near the unit circle.

References: parabolas written down by hand (vertex and value known in closed form), the roots
of characteristic polynomials derived by hand for an integrator behind a delay of d samples
plus a fraction θ (x_{k+1} = x_k + (1 − θ)T u_{k−d} + θT u_{k−d−1}) and for controllers with
poles near |z| = 1, and the plant data (:meth:`ModelParameters`, the vehicle's actuator and
delays) for the fields of a row.
"""

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from vega_loops import margins as M

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config" / "lpv_controller.npz"


# ------------------------------------------------------------------------ peak refinement
def _parabola(x, a, xv, yv):
    return a * (np.asarray(x) - xv) ** 2 + yv


@pytest.mark.parametrize("x, xv", [([0.1, 0.5, 1.2], 0.4), ([2.0, 2.3, 3.1], 2.9),
                                   ([-1.0, 0.0, 0.25], -0.7)])
def test_refine_peak_vertex_of_a_parabola(x, xv):
    """Three unevenly spaced samples of y = −3 (x − x_v)² + 2 around the middle one: the
    vertex (x_v, 2) exactly (log ω → ω = e^{x_v}), inside the three samples."""
    lw = np.array([-5.0] + list(x) + [9.0])
    y = np.concatenate([[-100.0], _parabola(x, -3.0, xv, 2.0), [-100.0]])
    peak, w = M._refine_peak(lw, y, 2)
    assert peak == pytest.approx(2.0, abs=1e-12)
    assert w == pytest.approx(math.exp(xv), rel=1e-12)


def test_refine_peak_at_the_second_and_second_to_last_samples():
    lw = np.array([0.0, 0.3, 0.7, 1.0])
    y = _parabola(lw, -2.0, 0.4, 1.5)               # vertex between samples 1 and 2
    assert M._refine_peak(lw, y, 1) == (pytest.approx(1.5, abs=1e-12),
                                        pytest.approx(math.exp(0.4), rel=1e-12))
    assert M._refine_peak(lw, y, 2) == (pytest.approx(1.5, abs=1e-12),
                                        pytest.approx(math.exp(0.4), rel=1e-12))


def test_refine_peak_at_the_ends_of_the_grid_is_the_sample():
    lw = np.array([0.0, 0.3, 0.7])
    y = np.array([5.0, 1.0, 0.0])
    assert M._refine_peak(lw, y, 0) == (5.0, 1.0)
    y = np.array([0.0, 1.0, 5.0])
    assert M._refine_peak(lw, y, 2) == (5.0, pytest.approx(math.exp(0.7), rel=1e-15))


def test_refine_peak_vertex_exactly_on_an_outer_sample():
    """y = −(x − x₀)² (and −(x − x₂)²) on x = 0, 1, 2: the vertex is the outer sample itself,
    accepted (x₀ ≤ x_v ≤ x₂, both ends included)."""
    lw = np.array([0.0, 1.0, 2.0])
    assert M._refine_peak(lw, np.array([0.0, -1.0, -4.0]), 1) == (0.0, 1.0)
    assert M._refine_peak(lw, np.array([-4.0, -1.0, 0.0]), 1) == (
        0.0, pytest.approx(math.exp(2.0), rel=1e-15))


def test_refine_peak_vertex_outside_or_no_maximum_is_the_sample():
    lw = np.array([0.0, 1.0, 2.0])
    # concave, vertex at x = 5 (beyond the samples): the middle sample
    assert M._refine_peak(lw, _parabola(lw, -1.0, 5.0, 0.0), 1) == (
        -16.0, pytest.approx(math.e, rel=1e-15))
    # convex (a = 0.5 > 0, a minimum at 0.3 inside): no peak to refine, the middle sample
    lw = np.array([-1.0, 0.0, 1.0])
    y = _parabola(lw, 0.5, 0.3, 0.0)
    assert M._refine_peak(lw, y, 1) == (pytest.approx(0.045, abs=1e-15), 1.0)
    # a straight line (a = 0): the sample, without a division by zero
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert M._refine_peak(np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 2.0]), 1) == (
            1.0, pytest.approx(math.e, rel=1e-15))


def test_extract_margins_bending_peak_between_grid_points():
    """A resonance sampled coarsely (≈ 3 % steps): the refined peak is the parabola's vertex
    through the three samples around the largest, written out here (Lagrange form)."""
    w0 = 30.0
    w = np.geomspace(10.0, 100.0, 81)
    L = 1.0 / (1.0 - (w / w0) ** 2 + 2j * 0.05 * (w / w0))
    got = M.extract_margins(w, L, (w0, 90.0))
    db = 20 * np.log10(np.abs(L))
    band = np.flatnonzero((w >= 0.8 * w0) & (w <= 1.2 * w0))
    j = band[np.argmax(db[band])]
    x, y = np.log(w[j - 1:j + 2]), db[j - 1:j + 2]
    c2 = np.polyfit(x, y, 2)                       # exact through three points
    xv = -c2[1] / (2 * c2[0])
    assert got["b1_peak_db"] == pytest.approx(np.polyval(c2, xv), abs=1e-9)
    assert got["b1_w_peak_radps"] == pytest.approx(math.exp(xv), rel=1e-9)
    assert got["b1_peak_db"] > db[j] + 1e-3         # the refinement moved it
    assert got["b1_phase_stabilised"] is True


# --------------------------------------------------------- stability with a fractional delay
def _static(k):
    return (np.array([[0.0]]), np.array([[0.0]]), np.array([[0.0]]), np.array([[k]]))


@pytest.mark.parametrize("d, theta", [(1, 0.5), (2, 0.3), (1, 0.95), (3, 0.1)])
def test_integrator_behind_a_fractional_delay(d, theta):
    """Plant 1/s, u = −k x, delay (d + θ)T with d ≥ 1 and θ > 0 (both command taps in use):
    z^{d+1}(z − 1) + kT((1 − θ) z + θ) by hand."""
    T = 0.02
    model = M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), T, (d + theta) * T)
    assert model[3] == d
    C = np.array([[1.0]])
    seen = set()
    for kT in (0.05, 0.2, 0.4, 0.6, 0.9, 1.3):
        k = kT / T
        poly = np.zeros(d + 3)
        poly[0], poly[1] = 1.0, -1.0
        poly[-2] += k * (1 - theta) * T
        poly[-1] += k * theta * T
        roots = np.roots(poly)
        expected = int(np.sum(np.abs(roots) > 1 + 1e-9))
        got = M.sampled_data_stability(model, C, _static(k), sign=-1.0)
        assert got["n_unstable"] == got["n_unstable_nyquist"] == expected, kT
        assert got["max_abs_eig"] == pytest.approx(np.max(np.abs(roots)), rel=1e-9)
        assert got["n_open_unstable"] == 0
        seen.add(expected)
    assert 0 in seen and len(seen) > 1               # stable and unstable gains both seen


def test_stability_count_on_the_circle_boundary():
    """A controller pole exactly on |z| = 1 (an integrator) is not unstable (|z| > 1 + ε), nor
    one at 1 + ε/2; one at 1 + 2ε is. Plant 1/(s + 1) behind no delay, K(z) = 1/(z − ρ) with
    Dd = 0 and a gain 1e-9 (the closed-loop poles stay at the open-loop ones to ~1e-9·T)."""
    T, eps = 0.02, 1e-6
    model = M.sampled_data_model(np.array([[-1.0]]), np.array([[1.0]]), T, 0.0)
    for rho, n in ((1.0, 0), (1.0 + 0.5 * eps, 0), (1.0 + 2 * eps, 1), (1.0 + 1e-3, 1)):
        K = (np.array([[rho]]), np.array([[1e-9]]), np.array([[1.0]]), np.array([[0.0]]))
        got = M.sampled_data_stability(model, np.array([[1.0]]), K, sign=-1.0,
                                       nyquist=False, eps=eps)
        assert (got["n_unstable"], got["n_open_unstable"]) == (n, n), rho
        assert got["max_abs_eig"] == pytest.approx(rho, abs=1e-8)
        assert "n_unstable_nyquist" not in got
    # a controller pole exactly at 1 + ε, decoupled (Bd = 0: the eigenvalue is exact): not
    # counted, neither closed- nor open-loop (|z| > 1 + ε)
    K = (np.array([[1.0 + eps]]), np.array([[0.0]]), np.array([[1.0]]), np.array([[0.0]]))
    got = M.sampled_data_stability(model, np.array([[1.0]]), K, sign=-1.0, nyquist=False,
                                   eps=eps)
    assert got == {"n_unstable": 0, "max_abs_eig": 1.0 + eps, "n_open_unstable": 0}


# --------------------------------------------------------------------- one frozen loop's row
def test_analyse_time_row_fields(table, context):
    """The row's plant fields are the perturbed parameters, the actuator of the vehicle data
    × (1 + δ), the vehicle's three delays + δ; the controller stays on the nominal schedule
    (clamped at t = 5 s, where v = 37 m/s is below the grid's 95.6 m/s)."""
    veh = context.vehicle
    tau0 = veh["delays.sensor_s"] + veh["delays.computing_s"] + veh["delays.actuator_s"]
    dev = {"thrust": 0.05, "actuator": -0.1, "delay_s": 0.01, "bending_frequency_1": 0.2,
           "bending_frequency_2": -0.2, "velocity": 0.1}
    for t in (5.0, 60.0):
        p0 = context.parameters(t)
        p = p0.perturbed(dev)
        rows = M.analyse_time(table, context, t, [(0, {}), (17, dev)])
        assert [(r["t_s"], r["corner"]) for r in rows] == [(t, 0), (t, 17)]
        r0, r = rows
        assert type(r["t_s"]) is float and type(r["corner"]) is int
        assert r0["clamped"] is r["clamped"] is (t == 5.0)
        assert r["v_sched_mps"] == r0["v_sched_mps"] == min(max(p0.v_mps,
                                                                table.grid_v_mps[0]),
                                                            table.grid_v_mps[-1])
        assert r["v_plant_mps"] == pytest.approx(p0.v_mps * 1.1, rel=1e-12)
        assert r["q_pa"] == pytest.approx(p.q_pa, rel=1e-12) and r["q_pa"] != r0["q_pa"]
        assert r0["q_pa"] == pytest.approx(p0.q_pa, rel=1e-12)
        assert (r["f1_hz"], r["f2_hz"]) == (pytest.approx(p0.f1_hz * 1.2),
                                            pytest.approx(p0.f2_hz * 0.8))
        assert (r0["f1_hz"], r0["f2_hz"]) == (p0.f1_hz, p0.f2_hz)
        assert r["delay_s"] == pytest.approx(tau0 + 0.01, abs=1e-15)
        assert r0["delay_s"] == pytest.approx(tau0, abs=1e-15)
        assert r["actuator_wn_radps"] == pytest.approx(
            veh["actuator.natural_frequency_radps"] * 0.9)
        assert r0["actuator_wn_radps"] == veh["actuator.natural_frequency_radps"]
        for row, q in ((r0, p0), (r, p)):
            assert set(M.CSV_COLUMNS) - {"n_unstable_nyquist"} <= set(row)
            # the bending peaks are read in the bands of the plant analysed (perturbed)
            for i, f in ((1, q.f1_hz), (2, q.f2_hz)):
                w = row[f"b{i}_w_peak_radps"]
                assert 0.8 * 2 * math.pi * f <= w <= 1.2 * 2 * math.pi * f
            # the sampled-data view differs from the continuous-equivalent only by the
            # aliases: within a fraction of a dB / degree here, and never the same number
            for key, tol in (("gm_low_db", 0.1), ("gm_high_db", 0.1), ("pm_deg", 0.5),
                             ("b1_peak_db", 0.2), ("b2_peak_db", 0.5)):
                assert row[f"sd_{key}"] == pytest.approx(row[key], abs=tol)
                assert row[f"sd_{key}"] != row[key]
            assert row["n_unstable"] == 0
        assert r0["n_unstable_nyquist"] == 0 and "n_unstable_nyquist" not in r
        # gain margin: the rigid band ends at 0.8 ω₁ of the plant analysed
        assert r0["w_gm_high_radps"] < 0.8 * 2 * math.pi * p0.f1_hz
    # Nyquist off: no cross-check even on corner 0
    (row,) = M.analyse_time(table, context, 60.0, [(0, {})], nyquist=False)
    assert "n_unstable_nyquist" not in row


def test_nichols_curves_one_per_corner(table, context):
    """The continuous-equivalent loop per corner on the grid of the NOMINAL plant (a larger
    delay multiplies the loop by e^{−jωΔτ} exactly: the delay changes
    the phase by −ωΔτ only), the curves of a corner with mode 1 +20 % differ most around
    mode 1."""
    t = 60.0
    p = context.parameters(t)
    w, curves = M.nichols_curves(table, context, t, [(0, {}), (5, {"delay_s": 0.01}),
                                                     (9, {"bending_frequency_1": 0.2})])
    assert sorted(curves) == [0, 5, 9]
    assert w[0] == pytest.approx(1e-3) and w.size == 1500 + 4000 + 200 - 1
    assert w[1500] == pytest.approx(0.55 * p.omega_radps[0])
    for L in curves.values():
        assert L.shape == w.shape
    ratio = curves[5] / curves[0]
    assert np.allclose(ratio, np.exp(-1j * w * 0.01), rtol=1e-9, atol=1e-12)
    dev = np.abs(curves[9] / curves[0] - 1)
    assert dev[0] < 1e-2 and dev.max() > 0.5
    w1 = p.omega_radps[0]
    assert 0.8 * w1 <= w[np.argmax(dev)] <= 1.5 * w1    # where mode 1 moved (+20 %)


@pytest.mark.parametrize("theta0", [0.5, math.pi])
@pytest.mark.parametrize("rho", [1.0 - 1e-4, 1.0 + 1e-3])
@pytest.mark.parametrize("cb, dd", [(0.5, 1.0), (2.0, 10.0), (-1.0, 60.0), (5.0, 5.0)])
def test_nyquist_count_with_a_controller_pole_pair_near_the_circle(theta0, rho, cb, dd):
    """Plant 1/s (no delay), u = −K(z) y, K(z) = cb / D(z) + dd with the pole pair
    D(z) = z² − 2ρ cos θ₀ z + ρ² near |z| = 1 at θ₀ = 0.5 rad, or a double pole at −ρ
    (θ₀ = π, the end of the half contour): the argument of 1 + L_d swings by ≈ 180° or more
    within 1e-3 rad of θ₀. Reference: the roots of (z − 1) D(z) + T (cb + dd D(z)) by hand;
    P = the two controller poles when ρ > 1."""
    T = 0.02
    model = M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), T, 0.0)
    c = math.cos(theta0)
    K = (np.array([[0.0, 1.0], [-rho ** 2, 2.0 * rho * c]]), np.array([[0.0], [1.0]]),
         np.array([[cb, 0.0]]), np.array([[dd]]))
    D = np.array([1.0, -2.0 * rho * c, rho ** 2])
    poly = np.polyadd(np.polymul([1.0, -1.0], D), T * np.polyadd([cb], dd * D))
    expected = int(np.sum(np.abs(np.roots(poly)) > 1 + 1e-9))
    got = M.sampled_data_stability(model, np.array([[1.0]]), K, sign=-1.0)
    assert got["n_open_unstable"] == (2 if rho > 1 else 0)
    assert got["n_unstable"] == got["n_unstable_nyquist"] == expected


def test_analyse_loop_cross_checks_by_default(table, context):
    from vega_model.actuator import ActuatorParams

    data = M.loop_data(table, context, 60.0)
    p = context.parameters(60.0)
    act = ActuatorParams.from_vehicle(context.vehicle)
    row = M.analyse_loop(data, p, act, 0.039)
    assert row["n_unstable_nyquist"] == row["n_unstable"] == 0
    assert "n_unstable_nyquist" not in M.analyse_loop(data, p, act, 0.039, nyquist=False)


@pytest.mark.parametrize("theta_p, delta", [(3.9e-4, 1e-5), (3.9e-4, 3e-5), (0.3, 1e-4),
                                            (math.pi - 3.9e-4, 3e-5)])
@pytest.mark.parametrize("cb, dd", [(1e-3, 0.5), (1e-2, 2.0)])
def test_nyquist_count_with_a_double_controller_pole_pair_close_to_the_circle(theta_p, delta,
                                                                              cb, dd):
    """K(z) = cb / D(z)² + dd, D(z) = z² − 2ρ cos θp z + ρ², ρ = 1 − δ: a double pole pair
    δ inside the circle, within 4e-4 rad of θ = 0 or π or at 0.3 rad. Along the contour the
    argument of 1 + L_d turns by ≈ 360° within a few δ of θp — inside one step of the
    uniform θ grid (π/4000 ≈ 7.9e-4), so the count needs the fine grids near 0 and π and
    the refinement. Reference: the roots of (z − 1) D(z)² + T (cb + dd D(z)²) by hand (none
    within 5e-6 of the circle: the premise, checked).

    1/D(z)² is realised as two 1/D(z) sections in series (block-triangular, each a 2×2
    companion form) coupled through a gain g = 1e-6 (undone in the output), not as the 4×4
    companion form of D(z)²: the eigenvalues of that companion matrix — four roots within 8e-4
    of z = 1 — are computed only to ≈ 4e-5 in double precision, and depending on the BLAS and
    CPU (OpenBLAS on an AMD EPYC, for one) two of them come out at |z| = 1 + 2.7e-5 for
    δ = 1e-5: an open-loop "unstable" count of 2 for a controller whose poles are all inside
    the circle. A double eigenvalue with a coupling g is perturbed by ≈ √(eps·g): with g = 1
    still 1e-6 past the circle, with g = 1e-6 ≈ 1e-11."""
    T = 0.02
    rho = 1.0 - delta
    model = M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), T, 0.0)
    D = np.array([1.0, -2.0 * rho * math.cos(theta_p), rho ** 2])
    D2 = np.polymul(D, D)
    A1 = np.array([[0.0, 1.0], [-D[2], -D[1]]])      # 1 / D(z): x' = A1 x + [0, 1] u, y = x0
    b1, c1 = np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])
    g = 1e-6                                          # section 1 feeds section 2 through g
    Ad = np.block([[A1, np.zeros((2, 2))], [g * b1 @ c1, A1]])
    K = (Ad, np.vstack([b1, np.zeros((2, 1))]), np.hstack([np.zeros((1, 2)), cb / g * c1]),
         np.array([[dd]]))
    z = np.exp(0.37j)                                 # the realisation is cb / D(z)² + dd
    k_z = (K[2] @ np.linalg.solve(z * np.eye(4) - Ad, K[1]) + K[3])[0, 0]
    assert k_z == pytest.approx(cb / np.polyval(D2, z) + dd, rel=1e-12)
    assert np.max(np.abs(np.linalg.eigvals(Ad))) < 1.0 - 0.5 * delta
    r = np.abs(np.roots(np.polyadd(np.polymul([1.0, -1.0], D2), T * np.polyadd([cb], dd * D2))))
    assert np.min(np.abs(r - 1.0)) > 5e-6
    got = M.sampled_data_stability(model, np.array([[1.0]]), K, sign=-1.0)
    assert got["n_open_unstable"] == 0
    assert got["n_unstable"] == got["n_unstable_nyquist"] == int(np.sum(r > 1.0))


# ------------------------------------------------- a controller pole 1e-6 inside the circle
# The Nyquist count of sampled_data_stability refines its θ grid wherever the argument of
# 1 + L_d jumps by more than 45° between samples; the loops of test_margins_tool.py never need
# it. Here a controller pole sits 1e-6 inside the unit circle (ρ = 1 − 1e-6, 2e-6 from the
# contour |z| = 1 + 1e-6, against a grid spacing of π/4000 ≈ 7.9e-4 rad): the argument turns
# by ≈ 180° between two samples near it. Reference: the roots of the characteristic
# polynomial derived by hand, as in test_margins_tool.py.
T = 0.02                    # sample period [s]
RHO, THETA0 = 1.0 - 1e-6, 1.0


@pytest.mark.parametrize("cb", [0.5, 2.0, -1.0, 5.0])
@pytest.mark.parametrize("dd", [1.0, 10.0, 60.0])
def test_nyquist_count_with_a_controller_pole_at_the_circle(cb, dd):
    """Plant 1/s (no delay), u = −K(z) y with K(z) = cb / D(z) + dd,
    D(z) = z² − 2ρ cos θ₀ z + ρ² (companion form): the closed loop's characteristic
    polynomial is (z − 1) D(z) + T (cb + dd D(z))."""
    model = M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), T, 0.0)
    Ad = np.array([[0.0, 1.0], [-RHO**2, 2.0 * RHO * np.cos(THETA0)]])
    K = (Ad, np.array([[0.0], [1.0]]), np.array([[cb, 0.0]]), np.array([[dd]]))
    D = np.array([1.0, -2.0 * RHO * np.cos(THETA0), RHO**2])
    poly = np.polyadd(np.polymul([1.0, -1.0], D), T * np.polyadd([cb], dd * D))
    expected = int(np.sum(np.abs(np.roots(poly)) > 1 + 1e-9))
    got = M.sampled_data_stability(model, np.array([[1.0]]), K, sign=-1.0)
    assert got["n_open_unstable"] == 0
    assert got["n_unstable"] == got["n_unstable_nyquist"] == expected
    assert got["max_abs_eig"] == pytest.approx(np.max(np.abs(np.roots(poly))), rel=1e-9, abs=0)
