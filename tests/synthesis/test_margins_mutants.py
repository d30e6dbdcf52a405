"""``vega_loops.margins``: tests written for the survivors of
`make mutation MODULE=margins` (docs/TESTING.md).

The Nyquist count of :func:`sampled_data_stability` refines its θ grid wherever the argument
of 1 + L_d jumps by more than 45° between samples; the loops of test_margins_tool.py never
needed it. Here a controller pole sits 1e-6 inside the unit circle (ρ = 1 − 1e-6, 2e-6 from
the contour |z| = 1 + 1e-6, against a grid spacing of π/4000 ≈ 7.9e-4 rad): the argument
turns by ≈ 180° between two samples near it. Reference: the roots of the characteristic
polynomial derived by hand, as in test_margins_tool.py.
"""

import numpy as np
import pytest

from vega_loops import margins as M

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
