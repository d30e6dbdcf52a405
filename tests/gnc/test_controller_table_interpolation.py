"""Controller-table interpolation in velocity and in the rate slice, by hand.

:meth:`vega_gnc.controller_table.ControllerTable.interpolate` against element-wise formulas
written here from the raw arrays: ``(1 − w)·M[i] + w·M[i+1]`` between velocity grid points
with w = (v − v_i)/(v_i+1 − v_i), and ``(1 − s)·slice0 + s·slice1`` between the two ρ̇ slices
(0 and 36 m/s²), clamped at both ends of each grid (rate None: the upper slice); for the
discrete and the continuous matrices. The tables are small hand-made ones
(tests/gnc/gnc_table_files.py).
"""

import numpy as np
import pytest

from gnc_table_files import table_arrays, write_plain_table, write_rate_table
from vega_gnc.controller_table import validate_arrays


@pytest.fixture(scope="module")
def rate_file(tmp_path_factory):
    """A 2-state table on 3 velocities × 2 ρ̇ slices (0 and 36 m/s²), stable everywhere."""
    return write_rate_table(tmp_path_factory.mktemp("rate") / "r.npz")


@pytest.fixture(scope="module")
def plain_file(tmp_path_factory):
    """A 2-state table on 3 velocities without rate slices."""
    return write_plain_table(tmp_path_factory.mktemp("plain") / "p.npz")


@pytest.mark.parametrize("v, i, w", [(100.0, 0, 0.0), (250.0, 0, 0.5), (400.0, 1, 0.0),
                                     (650.0, 1, 0.5), (900.0, 1, 1.0), (50.0, 0, 0.0),
                                     (2000.0, 1, 1.0)])
@pytest.mark.parametrize("rate, s", [(0.0, 0.0), (9.0, 0.25), (36.0, 1.0), (72.0, 1.0),
                                     (-9.0, 0.0), (None, 1.0)])
def test_interpolation_by_hand_in_velocity_and_rate(rate_file, v, i, w, rate, s):
    t = validate_arrays(rate_file, table_arrays(rate_file))
    got = t.interpolate(v, rate)
    got_cont = t.interpolate(v, rate, discrete=False)
    for k, name in enumerate(("Ad", "Bd", "Cd", "Dd")):
        for arr, out in ((getattr(t, name), got[k]), (getattr(t, name[0]), got_cont[k])):
            lo = (1 - s) * arr[i][0] + s * arr[i][1]
            hi = (1 - s) * arr[i + 1][0] + s * arr[i + 1][1]
            np.testing.assert_allclose(out, (1 - w) * lo + w * hi, rtol=1e-13, atol=1e-15)


def test_weights_without_rate_slices(plain_file):
    t = validate_arrays(plain_file, table_arrays(plain_file))
    assert t.weights(400.0) == (1, 0.0, 0, 0.0)
    assert t.weights(100.0) == (0, 0.0, 0, 0.0)
    assert t.weights(900.0) == (1, 1.0, 0, 0.0)
    i, w, j, s = t.weights(650.0, 20.0)
    assert (i, w, j, s) == (1, 0.5, 0, 0.0)
