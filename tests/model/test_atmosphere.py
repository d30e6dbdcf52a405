"""US76 atmosphere (vega_model.atmosphere): textbook values and an independent cross-check.

The engine is ``fluids.atmosphere.ATMOSPHERE_1976``; the cross-check uses ``ambiance``
(ICAO 1993 standard atmosphere). ICAO 1993 and US76 share the layer definitions and
constants up to 80 km; the two implementations differ only in the last digits of their
physical constants (gas constant, Earth radius for the geopotential conversion), which
measured here gives relative differences below 1e-5 in density and pressure and none in
temperature. The tolerance 5e-5 leaves a factor 5 for library updates while still catching
any real model difference (a 1 K temperature error alone would be 4e-3).
"""

import math

import ambiance
import numpy as np
import pytest

from vega_model.atmosphere import H_MAX_M, H_MIN_M, atmosphere

R0_M = 6356766.0  # US76 Earth radius for geopotential altitude [m] (US76 document, Eq. 18)


def _geometric(h_geopotential_m):
    """Geometric altitude of a geopotential altitude (US76 Eq. 18 inverted)."""
    return R0_M * h_geopotential_m / (R0_M - h_geopotential_m)


@pytest.mark.parametrize("h_geopot_m, rho, p, T, a", [
    # US Standard Atmosphere 1976, Table I (layer bases; geopotential altitude)
    (0.0, 1.2250, 101325.0, 288.15, 340.294),
    (11000.0, 0.36392, 22632.06, 216.65, 295.070),
    (20000.0, 0.088035, 5474.889, 216.65, 295.070),
    (32000.0, 0.013225, 868.0187, 228.65, 303.131),
    (47000.0, 0.0014275, 110.9063, 270.65, 329.799),
])
def test_textbook_values(h_geopot_m, rho, p, T, a):
    got = atmosphere(_geometric(h_geopot_m))
    assert got[0] == pytest.approx(rho, rel=2e-4)
    assert got[1] == pytest.approx(p, rel=2e-5)
    assert got[2] == pytest.approx(T, abs=1e-6)
    assert got[3] == pytest.approx(a, rel=2e-5)


def test_agrees_with_ambiance_0_to_80_km():
    h = np.arange(0.0, 80000.0 + 1.0, 250.0)
    rho, p, T, a = atmosphere(h)
    ref = ambiance.Atmosphere(h)
    assert np.max(np.abs(rho / ref.density - 1.0)) < 5e-5
    assert np.max(np.abs(p / ref.pressure - 1.0)) < 5e-5
    assert np.max(np.abs(T - ref.temperature)) < 1e-6
    assert np.max(np.abs(a / ref.speed_of_sound - 1.0)) < 5e-5


def test_vector_equals_scalar_and_keeps_shape():
    h = np.array([[0.0, 5000.0], [17400.0, 60000.0]])
    vec = atmosphere(h)
    for k in range(4):
        assert vec[k].shape == h.shape
    for idx in np.ndindex(h.shape):
        scalar = atmosphere(float(h[idx]))
        assert all(isinstance(x, float) for x in scalar)
        assert [vec[k][idx] for k in range(4)] == list(scalar)


@pytest.mark.parametrize("h", [H_MIN_M - 1.0, H_MAX_M + 1.0, math.nan, math.inf])
def test_out_of_range_is_rejected(h):
    with pytest.raises(ValueError, match="outside the US76 model range"):
        atmosphere(h)
