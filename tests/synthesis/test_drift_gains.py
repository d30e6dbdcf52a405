"""The drift-gain schedule of `vega design` (offline_synthesis.structured.DRIFT_GAINS_PATH): the
tuning holds k_ż and k_z at it and tunes the twelve other parameters.

Why (docs/FLIGHT_DESIGN.md §4, "The drift gains"): the first from-scratch table passed 724 of
852 Monte Carlo flights; the same table with the drift gains of the table flown since
2026-11-27 passed 746 (paired, sample by sample: 1 lost, 1 won)."""

import json
import math

import numpy as np
import pytest
from vega_core.errors import BadFile
from vega_model.parameters import default_context
from vega_model.uncertainty import UncertaintySet

from offline_synthesis import structured as S
from fixture_tables import STRUCTURED_2026_11_27


@pytest.fixture(scope="module")
def context():
    return default_context()


def test_the_packaged_schedule_is_the_2026_11_27_table_with_step_6_divided_out():
    """One source of truth: the rows are that table's k_ż (÷ 2 where its tuning record says
    step 6 scaled it) and k_z at each of its grid times up to the tail-off hold, exactly."""
    rows = S.load_drift_gains()
    meta = json.loads(str(np.load(STRUCTURED_2026_11_27)["metadata"]))
    how = meta["solver"]["how"]
    expected = []
    for t, x in zip(meta["grid_times_s"], meta["parameters_per_grid_time"]):
        if t > S.TAIL_OFF_HOLD_S:
            break
        scaled = "(drift, step 6)" in how[f"{float(t):g}"]
        expected.append((float(t), x[2] / (2.0 if scaled else 1.0), x[3]))
    assert rows == tuple(expected)
    assert rows[0][0] == 0.5 and rows[-1][0] == S.TAIL_OFF_HOLD_S
    # spot values: 4 s (the seed1 run tuned k_z −186 µrad/m there), 70 s (step 6 undone)
    assert S.drift_gains_at(rows, 4.0) == pytest.approx((-0.428235, -40.46473), abs=1e-5)
    assert meta["parameters_per_grid_time"][meta["grid_times_s"].index(70.0)][2] == \
        pytest.approx(2.0 * S.drift_gains_at(rows, 70.0)[0], abs=1e-12)


def test_interpolation_in_time_held_beyond_the_ends():
    rows = ((1.0, -1.0, -10.0), (3.0, -3.0, 30.0))
    assert S.drift_gains_at(rows, 2.0) == (-2.0, 10.0)
    assert S.drift_gains_at(rows, 2.5) == (-2.5, 20.0)
    assert S.drift_gains_at(rows, 0.0) == (-1.0, -10.0)
    assert S.drift_gains_at(rows, 99.0) == (-3.0, 30.0)
    assert S.drift_gains_at(None, 2.0) is None
    x = np.arange(14.0)
    pinned = S.pin_drift(x, (-2.5, 20.0))
    assert pinned[2] == -2.5 and pinned[3] == 20.0
    assert np.array_equal(np.delete(pinned, [2, 3]), np.delete(x, [2, 3])) and x[2] == 2.0
    assert np.array_equal(S.pin_drift(x, None), x)


@pytest.mark.parametrize("text, message", [
    ("schema_version: 2\nrows: [[0.5, -1, -10]]\n", "schema_version 1 and a list of rows"),
    ("schema_version: 1\nrows: []\n", "schema_version 1 and a list of rows"),
    ("schema_version: 1\nrows: [[0.5, -1]]\n", "rows[0]: three finite numbers"),
    ("schema_version: 1\nrows: [[0.5, -1, .nan]]\n", "rows[0]: three finite numbers"),
    ("schema_version: 1\nrows: [[0.5, -1, -10], [0.5, -1, -10]]\n",
     "rows[1]: times must increase (0.5 after 0.5)"),
    ("schema_version: 1\nrows: [[0.5, -9, -10]]\n", "rows[0]: k_zdot -9 outside the search box"),
    ("schema_version: 1\nrows: [[0.5, -1, 300]]\n", "rows[0]: k_z 300 outside the search box"),
])
def test_a_bad_schedule_is_one_line_naming_the_file(tmp_path, text, message):
    path = tmp_path / "gains.yaml"
    path.write_text(text)
    with pytest.raises(BadFile) as err:
        S.load_drift_gains(path)
    assert message in str(err.value) and str(path) in str(err.value)
    assert "\n" not in str(err.value)


def test_tuning_holds_the_pinned_gains_and_tunes_the_rest(context):
    uset = UncertaintySet.from_vehicle(context.vehicle)
    ds = S.design_set(context, 40.0, uset)
    pin = (-0.7, -33.0)
    x0 = np.array(S.START_X)
    x, cost, detail = S.tune_point(ds, x0, seed=3, maxiter=1, popsize=2, polish_maxfev=30,
                                   pin=pin)
    assert (x[2], x[3]) == pin
    assert cost == S.evaluate(x, ds)
    assert np.any(np.delete(x, [2, 3]) != np.delete(x0, [2, 3]))    # the rest was searched
    free, _, _ = S.tune_point(ds, x0, seed=3, maxiter=1, popsize=2, polish_maxfev=30)
    assert (free[2], free[3]) != pin


def test_a_short_design_holds_the_schedule_at_every_grid_point(context):
    rows = ((40.0, -0.5, -20.0), (50.0, -1.5, -60.0))
    design = S.design_flight(context, anchors_s=(46.0, 50.0), grid_step_s=2.0, maxiter=1,
                             popsize=2, workers=0, polish_maxfev=20, progress=lambda _: None,
                             check_between=False, drift_gains=rows)
    np.testing.assert_allclose(design.grid_times_s, [46.0, 48.0, 50.0])
    for t, x in zip(design.grid_times_s, design.x):
        assert (x[2], x[3]) == S.drift_gains_at(rows, float(t))
    assert design.tuning["drift_gains"] == {"scheduled": True, "rows": 2}
    assert (design.x[1][2], design.x[1][3]) == (-1.3, -52.0)        # 48 s, interpolated


def test_the_tail_off_tuning_holds_the_pinned_gains(context):
    meta = json.loads(str(np.load(STRUCTURED_2026_11_27)["metadata"]))
    by = dict(zip(meta["grid_times_s"], meta["parameters_per_grid_time"]))
    x, cost, _ = S.tune_tail(context, by[86.0], maxiter=1, popsize=2, polish_maxfev=5,
                             times_s=(90.0,), pin=(-0.4, -47.0))
    assert (x[2], x[3]) == (-0.4, -47.0) and math.isfinite(cost)
