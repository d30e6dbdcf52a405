"""A structured table with the load-relief parameters (vega_design.structured:
RELIEF_PARAMETERS, write_structured_table; docs/FLIGHT_DESIGN.md §7) is one the flight loader
takes, and with the relief switched off at every grid point (RELIEF_OFF: k_a = 0) it is the
table without relief: the same grid, the same input-output map at every grid point, order 9
instead of 8.

The table without relief is a real structured table (the frozen copy in tests/data); its
parameters, extended by RELIEF_OFF, are written again through the design's own writer.
"""

import json

import numpy as np
import pytest

from fixture_tables import STRUCTURED_2026_11_27

WITHOUT = STRUCTURED_2026_11_27


def _response(table, i, w):
    z = np.exp(1j * w * table.dt_s)
    Ad, Bd, Cd, Dd = table.Ad[i], table.Bd[i], table.Cd[i], table.Dd[i]
    return Cd @ np.linalg.solve(z * np.eye(Ad.shape[0]) - Ad, Bd) + Dd


@pytest.fixture(scope="module")
def relief_off_table(tmp_path_factory):
    from vega_design import structured as S
    from vega_model.parameters import default_context

    context = default_context()
    meta = json.loads(str(np.load(WITHOUT)["metadata"]))
    times = [float(t) for t in meta["grid_times_s"]]
    xs = [S.with_relief(np.asarray(x, dtype=float), *S.RELIEF_OFF)
          for x in meta["parameters_per_grid_time"]]
    tuning = {k: v for k, v in meta.get("solver", {}).items() if k not in ("method", "scipy")}
    design = S.StructuredDesign(np.array(times),
                                np.array([context.parameters(t).v_mps for t in times]),
                                np.array(xs), [], tuple(meta["anchors_s"]), tuning)
    out = tmp_path_factory.mktemp("relief") / "relief_off.npz"
    S.write_structured_table(out, design, context)
    return out


def test_relief_parameters_are_recorded_and_switched_off(relief_off_table):
    from vega_design import structured as S

    new = json.loads(str(np.load(relief_off_table)["metadata"]))
    old = json.loads(str(np.load(WITHOUT)["metadata"]))
    assert new["grid_times_s"] == old["grid_times_s"]
    assert new["weights"]["parameters"][-2:] == [p[0] for p in S.RELIEF_PARAMETERS]
    assert "(load relief)" in new["structure"]
    for x_new, x_old in zip(new["parameters_per_grid_time"], old["parameters_per_grid_time"]):
        assert len(x_new) == 16
        assert x_new[:14] == x_old and x_new[14:] == list(S.RELIEF_OFF)


def test_relief_off_is_the_table_without_relief(relief_off_table):
    from vega_gnc.controller_table import load_controller_table

    a, b = load_controller_table(relief_off_table), load_controller_table(WITHOUT)
    assert a.n_states == 9 and b.n_states == 8
    np.testing.assert_array_equal(a.grid_v_mps, b.grid_v_mps)
    for i in range(len(a.grid_v_mps)):
        for w in (0.1, 2.0, 30.0):
            np.testing.assert_allclose(_response(a, i, w), _response(b, i, w), rtol=1e-8,
                                       atol=1e-14)
