"""Aerodynamic model (vega_model.aero): public max-Q anchor, C_N(α) properties, hand values."""

import math

import numpy as np
import pytest

from vega_model.aero import Aerodynamics
from vega_model.flight_conditions import FlightConditions
from vega_model.vehicle_data import load_vehicle_data

# The one public VEGA aerodynamic point (Simplício's PhD thesis Table 10.1, as quoted in
# public material): at max-Q, C_Nα = 2.007 /rad and x_CP = 18.36 m from the base, S_ref 7.14 m².
CN_ALPHA_MAXQ = 2.007
X_CP_MAXQ_M = 18.36
S_REF_M2 = 7.14


@pytest.fixture(scope="module")
def aero():
    return Aerodynamics(load_vehicle_data())


@pytest.fixture(scope="module")
def mach_max_q():
    fc = FlightConditions.load()
    return float(fc.column("mach")[np.argmax(fc.column("q_pa"))])


def test_anchored_at_our_max_q(aero, mach_max_q):
    assert 1.7 < mach_max_q < 2.2          # our max-Q is supersonic, near M 1.94
    assert aero.s_ref_m2 == S_REF_M2
    assert aero.cn_alpha(mach_max_q) == pytest.approx(CN_ALPHA_MAXQ, rel=1e-12)
    assert aero.x_cp(mach_max_q) == pytest.approx(X_CP_MAXQ_M, rel=1e-12)


def test_anchor_agrees_with_slender_body_theory(aero, mach_max_q):
    """Slender-body theory: C_Nα = 2·S_base/S_ref (base diameter 3 m, thesis Table 2.1)."""
    s_base = math.pi * 3.0 ** 2 / 4.0
    assert aero.cn_alpha(mach_max_q) == pytest.approx(2.0 * s_base / aero.s_ref_m2, rel=0.015)


@pytest.mark.parametrize("mach", [0.0, 0.5, 1.0, 1.94, 3.0, 5.8])
def test_cn_derivative_at_zero_equals_cn_alpha(aero, mach):
    """∂C_N/∂α(0) = C_Nα. The crossflow term k·sin α|sin α| is odd and C¹ but not C² at 0,
    so a central difference carries an O(h) error of exactly k·h: bound it by that."""
    k = aero.crossflow_coefficient
    for h in (1e-5, 1e-7):
        slope = (aero.cn(h, mach) - aero.cn(-h, mach)) / (2.0 * h)
        assert abs(slope - aero.cn_alpha(mach)) <= k * h * (1.0 + 1e-6) + 1e-12
    assert aero.cn(0.0, mach) == 0.0


def test_cn_is_odd(aero):
    alpha = np.radians(np.linspace(-20.0, 20.0, 81))
    mach = np.linspace(0.0, 6.0, 81)
    np.testing.assert_allclose(aero.cn(-alpha, mach), -aero.cn(alpha, mach), rtol=0, atol=1e-15)


def test_cn_hand_value_with_crossflow(aero):
    """C_N(10°) = C_Nα sin α cos α + η C_dc S_plan/S_ref sin² α (Jorgensen, NASA TR R-474)."""
    k = 0.68 * 1.2 * 75.0 / 7.14                     # vehicle.yaml aerodynamics.crossflow
    a = math.radians(10.0)
    expected = 2.007 * math.sin(a) * math.cos(a) + k * math.sin(a) ** 2
    assert aero.crossflow_coefficient == pytest.approx(k, rel=1e-12)
    assert aero.cn(a, 1.94) == pytest.approx(expected, rel=1e-12)
    assert aero.cn(a, 1.94) > 1.5 * 2.007 * a        # crossflow adds > 50 % at 10°


def test_vectorised_broadcasting(aero):
    mach = np.array([0.3, 1.2, 4.0])
    assert aero.c_a(mach).shape == (3,)
    assert aero.cn(np.radians([[1.0], [2.0]]), mach).shape == (2, 3)
    assert aero.x_cp(mach).shape == (3,)


def test_axial_coefficient_shape(aero):
    """Positive everywhere; transonic peak at M 1.2; held constant outside the table."""
    mach = np.linspace(0.0, 8.0, 161)
    c_a = aero.c_a(mach)
    assert np.all(c_a > 0.0)
    assert mach[np.argmax(c_a)] == pytest.approx(1.2)
    assert aero.c_a(10.0) == aero.c_a(6.0)


def test_scalar_tables_equal_numpy_interp_bit_for_bit(aero):
    """The plant's plain-float tables give numpy.interp's numbers exactly: inside segments, on
    and next to every breakpoint, outside the table, and through a kept segment."""
    cn_alpha, c_a = aero.scalar_tables()
    rng = np.random.default_rng(3)
    breaks = np.concatenate([aero._axial_mach, aero._normal_mach])
    points = np.concatenate([rng.uniform(-1.0, 9.0, 20000), breaks,
                             np.nextafter(breaks, -np.inf), np.nextafter(breaks, np.inf)])
    for table, numpy_version in ((cn_alpha, aero.cn_alpha), (c_a, aero.c_a)):
        for m in points.tolist():
            want = float(numpy_version(m))
            assert table(m) == want
            lo, hi, slope, x0, y0 = table.segment(m)
            inside = m + 1e-9
            if lo < inside < hi:
                assert slope * (inside - x0) + y0 == float(numpy_version(inside))
    assert math.isnan(c_a(float("nan")))
    lo, hi, *_ = c_a.segment(float("nan"))
    assert not lo < 1.0 < hi
