"""Controller-table export round trip, rejection of malformed files (one-line errors), and the
installed default table (the shipped file, byte for byte)."""

import json

import numpy as np
import pytest

from vega_loops.export import write_controller_table
from vega_gnc.controller_table import (ControllerTableError, load_controller_table,
                                       validate_arrays)

NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]
META = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
        "units": {"input": ["rad", "rad/s", "m", "m/s"], "output": "rad"},
        "weights": {"name": "test"}, "solver": {"name": "none"}}


def _controllers(n_grid=3, n=3, rates=False, seed=1):
    rng = np.random.default_rng(seed)
    lead = (n_grid, 2) if rates else (n_grid,)
    A = -np.eye(n) * 5.0 + 0.3 * rng.standard_normal(lead + (n, n))
    B = rng.standard_normal(lead + (n, 4))
    C = rng.standard_normal(lead + (1, n))
    D = rng.standard_normal(lead + (1, 4))
    return A, B, C, D


@pytest.fixture
def table_file(tmp_path):
    A, B, C, D = _controllers()
    path = tmp_path / "ctrl.npz"
    write_controller_table(path, [100.0, 500.0, 1000.0], A, B, C, D, dt_s=0.02, gamma=0.95,
                           gamma_min=0.8, rate_bounds_mps2=[5.4, 36.4], metadata=META)
    return path, (A, B, C, D)


def test_round_trip(table_file):
    path, (A, B, C, D) = table_file
    table = load_controller_table(path)
    assert np.array_equal(table.A, A) and np.array_equal(table.D, D)
    assert table.input_names == tuple(NAMES) and table.measurement_sign == -1
    assert table.dt_s == 0.02 and table.gamma == 0.95 and table.gamma_min == 0.8
    assert table.metadata["discretisation"]["method"] == "tustin"
    # Tustin: Ad = (I − A dt/2)⁻¹ (I + A dt/2)
    n = A.shape[-1]
    expected = np.linalg.solve(np.eye(n) - A[1] * 0.01, np.eye(n) + A[1] * 0.01)
    assert np.allclose(table.Ad[1], expected, rtol=1e-12, atol=1e-12)
    # DC gain is preserved by Tustin
    dc_c = D[2] - C[2] @ np.linalg.solve(A[2], B[2])
    dc_d = table.Dd[2] + table.Cd[2] @ np.linalg.solve(np.eye(n) - table.Ad[2], table.Bd[2])
    assert np.allclose(dc_c, dc_d, rtol=1e-10)


def test_interpolation_linear_in_velocity(table_file):
    path, (A, _, _, _) = table_file
    table = load_controller_table(path)
    Ac, *_ = table.interpolate(300.0, discrete=False)
    assert np.allclose(Ac, 0.5 * A[0] + 0.5 * A[1])
    assert np.allclose(table.interpolate(50.0, discrete=False)[0], A[0])   # clamped low
    assert np.allclose(table.interpolate(2e3, discrete=False)[0], A[2])    # clamped high


def test_rate_slices(tmp_path):
    A, B, C, D = _controllers(rates=True)
    path = tmp_path / "r.npz"
    table = write_controller_table(path, [1.0, 2.0, 3.0], A, B, C, D, dt_s=0.02, gamma=1.0,
                                   gamma_min=0.9, rate_bounds_mps2=[5.4, 36.4], metadata=META,
                                   rate_grid_mps2=[5.4, 36.4])
    mid = (5.4 + 36.4) / 2
    assert np.allclose(table.interpolate(1.0, mid, discrete=False)[0], 0.5 * (A[0, 0] + A[0, 1]))
    assert np.allclose(table.interpolate(1.0, None, discrete=False)[0], A[0, 1])


def _arrays(path):
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


@pytest.mark.parametrize("mutate, message", [
    (lambda a: a.pop("Bd"), "missing key 'Bd'"),
    (lambda a: a.update(format_version=np.array(99)), "format_version 99"),
    (lambda a: a.update(grid_v_mps=np.array([100.0, 90.0, 1000.0])), "strictly increasing"),
    (lambda a: a["A"].__setitem__((0, 0, 0), np.nan), "'A' has non-finite"),
    (lambda a: a.update(C=a["C"][:, :, :2]), "'C' has shape"),
    (lambda a: a.update(metadata=np.array("{not json")), "not a JSON string"),
    (lambda a: a.update(metadata=np.array(json.dumps({"input_names": NAMES}))),
     "metadata lacks"),
    (lambda a: a["Ad"].__setitem__((1, 0, 0), 3.0), "contradicting the recorded stability"),
])
def test_rejects_malformed(table_file, mutate, message):
    path, _ = table_file
    arrays = _arrays(path)
    arrays = {k: np.array(v) for k, v in arrays.items()}
    mutate(arrays)
    with pytest.raises(ControllerTableError) as err:
        validate_arrays(str(path), arrays)
    text = str(err.value)
    assert message in text and str(path) in text and "\n" not in text


def test_rejects_unreadable_files(tmp_path):
    missing = tmp_path / "absent.npz"
    with pytest.raises(ControllerTableError, match="no such file"):
        load_controller_table(missing)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"PK\x03\x04 this is not a zip archive")
    with pytest.raises(ControllerTableError, match="not a readable controller table"):
        load_controller_table(garbage)


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
