"""Aerodynamic coefficients of the VEGA stack: C_A(M), C_Nα(M), C_N(α, M), x_CP(M).

The thesis (§2.5, Eqs. 2.13-2.17) uses ESA coefficient tables that are not public; its code
used toy formulas. This module is built on what is public and on classical slender-body
aerodynamics, with every number in ``data/vehicle.yaml`` (section ``aerodynamics``):

* **Normal-force slope and centre of pressure.** Anchored on the one public VEGA point,
  C_Nα = 2.007 /rad and x_CP = 18.36 m from the base at max-Q (Simplício's PhD thesis
  Table 10.1, S_ref = 7.14 m²). The Mach shape is *flat*: slender-body theory (Munk; Nielsen,
  *Missile Aerodynamics*, ch. 3) gives a normal-force slope 2·S_base/S_ref per radian and a
  centre of pressure fixed by the body's area distribution, both independent of Mach; for
  VEGA's 3 m base it predicts 2·7.07/7.14 = 1.98 /rad, within 1.5 % of the public value, so the
  anchor is consistent with the theory (docs/TRAJECTORY.md §4). The data are Mach tables, so a
  real aerodynamic database replaces them without code changes; the x_CP ±10 % uncertainty of
  thesis Table 2.3 covers the shape error.
* **Nonlinear normal force** (Jorgensen, NASA TR R-474, slender body + viscous crossflow):
  ``C_N(α, M) = C_Nα(M)·sin α·cos α + k·sin α·|sin α|`` with ``k = η·C_dc·S_plan/S_ref``.
  It is odd in α and its derivative at α = 0 is C_Nα(M) (the crossflow term is second order).
* **Axial force** C_A(M) at zero incidence: a table calibrated with the trajectory (it is the
  drag of the zero-lift gravity turn), docs/TRAJECTORY.md §4 and §6.

Outside a table's Mach range the end value is held (``numpy.interp``). All functions accept
scalars or arrays and broadcast like numpy; :meth:`Aerodynamics.scalar_tables` gives plain-float
versions of C_Nα(M) and C_A(M) for the nonlinear plant's inner loop (same numbers bit for bit,
:class:`ScalarTable`).
"""

from __future__ import annotations

from bisect import bisect_right

import numpy as np

from vega_model.vehicle_data import VehicleData

__all__ = ["Aerodynamics", "ScalarTable"]


class ScalarTable:
    """Piecewise-linear table y(x) for one float at a time, bit-identical to ``numpy.interp``.

    ``numpy.interp`` costs ≈ 2.5 µs per scalar call (array conversion); this costs ≈ 0.3 µs.
    Same arithmetic as numpy's C kernel: the end values are held outside [x_0, x_last], a
    breakpoint returns its own y, otherwise ``slope·(x − x_j) + y_j`` with
    ``slope = (y_j+1 − y_j)/(x_j+1 − x_j)`` (tests/model/test_aero.py compares the two).

    Parameters
    ----------
    x, y
        Breakpoints (strictly increasing) and values.
    """

    __slots__ = ("_x", "_y", "_slopes")

    def __init__(self, x, y):
        self._x = [float(v) for v in np.asarray(x, dtype=float).ravel()]
        self._y = [float(v) for v in np.asarray(y, dtype=float).ravel()]
        if len(self._x) != len(self._y) or not self._x:
            raise ValueError("table needs as many values as breakpoints, at least one")
        self._slopes = [(self._y[j + 1] - self._y[j]) / (self._x[j + 1] - self._x[j])
                        for j in range(len(self._x) - 1)]

    def __call__(self, v: float) -> float:
        """y(v) [float]; NaN for a NaN argument."""
        xs = self._x
        if v >= xs[-1]:
            return self._y[-1]
        if v <= xs[0]:
            return self._y[0]
        if v != v:   # NaN
            return v
        j = bisect_right(xs, v) - 1
        if xs[j] == v:
            return self._y[j]
        return self._slopes[j] * (v - xs[j]) + self._y[j]

    def segment(self, v: float) -> tuple[float, float, float, float, float]:
        """``(x_j, x_j+1, slope, x_j, y_j)`` of the segment that holds ``v``: for every u with
        x_j < u < x_j+1, ``slope·(u − x_j) + y_j`` is exactly ``self(u)``, so a caller may
        keep the segment and skip the search while its argument stays inside (open bounds).
        Outside the breakpoints (or NaN) the bounds are (+inf, −inf): no u is inside."""
        xs = self._x
        if not xs[0] <= v < xs[-1]:
            inf = float("inf")
            return inf, -inf, 0.0, 0.0, 0.0
        j = bisect_right(xs, v) - 1
        return xs[j], xs[j + 1], self._slopes[j], xs[j], self._y[j]


class Aerodynamics:
    """Aerodynamic coefficients from vehicle data (reference area ``s_ref_m2``).

    Parameters
    ----------
    vehicle : VehicleData
        Validated vehicle data (:func:`vega_model.vehicle_data.load_vehicle_data`).

    Attributes
    ----------
    s_ref_m2 : float
        Reference area of every coefficient [m²].
    crossflow_coefficient : float
        k = η·C_dc·S_plan/S_ref of the crossflow term [1].
    """

    def __init__(self, vehicle: VehicleData):
        self.s_ref_m2 = float(vehicle["geometry.s_ref_m2"])
        self._axial_mach = vehicle["aerodynamics.axial.mach"]
        self._c_a = vehicle["aerodynamics.axial.c_a"]
        self._normal_mach = vehicle["aerodynamics.normal.mach"]
        self._cn_alpha = vehicle["aerodynamics.normal.cn_alpha_per_rad"]
        self._x_cp = vehicle["aerodynamics.normal.x_cp_m"]
        self.crossflow_coefficient = float(
            vehicle["aerodynamics.crossflow.eta"] * vehicle["aerodynamics.crossflow.c_dc"]
            * vehicle["aerodynamics.crossflow.planform_area_m2"] / self.s_ref_m2)
        self._scalar: tuple[ScalarTable, ScalarTable] | None = None

    def c_a(self, mach):
        """Axial-force coefficient at zero incidence, C_A(M) [1] (thesis Eq. 2.13, body axes)."""
        return np.interp(mach, self._axial_mach, self._c_a)

    def cn_alpha(self, mach):
        """Normal-force slope at α = 0, C_Nα(M) [1/rad] (the linear model's C_N, thesis §2.10)."""
        return np.interp(mach, self._normal_mach, self._cn_alpha)

    def x_cp(self, mach):
        """Centre of pressure, distance from the vehicle base, x_CP(M) [m] (thesis Eq. 2.17)."""
        return np.interp(mach, self._normal_mach, self._x_cp)

    def scalar_tables(self) -> tuple[ScalarTable, ScalarTable]:
        """Plain-float C_Nα(M) [1/rad] and C_A(M) [1]: the same numbers as :meth:`cn_alpha`
        and :meth:`c_a` for one float at a time, ≈ 8× faster (the nonlinear plant calls them
        at every RK4 stage)."""
        if self._scalar is None:
            self._scalar = (ScalarTable(self._normal_mach, self._cn_alpha),
                            ScalarTable(self._axial_mach, self._c_a))
        return self._scalar

    def cn(self, alpha_rad, mach):
        """Normal-force coefficient C_N(α, M) [1] (thesis Eq. 2.16; Jorgensen's form).

        Parameters
        ----------
        alpha_rad : float or array_like
            Angle of attack [rad]; the sign of C_N follows the sign of α.
        mach : float or array_like
            Mach number [1].

        Notes
        -----
        ``C_Nα(M)·sin α·cos α + k·sin α·|sin α|``: continuously differentiable in α with
        ∂C_N/∂α = C_Nα(M) at α = 0, and odd, C_N(−α) = −C_N(α).
        """
        s = np.sin(alpha_rad)
        return (self.cn_alpha(mach) * s * np.cos(alpha_rad)
                + self.crossflow_coefficient * s * np.abs(s))
