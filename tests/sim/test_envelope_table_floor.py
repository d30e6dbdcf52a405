"""`envelope_table` with an explicit floor (bug found by mutation testing, issue 15: the table
held the envelope's value at mach_min below it and ignored ``floor_pa_rad``)."""

import math

import numpy as np

from vega_model.flight_conditions import COLUMNS, FlightConditions
from vega_sim.requirements import envelope_from_trajectory, envelope_table

D = math.pi / 180.0


def _conditions():
    """A synthetic trajectory: Mach 0…2 over 100 s, Q = 1000 Pa per unit Mach."""
    t = [0.0, 25.0, 50.0, 75.0, 100.0]
    mach = [0.0, 0.5, 1.0, 1.5, 2.0]
    data = np.ones((len(t), len(COLUMNS)))
    data[:, COLUMNS.index("t_s")] = t
    data[:, COLUMNS.index("mach")] = mach
    data[:, COLUMNS.index("q_pa")] = [1000.0 * m for m in mach]
    return FlightConditions("synthetic", COLUMNS, data, {})


def test_an_explicit_floor_is_held_below_mach_min():
    """4°·Q with a 300 Pa·deg floor below Mach 0.5 (where 4°·Q = 2000 Pa·deg): the table is
    300 from Mach 0 to 0.499 and 2000 at 0.5 — as the exact envelope says."""
    fc = _conditions()
    floor = math.radians(300.0)
    mach, values = envelope_table(4.0 * D, fc, mach_min=0.5, floor_pa_rad=floor)
    assert envelope_from_trajectory(0.2, 4.0 * D, fc, mach_min=0.5, floor_pa_rad=floor) == floor
    assert list(mach[:3]) == [0.0, 0.499, 0.5]
    assert np.degrees(values[:3]) == pytest_approx([300.0, 300.0, 2000.0])
    assert np.all(np.diff(mach) > 0)
    held = np.interp([0.0, 0.2, 0.49], mach, values)
    assert np.degrees(held) == pytest_approx([300.0, 300.0, 300.0])


def test_the_default_floor_keeps_the_table_form():
    """Without an explicit floor (the shipped file) the floor is the value at mach_min: one
    breakpoint at Mach 0 holding it, as before the fix."""
    fc = _conditions()
    mach, values = envelope_table(4.0 * D, fc, mach_min=0.5)
    assert list(mach[:2]) == [0.0, 0.5]
    assert np.degrees(values[:2]) == pytest_approx([2000.0, 2000.0])


def pytest_approx(expected):
    import pytest

    return pytest.approx(expected, rel=0, abs=1e-9)
