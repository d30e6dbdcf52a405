"""Load relief in the structured design (vega_design.structured: RELIEF_PARAMETERS, the
wind → α load objective; docs/FLIGHT_DESIGN.md §7).

* the relief branch: k_a·s/(τs + 1)·ż added to the feedback sum, checked against the transfer
  function formula; k_a = 0 is the controller without relief (the same input-output map);
* the load figure V·α/v_w against an independent assembly: the exact sampled-data closed loop
  of vega_loops.margins with the wind held over a sample (the controller, the hold
  and the delay as flown), at the low frequencies of the load band;
* the sign: on the nominal plant at max-Q with a tuned controller, relief of the negative sign
  (nose into the wind) lowers the wind → α gain, the other sign raises it;
* the cost: without the load objective it is the cost `vega design` tunes; with it,
  that cost plus weight × gain; the search box of a relief vector.
"""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from vega_design import structured as S
from vega_loops.export import discretise
from vega_loops.margins import _closed_loop_matrices, corner_plant, sampled_data_model

DT = 0.02
# a max-Q tuning: the 40 s grid point of tests/data/tvc_controller_2026-11-27.npz, rounded
X40 = np.array([0.0051, -0.1358, 0.4337, -7.6201, 1.2094, 0.4543, 0.8791, 0.0, 1.2, 1.2707,
                0.6, 0.1295, 1.159, 0.2])


@pytest.fixture(scope="module")
def context():
    from vega_model.parameters import default_context

    return default_context()


def _tf(K, s):
    A, B, C, D = K
    return (C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B) + D)[0]


def test_relief_branch_is_a_filtered_derivative_of_the_drift_rate():
    omega = (31.0, 75.0)
    base = S.controller_ss(X40, omega)
    k_a, tau = -12.0, 0.4                        # mrad/(m/s²), s
    relief = S.controller_ss(S.with_relief(X40, k_a, math.log10(tau)), omega)
    assert relief[0].shape == (9, 9) and relief[1].shape == (9, 4)
    for w in (0.05, 0.7, 3.0, 40.0):
        s = 1j * w
        filt = _tf(base, s)[3] / (X40[2] * 1e-3)       # the filters F(s): ż column / k_ż
        expected = _tf(base, s).copy()
        expected[3] += filt * k_a * 1e-3 * s / (tau * s + 1.0)
        np.testing.assert_allclose(_tf(relief, s), expected, rtol=1e-9)
    # the derivative has no DC gain: the static feedback gains are unchanged
    np.testing.assert_allclose(_tf(relief, 0.0), _tf(base, 0.0), rtol=1e-12)


def test_zero_relief_gain_is_the_controller_without_relief():
    omega = (31.0, 75.0)
    base = discretise(*S.controller_ss(X40, omega), DT)
    off = discretise(*S.controller_ss(S.with_relief(X40, *S.RELIEF_OFF), omega), DT)
    assert off[0].shape == (9, 9)
    for w in (0.01, 1.0, 30.0, 150.0):
        z = np.exp(1j * w * DT)
        np.testing.assert_allclose(_tf(off, z), _tf(base, z), rtol=1e-10, atol=1e-15)


def test_parameter_vector_lengths():
    lo, hi = S.bounds_for(len(S.PARAMETERS))
    assert lo is S.LOWER and hi is S.UPPER
    lo, hi = S.bounds_for(len(S.PARAMETERS) + 2)
    assert lo.size == 16 and lo[14] == -50.0 and hi[15] == 0.7
    with pytest.raises(ValueError):
        S.bounds_for(15)
    with pytest.raises(ValueError):
        S.controller_ss(np.zeros(15), (31.0, 75.0))
    with pytest.raises(ValueError):
        S.with_relief(np.zeros(16))


def _independent_wind_alpha(context, t_s, K, w):
    """V·α/v_w of the exact sampled-data loop (margins._closed_loop_matrices) with the wind
    entering through a zero-order hold without delay: valid for ω ≪ π/T."""
    from vega_model.actuator import linear_actuator_ss
    from vega_model.dynamics import OUTPUTS, linear_model

    p, act, tau = corner_plant(context, t_s, {})
    Ap, Bp, Cp, Dp = linear_model(p)
    Aa, Ba, Ca, Da = linear_actuator_ss(act)
    A = np.block([[Ap, Bp[:, :2] @ Ca[[0, 2]]], [np.zeros((2, 8)), Aa]])
    B = np.vstack([Bp[:, :2] @ Da[[0, 2]], Ba])
    Bw = np.concatenate([Bp[:, 2], [0.0, 0.0]])[:, None]
    C = np.hstack([Cp[1:], Dp[1:, :2] @ Ca[[0, 2]]])
    n = A.shape[0]
    model = sampled_data_model(A, B, DT, tau)
    A_cl = _closed_loop_matrices(model, C, K, S.SIGN)[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n:] = A, Bw
    Gw = expm(aug * DT)[:n, n:]
    B_cl = np.zeros((A_cl.shape[0], 1))
    B_cl[:n] = Gw
    # u_k = Cd x_c + sign·Dd·C x_k: α is read from the plant state (and the held wind)
    qa = OUTPUTS.index("q_alpha_pa_rad")
    c = np.zeros(A_cl.shape[0])
    c[:n] = np.concatenate([Cp[qa], Dp[qa, :2] @ Ca[[0, 2]]])
    scale = p.v_mps / p.q_pa
    out = []
    for wk in w:
        z = np.exp(1j * wk * DT)
        x = np.linalg.solve(z * np.eye(A_cl.shape[0]) - A_cl, B_cl)[:, 0]
        out.append((c @ x + Dp[qa, 2]) * scale)
    return np.array(out)


def test_wind_alpha_response_against_the_sampled_data_loop(context):
    t = 40.0
    omega = context.parameters(t).omega_radps
    w = np.array([0.02, 0.1, 0.35, 1.0])
    for x in (X40, S.with_relief(X40, -15.0, -0.3)):
        K = discretise(*S.controller_ss(x, omega), DT)
        got = S.wind_alpha_response(K, S.load_model(context, t, w))
        ref = _independent_wind_alpha(context, t, K, w)
        # the wind's hold (half a sample, 10 ms: 0.01 rad of phase at 1 rad/s) is the only
        # difference; measured ≤ 0.45 %
        np.testing.assert_allclose(got, ref, rtol=0.006)
    # attitude hold alone gives about −1 at the top of the band; the tuned loop amplifies
    # around 0.3 rad/s (the aerodynamically unstable vehicle weathercocks away from the wind)
    K = discretise(*S.controller_ss(X40, omega), DT)
    gain = S.wind_alpha_gain(K, S.load_model(context, t))
    assert 1.6 < gain < 2.0


def test_relief_sign_lowers_the_wind_alpha_gain(context):
    t = 40.0
    omega = context.parameters(t).omega_radps
    load = S.load_model(context, t)

    def gain(k_a):
        return S.wind_alpha_gain(discretise(*S.controller_ss(S.with_relief(X40, k_a, 0.0), omega),
                                            DT), load)

    g0 = gain(0.0)
    assert gain(-5.0) < g0 - 0.05 and gain(-20.0) < gain(-5.0)
    assert gain(+5.0) > g0 + 0.05


@pytest.mark.slow
def test_load_objective_in_the_cost(context):
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    ds = S.design_set(context, 40.0, uset)
    plain, detail = S.evaluate(X40, ds, detail=True)
    assert "wind_alpha_gain" not in detail
    # a relief vector with k_a = 0: the same cost (the same loop)
    assert S.evaluate(S.with_relief(X40, *S.RELIEF_OFF), ds) == pytest.approx(plain, abs=1e-9)
    S.with_load(ds, context, 0.3)
    loaded, detail = S.evaluate(X40, ds, detail=True)
    assert loaded == pytest.approx(plain + 0.3 * detail["wind_alpha_gain"], abs=1e-12)
    # relief into the wind lowers the load term of the cost
    relief = S.evaluate(S.with_relief(X40, -5.0, 0.0), ds, detail=True)[1]
    assert relief["wind_alpha_gain"] < detail["wind_alpha_gain"] - 0.05


@pytest.mark.slow
def test_load_metric_mean_counts_the_whole_band(context):
    """The mean figure is the mean of |V·α/v_w| over the band's frequencies, below the peak;
    an unknown metric is refused."""
    from vega_model.uncertainty import UncertaintySet

    t = 24.0
    K = discretise(*S.controller_ss(X40, context.parameters(t).omega_radps), DT)
    load = S.load_model(context, t)
    mag = np.abs(S.wind_alpha_response(K, load))
    assert S.wind_alpha_gain(K, load, "mean") == pytest.approx(mag.mean(), rel=1e-12)
    assert S.wind_alpha_gain(K, load, "mean") < S.wind_alpha_gain(K, load) - 0.1
    with pytest.raises(ValueError):
        S.wind_alpha_gain(K, load, "rms")
    ds = S.design_set(context, t, UncertaintySet.from_vehicle(context.vehicle))
    with pytest.raises(ValueError):
        S.with_load(ds, context, 0.5, "rms")
    plain = S.evaluate(X40, ds)
    S.with_load(ds, context, 0.5, "mean")
    cost, detail = S.evaluate(X40, ds, detail=True)
    assert detail["wind_alpha_gain"] == pytest.approx(S.wind_alpha_gain(K, load, "mean"))
    assert detail["wind_alpha_peak"] == pytest.approx(S.wind_alpha_gain(K, load))
    assert cost == pytest.approx(plain + 0.5 * detail["wind_alpha_gain"], abs=1e-12)
