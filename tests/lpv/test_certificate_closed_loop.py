"""The closed loop the certificate judges, and how ``certificate_check`` forms it: the closed
loop with a non-zero D22 (hand-derived) and an ill-posed loop (``closed_loop``), the plant
given as a GriddedPlant (looked up at grid values only), and what the check passes to the
synthesis result in its "exact" and "interpolated" controller modes.

The small plant, controller and certificate are those of test_certificate_negative.py.
"""

import numpy as np
import pytest

from vega_lpv.certificate import certificate_check, closed_loop
from vega_lpv.gridded_plant import GriddedPlant, PlantDataError, PlantPoint
from test_certificate_negative import (STABILISING, FakeResult, _lft, _lyapunov, _plant, _point,
                                       _structured)


def _scalar_point(d22):
    """ẋ = x + 0.5 w + 2 u; e = x + 0.1 u; y = 3 x + 0.2 w + d22 u."""
    return PlantPoint(np.array([[1.0]]), np.array([[0.5, 2.0]]), np.array([[1.0], [3.0]]),
                      np.array([[0.0, 0.1], [0.2, d22]]), n_w=1, n_u=1, n_e=1, n_y=1)


K_SCALAR = (np.array([[-2.0]]), np.array([[1.0]]), np.array([[0.7]]), np.array([[0.4]]))


def test_closed_loop_with_d22_by_hand():
    """D22 = 0.5, D_K = 0.4: Φ = 1/(1 − 0.2) = 1.25, u = 1.5 x + 0.875 x_K + 0.1 w,
    y = 3.75 x + 0.4375 x_K + 0.25 w, so ẋ = 4 x + 1.75 x_K + 0.7 w,
    ẋ_K = 3.75 x − 1.5625 x_K + 0.25 w, e = 1.15 x + 0.0875 x_K + 0.01 w."""
    A, B, C, D = closed_loop(_scalar_point(0.5), K_SCALAR)
    np.testing.assert_allclose(A, [[4.0, 1.75], [3.75, -1.5625]], rtol=1e-14)
    np.testing.assert_allclose(B, [[0.7], [0.25]], rtol=1e-14)
    np.testing.assert_allclose(C, [[1.15, 0.0875]], rtol=1e-14)
    np.testing.assert_allclose(D, [[0.01]], rtol=1e-13)


def test_ill_posed_loop_is_refused():
    """D_K·D22 = 0.4·2.5 = 1: I − D_K D22 = 0."""
    with pytest.raises(PlantDataError, match="ill-posed"):
        closed_loop(_scalar_point(2.5), K_SCALAR)


class RecordingResult(FakeResult):
    """FakeResult that records every argument the check passes."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.controller_calls, self.derivative_calls = [], []

    def controller(self, *args, **kw):
        self.controller_calls.append((args, kw))
        return self.K

    def dX_drho(self, rho):
        self.derivative_calls.append(("X", rho))
        return self.X1

    def dY_drho(self, rho):
        self.derivative_calls.append(("Y", rho))
        return self.Y1


@pytest.fixture(scope="module")
def pieces():
    pl = _plant()
    P = _lyapunov(_lft(pl, STABILISING)[0])
    K, X, Y = _structured(STABILISING, P)
    return pl, K, X, Y


def test_exact_mode_passes_the_point_and_the_rate_term(pieces):
    pl, K, X, Y = pieces
    result = RecordingResult(K, X, Y)
    point = _point(pl)
    N = np.zeros((2, 2))
    seen = []
    worst = certificate_check(lambda r: point, result, [1.5], [2.0],
                              rate_term=lambda r: seen.append(r) or N)
    assert worst.shape == (1, 1) and worst[0, 0] < 0
    assert seen == [1.5]
    ((args, kw),) = result.controller_calls
    assert args == (1.5, 2.0) and kw["plant_point"] is point and kw["rate_term"] is N
    assert sorted(result.derivative_calls) == [("X", 1.5), ("Y", 1.5)]


def test_interpolated_mode_asks_for_the_grid_controller_only(pieces):
    pl, K, X, Y = pieces
    result = RecordingResult(K, X, Y)
    worst = certificate_check(lambda r: _point(pl), result, [1.5], [2.0],
                              controller="interpolated")
    assert worst[0, 0] < 0
    assert result.controller_calls == [((1.5, 2.0), {})]


def test_gridded_plant_is_looked_up_at_grid_values_only(pieces):
    pl, K, X, Y = pieces
    p = _point(pl)
    grid = np.array([0.5, 1.0, 2.0])
    gp = GriddedPlant(grid, np.stack([p.A] * 3), np.stack([p.B] * 3), np.stack([p.C] * 3),
                      np.stack([p.D] * 3), 1, 1, 1, 1)
    ref = certificate_check(lambda r: p, FakeResult(K, X, Y), [1.0, 2.0], [0.0])
    got = certificate_check(gp, FakeResult(K, X, Y), [1.0, 2.0 * (1 + 1e-13)], [0.0])
    np.testing.assert_allclose(got, ref, rtol=1e-9)
    for off in (1.5, 1.0 + 1e-6, 0.5 + 5e-9):    # 5e-9: inside numpy's default atol
        with pytest.raises(PlantDataError, match="not a grid value"):
            certificate_check(gp, FakeResult(K, X, Y), [off], [0.0])
