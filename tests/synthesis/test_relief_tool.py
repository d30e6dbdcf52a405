"""tools/design/relief.py (issue 9 item 3): the window re-tuning with load relief writes a table
the flight loader takes, re-tunes only the grid times asked for, and leaves every other grid
point's controller as it was (relief off: k_a = 0, order 9 instead of 8).

A short budget (Nelder–Mead, 16 evaluations at one grid time): what is checked is the table
it writes, not the tuning's quality (docs/FLIGHT_DESIGN.md §7 measures that).
"""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from fixture_tables import STRUCTURED_2026_11_27

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = STRUCTURED_2026_11_27
sys.path.insert(0, str(ROOT / "tools/design"))


def _response(table, i, w):
    z = np.exp(1j * w * table.dt_s)
    Ad, Bd, Cd, Dd = table.Ad[i], table.Bd[i], table.Cd[i], table.Dd[i]
    return Cd @ np.linalg.solve(z * np.eye(Ad.shape[0]) - Ad, Bd) + Dd


@pytest.fixture(scope="module")
def relief_table(tmp_path_factory):
    import relief

    out = tmp_path_factory.mktemp("relief") / "r.npz"
    code = relief.main([str(SHIPPED), "--window", "38", "42", "--times", "40", "--local",
                        "--maxiter", "1", "--popsize", "1", "--out", str(out)])
    assert code == 0
    return out


def test_only_the_asked_grid_time_changes(relief_table):
    from vega_gnc.controller_table import load_controller_table

    from vega_design import structured as S

    new = json.loads(str(np.load(relief_table)["metadata"]))
    old = json.loads(str(np.load(SHIPPED)["metadata"]))
    assert new["grid_times_s"] == old["grid_times_s"]
    assert new["weights"]["parameters"][-2:] == [p[0] for p in S.RELIEF_PARAMETERS]
    record = new["solver"]["relief"][-1]
    assert record["window_s"] == [38.0, 42.0] and list(record["per_time"]) == ["40"]
    for t, x_new, x_old in zip(new["grid_times_s"], new["parameters_per_grid_time"],
                               old["parameters_per_grid_time"]):
        assert len(x_new) == 16
        if t != 40.0:
            assert x_new[:14] == x_old and x_new[14:] == list(S.RELIEF_OFF)
    a, b = load_controller_table(relief_table), load_controller_table(SHIPPED)
    assert a.n_states == 9 and b.n_states == 8
    np.testing.assert_array_equal(a.grid_v_mps, b.grid_v_mps)
    k40 = int(np.argmin(np.abs(a.grid_v_mps - _v(40.0))))
    for i in range(len(a.grid_v_mps)):
        if i == k40:
            continue
        for w in (0.1, 2.0, 30.0):
            # relief off: the same input-output map as the table without relief
            np.testing.assert_allclose(_response(a, i, w), _response(b, i, w), rtol=1e-8,
                                       atol=1e-14)


def _v(t_s):
    from vega_model.parameters import default_context

    return default_context().parameters(t_s).v_mps
