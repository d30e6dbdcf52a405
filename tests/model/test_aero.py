"""Aerodynamic model (vega_model.aero): public max-Q anchor, C_N(α) properties, hand values.

Hand values: the numbers of data/vehicle.yaml (section ``aerodynamics``) typed in here, linear
interpolation between them done by hand, and a small hand table for :class:`ScalarTable` with
hand-computed values and segments (inside, on the breakpoints, outside, NaN, bad shapes).
"""

import math

import numpy as np
import pytest

from vega_model.aero import Aerodynamics, ScalarTable
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


@pytest.mark.slow
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

# ------------------------------------------------------------------ hand values
# Each test below builds its own Aerodynamics: the constructor (reading vehicle.yaml into
# the tables) is then part of every one of them, not only of the first that uses a fixture.

# vehicle.yaml aerodynamics.axial (typed in by hand)
AXIAL_MACH = [0, 0.5, 0.8, 1.0, 1.2, 1.5, 2.0, 3.0, 4.0, 6.0]
AXIAL_CA = [0.190, 0.190, 0.221, 0.316, 0.348, 0.316, 0.265, 0.221, 0.190, 0.158]


def test_axial_coefficient_hand_values():
    aero = Aerodynamics(load_vehicle_data())
    for m, ca in zip(AXIAL_MACH, AXIAL_CA):
        assert aero.c_a(m) == pytest.approx(ca, rel=1e-12)
    # mid-segment: (0.221 + 0.316)/2 at M 0.9; a quarter of the way 1.2 → 1.5 at M 1.275
    assert aero.c_a(0.9) == pytest.approx(0.2685, rel=1e-12)
    assert aero.c_a(1.275) == pytest.approx(0.348 - 0.25 * 0.032, rel=1e-12)
    assert aero.c_a(-1.0) == pytest.approx(0.190) and aero.c_a(9.0) == pytest.approx(0.158)


def test_crossflow_coefficient_hand_value():
    """k = η·C_dc·S_plan/S_ref = 0.68 · 1.2 · 75 / 7.14 = 8.5714…"""
    aero = Aerodynamics(load_vehicle_data())
    assert aero.crossflow_coefficient == pytest.approx(0.68 * 1.2 * 75.0 / 7.14, rel=1e-12)
    assert aero.crossflow_coefficient == pytest.approx(8.571428571, rel=1e-9)
    a = math.radians(20.0)
    assert aero.cn(a, 1.0) == pytest.approx(
        2.007 * math.sin(a) * math.cos(a) + 8.571428571 * math.sin(a) ** 2, rel=1e-9)


def test_scalar_tables_are_built_once_and_give_the_hand_values():
    aero = Aerodynamics(load_vehicle_data())
    cn_alpha, c_a = aero.scalar_tables()
    again = aero.scalar_tables()
    assert again[0] is cn_alpha and again[1] is c_a
    assert cn_alpha(1.94) == pytest.approx(2.007, rel=1e-12)
    assert c_a(0.9) == pytest.approx(0.2685, rel=1e-12)
    assert c_a(0.25) == pytest.approx(0.190, rel=1e-12) and c_a(7.0) == pytest.approx(0.158)


# hand table: y = 10 at 0, 20 at 1, 0 at 3 → slopes +10 and −10
HAND_X, HAND_Y = [0, 1, 3], [10, 20, 0]


@pytest.mark.parametrize("v, y", [(-1.0, 10.0), (0.0, 10.0), (0.25, 12.5), (0.5, 15.0),
                                  (1.0, 20.0), (2.0, 10.0), (2.5, 5.0), (3.0, 0.0),
                                  (7.0, 0.0)])
def test_scalar_table_hand_values(v, y):
    assert ScalarTable(HAND_X, HAND_Y)(v) == y


def test_scalar_table_nan_and_bad_shapes():
    t = ScalarTable(HAND_X, HAND_Y)
    assert math.isnan(t(float("nan")))
    with pytest.raises(ValueError):
        ScalarTable([0.0, 1.0], [1.0])
    with pytest.raises(ValueError):
        ScalarTable([0.0], [1.0, 2.0])
    with pytest.raises(ValueError):
        ScalarTable([], [])


@pytest.mark.parametrize("v, seg", [(0.0, (0.0, 1.0, 10.0, 0.0, 10.0)),
                                    (0.5, (0.0, 1.0, 10.0, 0.0, 10.0)),
                                    (1.0, (1.0, 3.0, -10.0, 1.0, 20.0)),
                                    (2.0, (1.0, 3.0, -10.0, 1.0, 20.0)),
                                    (2.999, (1.0, 3.0, -10.0, 1.0, 20.0))])
def test_scalar_table_segment_hand_values(v, seg):
    assert ScalarTable(HAND_X, HAND_Y).segment(v) == seg


@pytest.mark.parametrize("v", (-0.5, 3.0, 4.0, float("nan")))
def test_scalar_table_segment_outside_is_empty(v):
    lo, hi, slope, x0, y0 = ScalarTable(HAND_X, HAND_Y).segment(v)
    assert (lo, hi) == (math.inf, -math.inf) and (slope, x0, y0) == (0.0, 0.0, 0.0)
