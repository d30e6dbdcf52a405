"""The drift-gain schedule of `vega design` (vega_design.structured.DRIFT_GAINS_PATH): the
tuning holds k_ż and k_z at it and tunes the twelve other parameters; the schedule (schema 2) is
per unit k_θ (k_ż = g_ż·k_θ, k_z = g_z·k_θ at the k_θ the tuning tries).

Why (docs/FLIGHT_DESIGN.md §4, "The drift gains"): a from-scratch table with tuned drift gains
passed 724 of 852 Monte Carlo flights; the same table with the drift gains of the table kept as
tests/data/tvc_controller_2026-11-27.npz passed 746 (paired, sample by sample: 1 lost, 1 won).
Absolute gains with a softer k_θ command more attitude per unit drift: a from-scratch table
tuned with absolute gains lost weak-wind flights at 80–83 s that way."""

import json
import math

import numpy as np
import pytest
from vega_core.errors import BadFile
from vega_model.parameters import default_context
from vega_model.uncertainty import UncertaintySet

from vega_design import structured as S
from fixture_tables import STRUCTURED_2026_11_27


@pytest.fixture(scope="module")
def context():
    return default_context()


def test_the_packaged_schedule_is_the_2026_11_27_table_per_unit_k_theta_with_step_6_divided_out():
    """One source of truth: the rows are that table's k_ż (÷ 2 where its tuning record says
    step 6 scaled it) and k_z, each divided by its k_θ, at each of its grid times up to the
    tail-off hold, exactly."""
    sched = S.load_drift_gains()
    assert isinstance(sched, S.DriftSchedule) and sched.per_k_theta
    meta = json.loads(str(np.load(STRUCTURED_2026_11_27)["metadata"]))
    how = meta["solver"]["how"]
    expected = []
    for t, x in zip(meta["grid_times_s"], meta["parameters_per_grid_time"]):
        if t > S.TAIL_OFF_HOLD_S:
            break
        scaled = "(drift, step 6)" in how[f"{float(t):g}"]
        k = 10.0 ** x[0]
        expected.append((float(t), x[2] / (2.0 if scaled else 1.0) / k, x[3] / k))
    assert sched.rows == tuple(expected)
    assert sched.rows[0][0] == 0.5 and sched.rows[-1][0] == S.TAIL_OFF_HOLD_S
    # at that table's own k_θ the pin gives back its gains: 4 s (the seed1 run tuned k_z
    # −186 µrad/m there), 70 s (step 6 undone)
    by = dict(zip(meta["grid_times_s"], meta["parameters_per_grid_time"]))
    assert S.pin_drift(by[4.0], S.drift_gains_at(sched, 4.0))[2:4] == \
        pytest.approx((-0.428235, -40.46473), abs=1e-5)
    assert by[70.0][2] == pytest.approx(
        2.0 * S.pin_drift(by[70.0], S.drift_gains_at(sched, 70.0))[2], abs=1e-12)


def test_interpolation_in_time_held_beyond_the_ends():
    rows = ((1.0, -1.0, -10.0), (3.0, -3.0, 30.0))
    assert S.drift_gains_at(rows, 2.0) == (-2.0, 10.0)
    assert S.drift_gains_at(rows, 2.5) == (-2.5, 20.0)
    assert S.drift_gains_at(rows, 0.0) == (-1.0, -10.0)
    assert S.drift_gains_at(rows, 99.0) == (-3.0, 30.0)
    assert S.drift_gains_at(None, 2.0) is None
    assert S.drift_gains_at(S.DriftSchedule(rows, per_k_theta=False), 2.5) == (-2.5, 20.0)
    assert S.drift_gains_at(S.DriftSchedule(rows), 2.5) == (-2.5, 20.0, True)
    x = np.arange(14.0)
    pinned = S.pin_drift(x, (-2.5, 20.0))
    assert pinned[2] == -2.5 and pinned[3] == 20.0
    assert np.array_equal(np.delete(pinned, [2, 3]), np.delete(x, [2, 3])) and x[2] == 2.0
    assert np.array_equal(S.pin_drift(x, None), x)


def test_gains_per_unit_k_theta_follow_k_theta_and_stay_in_their_box():
    x = np.array(S.START_X, dtype=float)
    x[0] = math.log10(0.4)
    pinned = S.pin_drift(x, (-2.0, -100.0, True))
    assert pinned[2] == pytest.approx(-0.8) and pinned[3] == pytest.approx(-40.0)
    x[0] = math.log10(0.2)                            # half the stiffness, half the gains
    assert S.pin_drift(x, (-2.0, -100.0, True))[2:4] == pytest.approx((-0.4, -20.0))
    assert np.array_equal(np.delete(S.pin_drift(x, (-2.0, -100.0, True)), [2, 3]),
                          np.delete(x, [2, 3]))
    x[0] = math.log10(4.0)                            # −400 µrad/m: clipped to the box
    assert S.pin_drift(x, (-2.0, -100.0, True))[2:4] == pytest.approx((-5.0, -200.0))


@pytest.mark.parametrize("text, message", [
    ("schema_version: 3\nrows: [[0.5, -1, -10]]\n", "schema_version 1 or 2 and a list of rows"),
    ("schema_version: 1\nrows: []\n", "schema_version 1 or 2 and a list of rows"),
    ("schema_version: 1\nrows: [[0.5, -1]]\n", "rows[0]: three finite numbers"),
    ("schema_version: 1\nrows: [[0.5, -1, .nan]]\n", "rows[0]: three finite numbers"),
    ("schema_version: 1\nrows: [[0.5, -1, -10], [0.5, -1, -10]]\n",
     "rows[1]: times must increase (0.5 after 0.5)"),
    ("schema_version: 1\nrows: [[0.5, -9, -10]]\n", "rows[0]: k_zdot -9 outside the search box"),
    ("schema_version: 1\nrows: [[0.5, -1, 300]]\n", "rows[0]: k_z 300 outside the search box"),
    ("schema_version: 2\nrows: [[0.5, -1, 2001]]\n", "rows[0]: g_z 2001 beyond 10× the search box"),
    ("schema_version: 2\nrows: [[0.5, -1]]\n", "rows[0]: three finite numbers [t_s, g_zdot, g_z]"),
])
def test_a_bad_schedule_is_one_line_naming_the_file(tmp_path, text, message):
    path = tmp_path / "gains.yaml"
    path.write_text(text)
    with pytest.raises(BadFile) as err:
        S.load_drift_gains(path)
    assert message in str(err.value) and str(path) in str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.slow
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
    # per unit k_θ: every candidate's drift gains are set from its own k_θ, so the result's
    # are g·k_θ at the k_θ it found (searched: not the start's)
    rel, cost, _ = S.tune_point(ds, x0, seed=3, maxiter=1, popsize=2, polish_maxfev=30,
                                pin=(-0.7, -33.0, True))
    assert rel[0] != x0[0]
    assert (rel[2], rel[3]) == pytest.approx((-0.7 * 10.0 ** rel[0], -33.0 * 10.0 ** rel[0]),
                                             rel=1e-12)
    assert cost == S.evaluate(rel, ds)


@pytest.mark.slow
def test_a_short_design_holds_the_schedule_at_every_grid_point(context):
    rows = ((40.0, -0.5, -20.0), (50.0, -1.5, -60.0))
    design = S.design_flight(context, anchors_s=(46.0, 50.0), grid_step_s=2.0, maxiter=1,
                             popsize=2, workers=0, polish_maxfev=20, progress=lambda _: None,
                             check_between=False, drift_gains=rows)
    np.testing.assert_allclose(design.grid_times_s, [46.0, 48.0, 50.0])
    for t, x in zip(design.grid_times_s, design.x):
        assert (x[2], x[3]) == S.drift_gains_at(rows, float(t))
    assert design.tuning["drift_gains"] == {"scheduled": True, "rows": 2, "per_k_theta": False}
    assert (design.x[1][2], design.x[1][3]) == (-1.3, -52.0)        # 48 s, interpolated


@pytest.mark.slow
def test_a_short_design_holds_the_schedule_per_unit_k_theta(context):
    sched = S.DriftSchedule(((40.0, -0.5, -20.0), (50.0, -1.5, -60.0)))
    design = S.design_flight(context, anchors_s=(46.0, 50.0), grid_step_s=2.0, maxiter=1,
                             popsize=2, workers=0, polish_maxfev=20, progress=lambda _: None,
                             check_between=False, drift_gains=sched)
    assert design.tuning["drift_gains"] == {"scheduled": True, "rows": 2, "per_k_theta": True}
    for t, x in zip(design.grid_times_s, design.x):
        g = S.drift_gains_at(sched, float(t))
        assert (x[2], x[3]) == pytest.approx((g[0] * 10.0 ** x[0], g[1] * 10.0 ** x[0]),
                                             rel=1e-12)
    assert len({round(float(x[0]), 12) for x in design.x}) > 1       # k_θ differs per point


@pytest.mark.slow
def test_the_tail_off_tuning_holds_the_pinned_gains(context):
    meta = json.loads(str(np.load(STRUCTURED_2026_11_27)["metadata"]))
    by = dict(zip(meta["grid_times_s"], meta["parameters_per_grid_time"]))
    x, cost, _ = S.tune_tail(context, by[86.0], maxiter=1, popsize=2, polish_maxfev=5,
                             times_s=(90.0,), pin=(-0.4, -47.0))
    assert (x[2], x[3]) == (-0.4, -47.0) and math.isfinite(cost)
    x, cost, _ = S.tune_tail(context, by[86.0], maxiter=1, popsize=2, polish_maxfev=5,
                             times_s=(90.0,), pin=(-2.4, -276.0, True))
    assert (x[2], x[3]) == pytest.approx((-2.4 * 10.0 ** x[0], -276.0 * 10.0 ** x[0]),
                                         rel=1e-12) and math.isfinite(cost)
