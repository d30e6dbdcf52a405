"""``vega_loops.margins``: the frequency responses and the pieces of one frozen loop,
against hand formulas and an independent loop assembly.

* :func:`_transfer`: C (pI − A)⁻¹ B by a direct solve per point written in the test, on a
  diagonalisable two-input two-output system and on a Jordan block (1/s², the eigenvector
  path would be wrong there), and the empty system;
* :func:`sampled_data_model` / :func:`sampled_data_response`: the integrator behind a delay
  d·T + θ, G_d(z) = ((T − θ) z^{−d} + θ z^{−d−1}) / (z − 1) by hand, a delay that is a whole
  number of samples in decimal but not in binary (0.06 / 0.02), and the refusals;
* :func:`flown_controller` / :func:`loop_data`: the interpolation written out here (grid
  weights, ρ̇ slices) and K(e^{jωT}) by direct solves;
* :func:`frozen_loop`: the rigid-body margins of the nominal loop against
  ``verification.loop_margins`` (its own interconnection, continuous controller, Padé delay:
  an independent assembly; the discrete controller and the hold move them by a few tenths).
"""

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from vega_loops import margins as M

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config" / "lpv_controller.npz"


def _direct(A, B, C, points):
    n = A.shape[0]
    return np.array([C @ np.linalg.solve(p * np.eye(n) - A, B) for p in points])


# ----------------------------------------------------------------------------- _transfer
def test_transfer_two_inputs_two_outputs():
    A = np.array([[-1.0, 2.0, 0.0], [0.0, -3.0, 1.0], [0.5, 0.0, -2.0]])
    B = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, -1.0]])
    C = np.array([[1.0, 0.0, 1.0], [0.0, 3.0, -1.0]])
    pts = np.array([0.1j, 1j, 2.0 + 3j, 10j, -0.5 + 0.2j])
    got = M._transfer(A, B, C, pts)
    assert got.shape == (5, 2, 2)
    assert np.allclose(got, _direct(A, B, C, pts), rtol=1e-12, atol=1e-14)
    # the same through ss_response (+ D) and discrete_response (z = e^{jωT})
    D = np.array([[0.5, 0.0], [0.0, -1.0]])
    w = np.array([0.1, 1.0, 10.0])
    assert np.allclose(M.ss_response(A, B, C, D, w), _direct(A, B, C, 1j * w) + D,
                       rtol=1e-12, atol=1e-14)
    Ad = 0.3 * A + 0.1 * np.eye(3)
    z = np.exp(1j * w * 0.02)
    assert np.allclose(M.discrete_response(Ad, B, C, D, w, 0.02),
                       _direct(Ad, B, C, z) + D, rtol=1e-12, atol=1e-14)


def test_transfer_of_a_jordan_block():
    """A = [[0, 1], [0, 0]] (defective: one eigenvector): C (pI − A)⁻¹ B = 1/p²."""
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0], [0.0, 1.0]])
    pts = np.array([0.5j, 2j, 1.0 + 1j])
    got = M._transfer(A, B, C, pts)
    assert np.allclose(got[:, 0, 0], 1 / pts ** 2, rtol=1e-12)
    assert np.allclose(got[:, 1, 0], 1 / pts, rtol=1e-12)
    # a nearly defective one (eigenvector condition number ≈ 1e9): still exact
    A = np.array([[0.0, 1.0], [0.0, 1e-9]])
    assert np.allclose(M._transfer(A, B, C, pts), _direct(A, B, C, pts), rtol=1e-9)


def test_transfer_of_no_states():
    got = M._transfer(np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((2, 0)), [1j, 2j])
    assert got.shape == (2, 2, 3) and not np.any(got) and got.dtype == complex
    K = M.discrete_response(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)),
                            [[2.0, -1.0]], [0.0, 3.0], 0.02)
    assert np.array_equal(K, np.array([[[2.0, -1.0]], [[2.0, -1.0]]]))


# --------------------------------------------------------------------- sampled-data model
@pytest.mark.parametrize("d, theta", [(0, 0.0), (1, 0.95), (2, 0.3)])
def test_sampled_data_response_of_a_delayed_integrator(d, theta):
    T = 0.02
    tau = (d + theta) * T
    w = np.array([0.1, 3.0, 40.0, 150.0])
    z = np.exp(1j * w * T)
    hand = ((1 - theta) * T * z ** (-d) + theta * T * z ** (-d - 1)) / (z - 1)
    A, B, C = np.array([[0.0]]), np.array([[1.0]]), np.array([[1.0], [2.0]])
    got = M.sampled_data_response(A, B, C, T, tau, w)
    assert got.shape == (4, 2, 1)
    assert np.allclose(got[:, 0, 0], hand, rtol=1e-9)
    assert np.allclose(got[:, 1, 0], 2 * hand, rtol=1e-9)
    model = M.sampled_data_model(A, B, T, tau)
    assert np.allclose(M.sampled_data_response(A, B, C, T, tau, w, model), got, rtol=1e-15)


def test_sampled_data_model_whole_samples_in_decimal():
    """0.06 / 0.02 is 2.9999999999999996 in binary: three whole samples, θ = 0."""
    Phi, G0, G1, d = M.sampled_data_model(np.array([[-2.0]]), np.array([[1.0]]), 0.02, 0.06)
    assert d == 3
    assert G0[0, 0] == pytest.approx((1 - math.exp(-0.04)) / 2, rel=1e-12)
    assert abs(G1[0, 0]) < 1e-15
    Phi, G0, G1, d = M.sampled_data_model(np.array([[-2.0]]), np.array([[1.0]]), 0.02, 0.0)
    assert d == 0 and G1[0, 0] == 0.0
    assert Phi[0, 0] == pytest.approx(math.exp(-0.04), rel=1e-12)


@pytest.mark.parametrize("dt, tau", [(0.0, 0.01), (-0.02, 0.01), (0.02, -1e-9),
                                     (0.02, float("nan")), (float("nan"), 0.01)])
def test_sampled_data_model_refuses(dt, tau):
    with pytest.raises(ValueError, match="need dt_s > 0 and delay_s >= 0"):
        M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), dt, tau)


# ------------------------------------------------------------------- the flown controller
def _hand_interpolation(table, v, slice_weight):
    g = table.grid_v_mps
    v = min(max(v, g[0]), g[-1])
    i = int(np.clip(np.searchsorted(g, v, side="right") - 1, 0, len(g) - 2))
    w = (v - g[i]) / (g[i + 1] - g[i])
    out = []
    for name in ("Ad", "Bd", "Cd", "Dd"):
        m = np.asarray(getattr(table, name))
        lo = (1 - slice_weight) * m[i][0] + slice_weight * m[i][1]
        hi = (1 - slice_weight) * m[i + 1][0] + slice_weight * m[i + 1][1]
        out.append((1 - w) * lo + w * hi)
    return out


def test_flown_controller_with_a_given_rate(table):
    r = table.rate_grid_mps2
    assert M.runtime_rate(table) == float(r[1]) and type(M.runtime_rate(table)) is float
    for rate, s in ((float(r[0]), 0.0), (0.25 * r[0] + 0.75 * r[1], 0.75), (None, 1.0)):
        K, v_sched, clamped = M.flown_controller(table, 500.0, rate)
        assert v_sched == 500.0 and clamped is False
        for got, want in zip(K, _hand_interpolation(table, 500.0, s)):
            assert np.allclose(got, want, rtol=1e-12, atol=1e-15)


def test_loop_data_by_hand(table, context):
    t = 60.0
    p = context.parameters(t)
    for v_given, v in ((None, p.v_mps), (500.0, 500.0), (5000.0, float(table.grid_v_mps[-1]))):
        data = M.loop_data(table, context, t, v_given)
        assert data.t_s == t and type(data.t_s) is float
        assert data.v_sched_mps == v and data.clamped is (v_given == 5000.0)
        assert data.sign == -1.0 and type(data.sign) is float
        assert data.dt_s == 0.02 and data.input_names == table.input_names
        assert data.w_radps.size == 1500 + 4000 + 200 - 1
        assert data.w_radps[1500] == pytest.approx(0.55 * p.omega_radps[0], rel=1e-12)
        Ad, Bd, Cd, Dd = _hand_interpolation(table, v, 1.0)
        for got, want in zip(data.K, (Ad, Bd, Cd, Dd)):
            assert np.allclose(got, want, rtol=1e-12, atol=1e-15)
        pick = [0, 1499, 1500, 3000, 5698]
        z = np.exp(1j * data.w_radps[pick] * 0.02)
        want = _direct(Ad, Bd, Cd, z) + Dd
        assert np.allclose(data.K_resp[pick], want, rtol=1e-7, atol=1e-12)


# ------------------------------------------------------------------------ the frozen loop
@pytest.mark.slow
def test_frozen_loop_margins_against_verification_loop_margins(table, context):
    """Nominal loops at 30 and 60 s: this module's loop (discrete controller, exact hold and
    delay) and verification.loop_margins (continuous controller of the same table, Padé-2
    delay, its own plant interconnection) give rigid-body margins within a few tenths of a dB
    and about a degree (not the bending peaks: there the discrete and the continuous
    controller differ); both views of this module's loop agree closer still."""
    from vega_model.actuator import ActuatorParams

    from vega_lpv.verification import loop_margins

    rate = M.runtime_rate(table)
    fake = SimpleNamespace(rho=table.grid_v_mps,
                           controller=lambda v, r: table.interpolate(v, r, discrete=False))
    act = ActuatorParams.from_vehicle(context.vehicle)
    for t in (30.0, 60.0):
        ref = loop_margins(fake, context, t, rate).as_dict()
        data = M.loop_data(table, context, t)
        p = context.parameters(t)
        loop = M.frozen_loop(data, p, act, 0.039)
        assert loop.omega_modes == tuple(p.omega_radps)
        assert loop.model[3] == 1 and loop.C.shape == (4, 10)
        got = M.extract_margins(data.w_radps, loop.L, loop.omega_modes)
        sd = M.extract_margins(data.w_radps, loop.L_d, loop.omega_modes)
        assert got["gm_low_db"] == pytest.approx(-ref["gm_low_db"], abs=0.5)
        assert got["gm_high_db"] == pytest.approx(ref["gm_high_db"], abs=0.5)
        assert got["pm_deg"] == pytest.approx(ref["pm_deg"], abs=2.0)
        for key in ("gm_low_db", "gm_high_db", "pm_deg"):
            assert sd[key] == pytest.approx(got[key], abs=0.1)
