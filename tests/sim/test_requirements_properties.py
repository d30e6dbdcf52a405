"""Property tests (hypothesis) of the requirement checks on generated series.

For random time histories (finite, signs mixed, some beyond the bounds) the verdicts, margins
and binding samples of :func:`vega_sim.requirements.evaluate_requirements` must agree with a
per-sample recomputation written here from thesis Table 3.1 as the module docstring states it
(|Qα| ≤ envelope(Mach), |z| < 500 m, |ż| < 15 m/s, |β| < 6.5°, ∫|β|dt < 250 °s by the
trapezoid rule), and with the symmetries of the requirements: negating every series changes
no verdict or margin, shrinking a passing run keeps it passing.
"""

import math
import pytest

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from vega_sim.requirements import evaluate_requirements, load_requirements, q_alpha_flip

SETTINGS = settings(derandomize=True, deadline=None, max_examples=150)
D = math.pi / 180.0
SPEC = load_requirements()


def _envelope_by_hand(mach):
    """Linear interpolation of the shipped table, end values held (one sample at a time)."""
    xs, ys = SPEC.envelope_mach.tolist(), SPEC.envelope_pa_rad.tolist()
    if mach <= xs[0]:
        return ys[0]
    if mach >= xs[-1]:
        return ys[-1]
    for j in range(len(xs) - 1):
        if xs[j] <= mach <= xs[j + 1]:
            return ys[j] + (ys[j + 1] - ys[j]) * (mach - xs[j]) / (xs[j + 1] - xs[j])
    raise AssertionError("unreachable")


@st.composite
def runs(draw):
    n = draw(st.integers(2, 40))
    dt = draw(st.sampled_from([0.01, 0.02, 0.1]))
    t = 10.0 + dt * np.arange(n)
    fl = st.floats(-1.0, 1.0, allow_nan=False)
    scale = draw(st.sampled_from([0.2, 0.9, 1.3]))          # mostly inside, some beyond
    qa_frac = np.array(draw(st.lists(fl, min_size=n, max_size=n)))
    mach = np.array(draw(st.lists(st.floats(0.0, 7.0), min_size=n, max_size=n)))
    z = 500.0 * scale * np.array(draw(st.lists(fl, min_size=n, max_size=n)))
    zd = 15.0 * scale * np.array(draw(st.lists(fl, min_size=n, max_size=n)))
    beta = 6.5 * D * scale * np.array(draw(st.lists(fl, min_size=n, max_size=n)))
    env = np.array([_envelope_by_hand(m) for m in mach])
    qa = scale * qa_frac * env
    return t, qa, mach, z, zd, beta


def _report(r, sign=1.0):
    t, qa, mach, z, zd, beta = r
    return evaluate_requirements(t, sign * qa, mach, sign * z, sign * zd, t, sign * beta,
                                 spec=SPEC)


@pytest.mark.slow
@SETTINGS
@given(runs())
def test_verdicts_and_margins_equal_the_per_sample_recomputation(r):
    t, qa, mach, z, zd, beta = r
    rep = _report(r)
    # constant bounds: the binding sample is the largest magnitude
    for key, series, bound in (("drift", z, 500.0), ("drift_rate", zd, 15.0),
                               ("deflection", beta, 6.5 * D)):
        peak = max(abs(float(v)) for v in series)
        res = rep[key]
        assert abs(res.peak_value) == peak
        assert res.margin == bound - peak
        assert bound - abs(res.value) == bound - peak      # binding sample (ties: the first)
        assert res.passed == (peak < bound)
    # load: |Qα| ≤ envelope(Mach) at every sample (non-strict)
    margins = [_envelope_by_hand(m) - abs(q) for q, m in zip(qa.tolist(), mach.tolist())]
    worst = min(margins)
    assert math.isclose(rep["q_alpha"].margin, worst, rel_tol=1e-9, abs_tol=1e-6)
    if abs(worst) > 1e-6:
        assert rep["q_alpha"].passed == (worst >= 0.0)
    # ∫|β| dt by the trapezoid rule, sample by sample
    integral = sum(0.5 * (abs(beta[k]) + abs(beta[k + 1])) * (t[k + 1] - t[k])
                   for k in range(len(t) - 1))
    assert math.isclose(rep["deflection_integral"].value, integral, rel_tol=1e-12,
                        abs_tol=1e-15)
    assert rep["deflection_integral"].passed == (integral < 250.0 * D)
    # the verdict is the conjunction of the gating rows
    assert rep.passed == all(rep[k].passed for k in
                             ("q_alpha", "drift", "drift_rate", "deflection",
                              "deflection_integral"))


@pytest.mark.slow
@SETTINGS
@given(runs())
def test_negating_every_series_changes_no_verdict_or_margin(r):
    a, b = _report(r), _report(r, sign=-1.0)
    for ra, rb in zip(a.results, b.results):
        assert ra.key == rb.key and ra.passed == rb.passed and ra.margin == rb.margin
        assert ra.time_s == rb.time_s
    assert a.passed == b.passed


@pytest.mark.slow
@SETTINGS
@given(runs(), st.floats(0.0, 1.0))
def test_shrinking_a_passing_run_keeps_it_passing(r, c):
    t, qa, mach, z, zd, beta = r
    rep = _report(r)
    small = _report((t, c * qa, mach, c * z, c * zd, c * beta))
    for ra, rs in zip(rep.results, small.results):
        if ra.passed:
            assert rs.passed, ra.key
        assert rs.margin >= ra.margin - 1e-9 * max(1.0, abs(ra.bound))


@pytest.mark.slow
@SETTINGS
@given(runs())
def test_q_alpha_sensitivity_agrees_with_the_q_alpha_verdict(r):
    t, qa, mach, *_ = r
    rep = _report(r)
    flip = q_alpha_flip(t, qa, mach, spec=SPEC)
    if abs(rep["q_alpha"].margin) > 1e-6:
        assert flip.passed == rep["q_alpha"].passed
    if rep["q_alpha"].passed and abs(rep["q_alpha"].margin) > 1e-6:
        assert flip.mach_min_flip == SPEC.envelope_definition.mach_min


@pytest.mark.slow
@SETTINGS
@given(st.integers(1, 30), st.sampled_from(["nan", "inf", "-inf"]), st.data())
def test_a_non_finite_sample_fails_its_requirement(n, bad, data):
    t = np.arange(n) * 0.02
    z = np.zeros(n)
    k = data.draw(st.integers(0, n - 1))
    z[k] = float(bad)
    rep = evaluate_requirements(t, np.zeros(n), np.full(n, 1.0), z, np.zeros(n), t,
                                np.zeros(n), spec=SPEC)
    assert not rep["drift"].passed and not rep.passed
    assert rep["drift"].time_s == t[k] and rep["drift"].margin == -math.inf
