"""Uncertainty set: the ranges of thesis Table 2.3, §2.12.3-2.12.4; sampling and corners; the
bound rules at their boundary values (lower ≤ 0 ≤ upper inclusive, a relative lower bound
> −1) and the plain-data view's keys and values."""

import numpy as np
import pytest

from vega_model.uncertainty import UNCERTAINTY_NAMES, UncertainParameter, UncertaintySet
from vega_model.vehicle_data import load_vehicle_data

# thesis Table 2.3 (fractions), §2.12.3 (TVC 10 %), §2.12.4 (±10 ms absolute)
TABLE = {
    "thrust": (-0.10, 0.10), "velocity": (-0.10, 0.10), "density": (-0.10, 0.10),
    "x_cp": (-0.10, 0.10), "x_cg": (-0.02, 0.02), "mass": (-0.02, 0.02), "jyy": (-0.02, 0.02),
    "bending_frequency_1": (-0.20, 0.15), "bending_frequency_2": (-0.25, 0.20),
    "psi_mode_1": (-0.40, 0.30), "psi_mode_2": (-0.50, 0.50),
    "actuator": (-0.10, 0.10), "delay_s": (-0.010, 0.010),
}


@pytest.fixture(scope="module")
def uset():
    return UncertaintySet.from_vehicle(load_vehicle_data())


def test_bounds_from_thesis(uset):
    assert uset.names == UNCERTAINTY_NAMES == tuple(TABLE)
    for name, (lo, hi) in TABLE.items():
        p = uset[name]
        assert (p.lower, p.upper) == pytest.approx((lo, hi), abs=1e-15), name
        assert p.kind == ("absolute" if name == "delay_s" else "relative")
        assert p.source and p.applies_to


def test_nominal_is_zero(uset):
    assert uset.nominal() == {n: 0.0 for n in TABLE}


def test_samples_within_bounds_and_fill_them(uset):
    rng = np.random.default_rng(3)
    draws = [uset.sample(rng) for _ in range(2000)]
    for name, (lo, hi) in TABLE.items():
        v = np.array([d[name] for d in draws])
        assert np.all(v >= lo) and np.all(v <= hi)
        # uniform: the extremes of 2000 draws come within 1 % of the range of each bound
        assert v.min() < lo + 0.01 * (hi - lo) and v.max() > hi - 0.01 * (hi - lo)
        assert v.mean() == pytest.approx(0.5 * (lo + hi), abs=0.05 * (hi - lo))
    # reproducible with the caller's seed
    assert uset.sample(np.random.default_rng(9)) == uset.sample(np.random.default_rng(9))
    with pytest.raises(TypeError):
        uset.sample(np.random.RandomState(0))


def test_corners(uset):
    corners = list(uset.corners())
    assert len(corners) == 2 ** 13 == 8192
    keys = {tuple(sorted(c.items())) for c in corners}
    assert len(keys) == 8192                                   # all distinct
    for c in corners[:50] + corners[-50:]:
        for name, (lo, hi) in TABLE.items():
            assert c[name] == pytest.approx(lo) or c[name] == pytest.approx(hi)
    sub = list(uset.corners(["thrust", "psi_mode_1"]))
    assert len(sub) == 4
    assert sub[0]["thrust"] == pytest.approx(-0.1) and sub[0]["psi_mode_1"] == pytest.approx(-0.4)
    assert sub[0]["mass"] == 0.0


def test_to_dict_and_validation(uset):
    d = uset.to_dict()
    assert d["bending_frequency_2"]["lower"] == pytest.approx(-0.25)
    assert d["delay_s"]["kind"] == "absolute"
    with pytest.raises(ValueError):
        UncertainParameter("x", 0.1, 0.2, "relative", "nominal must be inside")
    with pytest.raises(ValueError):
        UncertainParameter("x", -1.5, 0.2, "relative", "would flip the sign")
    with pytest.raises(ValueError):
        UncertainParameter("x", -0.1, 0.2, "scaled", "bad kind")
    with pytest.raises(KeyError):
        uset["no_such_parameter"]


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
