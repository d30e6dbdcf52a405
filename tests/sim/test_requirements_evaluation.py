"""Requirement evaluation (:func:`vega_sim.requirements.evaluate_requirements`) at its edges.

Every input series of the wrong length or shape is refused naming the series; the strict pass
rules hold at the bound (drift, drift rate, deflection integral: "<" the bound; the Qα
objective: "≤"); the deflection integrals are trapezoids worked out by hand (one nozzle sample:
0), including on sample times other than 1 s; the fields of a result row; a non-finite value
has margin −inf; the Qα sensitivity is computed with the spec given (and refuses arrays of the
wrong length by name).

Bounds are those of the shipped requirement file (docs/REQUIREMENTS.md, thesis Table 3.1):
drift 500 m, drift rate 15 m/s, deflection integral 4.3633 rad·s (250°·s).
"""

import math

import numpy as np
import pytest

from vega_sim.requirements import evaluate_requirements, load_requirements, q_alpha_flip

SPEC = load_requirements()
T = np.array([0.0, 1.0, 2.0])
ZERO = np.zeros(3)
MACH = np.array([0.5, 0.6, 0.7])
D = math.pi / 180.0


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
    line, allowable = r.informational
    assert line.key == "q_alpha_objective" and line.margin == 0.0 and line.passed
    assert allowable.key == "q_alpha_allowable" and allowable.passed
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


# ------------------------------------------------------------ sample times other than 1 s
def _series(n=5, dt=0.01):
    t = dt * np.arange(n)
    return t


def test_integrals_use_the_sample_times():
    """∫|β| dt and ∫β_cmd dt with dt = 0.01 s (hand trapezoids)."""
    t = _series()
    beta = np.array([1.0, -2.0, 3.0, -4.0, 5.0]) * D
    rep = evaluate_requirements(t, np.zeros(5), np.full(5, 1.0), np.zeros(5), np.zeros(5), t,
                                beta, beta_cmd_rad=beta)
    # |β|: 0.01·(1/2 + 2 + 3 + 4 + 5/2)° = 0.12 °s; signed: 0.01·(1/2 − 2 + 3 − 4 + 5/2) = 0
    assert rep["deflection_integral"].value == pytest.approx(0.12 * D, rel=1e-12)
    assert rep.command_signed_integral_rad_s == pytest.approx(0.0, abs=1e-15)
    rep2 = evaluate_requirements(t[:2], np.zeros(2), np.ones(2), np.zeros(2), np.zeros(2),
                                 t[:2], beta[:2], beta_cmd_rad=np.array([1.0, 3.0]) * D)
    assert rep2.command_signed_integral_rad_s == pytest.approx(0.02 * D, rel=1e-12)
    assert rep2["deflection_integral"].value == pytest.approx(0.015 * D, rel=1e-12)
    rep1 = evaluate_requirements(t[:1], np.zeros(1), np.ones(1), np.zeros(1), np.zeros(1),
                                 t[:1], beta[:1], beta_cmd_rad=beta[:1])
    assert rep1["deflection_integral"].value == 0.0 and rep1.command_signed_integral_rad_s == 0.0


def test_flip_array_length_errors_name_the_array():
    t = _series(3)
    with pytest.raises(ValueError, match=r"^t_s must be a non-empty 1-D array"):
        q_alpha_flip([], [], [])
    with pytest.raises(ValueError, match=r"^q_alpha_pa_rad has 2 samples, expected 3"):
        q_alpha_flip(t, [1.0, 2.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"^mach has 4 samples, expected 3"):
        q_alpha_flip(t, [1.0, 2.0, 3.0], [1.0, 1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"^q_alpha_pa_rad must be a non-empty 1-D array"):
        q_alpha_flip(t, [[1.0, 2.0, 3.0]], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"^mach must be a non-empty 1-D array"):
        q_alpha_flip(t, [1.0, 2.0, 3.0], [[1.0, 1.0, 1.0]])
