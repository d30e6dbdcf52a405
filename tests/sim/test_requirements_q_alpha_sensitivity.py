"""The Qα sensitivity (:func:`vega_sim.requirements.q_alpha_flip`) on hand envelopes.

What envelope parameters a run meets: the smallest α_allow of α_allow·Q_nom(M) above the Mach
threshold M₀, the largest |Qα| below it (the floor it needs), α_allow with the floor tied to
α_allow·Q_nom(M₀), and the lowest Mach threshold that still passes
(docs/REQUIREMENTS.md §4). Independent reference: three-point envelope tables (Mach 0 / 1 / 2,
values in Pa·deg, α_max 4°, M₀ = 1) written into a temporary copy of the shipped requirement
file, on which every expected value is worked out by hand, zero envelopes and ratios of
exactly 1 included.
"""

import copy
import math
import warnings

import numpy as np
import pytest
import yaml

from vega_sim.requirements import default_requirements_path, load_requirements, q_alpha_flip

D = math.pi / 180.0


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
