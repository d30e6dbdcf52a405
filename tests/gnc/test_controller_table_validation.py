"""The controller-table loader's validation rules, each at its boundary.

A table just inside a rule is accepted, one just outside is refused by that rule with a
message naming it (:func:`vega_gnc.controller_table.validate_arrays`): the velocity grid
(at least 2 points, strictly increasing, 1-D), the rate grid, the matrix shapes, the input
names, the sample time dt_s [s], the rate bounds [m/s²], the recorded stability against the
spectral radius of Ad (a discrete pole on the unit circle is not stable), and the structured
design's NaN placeholders for γ and the rate bounds (an LPV design has none). The tables are
small hand-made ones (tests/gnc/gnc_table_files.py), edited one key at a time.
"""

import numpy as np
import pytest

from gnc_table_files import table_arrays, write_plain_table, write_rate_table
from vega_gnc.controller_table import ControllerTableError, validate_arrays


@pytest.fixture(scope="module")
def rate_file(tmp_path_factory):
    """A 2-state table on 3 velocities × 2 ρ̇ slices (0 and 36 m/s²), stable everywhere."""
    return write_rate_table(tmp_path_factory.mktemp("rate") / "r.npz")


@pytest.fixture(scope="module")
def plain_file(tmp_path_factory):
    """A 2-state table on 3 velocities without rate slices."""
    return write_plain_table(tmp_path_factory.mktemp("plain") / "p.npz")


def _refused(path, arrays, fragment):
    with pytest.raises(ControllerTableError, match=fragment):
        validate_arrays(path, arrays)


# ------------------------------------------------------------------------------ accepted values
def test_valid_table_keeps_path_rate_bounds_and_read_only_arrays(plain_file):
    t = validate_arrays(plain_file, table_arrays(plain_file))
    assert t.path == plain_file
    assert t.rate_bounds_mps2 == (5.0, 36.0)
    assert t.gamma == 1.0 and t.gamma_min == 0.9 and t.dt_s == 0.02
    assert t.n_states == 2
    assert not t.Ad.flags.writeable


def test_two_point_grid_and_equal_rate_bounds_are_accepted(plain_file):
    a = table_arrays(plain_file)
    two = {k: (v[:2] if k in ("A", "B", "C", "D", "Ad", "Bd", "Cd", "Dd") else v)
           for k, v in a.items() if k != "metadata"}
    two["grid_v_mps"] = np.array([100.0, 400.0])
    two = table_arrays(plain_file, **two, meta={"controller_stable": [True, True]})
    assert validate_arrays(plain_file, two).grid_v_mps.tolist() == [100.0, 400.0]
    equal = table_arrays(plain_file, rate_bounds_mps2=np.array([20.0, 20.0]))
    assert validate_arrays(plain_file, equal).rate_bounds_mps2 == (20.0, 20.0)


# ------------------------------------------------------------------------------ refused values
def test_one_point_grid_is_refused(plain_file):
    a = table_arrays(plain_file)
    one = {k: (v[:1] if k in ("A", "B", "C", "D", "Ad", "Bd", "Cd", "Dd") else v)
           for k, v in a.items() if k != "metadata"}
    one["grid_v_mps"] = np.array([100.0])
    _refused(plain_file, table_arrays(plain_file, **one, meta={"controller_stable": [True]}),
             "at least 2 velocities")


def test_grid_with_a_repeated_velocity_is_refused(plain_file):
    _refused(plain_file, table_arrays(plain_file, grid_v_mps=np.array([100.0, 400.0, 400.0])),
             "strictly increasing")


def test_two_dimensional_grid_is_refused(plain_file):
    _refused(plain_file, table_arrays(plain_file, grid_v_mps=np.array([[100.0, 400.0, 900.0]])),
             "1-D array")


@pytest.mark.parametrize("rate_grid", [[36.0, 36.0], [0.0, np.inf], [0.0, 10.0, 36.0]])
def test_bad_rate_grid_is_refused(rate_file, rate_grid):
    _refused(rate_file, table_arrays(rate_file, rate_grid_mps2=np.array(rate_grid)),
             "rate_grid_mps2")


def test_non_square_state_matrix_is_refused(plain_file):
    a = table_arrays(plain_file)
    _refused(plain_file, table_arrays(plain_file, A=a["A"][:, :, :1]), "'A' has shape")


def test_state_matrix_with_the_wrong_number_of_grid_points_is_refused(plain_file):
    a = table_arrays(plain_file)
    _refused(plain_file, table_arrays(plain_file, A=a["A"][:2]), "'A' has shape")


def test_missing_rate_slice_axis_is_refused(rate_file):
    a = table_arrays(rate_file)
    _refused(rate_file, table_arrays(rate_file, A=a["A"][:, 0]), "'A' has shape")


@pytest.mark.parametrize("names", [[], "theta_ins_rad", ["theta_ins_rad", "theta_ins_rad"],
                                   ["theta_ins_rad", "alpha"]])
def test_bad_input_names_are_refused(plain_file, names):
    _refused(plain_file, table_arrays(plain_file, meta={"input_names": names}), "input_names")


@pytest.mark.parametrize("dt", [np.array(0.0), np.array(-0.02), np.array([0.02, 0.02])])
def test_non_positive_or_several_sample_times_are_refused(plain_file, dt):
    _refused(plain_file, table_arrays(plain_file, dt_s=dt), "dt_s")


def test_reversed_rate_bounds_are_refused_in_an_lpv_design(plain_file):
    _refused(plain_file, table_arrays(plain_file, rate_bounds_mps2=np.array([36.0, 5.0])),
             "rate_bounds_mps2")


def test_recorded_stability_must_match_the_spectral_radius(plain_file):
    """The fixture is stable at every point (radius < 1): recording one point unstable, or a
    stable record given as 0/1 integers with one 0, is refused."""
    _refused(plain_file, table_arrays(plain_file, meta={"controller_stable": [True, False, True]}),
             "contradicting")
    _refused(plain_file, table_arrays(plain_file, meta={"controller_stable": [1, 0, 1]}),
             "contradicting")


def test_spectral_radius_exactly_one_is_not_stable(plain_file):
    """A discrete pole on the unit circle (Ad = diag(1, 0.5) at one point) is not stable."""
    a = table_arrays(plain_file)
    Ad = np.array(a["Ad"], copy=True)
    Ad[1] = np.diag([1.0, 0.5])
    _refused(plain_file, table_arrays(plain_file, Ad=Ad), "contradicting")
    ok = table_arrays(plain_file, Ad=Ad, meta={"controller_stable": [True, False, True]})
    assert validate_arrays(plain_file, ok).Ad[1, 0, 0] == 1.0


def test_spectral_radius_between_one_and_two_is_not_stable(plain_file):
    a = table_arrays(plain_file)
    Ad = np.array(a["Ad"], copy=True)
    Ad[2] = np.diag([1.5, 0.5])
    _refused(plain_file, table_arrays(plain_file, Ad=Ad), "contradicting")


# -------------------------------------------------------------------------- structured design
def _structured(path, **changes):
    nan = np.array(np.nan)
    base = dict(gamma=nan, gamma_min=nan, rate_bounds_mps2=np.array([np.nan, np.nan]))
    base.update(changes)
    return table_arrays(path, **base, meta={"design": "structured"})


def test_structured_design_with_nan_placeholders_is_accepted(plain_file):
    t = validate_arrays(plain_file, _structured(plain_file))
    assert t.design == "structured"
    assert np.isnan(t.gamma) and np.isnan(t.gamma_min)
    assert np.isnan(t.rate_bounds_mps2[0]) and np.isnan(t.rate_bounds_mps2[1])


@pytest.mark.parametrize("key, value", [("gamma", np.array(1.0)),
                                        ("gamma_min", np.array([np.nan, 0.5])),
                                        ("rate_bounds_mps2", np.array([1, 2]))])
def test_structured_design_refuses_a_figure_it_cannot_have(plain_file, key, value):
    _refused(plain_file, _structured(plain_file, **{key: value}), "must be NaN")


def test_lpv_design_refuses_nan_gamma(plain_file):
    """Without metadata 'design' the table is LPV: NaN γ is not a placeholder there."""
    _refused(plain_file, table_arrays(plain_file, gamma=np.array(np.nan)), "gamma")


# ------------------------------------------------------------------------ loading and conversion
def test_loaded_table_names_its_file(plain_file):
    from vega_gnc.controller_table import load_controller_table

    assert load_controller_table(plain_file).path == plain_file


def test_integer_rate_grid_is_read_as_float(rate_file):
    t = validate_arrays(rate_file, table_arrays(rate_file, rate_grid_mps2=np.array([0, 36])))
    assert t.rate_grid_mps2.dtype == np.float64
    assert t.rate_grid_mps2.tolist() == [0.0, 36.0]


@pytest.mark.parametrize("A", [np.ones(3), np.ones((3, 2))])
def test_state_matrix_of_too_few_dimensions_is_refused(plain_file, A):
    _refused(plain_file, table_arrays(plain_file, A=A), "'A' has shape")
