"""The requirement report's text (:class:`vega_sim.requirements.RequirementReport`).

Independent reference: the console table typed out by hand for hand-made results (columns as
wide as their widest cell, strict bounds printed "<", "≤" for Qα, the informational line
"info:", the notes with the thesis' definitions and the Qα sensitivity line), the sensitivity
text with and without samples, and the excess text of a non-finite value in display units
(rad shown in deg, Pa·rad in Pa·deg).
"""

import math

from vega_sim.requirements import QAlphaFlip, RequirementReport, RequirementResult, ThesisFigure

D = math.pi / 180.0


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
