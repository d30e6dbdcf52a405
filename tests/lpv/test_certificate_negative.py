"""The closed-loop stability certificate (``certificate.certificate_check``) must REJECT what is
not a proof, and the controller table's recorded stability must be recomputed, not trusted.

``certificate_check`` builds, at each (ρ, ρ̇), P_cl = [[Y, −Q], [−Q, Q]] with Q = Y − γ⁻²X⁻¹
(balanced plant coordinates x = T x_s, w = d w_s) and returns max(λ_max(BRL), λ_max(−P_cl)):
negative = certified. Here the "synthesis result" is a small object following what the
function reads (scaling T, T⁻¹, d; γ; X(ρ), Y(ρ) and their ρ-derivatives; controller), built
from a Lyapunov matrix chosen by the test:

* the closed loop is formed by the textbook LFT formula (D22 = 0), not ``closed_loop``;
* the Lyapunov matrix P of the closed loop comes from scipy's Lyapunov solver; the controller
  realisation is changed (x_K = M z_K, M = −P22⁻¹P12ᵀ) so that P has the structure
  [[Y, −Q], [−Q, Q]] the certificate assumes, which gives X and Y;
* the reference value of the certificate is recomputed here from these matrices, with Ṗ by
  central finite differences of P(ρ) (not the closed-form Q̇ of the code), eigenvalues by
  numpy; the verdicts also follow from theory (no P certifies an unstable closed loop; an
  indefinite P is no certificate even when the Lyapunov inequality holds for it).
"""

import json
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.linalg import solve_continuous_lyapunov

from vega_lpv.certificate import certificate_check
from vega_lpv.gridded_plant import PlantPoint

GAMMA = 0.5
T_BAL = np.array([[2.0, 0.3], [-0.4, 0.5]])       # x = T x_s (non-trivial balancing)
D_BAL = 0.7                                       # w = d w_s, e_s = e / d


# ----------------------------------------------------------------------------- construction
def _plant(a00=-0.5, A=None):
    """n = 2, one disturbance, one control, one performance output, one measurement."""
    if A is None:
        A = np.array([[a00, 1.0], [0.8, 0.3]])      # open loop unstable (det < 0)
    B1 = np.array([[0.05], [0.02]])
    B2 = np.array([[0.0], [1.0]])
    C1 = np.array([[0.04, -0.03]])
    C2 = np.array([[1.0, 0.2]])
    D11, D12, D21 = np.array([[0.01]]), np.array([[0.02]]), np.array([[0.03]])
    return SimpleNamespace(A=A, B1=B1, B2=B2, C1=C1, C2=C2, D11=D11, D12=D12, D21=D21)


def _point(pl):
    return PlantPoint(pl.A, np.hstack([pl.B1, pl.B2]), np.vstack([pl.C1, pl.C2]),
                      np.block([[pl.D11, pl.D12], [pl.D21, np.zeros((1, 1))]]),
                      n_w=1, n_u=1, n_e=1, n_y=1)


def _lft(pl, K):
    """Textbook lower LFT with D22 = 0: u = C_K x_K + D_K y, ẋ_K = A_K x_K + B_K y."""
    AK, BK, CK, DK = K
    A = np.block([[pl.A + pl.B2 @ DK @ pl.C2, pl.B2 @ CK], [BK @ pl.C2, AK]])
    B = np.vstack([pl.B1 + pl.B2 @ DK @ pl.D21, BK @ pl.D21])
    C = np.hstack([pl.C1 + pl.D12 @ DK @ pl.C2, pl.D12 @ CK])
    D = pl.D11 + pl.D12 @ DK @ pl.D21
    return A, B, C, D


STABILISING = (np.array([[-3.0, 0.5], [0.2, -4.0]]), np.array([[1.0], [-0.5]]),
               np.array([[-0.6, 0.4]]), np.array([[-3.0]]))


def _S():
    return np.block([[T_BAL, np.zeros((2, 2))], [np.zeros((2, 2)), np.eye(2)]])


def _structured(K, P_orig):
    """Controller realisation and (X, Y) such that the certificate's P_cl equals the given
    closed-loop Lyapunov matrix P (original coordinates), moved to (x_s, z_K)."""
    S = _S()
    Ps = S.T @ P_orig @ S
    P12, P22 = Ps[:2, 2:], Ps[2:, 2:]
    M = -np.linalg.solve(P22, P12.T)               # x_K = M z_K makes the (1,2) block −Q
    Ms = np.block([[np.eye(2), np.zeros((2, 2))], [np.zeros((2, 2)), M]])
    Pn = Ms.T @ Ps @ Ms
    Y, Q = Pn[:2, :2], Pn[2:, 2:]
    assert np.allclose(Pn[:2, 2:], -Q, atol=1e-10) and np.allclose(Q, Q.T, atol=1e-10)
    X = np.linalg.inv(Y - Q) / GAMMA ** 2          # Y − Q = γ⁻² X⁻¹
    AK, BK, CK, DK = K
    Minv = np.linalg.inv(M)
    return (Minv @ AK @ M, Minv @ BK, CK @ M, DK), X, Y


class FakeResult:
    """What certificate_check reads from a synthesis result."""

    def __init__(self, K, X0, Y0, rho0=1.0, X1=None, Y1=None):
        self.K, self.X0, self.Y0, self.rho0 = K, X0, Y0, rho0
        self.X1 = np.zeros_like(X0) if X1 is None else X1
        self.Y1 = np.zeros_like(Y0) if Y1 is None else Y1
        self.gamma = GAMMA
        self.sizes = (1, 1, 1, 1)
        self.scaling = SimpleNamespace(T=T_BAL, T_inv=np.linalg.inv(T_BAL), d=D_BAL)
        self.calls = []

    def X(self, rho):
        return self.X0 + (rho - self.rho0) * self.X1

    def Y(self, rho):
        return self.Y0 + (rho - self.rho0) * self.Y1

    def dX_drho(self, rho):
        return self.X1

    def dY_drho(self, rho):
        return self.Y1

    def controller(self, rho, rho_dot, plant_point=None, rate_term=None):
        self.calls.append((rho, rho_dot))
        return self.K


def _reference(pl, result, rho, rho_dot, h=1e-6):
    """Independent recomputation of the certificate value at (ρ, ρ̇): max(λ_max(BRL), λ_max(−P))
    in the balanced coordinates, Ṗ by central differences."""
    def P_of(r):
        X, Y = result.X(r), result.Y(r)
        Q = Y - np.linalg.inv(X) / result.gamma ** 2
        return np.block([[Y, -Q], [-Q, Q]])

    P = P_of(rho)
    P_dot = rho_dot * (P_of(rho + h) - P_of(rho - h)) / (2 * h)
    A, B, C, D = _lft(pl, result.K)
    S = _S()
    Si = np.linalg.inv(S)
    As, Bs, Cs = Si @ A @ S, Si @ B * D_BAL, C @ S / D_BAL
    g = result.gamma
    brl = np.block([[As.T @ P + P @ As + P_dot, P @ Bs, Cs.T / g],
                    [Bs.T @ P, -np.eye(1), D.T / g],
                    [Cs / g, D / g, -np.eye(1)]])
    sym = lambda M: 0.5 * (M + M.T)  # noqa: E731
    return max(np.linalg.eigvalsh(sym(brl)).max(), -np.linalg.eigvalsh(sym(P)).min())


def _lyapunov(A, q=1.0):
    """P with AᵀP + PA = −q I (unique when no two eigenvalues of A sum to zero)."""
    return solve_continuous_lyapunov(A.T, -q * np.eye(A.shape[0]))


@pytest.fixture(scope="module")
def certified():
    """A stabilising controller and a valid certificate (P > 0, strict BRL)."""
    pl = _plant()
    A_cl = _lft(pl, STABILISING)[0]
    assert np.linalg.eigvals(A_cl).real.max() < -0.3          # stable closed loop
    P = _lyapunov(A_cl)
    assert np.linalg.eigvalsh(P).min() > 0
    K, X, Y = _structured(STABILISING, P)
    return pl, FakeResult(K, X, Y)


# ----------------------------------------------------------------------------- positive case
def test_valid_certificate_is_accepted_with_the_reference_value(certified):
    pl, result = certified
    rho = np.array([0.5, 1.0, 2.0])
    worst = certificate_check(lambda r: _point(pl), result, rho, (-1.0, 0.0, 1.0))
    assert worst.shape == (3, 3)
    assert np.all(worst < 0.0)
    ref = np.array([[_reference(pl, result, r, rd) for rd in (-1.0, 0.0, 1.0)] for r in rho])
    np.testing.assert_allclose(worst, ref, rtol=1e-6, atol=1e-9)
    # the certificate's matrices are the construction's: P_cl > 0 in original coordinates too
    S_inv = np.linalg.inv(_S())
    Y, X = result.Y(1.0), result.X(1.0)
    Q = Y - np.linalg.inv(X) / GAMMA ** 2
    P_orig_like = S_inv.T @ np.block([[Y, -Q], [-Q, Q]]) @ S_inv
    assert np.linalg.eigvalsh(0.5 * (P_orig_like + P_orig_like.T)).min() > 0


def test_plant_given_as_a_matrix_tuple_is_the_same(certified):
    pl, result = certified
    p = _point(pl)
    a = certificate_check(lambda r: _point(pl), result, [1.0], [0.0])
    b = certificate_check(lambda r: (p.A, p.B, p.C, p.D), result, [1.0], [0.0])
    np.testing.assert_array_equal(a, b)


# ----------------------------------------------------------------------------- negative cases
def _non_positive_result(kind):
    """A closed loop with eigenvalues of both signs ("indefinite") or all unstable
    ("negative"), and the unique P of AᵀP + PA = −I: the Lyapunov inequality holds, P is NOT
    positive definite."""
    AK, BK, CK, DK = STABILISING
    if kind == "indefinite":
        pl = _plant()
        K = (AK + 2.6 * np.eye(2), BK, CK, DK + 2.6)
    else:                                            # anti-stable plant and controller
        pl = _plant(A=np.array([[1.0, 1.0], [0.0, 2.0]]))
        K = (np.array([[3.0, 0.5], [0.2, 1.5]]), 0.1 * BK, 0.1 * CK, np.array([[0.1]]))
    A_cl = _lft(pl, K)[0]
    P = _lyapunov(A_cl)
    Kn, X, Y = _structured(K, P)
    return pl, FakeResult(Kn, X, Y), A_cl, P


def _brl_and_p(pl, result, rho=1.0):
    """λ_max of the (ρ̇ = 0) bounded-real matrix and λ_min of P_cl, recomputed."""
    X, Y = result.X(rho), result.Y(rho)
    Q = Y - np.linalg.inv(X) / GAMMA ** 2
    P = np.block([[Y, -Q], [-Q, Q]])
    A, B, C, D = _lft(pl, result.K)
    S = _S()
    Si = np.linalg.inv(S)
    As, Bs, Cs = Si @ A @ S, Si @ B * D_BAL, C @ S / D_BAL
    brl = np.block([[As.T @ P + P @ As, P @ Bs, Cs.T / GAMMA], [Bs.T @ P, -np.eye(1), D.T / GAMMA],
                    [Cs / GAMMA, D / GAMMA, -np.eye(1)]])
    return np.linalg.eigvalsh(0.5 * (brl + brl.T)).max(), np.linalg.eigvalsh(0.5 * (P + P.T)).min()


@pytest.mark.parametrize("kind", ["indefinite", "negative"])
def test_non_positive_lyapunov_matrix_is_rejected(kind):
    """P indefinite (closed loop with stable and unstable eigenvalues) or negative definite
    (all unstable): AᵀP + PA = −I < 0 and the bounded-real matrix is negative definite, so only
    the P > 0 test can reject it — and it must, with the value −λ_min(P_cl)."""
    pl, result, A_cl, P = _non_positive_result(kind)
    eig = np.linalg.eigvals(A_cl).real
    p_eig = np.linalg.eigvalsh(P)
    if kind == "negative":
        assert eig.min() > 0 and p_eig.max() < 0
    else:
        assert eig.min() < 0 < eig.max() and p_eig.min() < 0 < p_eig.max()
    brl_max, p_min = _brl_and_p(pl, result)
    assert brl_max < 0.0 and p_min < 0.0            # the BRL alone would "certify" it
    worst = certificate_check(lambda r: _point(pl), result, [1.0], [0.0])
    assert worst[0, 0] > 0.0
    assert worst[0, 0] == pytest.approx(_reference(pl, result, 1.0, 0.0), rel=1e-6)
    assert worst[0, 0] == pytest.approx(-p_min, rel=1e-6)


def test_unstable_closed_loop_is_rejected_whatever_the_lyapunov_matrix(certified):
    """The valid certificate's (X, Y) with a destabilising controller (D_K sign flipped):
    no P > 0 can satisfy the Lyapunov inequality of an unstable matrix."""
    pl, good = certified
    AK, BK, CK, DK = good.K
    bad = FakeResult((AK, BK, CK, -DK), good.X0, good.Y0)
    assert np.linalg.eigvals(_lft(pl, bad.K)[0]).real.max() > 0
    worst = certificate_check(lambda r: _point(pl), bad, [0.5, 1.0], [-1.0, 1.0])
    assert np.all(worst > 0.0)
    np.testing.assert_allclose(worst[1], [_reference(pl, bad, 1.0, rd) for rd in (-1.0, 1.0)],
                               rtol=1e-6)


def test_violation_at_one_grid_point_only_is_found_there(certified):
    """The plant at ρ = 2 only is changed so that the closed loop is unstable: that row fails,
    the others stay certified, and the overall verdict is a failure."""
    pl, result = certified
    bad_pl = _plant(a00=6.0)
    assert np.linalg.eigvals(_lft(bad_pl, result.K)[0]).real.max() > 0

    def plant_at(rho):
        return _point(bad_pl if rho == 2.0 else pl)

    rho = [1.0, 1.5, 2.0, 2.5]
    worst = certificate_check(plant_at, result, rho, (-1.0, 1.0))
    assert np.all(worst[[0, 1, 3]] < 0.0)
    assert np.all(worst[2] > 0.0)
    assert not np.all(worst < 0.0) and worst.max() > 0.0
    np.testing.assert_allclose(worst[2],
                               [_reference(bad_pl, result, 2.0, rd) for rd in (-1.0, 1.0)],
                               rtol=1e-6)


@pytest.mark.parametrize("which", ["Y", "X"])
def test_violation_at_one_rate_vertex_only_is_found_there(certified, which):
    """A Lyapunov matrix that varies with ρ: Ṗ = ρ̇ ∂P/∂ρ enters the inequality. With
    ∂Y/∂ρ = 0.3 Y (or ∂X/∂ρ = 0.1 X) the inequality fails at ρ̇ = +2 only and holds at −2 and 0
    (a sign error in Ṗ or Q̇ moves the failure to −2); the reference Ṗ is a finite difference
    of P(ρ), not the code's Q̇ formula."""
    pl, good = certified
    if which == "Y":
        result = FakeResult(good.K, good.X0, good.Y0, Y1=0.3 * good.Y0)
    else:
        result = FakeResult(good.K, good.X0, good.Y0, X1=0.1 * good.X0)
    rates = (-2.0, 0.0, 2.0)
    worst = certificate_check(lambda r: _point(pl), result, [1.0], rates)
    ref = [_reference(pl, result, 1.0, rd) for rd in rates]
    np.testing.assert_allclose(worst[0], ref, rtol=1e-5, atol=1e-8)
    assert worst[0, 0] < 0.0 and worst[0, 1] < 0.0
    assert worst[0, 2] > 0.0
    # the controller was asked at each rate vertex
    assert [c[1] for c in result.calls] == list(rates)


def test_rate_term_of_the_plant_enters_the_inequality(certified):
    """``rate_term`` N(ρ): the plant is A + ρ̇N. A destabilising N breaks the inequality at the
    positive rate vertex only (reference: the LFT with A + ρ̇N)."""
    pl, result = certified
    N = np.array([[3.0, 0.0], [0.0, 3.0]])
    worst = certificate_check(lambda r: _point(pl), result, [1.0], (-1.0, 1.0),
                              rate_term=lambda r: N)
    ref = []
    for rd in (-1.0, 1.0):
        shifted = SimpleNamespace(**{**vars(pl), "A": pl.A + rd * N})
        ref.append(_reference(shifted, result, 1.0, rd))
    np.testing.assert_allclose(worst[0], ref, rtol=1e-6)
    assert worst[0, 0] < 0.0 < worst[0, 1]


def test_skew_part_of_y_does_not_change_the_verdict(certified):
    """A non-symmetric Y (solver rounding, or a bug upstream) is judged by its quadratic form:
    adding a skew-symmetric part to Y leaves x'P x and every symmetric part unchanged, so the
    certificate value is the same — the code must symmetrise before eigvalsh (which reads one
    triangle only)."""
    pl, good = certified
    skew = np.array([[0.0, 5.0], [-5.0, 0.0]]) * np.abs(good.Y0).max()
    tilted = FakeResult(good.K, good.X0, good.Y0 + skew)
    a = certificate_check(lambda r: _point(pl), good, [1.0], [0.0])
    b = certificate_check(lambda r: _point(pl), tilted, [1.0], [0.0])
    assert b[0, 0] == pytest.approx(a[0, 0], rel=1e-6)
    assert b[0, 0] == pytest.approx(_reference(pl, tilted, 1.0, 0.0), rel=1e-6)


def test_bad_controller_mode_is_refused(certified):
    pl, result = certified
    with pytest.raises(ValueError, match="controller must be 'exact' or 'interpolated'"):
        certificate_check(lambda r: _point(pl), result, [1.0], [0.0], controller="frozen")


# ----------------------------------------------------------------------------- controller table
NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]
META = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
        "units": {}, "weights": {}, "solver": {}}


def _rotation(r, angle=0.3):
    """Discrete matrix with eigenvalues r·e^{±j·angle} (real parts r·cos(angle) < r)."""
    c, s = np.cos(angle), np.sin(angle)
    return r * np.array([[c, -s], [s, c]])


@pytest.fixture
def table_arrays(tmp_path):
    from vega_loops.export import write_controller_table

    rng = np.random.default_rng(5)
    lead = (3, 2)
    A = -3.0 * np.eye(2) + 0.2 * rng.standard_normal(lead + (2, 2))
    B = rng.standard_normal(lead + (2, 4))
    C = rng.standard_normal(lead + (1, 2))
    D = rng.standard_normal(lead + (1, 4))
    path = tmp_path / "t.npz"
    write_controller_table(path, [100.0, 500.0, 900.0], A, B, C, D, dt_s=0.02, gamma=1.0,
                           gamma_min=0.9, rate_bounds_mps2=[0.0, 36.0], metadata=META,
                           rate_grid_mps2=[0.0, 36.0])
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: np.array(npz[k]) for k in npz.files}
    return str(path), arrays


def _with(arrays, Ad_at=None, stable=None):
    out = {k: np.array(v) for k, v in arrays.items()}
    meta = json.loads(str(out["metadata"]))
    if Ad_at is not None:
        index, matrix = Ad_at
        out["Ad"][index] = matrix
    if stable is not None:
        meta["controller_stable"] = stable
    out["metadata"] = np.array(json.dumps(meta))
    return out


def _radius(Ad):
    """Spectral radius per controller, recomputed here."""
    return np.array([[max(abs(np.linalg.eigvals(Ad[i, j]))) for j in range(Ad.shape[1])]
                     for i in range(Ad.shape[0])])


def test_table_records_the_true_stability(table_arrays):
    from vega_gnc.controller_table import validate_arrays

    path, arrays = table_arrays
    table = validate_arrays(path, arrays)
    radius = _radius(table.Ad)
    assert np.all(radius < 1.0)
    assert table.metadata["controller_stable"] == [[True, True], [True, True], [True, True]]


@pytest.mark.parametrize("matrix, r, index", [
    (_rotation(1.02), 1.02, (2, 1)),
    (_rotation(1.0005), 1.0005, (0, 0)),
    (np.diag([1.0, 0.5]), 1.0, (1, 1)),               # an integrator: |λ| = 1 exactly
    (np.diag([0.5, -1.01]), 1.01, (1, 0)),            # a negative real eigenvalue
])
def test_table_rejects_an_unstable_controller_recorded_as_stable(table_arrays, matrix, r, index):
    """One slice of one grid point with eigenvalues of modulus r ≥ 1 (complex ones with real
    parts < 1, a negative one): recorded stable → rejected, naming that index. r = 1 exactly
    is not stable (radius < 1 is the rule)."""
    from vega_gnc.controller_table import ControllerTableError, validate_arrays

    path, arrays = table_arrays
    bad = _with(arrays, Ad_at=(index, matrix))
    assert _radius(bad["Ad"])[index] == pytest.approx(r, abs=1e-12)
    assert np.linalg.eigvals(bad["Ad"][index]).real.max() <= 1.0
    with pytest.raises(ControllerTableError) as err:
        validate_arrays(path, bad)
    text = str(err.value)
    assert f"grid index {index}" in text and "contradicting the recorded stability" in text
    # the same matrices with the truth recorded are accepted
    stable = (_radius(bad["Ad"]) < 1.0).tolist()
    assert validate_arrays(path, _with(bad, stable=stable)).metadata["controller_stable"] == stable


def test_table_rejects_a_stable_controller_recorded_as_unstable(table_arrays):
    from vega_gnc.controller_table import ControllerTableError, validate_arrays

    path, arrays = table_arrays
    stable = [[True, True], [True, False], [True, True]]
    with pytest.raises(ControllerTableError, match=r"grid index \(1, 1\) has spectral radius"):
        validate_arrays(path, _with(arrays, stable=stable))
    # a marginally stable controller (|λ| = 0.999) must be recorded stable
    almost = _with(arrays, Ad_at=((1, 1), _rotation(0.999)))
    with pytest.raises(ControllerTableError, match=r"grid index \(1, 1\)"):
        validate_arrays(path, _with(almost, stable=stable))
    assert validate_arrays(path, almost).metadata["controller_stable"][1][1] is True


def test_table_rejects_a_stability_record_of_the_wrong_shape(table_arrays):
    from vega_gnc.controller_table import ControllerTableError, validate_arrays

    path, arrays = table_arrays
    with pytest.raises(ControllerTableError, match="'controller_stable' must have shape"):
        validate_arrays(path, _with(arrays, stable=[True, True, True]))
