"""Step 7 of the structured design (vega_design.corner_repair): the single-parameter
repairs of the bending criterion at the dispersed corners.

The real case: the shipped table records its hand edits (``solver.edits``); with the one at
43 s undone (notch1_zeta_num 0.035 back to 0.0482) the flown controller misses the exact
bending criterion at corners 536 and 568 at 43 s (in-band GM 5.86–5.90 dB, docs/
FLIGHT_DESIGN.md §4), which step 7 must find and repair, on real frozen loops.
"""

import json

import numpy as np
import pytest
from vega_model.parameters import default_context

from vega_design import corner_repair as R
from vega_design import structured as S
from vega_loops.margins import REQUIREMENTS, bending_ok
from fixture_tables import STRUCTURED_2026_11_27

TABLE = STRUCTURED_2026_11_27     # the 43 s hand edit is in its tuning record
CORNERS = (0, 536, 568)        # nominal; f1 -20 %, mode-1 shapes +30 %, thrust, actuator +10 %


def _row(peak, gm, pm, unstable=0, mode2=(-30.0, np.inf, np.inf)):
    return {"t_s": 43.0, "corner": 7, "n_unstable": unstable,
            "b1_peak_db": peak, "b1_gm_db": gm, "b1_pm_deg": pm,
            "b2_peak_db": mode2[0], "b2_gm_db": mode2[1], "b2_pm_deg": mode2[2]}


@pytest.mark.parametrize("peak, gm, pm, slack", [
    (-8.0, np.inf, np.inf, 2.0),        # gain-stabilised, 2 dB below −6 dB
    (-6.0, 1.0, 0.0, 0.0),              # on the gain boundary
    (0.0, 7.0, 40.0, 1.0),              # phase-stabilised: min(7 − 6, (40 − 30)/5)
    (0.0, 9.0, 35.0, 1.0),              # ... the phase side decides: (35 − 30)/5
    (-3.0, 5.9, 60.0, -0.1),            # misses: GM 0.1 dB short, gain side −3 dB
    (0.0, 8.0, 29.0, -0.2),             # misses: PM 1° short = −0.2 dB-equivalent
])
def test_bending_slack_hand_values_and_the_verdict(peak, gm, pm, slack):
    row = _row(peak, gm, pm)
    assert R.bending_slack(row, 1) == pytest.approx(slack, abs=1e-12)
    assert bending_ok(row, 1) == (slack >= 0.0)


def test_row_misses_names_each_failed_criterion():
    assert R.row_misses(_row(-8.0, np.inf, np.inf)) == set()
    assert R.row_misses(_row(0.0, 5.0, 40.0)) == {(43.0, 7, "bending_1")}
    assert R.row_misses(_row(-8.0, np.inf, np.inf, unstable=1, mode2=(0.0, 3.0, 40.0))) == {
        (43.0, 7, "stable"), (43.0, 7, "bending_2")}


def test_candidate_edits_stay_in_the_box_and_move_one_parameter():
    names = [p[0] for p in S.PARAMETERS]
    x = np.array(S.START_X, dtype=float)
    x[names.index("notch1_zeta_num")] = 0.05
    new = R.candidate(x, ("notch1_zeta_num", "scale", 0.7, 1))
    assert new[names.index("notch1_zeta_num")] == pytest.approx(0.035)
    assert np.count_nonzero(new != x) == 1
    new = R.candidate(x, ("log10_lp1_radps", "add", -0.03, 1))
    assert new[names.index("log10_lp1_radps")] == pytest.approx(x[names.index(
        "log10_lp1_radps")] - 0.03)
    x[names.index("notch1_zeta_num")] = 3e-6                     # the 34.5 s point's ζ_num
    assert R.candidate(x, ("notch1_zeta_num", "scale", 0.7, 1)) is None
    x[names.index("notch1_ratio")] = S.UPPER[names.index("notch1_ratio")] - 0.01
    assert R.candidate(x, ("notch1_ratio", "add", +0.02, 1)) is None
    assert R.candidate(x, ("notch1_ratio", "add", -0.02, 1)) is not None


def test_interval_times_are_the_half_second_grid_flown_between_two_points():
    assert R.interval_times(42.5, 43.0) == [43.0]
    assert R.interval_times(40.0, 42.0) == [40.5, 41.0, 41.5, 42.0]
    assert R.interval_times(0.5, 2.0, first=True) == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert R.interval_times(42.5, 43.0, first=True) == [42.5, 43.0]   # a slice: no pad time
    assert R.interval_times(45.75, 45.875) == []


def _done_before_43_edit():
    """Grid points 42.5, 43, 44 s of the shipped table, the 43 s hand edit undone from the
    tuning record."""
    meta = json.loads(str(np.load(TABLE)["metadata"]))
    (edit,) = [e for e in meta["solver"]["edits"] if e["t_s"] == 43.0]
    assert (edit["parameter"], edit["to"]) == ("notch1_zeta_num", 0.035)
    done = {float(t): (np.array(x, dtype=float), None, "given")
            for t, x in zip(meta["grid_times_s"], meta["parameters_per_grid_time"])
            if 42.5 <= t <= 44.0}
    i = [p[0] for p in S.PARAMETERS].index("notch1_zeta_num")
    assert done[43.0][0][i] == 0.035
    done[43.0][0][i] = edit["from"]
    return done, i, edit


@pytest.fixture(scope="module")
def context():
    return default_context()


@pytest.mark.slow
def test_the_undone_43s_edit_is_found_and_repaired(context):
    done, i, edit = _done_before_43_edit()
    rows = R.check_intervals(context, done, CORNERS, workers=0)
    misses = set().union(*(R.row_misses(r) for rs in rows.values() for r in rs))
    # the verification's finding (FLIGHT_DESIGN §4): mode 1 at the two corners, at 43 s
    assert misses == {(43.0, 536, "bending_1"), (43.0, 568, "bending_1")}
    new, record = R.repair_corner_bending(context, done, corner_ids=CORNERS, workers=0,
                                          rows=rows)
    assert record["misses_before"] == 2 and record["misses_after"] == 0
    assert record["left"] == []
    (made,) = record["edits"]
    assert made["t_s"] == 43.0 and made["parameter"] in {e[0] for e in R.EDITS if e[3] == 1}
    changed = [t for t in done if not np.array_equal(new[t][0], done[t][0])]
    assert changed == [43.0]
    assert np.count_nonzero(new[43.0][0] != done[43.0][0]) == 1
    # independent re-check of the repaired point: the two corners now meet the criterion
    pair = S._pair_table(context, (42.5, new[42.5][0]), (43.0, new[43.0][0]))
    rows_after = R._analyse(context, pair, [43.0],
                            [(c, R.dispersed_corners(_uset(context))[c]) for c in CORNERS])
    for row in rows_after:
        assert bending_ok(row, 1) and bending_ok(row, 2) and row["n_unstable"] == 0
    # the design set of the point keeps every requirement it met (no miss added)
    ds = S.design_set(context, 43.0, _uset(context))
    before = S.requirement_misses(S.evaluate(done[43.0][0], ds, detail=True)[1])
    after = S.requirement_misses(S.evaluate(new[43.0][0], ds, detail=True)[1])
    assert all(a <= b for a, b in zip(after, before))
    assert new[43.0][1]["pm_deg"] >= REQUIREMENTS["pm_deg"]


def _uset(context):
    from vega_model.uncertainty import UncertaintySet

    return UncertaintySet.from_vehicle(context.vehicle)


@pytest.mark.slow
def test_no_edit_when_no_candidate_acts_on_the_missed_mode(context, monkeypatch):
    """Mode-1 misses and only mode-2 edits to try: nothing changes, the misses are reported."""
    done, _, _ = _done_before_43_edit()
    monkeypatch.setattr(R, "EDITS", tuple(e for e in R.EDITS if e[3] == 2))
    new, record = R.repair_corner_bending(context, done, corner_ids=CORNERS, workers=0)
    assert record["edits"] == [] and record["misses_after"] == 2
    assert all(np.array_equal(new[t][0], done[t][0]) for t in done)


@pytest.mark.slow
def test_the_worst_case_check_refuses_an_edit_that_loses_it(context, monkeypatch):
    """A worst-case check that passes for the unedited tables only: every repair refused (the
    first-notch edits only, one round: the refusal path, not the search, is under test)."""
    monkeypatch.setattr(R, "EDITS", tuple(e for e in R.EDITS if e[0] == "notch1_zeta_num"))
    monkeypatch.setattr(R, "MAX_ROUNDS", 1)
    done, _, _ = _done_before_43_edit()
    original = {t: S._pair_table(context, (a, done[a][0]), (t, done[t][0]))
                for a, t in ((42.5, 43.0), (43.0, 44.0))}

    def only_unedited(table, _context, _t):
        return any(np.array_equal(table.Ad, o.Ad) for o in original.values())

    new, record = R.repair_corner_bending(context, done, corner_ids=CORNERS, workers=0,
                                          worst_case=only_unedited)
    assert record["edits"] == [] and record["misses_after"] == 2
    assert record["worst_case_checked"] is True


def test_units_hold_the_tail_off_together():
    assert R.units_of([44.0, 42.5, 43.0, 86.0, 90.0, 88.0], 86.0) == [
        (42.5,), (43.0,), (44.0,), (86.0, 88.0, 90.0)]
    assert R.units_of([42.5, 43.0], np.inf) == [(42.5,), (43.0,)]
    # no grid point at the hold time itself: the points after it are the hold
    assert R.units_of([84.0, 87.0, 90.0], 86.0) == [(84.0,), (87.0, 90.0)]


@pytest.mark.slow
def test_the_tail_off_hold_is_edited_as_one(context):
    """Misses flown by the held tail-off controller (here: the hold from 43 s, the 44 s point
    holding the 43 s parameters) are repaired by one edit of every point of the hold; a point
    before the hold cannot act on a miss at the hold time itself and is not touched."""
    done, _, _ = _done_before_43_edit()
    held = {42.5: done[42.5], 43.0: done[43.0], 44.0: (done[43.0][0].copy(), None, "held")}
    new, record = R.repair_corner_bending(context, held, corner_ids=CORNERS, until_s=43.0,
                                          workers=0)
    assert record["misses_before"] >= 2           # 536 and 568 at 43 s at least
    assert record["misses_after"] == 0 and record["left"] == []
    (made,) = record["edits"]
    assert made["t_s"] == 43.0 and made["held_s"] == [43.0, 44.0]
    assert np.array_equal(new[42.5][0], held[42.5][0])
    assert np.array_equal(new[43.0][0], new[44.0][0])       # still one held controller
    assert np.count_nonzero(new[43.0][0] != held[43.0][0]) == 1
    assert "corner repair, step 7" in new[44.0][2]
    # independent re-check on both intervals flown with the hold: every loop meets the criterion
    uset = _uset(context)
    for (a, b), times in (((42.5, 43.0), [43.0]), ((43.0, 44.0), [43.5, 44.0])):
        pair = S._pair_table(context, (a, new[a][0]), (b, new[b][0]))
        rows = R._analyse(context, pair, times,
                          [(c, R.dispersed_corners(uset)[c]) for c in CORNERS])
        for row in rows:
            assert bending_ok(row, 1) and bending_ok(row, 2) and row["n_unstable"] == 0
