"""Aerodynamics: tests written for the survivors of `make mutation MODULE=aero`.

Independent references: the numbers of data/vehicle.yaml (section ``aerodynamics``) typed in
here by hand, linear interpolation between them done by hand, and a small hand table for
:class:`ScalarTable` with hand-computed values and segments. Each test builds its own
:class:`Aerodynamics` (a module fixture would run the constructor in one test only).
"""

import math

import pytest

from vega_model.aero import Aerodynamics, ScalarTable
from vega_model.vehicle_data import load_vehicle_data

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
