"""Requirement checks that mutation testing (``make mutation MODULE=requirements``) found
unchecked: every input series' length and shape refused by name, the strict pass rules at
the bound (drift, drift rate, deflection integral: "<" the bound; Qα objective: "≤"), the
deflection integrals by hand, and the fields of a result row.

Bounds are those of the shipped requirement file (docs/REQUIREMENTS.md): drift 500 m, drift
rate 15 m/s, deflection integral 4.3633 rad·s (250°·s).
"""

import math

import numpy as np
import pytest

from vega_sim.requirements import evaluate_requirements, load_requirements

SPEC = load_requirements()
T = np.array([0.0, 1.0, 2.0])
ZERO = np.zeros(3)
MACH = np.array([0.5, 0.6, 0.7])


def _eval(**over):
    args = dict(t_s=T, q_alpha_pa_rad=ZERO, mach=MACH, z_m=ZERO, z_dot_mps=ZERO,
                beta_t_s=T, beta_rad=ZERO)
    args.update(over)
    beta_cmd = args.pop("beta_cmd_rad", None)
    return evaluate_requirements(**args, beta_cmd_rad=beta_cmd, spec=SPEC)


@pytest.mark.parametrize("name", ["q_alpha_pa_rad", "mach", "z_m", "z_dot_mps"])
def test_a_truth_series_of_another_length_is_refused_by_name(name):
    with pytest.raises(ValueError, match=f"^{name} has 2 samples, expected 3$"):
        _eval(**{name: np.zeros(2)})


@pytest.mark.parametrize("name", ["beta_rad", "beta_cmd_rad"])
def test_a_nozzle_series_of_another_length_is_refused_by_name(name):
    with pytest.raises(ValueError, match=f"^{name} has 4 samples, expected 3$"):
        _eval(**{name: np.zeros(4)})


@pytest.mark.parametrize("name", ["t_s", "beta_t_s"])
def test_an_empty_time_base_is_refused_by_name(name):
    with pytest.raises(ValueError, match=f"^{name} must be a non-empty 1-D array$"):
        _eval(**{name: np.zeros(0)})


@pytest.mark.parametrize("key, series, bound", [("drift", "z_m", 500.0),
                                                ("drift_rate", "z_dot_mps", 15.0)])
def test_strict_bounds_fail_at_the_bound_and_pass_half_a_unit_inside(key, series, bound):
    at = _eval(**{series: np.array([0.0, -bound, 0.0])})[key]
    assert at.margin == 0.0 and not at.passed and at.time_s == 1.0
    inside = _eval(**{series: np.array([0.0, bound - 0.5, 0.0])})[key]
    assert inside.margin == pytest.approx(0.5) and inside.passed


def test_deflection_integral_by_hand_and_its_strict_bound():
    """|β| = 0.1, 0.3, 0.1 rad at 0, 1, 2 s: trapezoid ∫|β| dt = 0.2 + 0.2 = 0.4 rad·s; the
    signed ∫β_cmd for β_cmd = 0.1, −0.3, 0.1 is (0.1 − 0.3)/2 + (−0.3 + 0.1)/2 = −0.2 rad·s."""
    b = np.array([0.1, -0.3, 0.1])
    r = _eval(beta_rad=b, beta_cmd_rad=b)
    row = r["deflection_integral"]
    assert row.value == pytest.approx(0.4, abs=1e-15) and row.time_s == 2.0
    assert row.margin == pytest.approx(SPEC.deflection_integral_rad_s - 0.4) and row.passed
    assert r.command_peak_rad == 0.3
    assert r.command_signed_integral_rad_s == pytest.approx(-0.2, abs=1e-15)
    # exactly at the bound: a constant |β| over 1 s whose integral is the bound
    lim = SPEC.deflection_integral_rad_s
    tb = np.array([0.0, 1.0])
    at = _eval(beta_t_s=tb, beta_rad=np.array([lim, lim]))["deflection_integral"]
    assert at.value == lim and at.margin == 0.0 and not at.passed
    half = _eval(beta_t_s=tb, beta_rad=np.array([lim - 0.5, lim - 0.5]))["deflection_integral"]
    assert half.margin == pytest.approx(0.5) and half.passed


def test_one_nozzle_sample_has_zero_integrals():
    r = _eval(beta_t_s=np.array([3.0]), beta_rad=np.array([0.05]),
              beta_cmd_rad=np.array([-0.05]))
    assert r["deflection_integral"].value == 0.0
    assert r.command_signed_integral_rad_s == 0.0 and r.command_peak_rad == 0.05


def test_q_alpha_objective_is_met_at_the_objective():
    """The informational 3°·Q line passes with margin exactly 0 (≤ the objective)."""
    obj = SPEC.objective(MACH)
    r = _eval(q_alpha_pa_rad=obj.copy())
    (line,) = r.informational
    assert line.key == "q_alpha_objective" and line.margin == 0.0 and line.passed
    assert not line.gating and line.thesis is None


def test_result_rows_carry_their_description_and_unit():
    r = _eval()
    for row in r.results:
        assert row.requirement and row.metric and row.unit, row.key
        assert row.gating
    assert r["drift"].unit == "m" and r["drift_rate"].unit == "m/s"


def test_non_finite_value_has_minus_infinite_margin():
    r = _eval(z_m=np.array([0.0, math.nan, 0.0]))["drift"]
    assert r.margin == -math.inf and not r.passed and math.isnan(r.value)


def test_flip_is_computed_with_the_given_spec():
    assert SPEC.envelope_definition is not None
    assert _eval().q_alpha_flip is not None
