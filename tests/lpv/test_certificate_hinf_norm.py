"""certificate.hinf_norm against H∞ norms worked out by hand (no second numerical method).

References, all closed forms of |G(jω)| maximised over ω (any control text, e.g. Skogestad &
Postlethwaite, *Multivariable Feedback Control*, 2nd ed., §2.4 and §4.10):

* k/(s + a), a > 0: the peak is at ω = 0, |k|/a.
* ω_n²/(s² + 2ζω_n s + ω_n²): the resonance peak 1/(2ζ√(1 − ζ²)) at ω_n√(1 − 2ζ²) for
  ζ < 1/√2; for ζ ≥ 1/√2 |G| decreases monotonically from 1 at ω = 0.
* a diagonal (decoupled) system: its largest singular value at each ω is the largest channel
  magnitude, so the norm is the largest of the channels' norms (not their sum).
* G + D with a constant D: 1/(s + 1) + 2 peaks at ω = 0 (3); 1/(s + 1) − 2 = −(2s + 1)/(s + 1)
  has |G(jω)|² = (4ω² + 1)/(ω² + 1) = 4 − 3/(1 + ω²), rising to |D| = 2 as ω → ∞.
* no states (G = D): the largest singular value of D, here by the 2 × 2 eigenvalue formula.
* A not Hurwitz (an eigenvalue with real part ≥ 0, also exactly 0 and on the imaginary axis,
  also when the mode is hidden from the input/output): the H∞ norm does not exist → inf, even
  where the L∞ norm (what SLICOT ab13dd computes) is finite: 1/(s − 0.5) has L∞ norm 2.

The function uses a relative tolerance of 1e-10; the comparisons here are at 1e-9 relative.
"""

import math
from fractions import Fraction

import numpy as np
import pytest

from vega_lpv.certificate import hinf_norm

REL = 1e-9


def _second_order(zeta, omega_n=3.0, gain=1.0):
    """gain·ω_n²/(s² + 2ζω_n s + ω_n²) in controllable canonical form (ω_n in rad/s)."""
    A = [[0.0, 1.0], [-omega_n ** 2, -2.0 * zeta * omega_n]]
    B = [[0.0], [gain * omega_n ** 2]]
    C = [[1.0, 0.0]]
    return A, B, C, [[0.0]]


def _resonance_peak(zeta):
    return 1.0 / (2.0 * zeta * math.sqrt(1.0 - zeta ** 2)) if zeta < 1.0 / math.sqrt(2.0) else 1.0


@pytest.mark.parametrize(("a", "b", "c", "expected"), [
    (2.0, 1.0, 1.0, 0.5),          # 1/(s + 2)
    (2.0, 3.0, 1.5, 2.25),         # 4.5/(s + 2)
    (0.25, -1.0, 2.0, 8.0),        # −2/(s + 0.25): the magnitude, not the sign
])
def test_first_order_lag_peaks_at_zero_frequency(a, b, c, expected):
    norm = hinf_norm([[-a]], [[b]], [[c]], [[0.0]])
    assert type(norm) is float
    assert norm == pytest.approx(expected, rel=REL)


@pytest.mark.parametrize("zeta", [0.05, 0.3, 0.6, 0.7, 0.72, 0.8, 1.5])
def test_second_order_resonance_peak(zeta):
    """ζ = 0.7 is just below 1/√2 (peak 1.000200, a 2e-4 bump that a loose tolerance misses),
    0.72 just above (no peak: 1 at ω = 0); 0.05 is a sharp resonance (peak 10.0125)."""
    norm = hinf_norm(*_second_order(zeta))
    assert norm == pytest.approx(_resonance_peak(zeta), rel=REL)


def test_diagonal_mimo_system_takes_the_largest_channel():
    """diag(1/(s + 2), 3·ω_n²/(s² + 2·0.1·ω_n s + ω_n²)): channel norms 0.5 and 3·5.0252."""
    A2, B2, C2, _ = _second_order(0.1, omega_n=5.0, gain=3.0)
    A = np.zeros((3, 3))
    A[0, 0] = -2.0
    A[1:, 1:] = A2
    B = np.zeros((3, 2))
    B[0, 0] = 1.0
    B[1:, 1:] = B2
    C = np.zeros((2, 3))
    C[0, 0] = 1.0
    C[1:, 1:] = C2
    expected = 3.0 * _resonance_peak(0.1)
    assert hinf_norm(A, B, C, np.zeros((2, 2))) == pytest.approx(expected, rel=REL)
    # the first channel alone, through the same state-space arrays
    assert hinf_norm(A, B[:, :1], C[:1], np.zeros((1, 1))) == pytest.approx(0.5, rel=REL)


@pytest.mark.parametrize(("d", "expected"), [
    (2.0, 3.0),     # 1/(s + 1) + 2: 3 at ω = 0
    (-2.0, 2.0),    # 1/(s + 1) − 2: |G(jω)|² = 4 − 3/(1 + ω²) → 4 as ω → ∞
])
def test_feedthrough_enters_the_norm(d, expected):
    assert hinf_norm([[-1.0]], [[1.0]], [[1.0]], [[d]]) == pytest.approx(expected, rel=REL)


def test_slow_stable_pole_is_not_taken_for_unstable():
    """1/(s + 1e-6): stable, however slow; the norm is the DC gain 1e6."""
    assert hinf_norm([[-1e-6]], [[1.0]], [[1.0]], [[0.0]]) == pytest.approx(1e6, rel=REL)


def test_system_without_states_is_the_largest_singular_value_of_d():
    """D = [[1, 2], [3, 4]]: DᵀD has trace 30 and determinant 4, so σ_max² = 15 + √221."""
    D = [[1.0, 2.0], [3.0, 4.0]]
    norm = hinf_norm(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0)), D)
    assert norm == pytest.approx(math.sqrt(15.0 + math.sqrt(221.0)), rel=REL)


@pytest.mark.parametrize(("A", "B", "C"), [
    ([[0.5]], [[1.0]], [[1.0]]),                            # 1/(s − 0.5): L∞ norm 2, H∞ none
    ([[1e-12]], [[1.0]], [[1.0]]),                          # barely unstable: L∞ norm 1e12
    ([[0.0]], [[1.0]], [[1.0]]),                            # integrator: eigenvalue exactly 0
    ([[0.0, 1.0], [-1.0, 0.0]], [[0.0], [1.0]], [[1.0, 0.0]]),   # undamped: eigenvalues ±j
    (np.diag([0.0, -1.0]), [[0.0], [1.0]], [[0.0, 1.0]]),   # hidden mode at 0; 1/(s + 1) seen
    (np.diag([3.0, -1.0]), [[0.0], [1.0]], [[0.0, 1.0]]),   # hidden unstable mode
])
def test_a_not_hurwitz_gives_infinity(A, B, C):
    norm = hinf_norm(A, B, C, [[0.0]])
    assert type(norm) is float and math.isinf(norm) and norm > 0


def test_exact_rational_entries_are_converted_to_float():
    """A from an exact (symbolic or rational) derivation: Fraction entries are numbers too."""
    A = [[Fraction(-2), Fraction(0)], [Fraction(0), Fraction(-1, 2)]]
    B = [[1.0], [1.0]]
    C = [[1.0, 0.0]]       # 1/(s + 2) is seen; 1/(s + 1/2) is not observed
    assert hinf_norm(A, B, C, [[0.0]]) == pytest.approx(0.5, rel=REL)
    assert math.isinf(hinf_norm([[Fraction(1, 3)]], [[1.0]], [[1.0]], [[0.0]]))


@pytest.mark.parametrize("where", ["A", "B", "C", "D"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_non_finite_matrices_are_refused_at_once(where, bad):
    """SLICOT's ab13dd never returns on NaN input (seen with B or C set to NaN): refused."""
    m = {"A": [[-1.0]], "B": [[1.0]], "C": [[1.0]], "D": [[0.0]]}
    m[where] = [[bad]]
    with pytest.raises(ValueError, match=f"hinf_norm: {where} is not finite"):
        hinf_norm(m["A"], m["B"], m["C"], m["D"])


def test_rational_entries_in_every_matrix_are_numbers():
    """B, C and D from an exact derivation too (the finiteness check reads them as floats):
    k/(s + a) + d with k = 3/2, a = 1/2, d = 1/4 → |k|/a + d = 3.25 (peak at ω = 0)."""
    got = hinf_norm([[Fraction(-1, 2)]], [[Fraction(3, 2)]], [[Fraction(1)]], [[Fraction(1, 4)]])
    assert got == pytest.approx(3.25, rel=1e-9)
