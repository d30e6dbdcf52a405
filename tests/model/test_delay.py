"""Delays: Padé state-space models against python-control; the exact sampled delay line."""

import math

import control
import numpy as np
import pytest

from vega_model.delay import DelayLine, DelayParams, pade_ss
from vega_model.vehicle_data import load_vehicle_data


def _freq_response(ss, w):
    A, B, C, D = ss
    n = A.shape[0]
    return np.array([(C @ np.linalg.solve(1j * wk * np.eye(n) - A, B) + D)[0, 0] for wk in w])


def test_delay_params_from_vehicle():
    d = DelayParams.from_vehicle(load_vehicle_data())
    assert (d.actuator_s, d.sensor_s, d.computing_s) == pytest.approx((0.015, 0.012, 0.012))
    assert d.total_s == pytest.approx(0.039)           # thesis §2.12.4
    assert d.pade_order == 2


@pytest.mark.parametrize("order", (1, 2, 3, 5))
@pytest.mark.parametrize("tau", (0.029, 0.039, 0.049))
def test_pade_matches_python_control(order, tau):
    num, den = control.pade(tau, order)
    w = np.logspace(-1, 3, 40)
    ref = np.polyval(num, 1j * w) / np.polyval(den, 1j * w)
    got = _freq_response(pade_ss(tau, order), w)
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=0)
    # same poles
    A = pade_ss(tau, order)[0]
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(A)),
                               np.sort_complex(np.roots(den)), rtol=1e-8)


def test_second_order_pade_matrices_by_hand():
    """(1 − sτ/2 + s²τ²/12)/(1 + sτ/2 + s²τ²/12): A = [[0, 1], [−12, −6]]/τ, C = [0, −12]."""
    tau = 0.039
    A, B, C, D = pade_ss(tau, 2)
    np.testing.assert_allclose(A, np.array([[0.0, 1.0], [-12.0, -6.0]]) / tau)
    np.testing.assert_allclose(B, np.array([[0.0], [1.0 / tau]]))
    np.testing.assert_allclose(C, [[0.0, -12.0]])
    assert D[0, 0] == 1.0


def test_pade_is_all_pass_with_the_delay_phase_at_low_frequency():
    tau = 0.039
    g = _freq_response(pade_ss(tau, 2), np.array([0.1, 1.0, 10.0, 100.0]))
    np.testing.assert_allclose(np.abs(g), 1.0, rtol=1e-12)
    assert np.angle(g[1]) == pytest.approx(-tau, rel=1e-6)      # phase −ωτ at ω = 1 rad/s
    assert np.angle(g[2]) == pytest.approx(-10 * tau, rel=1e-3)


def test_pade_zero_delay_and_invalid():
    A, B, C, D = pade_ss(0.0)
    assert A.shape == (0, 0) and D[0, 0] == 1.0
    with pytest.raises(ValueError):
        pade_ss(-0.01)
    with pytest.raises(ValueError):
        pade_ss(0.039, 0)


def test_delay_line_exact_shift():
    line = DelayLine(0.015, 0.001, initial=-1.0)
    assert line.n_steps == 15
    out = [line.push(float(k)) for k in range(100)]
    assert out[:15] == [-1.0] * 15
    assert out[15:] == [float(k) for k in range(85)]
    line.reset(7.0)
    assert line.push(1.0) == 7.0


def test_delay_line_zero_delay_passes_through_and_holds_objects():
    assert DelayLine(0.0, 0.001).push(3.5) == 3.5
    line = DelayLine(0.02, 0.01, initial=(0.0, 0.0))
    assert [line.push((k, -k)) for k in range(4)] == [(0.0, 0.0), (0.0, 0.0), (0, 0), (1, -1)]


def test_delay_line_rejects_non_integer_delays():
    with pytest.raises(ValueError):
        DelayLine(0.0155, 0.001)
    with pytest.raises(ValueError):
        DelayLine(0.015 + 1e-10, 0.001)        # 1e-7 steps off
    with pytest.raises(ValueError):
        DelayLine(-0.001, 0.001)
    with pytest.raises(ValueError):
        DelayLine(math.nan, 0.001)
    # rounding of 0.039 / 0.001 is accepted
    assert DelayLine(0.039, 0.001).n_steps == 39
