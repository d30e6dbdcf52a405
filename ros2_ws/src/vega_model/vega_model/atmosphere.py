"""US Standard Atmosphere 1976: density, pressure, temperature and speed of sound.

A thin wrapper around a maintained implementation, ``fluids.atmosphere.ATMOSPHERE_1976``
(Caleb Bell's *fluids*; NOAA/NASA/USAF, "U.S. Standard Atmosphere, 1976", NASA-TM-X-74335).
The input is the **geometric** altitude above mean sea level; the model converts it to
geopotential altitude itself (so T = 216.65 K is reached at 11 000 m *geopotential*, i.e.
11 019 m geometric). ``tests/model/test_atmosphere.py`` cross-checks it against the independent
``ambiance`` package (ICAO 1993 standard atmosphere, identical to US76 up to 80 km in the
quantities used here) and against textbook values.

The thesis (§2.5, Eqs. 2.12 and 2.15) needs ρ(h) for the dynamic pressure and the speed of
sound for the Mach number; its own code used an exponential density fit (see
docs/THESIS_NOTES.md §3), which we replace by the standard model.
"""

from __future__ import annotations

import numpy as np
from fluids.atmosphere import ATMOSPHERE_1976

__all__ = ["H_MIN_M", "H_MAX_M", "atmosphere"]

H_MIN_M = -610.0
"""Lowest geometric altitude of the model's stated validity [m] (fluids documentation)."""

H_MAX_M = 86000.0
"""Highest geometric altitude of the model's stated validity [m] (US76 lower atmosphere)."""


def _scalar(h_m: float) -> tuple[float, float, float, float]:
    if not (H_MIN_M <= h_m <= H_MAX_M):  # also rejects NaN
        raise ValueError(f"atmosphere: altitude {h_m!r} m outside the US76 model range "
                         f"[{H_MIN_M:g}, {H_MAX_M:g}] m")
    a = ATMOSPHERE_1976(h_m)
    return a.rho, a.P, a.T, a.v_sonic


def atmosphere(h_m):
    """US76 atmosphere at geometric altitude ``h_m``.

    Parameters
    ----------
    h_m : float or array_like
        Geometric altitude above mean sea level [m], within [H_MIN_M, H_MAX_M].

    Returns
    -------
    rho, p, T, a
        Density [kg/m³], pressure [Pa], temperature [K], speed of sound [m/s]: floats for
        a scalar input, ``numpy`` arrays of the input's shape otherwise.

    Raises
    ------
    ValueError
        An altitude outside the model range or not finite (one line).

    Notes
    -----
    Scalar calls cost about 1 µs (no numpy on that path). Arrays are evaluated point by
    point with the same scalar model, so both paths give identical numbers.
    """
    if np.ndim(h_m) == 0:
        return _scalar(float(h_m))
    h = np.asarray(h_m, dtype=float)
    out = np.array([_scalar(x) for x in h.ravel()], dtype=float).reshape(h.size, 4)
    return tuple(out[:, k].reshape(h.shape) for k in range(4))

