"""Tabulated wind profile (vega_model.wind.WindTable): its interpolation law against hand
values, against Eq. 2.54 tabulated from it (with the interpolation error bounded per interval
by hand), in the wind model, and the tables it refuses."""

import math

import numpy as np
import pytest

from vega_core.errors import BadInput
from vega_model.vehicle_data import load_vehicle_data
from vega_model.wind import (MAX_TABLE_WIND_MPS, ProfileChange, WindModel, WindTable,
                             WindTableError, wind_profile_mps)


@pytest.fixture(scope="module")
def data():
    return load_vehicle_data()


def test_linear_between_rows_and_ends_held():
    t = WindTable([0.0, 1000.0, 3000.0], [2.0, 12.0, -4.0])
    assert t.at(0.0) == 2.0 and t.at(1000.0) == 12.0 and t.at(3000.0) == -4.0
    assert t.at(500.0) == 7.0                       # 2 + (12 − 2)·0.5
    assert t.at(2500.0) == 0.0                      # 12 + (−16)·0.75
    assert t.at(-200.0) == 2.0 and t.at(50_000.0) == -4.0
    assert math.isnan(t.at(math.nan))
    h = np.array([[-1.0, 0.0, 500.0], [2500.0, 3000.0, 4e4]])
    assert np.array_equal(t.values(h), [[2.0, 2.0, 7.0], [0.0, -4.0, -4.0]])


def _interval_bounds(alt, data):
    """Largest error of linear interpolation of Eq. 2.54 on each interval [h_i, h_i+1], by hand.

    V = 10A[(h/H_l)^0.9 − 0.9 h/H_l] below H_l: its linear part is interpolated exactly; on the
    first interval [0, Δ] the chord of (h/H_l)^0.9 misses by (Δ/H_l)^0.9 · max_u(u^0.9 − u) =
    (Δ/H_l)^0.9 · 0.9^9 · 0.1 (at u = 0.9^10); above it |V''| = 0.9 A h^−1.1 H_l^−0.9 is largest
    at the interval's start and the error is at most Δ²/8 · |V''|. Constant A and 0: exact. The
    1-cosine edge: |V''| ≤ A/2 (π/H_u)², error ≤ Δ²/8 · A/2 (π/H_u)²."""
    amp, h_l, h_u, h_f = (data[f"wind.profile.{k}"] for k in ("amplitude_mps", "h_lower_m",
                                                               "h_upper_m", "h_final_m"))
    out = []
    for lo, hi in zip(alt[:-1], alt[1:]):
        d = hi - lo
        if hi <= h_l:
            out.append(10 * amp * (d / h_l) ** 0.9 * 0.9 ** 9 * 0.1 if lo == 0.0
                       else d * d / 8 * 0.9 * amp * lo ** -1.1 * h_l ** -0.9)
        elif hi <= h_f - h_u or lo >= h_f:
            out.append(0.0)
        else:
            out.append(d * d / 8 * amp / 2 * (math.pi / h_u) ** 2)
    return np.array(out)


def test_table_of_eq_2_54_flies_eq_2_54_to_the_interpolation_bound(data):
    """Eq. 2.54 tabulated every 100 m (the sampler's spacing, docs/WINDS.md): within
    10A(Δ/H_l)^0.9·0.9^9·0.1 = 0.366 m/s in the first 100 m, 0.106 m/s at 100–200 m, falling
    to 4e-3 m/s at 1.9–2 km, Δ²/8·A/2(π/H_u)² = 0.014 m/s on the trailing edge, exact
    elsewhere (breakpoints on the grid); checked every 1 m."""
    alt = np.arange(0.0, 30_001.0, 100.0)
    for key in ("h_lower_m", "h_final_m"):
        assert data[f"wind.profile.{key}"] % 100.0 == 0.0
    assert (data["wind.profile.h_final_m"] - data["wind.profile.h_upper_m"]) % 100.0 == 0.0
    table = WindTable(alt, wind_profile_mps(alt, data))
    bounds = _interval_bounds(alt, data)
    assert bounds[0] == pytest.approx(0.3659, abs=1e-4)
    assert bounds.max() == bounds[0]
    h = np.arange(0.0, 30_000.0, 1.0)
    err = np.abs(table.values(h) - wind_profile_mps(h, data))
    interval = np.minimum((h // 100).astype(int), bounds.size - 1)
    assert np.all(err <= bounds[interval] + 1e-12)
    assert err[h >= 200.0].max() < 0.05
    # the bound is not loose: the first interval reaches 90 % of it
    assert err[h < 100.0].max() > 0.9 * bounds[0]


def test_wind_model_flies_the_table_changed(data):
    """The model's steady part is scale · T(h − shift) at every step; turbulence and gust add
    as with Eq. 2.54 (same seed: same turbulence)."""
    table = WindTable([0.0, 5000.0, 12_000.0], [3.0, 20.0, -8.0])
    change = ProfileChange(1.3, -800.0)
    with_table = WindModel(data, profile=table, turbulence="light", seed=4, change=change)
    plain = WindModel(data, profile=False, turbulence="light", seed=4)
    assert with_table.profile and with_table.table is table
    for t, h in enumerate((0.0, 1234.5, 4200.0, 11_200.0, 11_500.0, 40_000.0)):
        parts = with_table.step_components(t * 1e-3, h, 300.0)
        assert parts.profile_mps == 1.3 * table.at(h + 800.0)
        assert parts.turbulence_mps == plain.step(t * 1e-3, h, 300.0)


@pytest.mark.parametrize("alt, wind, key, problem", [
    ([0.0, 100.0, 100.0], [1.0, 2.0, 3.0], "altitude_m[2]", "strictly increasing"),
    ([0.0, 200.0, 100.0], [1.0, 2.0, 3.0], "altitude_m[2]", "strictly increasing"),
    ([0.0, 100.0, 200.0], [1.0, math.nan, 3.0], "wind_mps[1]", "finite"),
    ([0.0, math.inf], [1.0, 2.0], "altitude_m[1]", "finite"),
    ([0.0, 100.0, 200.0], [1.0, 2.0], "wind_mps", "2 values for 3 altitudes"),
    ([0.0], [1.0], "altitude_m", "at least 2 rows"),
    ([], [], "altitude_m", "at least 2 rows"),
    ([0.0, 100.0], [1.0, MAX_TABLE_WIND_MPS + 1.0], "wind_mps[1]", "within ±120 m/s"),
    ([0.0, "1"], [1.0, 2.0], "altitude_m[1]", "must be a number"),
    ([0.0, True], [1.0, 2.0], "altitude_m[1]", "must be a number"),
    ("0, 1", [1.0, 2.0], "altitude_m", "list of numbers"),
    (np.zeros((2, 2)), [1.0, 2.0], "altitude_m", "one-dimensional"),
])
def test_bad_tables_refused_in_one_line(alt, wind, key, problem):
    with pytest.raises(WindTableError) as err:
        WindTable(alt, wind)
    assert isinstance(err.value, BadInput)
    assert err.value.key == key and problem in err.value.problem
    assert str(err.value).startswith(f"{key}: ") and "\n" not in str(err.value)


def test_table_is_hashable_and_numpy_input_stored_as_floats():
    a = WindTable(np.array([0, 100]), np.array([1.5, 2.5]), "x")
    assert a == WindTable((0.0, 100.0), (1.5, 2.5), "x") and hash(a) == hash(
        WindTable([0.0, 100.0], [1.5, 2.5], "x"))
    assert all(type(v) is float for v in a.altitude_m + a.wind_mps)
