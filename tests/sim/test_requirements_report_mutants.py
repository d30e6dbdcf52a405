"""Requirement report text, Qα sensitivity and envelope generation: tests written for the
survivors of `make mutation MODULE=requirements`.

Independent references: the report table typed out by hand for hand-made results; hand
envelopes (three-point Mach tables in a temporary requirement file) on which the flip values
are worked out by hand; a synthetic flight-condition table with Q linear in Mach, whose
envelope α·Q(M) is exactly linear (so its table needs no interior breakpoint).
"""

import copy
import math
import warnings

import numpy as np
import pytest
import yaml

from vega_model.flight_conditions import COLUMNS, FlightConditions
from vega_sim.requirements import (QAlphaFlip, RequirementReport, RequirementResult,
                                   ThesisFigure, default_requirements_path,
                                   envelope_from_trajectory, envelope_table, load_requirements,
                                   q_alpha_flip)

D = math.pi / 180.0


# ---------------------------------------------------------------------------- report text

def _results():
    r1 = RequirementResult(
        key="q_alpha", requirement="Load", metric="Qα", value=-1000.0 * D, bound=2000.0 * D,
        margin=1000.0 * D, passed=True, time_s=1.5, unit="Pa*rad", display_unit="Pa*deg",
        display_scale=1 / D, thesis=ThesisFigure(-1500.0 * D, "signed extreme"),
        peak_value=-1200.0 * D, peak_time_s=2.25, peak_bound=3000.0 * D)
    r2 = RequirementResult(
        key="drift", requirement="Lateral", metric="z", value=600.0, bound=500.0,
        margin=-100.0, passed=False, time_s=10.0, unit="m", display_unit="m",
        display_scale=1.0, thesis=None, peak_value=600.0, peak_time_s=10.0, peak_bound=500.0)
    r3 = RequirementResult(
        key="q_alpha_objective", requirement="Objective", metric="Qα", value=1000.0 * D,
        bound=500.0 * D, margin=-500.0 * D, passed=False, time_s=1.5, unit="Pa*rad",
        display_unit="Pa*deg", display_scale=1 / D, thesis=None, gating=False)
    return r1, r2, r3


def _flip(**over):
    kw = dict(alpha_max_rad=4 * D, mach_min=0.31, floor_pa_rad=100 * D, alpha_flip_rad=2 * D,
              alpha_flip_time_s=1.5, alpha_flip_mach=0.5, floor_flip_pa_rad=50 * D,
              floor_flip_time_s=0.25, alpha_flip_tied_rad=2.5 * D, mach_min_flip=0.31)
    kw.update(over)
    return QAlphaFlip(**kw)


FLIP_TEXT = ("Qα sensitivity: this run meets α_allow·Q_nom(M) with α_allow ≥ 2° (binding at "
             "1.500 s, M 0.500) and floor ≥ 50 Pa*deg (max |Qα| below M 0.31, at 0.250 s); "
             "with the floor tied to α_allow·Q_nom(0.31): α_allow ≥ 2.5°; at α_allow = 4° with "
             "the tied floor: Mach threshold ≥ 0.310 (file: 4°, M 0.31, floor 100 Pa*deg)")

TABLE = """\
requirement  metric  value         bound          margin       at [s]  max |value|             pass      thesis Table 5.1
Load         Qα      -1000 Pa*deg  ≤ 2000 Pa*deg  1000 Pa*deg  1.500   1200 Pa*deg at 2.250 s  yes       -1500 Pa*deg
Lateral      z       600 m         < 500 m        -100 m       10.000  600 m at 10.000 s       NO
Objective    Qα      1000 Pa*deg   ≤ 500 Pa*deg   -500 Pa*deg  1.500                           info: no
notes:
  Qα: thesis signed extreme
  Qα (Objective): informational, never gates the verdict
  """ + FLIP_TEXT + """
  with the thesis' definitions (command, signed integral): max |β_cmd| = 3 deg, ∫β_cmd dt = -0.5 deg*s"""  # noqa: E501


def test_report_table_typed_out_by_hand():
    r1, r2, r3 = _results()
    rep = RequirementReport((r1, r2), command_peak_rad=3 * D,
                            command_signed_integral_rad_s=-0.5 * D, informational=(r3,),
                            q_alpha_flip=_flip())
    assert rep.table() == TABLE
    assert not rep.passed


def test_report_table_without_notes():
    _, r2, _ = _results()
    assert RequirementReport((r2,)).table() == (
        "requirement  metric  value  bound    margin  at [s]  max |value|        pass  "
        "thesis Table 5.1\n"
        "Lateral      z       600 m  < 500 m  -100 m  10.000  600 m at 10.000 s  NO")


def test_flip_text_with_and_without_samples():
    assert _flip().text() == FLIP_TEXT
    empty = _flip(alpha_flip_rad=0.0, alpha_flip_time_s=math.nan, alpha_flip_mach=math.nan,
                  floor_flip_pa_rad=0.0, floor_flip_time_s=math.nan, alpha_flip_tied_rad=0.0,
                  mach_min_flip=math.nan)
    assert empty.text() == (
        "Qα sensitivity: this run meets α_allow·Q_nom(M) with any α_allow (no sample) and any "
        "floor (no sample below M 0.31); with the floor tied to α_allow·Q_nom(0.31): "
        "α_allow ≥ 0°; at α_allow = 4° with the tied floor: no Mach threshold (file: 4°, "
        "M 0.31, floor 100 Pa*deg)")


def test_excess_text_of_a_non_finite_value_gives_the_bound_in_display_units():
    r = RequirementResult(
        key="deflection", requirement="Actuation", metric="β", value=math.nan,
        bound=6.5 * D, margin=-math.inf, passed=False, time_s=1.0, unit="rad",
        display_unit="deg", display_scale=1 / D, thesis=None)
    assert r.excess_text() == "is nan (bound 6.5 deg)"


# ------------------------------------------------------------------- Qα sensitivity (flip)

@pytest.fixture(scope="module")
def raw():
    with open(default_requirements_path()) as f:
        return yaml.safe_load(f)


def _spec(tmp_path, raw, values_pa_deg, mach_min, name):
    """A requirement file with envelope table Mach [0, 1, 2] → values [Pa·deg], α_max 4°."""
    tree = copy.deepcopy(raw)
    env = tree["q_alpha_envelope"]
    env["mach"], env["value"] = [0.0, 1.0, 2.0], list(values_pa_deg)
    env["definition"] = {"alpha_max_deg": 4.0, "mach_min": mach_min,
                         "floor_pa_deg": values_pa_deg[0]}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return load_requirements(path)


def _flip_of(spec, mach, qa_pa_deg):
    mach = np.asarray(mach, dtype=float)
    return q_alpha_flip(np.arange(mach.size) * 0.5, np.asarray(qa_pa_deg) * D, mach, spec=spec)


def test_sample_at_mach_min_counts_above(tmp_path, raw):
    """Envelope 100 / 100 / 300 Pa·deg at M 0 / 1 / 2, M₀ = 1: a sample at M = 1 with
    |Qα| = 150 Pa·deg needs α ≥ 4°·150/100 = 6°; no sample is below M₀."""
    spec = _spec(tmp_path, raw, [100.0, 100.0, 300.0], 1.0, "e1")
    f = _flip_of(spec, [1.0, 2.0], [150.0, 0.0])
    assert f.alpha_flip_rad == pytest.approx(6.0 * D, rel=1e-12)
    assert f.floor_flip_pa_rad == 0.0 and math.isnan(f.floor_flip_time_s)
    assert f.alpha_flip_tied_rad == pytest.approx(6.0 * D, rel=1e-12)


def test_zero_q_alpha_needs_no_allowance_and_one_is_a_number(tmp_path, raw):
    spec = _spec(tmp_path, raw, [100.0, 100.0, 300.0], 1.0, "e1")
    f = _flip_of(spec, [1.5, 2.0], [0.0, 0.0])
    assert f.alpha_flip_rad == 0.0 and f.floor_flip_pa_rad == 0.0
    # |Qα| = 1.0 Pa·rad exactly at M 2 (envelope 300 Pa·deg): α = 4°·(180/π)/300
    f1 = q_alpha_flip([0.0], [1.0], [2.0], spec=spec)
    assert f1.alpha_flip_rad == pytest.approx(4.0 * D * (1.0 / D) / 300.0, rel=1e-12)


def test_largest_sample_below_mach_min_is_the_floor_flip(tmp_path, raw):
    spec = _spec(tmp_path, raw, [100.0, 100.0, 300.0], 1.0, "e1")
    f = _flip_of(spec, [0.2, 0.5, 0.7, 2.0], [10.0, 50.0, 20.0, 0.0])
    assert f.floor_flip_pa_rad == pytest.approx(50.0 * D, rel=1e-12)
    assert f.floor_flip_time_s == 0.5
    # tied: 4° · 50 / 100
    assert f.alpha_flip_tied_rad == pytest.approx(2.0 * D, rel=1e-12)


def test_small_floor_flip_still_ties(tmp_path, raw):
    """|Qα| = 0.5 Pa·rad below M₀ (≈ 28.6 Pa·deg): tied α = 4°·28.65/100 = 1.146°."""
    spec = _spec(tmp_path, raw, [100.0, 100.0, 300.0], 1.0, "e1")
    f = q_alpha_flip([0.0, 1.0], [0.5, 0.0], [0.5, 2.0], spec=spec)
    assert f.floor_flip_pa_rad == 0.5
    assert f.alpha_flip_tied_rad == pytest.approx(4.0 * D * 0.5 / (100.0 * D), rel=1e-12)


def test_zero_envelope_at_mach_min(tmp_path, raw):
    """Envelope 0 / 0 / 300 Pa·deg, M₀ = 1: a load below M₀ can never be tied (α = ∞); with
    none below, the tied α is the plain one; no division warnings."""
    spec = _spec(tmp_path, raw, [0.0, 0.0, 300.0], 1.0, "e0")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f = _flip_of(spec, [1.0, 2.0], [0.0, 150.0])
        assert f.alpha_flip_rad == pytest.approx(2.0 * D, rel=1e-12)
        assert f.alpha_flip_tied_rad == pytest.approx(2.0 * D, rel=1e-12)
        g = _flip_of(spec, [0.5, 2.0], [10.0, 150.0])
        assert g.alpha_flip_tied_rad == math.inf
        h = _flip_of(spec, [1.0, 2.0], [5.0, 0.0])      # load where the envelope is 0
        assert h.alpha_flip_rad == math.inf


def test_small_envelope_at_mach_min_gives_a_finite_tied_value(tmp_path, raw):
    """Envelope 20 Pa·deg (0.35 Pa·rad) at M₀ = 1; |Qα| = 10 Pa·deg below: tied α = 2°."""
    spec = _spec(tmp_path, raw, [20.0, 20.0, 300.0], 1.0, "e20")
    f = _flip_of(spec, [0.5, 2.0], [10.0, 0.0])
    assert f.alpha_flip_tied_rad == pytest.approx(2.0 * D, rel=1e-12)


@pytest.mark.parametrize("values, mach, qa, expected", [
    # envelope 100/100/300, M₀ 1. Ratio exactly 1 at M 2 and a floor load at half: passes → M₀
    ([100.0, 100.0, 300.0], [0.5, 2.0], [50.0, 300.0], 1.0),
    # floor load exactly at the floor: passes → M₀
    ([100.0, 100.0, 300.0], [0.5, 2.0], [100.0, 100.0], 1.0),
    # floor load 150 > 100: threshold at the M 2 sample (ratio exactly 1 there is allowed)
    ([100.0, 100.0, 300.0], [0.5, 2.0], [150.0, 300.0], 2.0),
    # floor load exactly the table value at M 2 (300): allowed → 2
    ([100.0, 100.0, 300.0], [0.5, 2.0], [300.0, 0.0], 2.0),
    # M 2 sample above its envelope: no threshold
    ([100.0, 100.0, 300.0], [0.5, 2.0], [150.0, 400.0], math.nan),
    # envelope 50/100/300: a floor load of 80 fails the floor (50) but is within table(M₀)
    # = 100, so the threshold is the sample at M₀ itself
    ([50.0, 100.0, 300.0], [0.5, 1.0, 2.0], [80.0, 0.0, 0.0], 1.0),
    # envelope 200/150/200: the sample at M₀ itself (200 > 150) is above M₀ and fails, so
    # the threshold moves to M 2 (below it: max 200 ≤ table(2) = 200)
    ([200.0, 150.0, 200.0], [1.0, 2.0, 0.5], [200.0, 150.0, 100.0], 2.0),
])
def test_mach_threshold_hand_cases(tmp_path, raw, values, mach, qa, expected):
    spec = _spec(tmp_path, raw, values, 1.0, "e")
    got = _flip_of(spec, mach, qa).mach_min_flip
    if math.isnan(expected):
        assert math.isnan(got)
    else:
        assert got == expected


# --------------------------------------------------------------- envelope from trajectory

def _conditions(t, mach, q):
    data = np.ones((len(t), len(COLUMNS)))
    data[:, COLUMNS.index("t_s")] = t
    data[:, COLUMNS.index("mach")] = mach
    data[:, COLUMNS.index("q_pa")] = q
    return FlightConditions("synthetic", COLUMNS, data, {})


def test_trajectory_q_uses_the_given_table_running_maximum_and_t_max():
    """Mach 0, 0.5, 1, 1, 0.8 at t 0..4 (Q 0, 100, 400, 300, 200 Pa): Q_nom(M) keeps the
    samples where Mach reaches a new maximum (t 0, 1, 2): Q_nom(1) = 400, Q_nom(0.75) = 250."""
    fc = _conditions([0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 0.5, 1.0, 1.0, 0.8],
                     [0.0, 100.0, 400.0, 300.0, 200.0])
    env = envelope_from_trajectory([0.25, 0.75, 1.0, 3.0], 2.0, fc)
    np.testing.assert_allclose(env, [100.0, 500.0, 800.0, 800.0], rtol=1e-12)
    # t_max_s = 2 includes the sample at t = 2 exactly; t_max_s = 1 stops at M 0.5
    assert envelope_from_trajectory(1.0, 2.0, fc, t_max_s=2.0) == pytest.approx(800.0)
    assert envelope_from_trajectory(1.0, 2.0, fc, t_max_s=1.0) == pytest.approx(200.0)
    # the first two samples decide the first segment
    fc2 = _conditions([0.0, 1.0, 2.0], [0.2, 0.4, 0.3], [10.0, 30.0, 0.0])
    np.testing.assert_allclose(envelope_from_trajectory([0.2, 0.3, 0.4], 1.0, fc2),
                               [10.0, 20.0, 30.0], rtol=1e-12)


def _linear_fc():
    """Q = 1000·M Pa at M 0 … 2 up to t = 100 s, and M 2.5 (Q 2500) at t = 100.5 s."""
    t = [0.0, 25.0, 50.0, 75.0, 100.0, 100.5]
    mach = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]
    return _conditions(t, mach, [1000.0 * m for m in mach])


def test_envelope_defaults_stop_at_100_s_and_have_no_floor():
    fc = _linear_fc()
    a = 4.0 * D
    assert envelope_from_trajectory(2.5, a, fc) == pytest.approx(a * 2000.0, rel=1e-12)
    assert envelope_from_trajectory(0.5, a, fc) == pytest.approx(a * 500.0, rel=1e-12)
    assert envelope_from_trajectory(0.25, a, fc, t_max_s=101.0) == pytest.approx(a * 250.0)


def test_envelope_floor_below_mach_min_only():
    fc = _linear_fc()
    a = 4.0 * D
    env = envelope_from_trajectory([0.1, 0.5, 0.5 - 1e-9, 1.0], a, fc, mach_min=0.5,
                                   floor_pa_rad=7.0)
    np.testing.assert_allclose(env, [7.0, a * 500.0, 7.0, a * 1000.0], rtol=1e-12)
    # default floor: the envelope's value at mach_min
    assert envelope_from_trajectory(0.1, a, fc, mach_min=0.5) == pytest.approx(a * 500.0)


def test_envelope_table_of_a_linear_envelope_has_no_interior_breakpoint():
    """α·Q(M) is linear in M: the greedy table is its two end points (values rounded to
    0.1 Pa·deg): 0 and 4°·2000 Pa = 8000 Pa·deg at M 2 (t ≤ 100 s)."""
    fc = _linear_fc()
    mach, values = envelope_table(4.0 * D, fc)
    np.testing.assert_allclose(mach, [0.0, 2.0])
    np.testing.assert_allclose(np.degrees(values), [0.0, 8000.0], rtol=1e-12)
    # with mach_min 0.5: [0, 0.5, 2] at 2000, 2000, 8000 Pa·deg
    mach, values = envelope_table(4.0 * D, fc, mach_min=0.5)
    np.testing.assert_allclose(mach, [0.0, 0.5, 2.0])
    np.testing.assert_allclose(np.degrees(values), [2000.0, 2000.0, 8000.0], rtol=1e-12)


def test_envelope_table_values_are_rounded_to_a_tenth_of_a_pa_deg():
    """Q = 1000·M + 0.123 Pa: 4°·Q(0) = 0.492 Pa·deg → 0.5; at M 2: 8000.492 → 8000.5."""
    t = [0.0, 50.0, 100.0]
    mach = [0.0, 1.0, 2.0]
    fc = _conditions(t, mach, [1000.0 * m + 0.123 for m in mach])
    m, values = envelope_table(4.0 * D, fc)
    np.testing.assert_allclose(m, [0.0, 2.0])
    np.testing.assert_allclose(np.degrees(values), [0.5, 8000.5], rtol=1e-12)


def test_envelope_table_ends_at_the_first_step_multiple_at_or_above_the_top_mach():
    """Top Mach 1.9996 (second-to-last 1.5): the table ends at 2.000."""
    t = [0.0, 50.0, 75.0, 100.0]
    mach = [0.0, 1.0, 1.5, 1.9996]
    fc = _conditions(t, mach, [1000.0 * m for m in mach])
    m, _ = envelope_table(4.0 * D, fc)
    assert m[0] == 0.0 and m[-1] == pytest.approx(2.0, abs=1e-12)


def test_envelope_table_honours_t_max():
    """t_max_s = 101 s takes the M 2.5 sample (t = 100.5 s) of the linear table: [0, 2.5] at
    0 and 4°·2500 Pa = 10000 Pa·deg."""
    mach, values = envelope_table(4.0 * D, _linear_fc(), t_max_s=101.0)
    np.testing.assert_allclose(mach, [0.0, 2.5])
    np.testing.assert_allclose(np.degrees(values), [0.0, 10000.0], rtol=1e-12)
