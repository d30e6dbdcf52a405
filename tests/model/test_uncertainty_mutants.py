"""Uncertainty-set behaviour that mutation testing (``make mutation MODULE=uncertainty``)
found unchecked: the bound rules at their boundary values (lower ≤ 0 ≤ upper inclusive, a
relative lower bound must be > −1) and the plain-data view's keys and values.
"""

import pytest

from vega_model.uncertainty import UncertainParameter, UncertaintySet


@pytest.mark.parametrize("lower, upper", [(0.0, 0.2), (-0.2, 0.0), (0.0, 0.0)])
def test_a_bound_at_zero_is_allowed(lower, upper):
    p = UncertainParameter("mass", lower, upper, "relative", "m")
    assert (p.lower, p.upper) == (lower, upper)


@pytest.mark.parametrize("lower, upper", [(1e-9, 0.2), (-0.2, -1e-9)])
def test_nominal_outside_the_bounds_is_refused(lower, upper):
    with pytest.raises(ValueError, match="lower <= 0 <= upper"):
        UncertainParameter("mass", lower, upper, "relative", "m")


def test_relative_lower_bound_of_minus_one_is_refused_just_above_allowed():
    with pytest.raises(ValueError, match="must be > -1"):
        UncertainParameter("mass", -1.0, 0.1, "relative", "m")
    assert UncertainParameter("mass", -0.999999, 0.1, "relative", "m").lower == -0.999999
    # an absolute deviation (seconds) may go below -1
    assert UncertainParameter("delay_s", -1.5, 0.1, "absolute", "tau").lower == -1.5


def test_to_dict_lists_every_field_by_name():
    s = UncertaintySet([UncertainParameter("mass", -0.1, 0.2, "relative", "m", "Table 2.3"),
                        UncertainParameter("delay_s", -0.01, 0.02, "absolute", "tau", "§2.12.4")])
    assert s.to_dict() == {
        "mass": {"lower": -0.1, "upper": 0.2, "kind": "relative", "applies_to": "m",
                 "source": "Table 2.3"},
        "delay_s": {"lower": -0.01, "upper": 0.02, "kind": "absolute", "applies_to": "tau",
                    "source": "§2.12.4"},
    }


def test_iterating_a_set_gives_its_parameters_in_order():
    a = UncertainParameter("mass", -0.1, 0.2, "relative", "m")
    b = UncertainParameter("delay_s", -0.01, 0.02, "absolute", "tau")
    s = UncertaintySet([a, b])
    assert [p.name for p in s] == ["mass", "delay_s"]
    assert list(s) == [a, b] and len(s) == 2
