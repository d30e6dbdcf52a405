"""Envelope generation from a trajectory: :func:`vega_sim.requirements.envelope_from_trajectory`
and :func:`vega_sim.requirements.envelope_table`.

Independent reference: synthetic flight-condition tables with Q linear in Mach (Q = 1000 Pa
per unit Mach), whose envelope α·Q(M) is exactly linear, so that every value and table is
worked out by hand: Q_nom(M) taken from the samples where Mach reaches a new maximum, up to
t_max_s (100 s by default); below mach_min the floor (by default the envelope at mach_min; an
explicit floor_pa_rad is held from Mach 0 to just below mach_min); table breakpoints on the
Mach step 0.001 and values rounded to 0.1 Pa·deg. Envelopes in Pa·rad, α in rad.
"""

import math

import numpy as np
import pytest

from vega_model.flight_conditions import COLUMNS, FlightConditions
from vega_sim.requirements import envelope_from_trajectory, envelope_table

D = math.pi / 180.0


# --------------------------------------------------------------- envelope from trajectory

def _conditions(t, mach, q):
    data = np.ones((len(t), len(COLUMNS)))
    data[:, COLUMNS.index("t_s")] = t
    data[:, COLUMNS.index("mach")] = mach
    data[:, COLUMNS.index("q_pa")] = q
    return FlightConditions("synthetic", COLUMNS, data, {})


def test_trajectory_q_uses_the_given_table_running_maximum_and_t_max():
    """Mach 0, 0.5, 1, 1, 0.8 at t 0..4 (Q 0, 100, 400, 300, 200 Pa): Q_nom(M) keeps the
    samples where Mach reaches a new maximum (t 0, 1, 2): Q_nom(1) = 400, Q_nom(0.75) = 250."""
    fc = _conditions([0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 0.5, 1.0, 1.0, 0.8],
                     [0.0, 100.0, 400.0, 300.0, 200.0])
    env = envelope_from_trajectory([0.25, 0.75, 1.0, 3.0], 2.0, fc)
    np.testing.assert_allclose(env, [100.0, 500.0, 800.0, 800.0], rtol=1e-12)
    # t_max_s = 2 includes the sample at t = 2 exactly; t_max_s = 1 stops at M 0.5
    assert envelope_from_trajectory(1.0, 2.0, fc, t_max_s=2.0) == pytest.approx(800.0)
    assert envelope_from_trajectory(1.0, 2.0, fc, t_max_s=1.0) == pytest.approx(200.0)
    # the first two samples decide the first segment
    fc2 = _conditions([0.0, 1.0, 2.0], [0.2, 0.4, 0.3], [10.0, 30.0, 0.0])
    np.testing.assert_allclose(envelope_from_trajectory([0.2, 0.3, 0.4], 1.0, fc2),
                               [10.0, 20.0, 30.0], rtol=1e-12)


def _linear_fc():
    """Q = 1000·M Pa at M 0 … 2 up to t = 100 s, and M 2.5 (Q 2500) at t = 100.5 s."""
    t = [0.0, 25.0, 50.0, 75.0, 100.0, 100.5]
    mach = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]
    return _conditions(t, mach, [1000.0 * m for m in mach])


def test_envelope_defaults_stop_at_100_s_and_have_no_floor():
    fc = _linear_fc()
    a = 4.0 * D
    assert envelope_from_trajectory(2.5, a, fc) == pytest.approx(a * 2000.0, rel=1e-12)
    assert envelope_from_trajectory(0.5, a, fc) == pytest.approx(a * 500.0, rel=1e-12)
    assert envelope_from_trajectory(0.25, a, fc, t_max_s=101.0) == pytest.approx(a * 250.0)


def test_envelope_floor_below_mach_min_only():
    fc = _linear_fc()
    a = 4.0 * D
    env = envelope_from_trajectory([0.1, 0.5, 0.5 - 1e-9, 1.0], a, fc, mach_min=0.5,
                                   floor_pa_rad=7.0)
    np.testing.assert_allclose(env, [7.0, a * 500.0, 7.0, a * 1000.0], rtol=1e-12)
    # default floor: the envelope's value at mach_min
    assert envelope_from_trajectory(0.1, a, fc, mach_min=0.5) == pytest.approx(a * 500.0)


def test_envelope_table_of_a_linear_envelope_has_no_interior_breakpoint():
    """α·Q(M) is linear in M: the greedy table is its two end points (values rounded to
    0.1 Pa·deg): 0 and 4°·2000 Pa = 8000 Pa·deg at M 2 (t ≤ 100 s)."""
    fc = _linear_fc()
    mach, values = envelope_table(4.0 * D, fc)
    np.testing.assert_allclose(mach, [0.0, 2.0])
    np.testing.assert_allclose(np.degrees(values), [0.0, 8000.0], rtol=1e-12)
    # with mach_min 0.5: [0, 0.5, 2] at 2000, 2000, 8000 Pa·deg
    mach, values = envelope_table(4.0 * D, fc, mach_min=0.5)
    np.testing.assert_allclose(mach, [0.0, 0.5, 2.0])
    np.testing.assert_allclose(np.degrees(values), [2000.0, 2000.0, 8000.0], rtol=1e-12)


def test_envelope_table_values_are_rounded_to_a_tenth_of_a_pa_deg():
    """Q = 1000·M + 0.123 Pa: 4°·Q(0) = 0.492 Pa·deg → 0.5; at M 2: 8000.492 → 8000.5."""
    t = [0.0, 50.0, 100.0]
    mach = [0.0, 1.0, 2.0]
    fc = _conditions(t, mach, [1000.0 * m + 0.123 for m in mach])
    m, values = envelope_table(4.0 * D, fc)
    np.testing.assert_allclose(m, [0.0, 2.0])
    np.testing.assert_allclose(np.degrees(values), [0.5, 8000.5], rtol=1e-12)


def test_envelope_table_ends_at_the_first_step_multiple_at_or_above_the_top_mach():
    """Top Mach 1.9996 (second-to-last 1.5): the table ends at 2.000."""
    t = [0.0, 50.0, 75.0, 100.0]
    mach = [0.0, 1.0, 1.5, 1.9996]
    fc = _conditions(t, mach, [1000.0 * m for m in mach])
    m, _ = envelope_table(4.0 * D, fc)
    assert m[0] == 0.0 and m[-1] == pytest.approx(2.0, abs=1e-12)


def test_envelope_table_honours_t_max():
    """t_max_s = 101 s takes the M 2.5 sample (t = 100.5 s) of the linear table: [0, 2.5] at
    0 and 4°·2500 Pa = 10000 Pa·deg."""
    mach, values = envelope_table(4.0 * D, _linear_fc(), t_max_s=101.0)
    np.testing.assert_allclose(mach, [0.0, 2.5])
    np.testing.assert_allclose(np.degrees(values), [0.0, 10000.0], rtol=1e-12)


# ------------------------------------------------------------ an explicit floor in the table
def _mach_0_to_2():
    """A synthetic trajectory: Mach 0…2 over 100 s, Q = 1000 Pa per unit Mach."""
    t = [0.0, 25.0, 50.0, 75.0, 100.0]
    mach = [0.0, 0.5, 1.0, 1.5, 2.0]
    return _conditions(t, mach, [1000.0 * m for m in mach])


def test_an_explicit_floor_is_held_below_mach_min():
    """4°·Q with a 300 Pa·deg floor below Mach 0.5 (where 4°·Q = 2000 Pa·deg): the table is
    300 from Mach 0 to 0.499 and 2000 at 0.5 — as the exact envelope says."""
    fc = _mach_0_to_2()
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
    breakpoint at Mach 0 holding it."""
    fc = _mach_0_to_2()
    mach, values = envelope_table(4.0 * D, fc, mach_min=0.5)
    assert list(mach[:2]) == [0.0, 0.5]
    assert np.degrees(values[:2]) == pytest_approx([2000.0, 2000.0])


def pytest_approx(expected):
    return pytest.approx(expected, rel=0, abs=1e-9)
