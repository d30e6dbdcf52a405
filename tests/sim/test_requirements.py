"""Requirement definitions (thesis Table 3.1) and the array-in metric computation."""

import math

import numpy as np
import pytest

from vega_sim.requirements import (default_requirements_path, envelope_from_trajectory,
                                   evaluate_requirements, load_requirements)

D = np.radians   # degrees → radians


@pytest.fixture(scope="module")
def spec():
    return load_requirements()


def test_shipped_bounds_in_si(spec):
    assert spec.drift_m == 500.0 and spec.drift_rate_mps == 15.0
    assert spec.deflection_rad == pytest.approx(D(6.5), rel=1e-15)
    assert spec.deflection_integral_rad_s == pytest.approx(D(250.0), rel=1e-15)
    thesis = {k: v.value for k, v in spec.thesis.items()}
    assert thesis == pytest.approx({"q_alpha": D(-14554.6), "drift": -0.5002,
                                    "drift_rate": 0.1221, "deflection": D(2.9281),
                                    "deflection_integral": D(0.4985)}, rel=1e-12)
    assert "command" in spec.thesis["deflection"].note
    assert "signed" in spec.thesis["deflection_integral"].note
    assert all(spec.sources[k].startswith("thesis Table 3.1") for k in spec.sources)


def test_envelope_is_three_degrees_times_q_along_the_trajectory(spec):
    """The shipped table is what the generator gives (rounded to 0.1 Pa·deg)."""
    assert spec.provenance["alpha_max_deg"] == 3.0
    regenerated = envelope_from_trajectory(spec.envelope_mach, D(3.0))
    assert np.max(np.abs(regenerated - spec.envelope_pa_rad)) <= D(0.05) + 1e-9
    assert spec.envelope_pa_rad[0] == 0.0 and spec.envelope_mach[0] == 0.0
    # max-Q ≈ 60.2 kPa → ≈ 180 600 Pa·deg near Mach 1.9
    assert np.max(spec.envelope_pa_rad) == pytest.approx(D(3.0) * 60.0e3, rel=0.01)


def test_envelope_interpolation(spec):
    m, e = spec.envelope_mach, spec.envelope_pa_rad
    assert spec.envelope(1.0) == pytest.approx(D(131333.8))
    assert spec.envelope(1.05) == pytest.approx(D(0.5 * (131333.8 + 143230.3)))
    assert spec.envelope(m[-1] + 1.0) == e[-1]          # end value held
    assert np.allclose(spec.envelope(m), e)


def _synthetic():
    t = np.arange(5.0)
    mach = np.array([0.1, 0.5, 1.0, 1.05, 3.0])
    q_alpha = D(np.array([0.0, 40_000.0, -131_000.0, -137_000.0, -5_000.0]))
    z = np.array([0.0, -3.0, 2.0, 1.0, 0.5])
    z_dot = np.array([0.1, -0.2, 14.9, 0.0, 0.0])
    beta = D(np.array([0.0, 1.0, -2.0, 0.0, 0.0]))
    return t, q_alpha, mach, z, z_dot, t, beta


def test_metrics_on_hand_computed_arrays(spec):
    t, qa, mach, z, zd, tb, beta = _synthetic()
    cmd = D(np.array([0.0, 1.0, -3.0, 0.0, 0.0]))
    report = evaluate_requirements(t, qa, mach, z, zd, tb, beta, beta_cmd_rad=cmd, spec=spec)
    assert report.passed
    q = report["q_alpha"]             # margins [2112.4, 6596.3, 333.8, 282.05, 127925.8] Pa·deg
    assert (q.time_s, q.value) == (3.0, qa[3])
    assert q.bound == pytest.approx(D(137282.05)) and q.margin == pytest.approx(D(282.05))
    z_row = report["drift"]
    assert (z_row.value, z_row.bound, z_row.margin, z_row.time_s) == (-3.0, 500.0, 497.0, 1.0)
    zd_row = report["drift_rate"]
    assert (zd_row.value, zd_row.time_s) == (14.9, 2.0)
    assert zd_row.margin == pytest.approx(0.1)
    b = report["deflection"]
    assert (b.value, b.time_s) == (D(-2.0), 2.0) and b.margin == pytest.approx(D(4.5))
    integral = report["deflection_integral"]    # trapezoid of |β|: 0.5 + 1.5 + 1 = 3 °s
    assert integral.value == pytest.approx(D(3.0)) and integral.time_s == 4.0
    assert integral.margin == pytest.approx(D(247.0))
    assert report.command_peak_rad == pytest.approx(D(3.0))
    assert report.command_signed_integral_rad_s == pytest.approx(D(-2.0))
    assert [r.display_unit for r in report.results] == ["Pa*deg", "m", "m/s", "deg", "deg*s"]
    text = report.table()
    for figure in ("-14554.6", "-0.5002", "0.1221", "2.9281", "0.4985", "-137000 Pa*deg",
                   "≤ 137282 Pa*deg", "< 6.5 deg", "max |β_cmd| = 3 deg"):
        assert figure in text, figure
    assert " NO " not in text


def test_violations_and_boundaries(spec):
    t, qa, mach, z, zd, tb, beta = _synthetic()
    qa_over = qa.copy()
    qa_over[3] = D(-137_300.0)                      # 17.95 Pa·deg over the envelope
    report = evaluate_requirements(t, qa_over, mach, z, zd, tb, beta, spec=spec)
    assert not report.passed and not report["q_alpha"].passed
    assert report["q_alpha"].margin == pytest.approx(D(-17.95))
    assert " NO " in report.table() and report.command_peak_rad is None
    # the envelope is 0 at M = 0, with zero load: not a violation (≤)
    zero = evaluate_requirements([0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0],
                                 [0.0, 1.0], [0.0, 0.0], spec=spec)
    assert zero.passed and zero["q_alpha"].margin == 0.0
    # the other bounds are strict (<)
    on_bound = z.copy()
    on_bound[4] = -500.0
    assert not evaluate_requirements(t, qa, mach, on_bound, zd, tb, beta,
                                     spec=spec)["drift"].passed
    beta_stop = beta.copy()
    beta_stop[1] = spec.deflection_rad
    assert not evaluate_requirements(t, qa, mach, z, zd, tb, beta_stop,
                                     spec=spec)["deflection"].passed
    big = np.full(5, D(70.0))                       # ∫ = 280 °s over 4 s
    row = evaluate_requirements(t, qa, mach, z, zd, tb, big, spec=spec)["deflection_integral"]
    assert not row.passed and row.margin == pytest.approx(D(-30.0))
    diverged = z.copy()
    diverged[2] = np.nan
    row = evaluate_requirements(t, qa, mach, diverged, zd, tb, beta, spec=spec)["drift"]
    assert not row.passed and math.isnan(row.value) and row.time_s == 2.0


def test_bad_arrays(spec):
    t, qa, mach, z, zd, tb, beta = _synthetic()
    with pytest.raises(ValueError, match="z_m has 4 samples, expected 5"):
        evaluate_requirements(t, qa, mach, z[:4], zd, tb, beta, spec=spec)
    with pytest.raises(ValueError, match="beta_t_s must be a non-empty 1-D array"):
        evaluate_requirements(t, qa, mach, z, zd, [], [], spec=spec)


@pytest.mark.parametrize("old, new, message", [
    ("schema_version: 1", "schema_version: 1\nextra: 2", "field 'extra': unknown key"),
    ("drift:\n  value: 500.0\n  unit: m", "drift:\n  value: 500.0\n  unit: deg",
     "field 'drift.unit'"),
    ("drift:\n  value: 500.0", "drift:\n  value: '500'", "field 'drift.value'"),
    ("drift:\n  value: 500.0", "drift:\n  value: -1.0", "field 'drift.value': must be > 0"),
    ("  unit: m/s\n  source: \"thesis Table 3.1 (lateral velocity",
     "  unit: m/s\n  limit: 3\n  source: \"thesis Table 3.1 (lateral velocity",
     "field 'drift_rate.limit': unknown key"),
    ("  mach: [0, 0.1, 0.2,", "  mach: [0, 0.2, 0.1,", "field 'q_alpha_envelope.mach'"),
    ("  mach: [0, 0.1, 0.2,", "  mach: [0, 0.1,", "mach and value differ in length"),
    ("  q_alpha:\n    value: -14554.6", "  q_alpha:\n    valu: -14554.6",
     "field 'thesis_table_5_1.q_alpha.valu': unknown key"),
    ("  drift_rate:\n    value: 0.1221", "  drift_rte:\n    value: 0.1221",
     "field 'thesis_table_5_1.drift_rte': unknown key"),
])
def test_config_errors_name_the_field(tmp_path, old, new, message):
    text = default_requirements_path().read_text()
    assert old in text, old
    path = tmp_path / "requirements.yaml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(ValueError) as info:
        load_requirements(path)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert str(info.value).startswith(str(path))


def test_missing_section(tmp_path):
    text = default_requirements_path().read_text()
    path = tmp_path / "r.yaml"
    path.write_text(text.replace("deflection_integral:\n", "deflection_integrals:\n", 1))
    with pytest.raises(ValueError, match="field 'deflection_integrals': unknown key"):
        load_requirements(path)
    with pytest.raises(ValueError, match="cannot read requirements"):
        load_requirements(tmp_path / "none.yaml")
