"""Controller table checks that mutation testing (``make mutation MODULE=controller_table``)
found unchecked: each validation rule at its boundary (a table just inside is accepted, one
just outside refused by that rule), the structured design's NaN placeholders, and the
interpolation in velocity and in the rate slice against element-wise hand formulas
(``(1 − w)·M[i] + w·M[i+1]``, ``(1 − s)·slice0 + s·slice1``), written from the raw arrays.
"""

import json

import numpy as np
import pytest

from vega_loops.export import write_controller_table
from vega_gnc.config_files import read_npz
from vega_gnc.controller_table import ControllerTableError, validate_arrays

NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]
GRID = [100.0, 400.0, 900.0]


def _meta(**extra):
    meta = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
            "units": {}, "weights": {}, "solver": {}}
    meta.update(extra)
    return meta


@pytest.fixture(scope="module")
def rate_file(tmp_path_factory):
    """A 2-state table on 3 velocities × 2 ρ̇ slices (0 and 36 m/s²), stable everywhere."""
    rng = np.random.default_rng(5)
    lead = (3, 2)
    A = -3.0 * np.eye(2) + 0.3 * rng.standard_normal(lead + (2, 2))
    B = rng.standard_normal(lead + (2, 4))
    C = rng.standard_normal(lead + (1, 2))
    D = rng.standard_normal(lead + (1, 4))
    path = tmp_path_factory.mktemp("rate") / "r.npz"
    write_controller_table(path, GRID, A, B, C, D, dt_s=0.02, gamma=1.0, gamma_min=0.9,
                           rate_bounds_mps2=[0.0, 36.0], metadata=_meta(),
                           rate_grid_mps2=[0.0, 36.0])
    return str(path)


@pytest.fixture(scope="module")
def plain_file(tmp_path_factory):
    rng = np.random.default_rng(6)
    A = -3.0 * np.eye(2) + 0.3 * rng.standard_normal((3, 2, 2))
    B = rng.standard_normal((3, 2, 4))
    C = rng.standard_normal((3, 1, 2))
    D = rng.standard_normal((3, 1, 4))
    path = tmp_path_factory.mktemp("plain") / "p.npz"
    write_controller_table(path, GRID, A, B, C, D, dt_s=0.02, gamma=1.0, gamma_min=0.9,
                           rate_bounds_mps2=[5.0, 36.0], metadata=_meta())
    return str(path)


def _arrays(path, **changes):
    arrays = dict(read_npz(path, ControllerTableError, "controller table"))
    meta_changes = changes.pop("meta", None)
    if meta_changes is not None:
        meta = json.loads(str(np.asarray(arrays["metadata"]).item()))
        meta.update(meta_changes)
        arrays["metadata"] = np.array(json.dumps(meta))
    arrays.update(changes)
    return arrays


def _refused(path, arrays, fragment):
    with pytest.raises(ControllerTableError, match=fragment):
        validate_arrays(path, arrays)


# ------------------------------------------------------------------------------ accepted values
def test_valid_table_keeps_path_rate_bounds_and_read_only_arrays(plain_file):
    t = validate_arrays(plain_file, _arrays(plain_file))
    assert t.path == plain_file
    assert t.rate_bounds_mps2 == (5.0, 36.0)
    assert t.gamma == 1.0 and t.gamma_min == 0.9 and t.dt_s == 0.02
    assert t.n_states == 2
    assert not t.Ad.flags.writeable


def test_two_point_grid_and_equal_rate_bounds_are_accepted(plain_file):
    a = _arrays(plain_file)
    two = {k: (v[:2] if k in ("A", "B", "C", "D", "Ad", "Bd", "Cd", "Dd") else v)
           for k, v in a.items() if k != "metadata"}
    two["grid_v_mps"] = np.array([100.0, 400.0])
    two = _arrays(plain_file, **two, meta={"controller_stable": [True, True]})
    assert validate_arrays(plain_file, two).grid_v_mps.tolist() == [100.0, 400.0]
    equal = _arrays(plain_file, rate_bounds_mps2=np.array([20.0, 20.0]))
    assert validate_arrays(plain_file, equal).rate_bounds_mps2 == (20.0, 20.0)


# ------------------------------------------------------------------------------ refused values
def test_one_point_grid_is_refused(plain_file):
    a = _arrays(plain_file)
    one = {k: (v[:1] if k in ("A", "B", "C", "D", "Ad", "Bd", "Cd", "Dd") else v)
           for k, v in a.items() if k != "metadata"}
    one["grid_v_mps"] = np.array([100.0])
    _refused(plain_file, _arrays(plain_file, **one, meta={"controller_stable": [True]}),
             "at least 2 velocities")


def test_grid_with_a_repeated_velocity_is_refused(plain_file):
    _refused(plain_file, _arrays(plain_file, grid_v_mps=np.array([100.0, 400.0, 400.0])),
             "strictly increasing")


def test_two_dimensional_grid_is_refused(plain_file):
    _refused(plain_file, _arrays(plain_file, grid_v_mps=np.array([[100.0, 400.0, 900.0]])),
             "1-D array")


@pytest.mark.parametrize("rate_grid", [[36.0, 36.0], [0.0, np.inf], [0.0, 10.0, 36.0]])
def test_bad_rate_grid_is_refused(rate_file, rate_grid):
    _refused(rate_file, _arrays(rate_file, rate_grid_mps2=np.array(rate_grid)),
             "rate_grid_mps2")


def test_non_square_state_matrix_is_refused(plain_file):
    a = _arrays(plain_file)
    _refused(plain_file, _arrays(plain_file, A=a["A"][:, :, :1]), "'A' has shape")


def test_state_matrix_with_the_wrong_number_of_grid_points_is_refused(plain_file):
    a = _arrays(plain_file)
    _refused(plain_file, _arrays(plain_file, A=a["A"][:2]), "'A' has shape")


def test_missing_rate_slice_axis_is_refused(rate_file):
    a = _arrays(rate_file)
    _refused(rate_file, _arrays(rate_file, A=a["A"][:, 0]), "'A' has shape")


@pytest.mark.parametrize("names", [[], "theta_ins_rad", ["theta_ins_rad", "theta_ins_rad"],
                                   ["theta_ins_rad", "alpha"]])
def test_bad_input_names_are_refused(plain_file, names):
    _refused(plain_file, _arrays(plain_file, meta={"input_names": names}), "input_names")


@pytest.mark.parametrize("dt", [np.array(0.0), np.array(-0.02), np.array([0.02, 0.02])])
def test_non_positive_or_several_sample_times_are_refused(plain_file, dt):
    _refused(plain_file, _arrays(plain_file, dt_s=dt), "dt_s")


def test_reversed_rate_bounds_are_refused_in_an_lpv_design(plain_file):
    _refused(plain_file, _arrays(plain_file, rate_bounds_mps2=np.array([36.0, 5.0])),
             "rate_bounds_mps2")


def test_recorded_stability_must_match_the_spectral_radius(plain_file):
    """The fixture is stable at every point (radius < 1): recording one point unstable, or a
    stable record given as 0/1 integers with one 0, is refused."""
    _refused(plain_file, _arrays(plain_file, meta={"controller_stable": [True, False, True]}),
             "contradicting")
    _refused(plain_file, _arrays(plain_file, meta={"controller_stable": [1, 0, 1]}),
             "contradicting")


def test_spectral_radius_exactly_one_is_not_stable(plain_file):
    """A discrete pole on the unit circle (Ad = diag(1, 0.5) at one point) is not stable."""
    a = _arrays(plain_file)
    Ad = np.array(a["Ad"], copy=True)
    Ad[1] = np.diag([1.0, 0.5])
    _refused(plain_file, _arrays(plain_file, Ad=Ad), "contradicting")
    ok = _arrays(plain_file, Ad=Ad, meta={"controller_stable": [True, False, True]})
    assert validate_arrays(plain_file, ok).Ad[1, 0, 0] == 1.0


def test_spectral_radius_between_one_and_two_is_not_stable(plain_file):
    a = _arrays(plain_file)
    Ad = np.array(a["Ad"], copy=True)
    Ad[2] = np.diag([1.5, 0.5])
    _refused(plain_file, _arrays(plain_file, Ad=Ad), "contradicting")


# -------------------------------------------------------------------------- structured design
def _structured(path, **changes):
    nan = np.array(np.nan)
    base = dict(gamma=nan, gamma_min=nan, rate_bounds_mps2=np.array([np.nan, np.nan]))
    base.update(changes)
    return _arrays(path, **base, meta={"design": "structured"})


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
    _refused(plain_file, _arrays(plain_file, gamma=np.array(np.nan)), "gamma")


# ------------------------------------------------------------------------------- interpolation
@pytest.mark.parametrize("v, i, w", [(100.0, 0, 0.0), (250.0, 0, 0.5), (400.0, 1, 0.0),
                                     (650.0, 1, 0.5), (900.0, 1, 1.0), (50.0, 0, 0.0),
                                     (2000.0, 1, 1.0)])
@pytest.mark.parametrize("rate, s", [(0.0, 0.0), (9.0, 0.25), (36.0, 1.0), (72.0, 1.0),
                                     (-9.0, 0.0), (None, 1.0)])
def test_interpolation_by_hand_in_velocity_and_rate(rate_file, v, i, w, rate, s):
    t = validate_arrays(rate_file, _arrays(rate_file))
    got = t.interpolate(v, rate)
    got_cont = t.interpolate(v, rate, discrete=False)
    for k, name in enumerate(("Ad", "Bd", "Cd", "Dd")):
        for arr, out in ((getattr(t, name), got[k]), (getattr(t, name[0]), got_cont[k])):
            lo = (1 - s) * arr[i][0] + s * arr[i][1]
            hi = (1 - s) * arr[i + 1][0] + s * arr[i + 1][1]
            np.testing.assert_allclose(out, (1 - w) * lo + w * hi, rtol=1e-13, atol=1e-15)


def test_weights_without_rate_slices(plain_file):
    t = validate_arrays(plain_file, _arrays(plain_file))
    assert t.weights(400.0) == (1, 0.0, 0, 0.0)
    assert t.weights(100.0) == (0, 0.0, 0, 0.0)
    assert t.weights(900.0) == (1, 1.0, 0, 0.0)
    i, w, j, s = t.weights(650.0, 20.0)
    assert (i, w, j, s) == (1, 0.5, 0, 0.0)


def test_loaded_table_names_its_file(plain_file):
    from vega_gnc.controller_table import load_controller_table

    assert load_controller_table(plain_file).path == plain_file


def test_integer_rate_grid_is_read_as_float(rate_file):
    t = validate_arrays(rate_file, _arrays(rate_file, rate_grid_mps2=np.array([0, 36])))
    assert t.rate_grid_mps2.dtype == np.float64
    assert t.rate_grid_mps2.tolist() == [0.0, 36.0]


@pytest.mark.parametrize("A", [np.ones(3), np.ones((3, 2))])
def test_state_matrix_of_too_few_dimensions_is_refused(plain_file, A):
    _refused(plain_file, _arrays(plain_file, A=A), "'A' has shape")


def test_the_default_table_is_the_installed_copy_of_the_shipped_tvc_controller():
    """The installed file (ament share directory) against the repository's own copy, read
    byte for byte (the path is not formed the way default_table_path forms it)."""
    from pathlib import Path

    from vega_gnc.controller_table import default_table_path

    path = default_table_path()
    shipped = (Path(__file__).resolve().parents[2] / "ros2_ws" / "src" / "vega_gnc" / "config"
               / "tvc_controller.npz")
    assert path.name == "tvc_controller.npz"
    assert path.parent.name == "config" and "vega_gnc" in path.parts
    assert path.read_bytes() == shipped.read_bytes()
