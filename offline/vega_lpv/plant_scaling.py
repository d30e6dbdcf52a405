"""Pre-processing of the gridded plant before the LPV LMIs (docs/LPV_SYNTHESIS.md §1).

The transformations, all undone or cancelled in the closed loop:

1. one state similarity x = T x_s for the whole grid: the diagonal Osborne-type balancing of
   §1 (peak over the grid of |[A B; C D]|), followed by default by a constant Riccati
   balancing (below); and one scalar d on the exogenous channels (w = d w_s, e_s = e / d);
2. the normalised scheduling variable θ = (ρ − ρ_mid)/ρ_half ∈ [−1, 1];
3. pointwise orthogonalisation (QR) to D12 = [0; I], D21 = [0 I] and D22 = 0, keeping the loop
   shift F_T = −T_Lᵀ D22 T_R for the controller reconstruction.

The state and (w, e) scalings leave the closed-loop induced L2 norm unchanged; U_e, U_w are
orthogonal and so leave it unchanged too; T_R, T_L and F_T act on u and y only and are absorbed
into the controller (reconstruction.py).

Riccati balancing (an addition to §1, the "balanced realisation of the whole weighted plant"
asked for in §7): the diagonal balancing only equalises matrix entries, while the LMI solution
X, Y of a plant with widely spread time constants (slow weight poles, lightly damped modes
next to fast actuator and weight poles) is ill-conditioned in that basis, and the solver then
loses the accuracy that the strict eigenvalue checks need. X and Y are, for γ → ∞, the
inverses of the H2 control and filter Riccati solutions P and S of the normalised plant,

    P Â + ÂᵀP − P B2 B2ᵀ P + C11ᵀC11 = 0,     S Ãᵀ + Ã S − S C2ᵀ C2 S + B11 B11ᵀ = 0,

so a constant T_b that balances X_g = mean_i (P_i + μI)⁻¹ against Y_g = mean_i (S_i + μI)⁻¹
(T_b⁻¹ X_g T_b⁻ᵀ = T_bᵀ Y_g T_b = Σ, the LQG balancing of Jonckheere & Silverman 1983)
makes the LMI variables close to diagonal and well scaled. On the hard LTI test plants
(tests/synthesis/test_lmi_lti.py) the diagonal balancing alone gave a stage-1 γ 1.3 % above the
sb10ad optimum (bending modes with a near-cancelling notch) or answers that failed the eigenvalue
checks (mixed sensitivity with a 2e-3 rad/s weight pole); with it 0.33 % and 0.012 %.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg

from vega_lpv.gridded_plant import GriddedPlant, PlantDataError

__all__ = ["NormalisedPoint", "PlantScaling", "plant_scaling"]

# Rank test of D12 and D21: smallest singular value relative to max(1, ‖D‖₂).
_RANK_RTOL = 1e-10


@dataclass(frozen=True)
class NormalisedPoint:
    """One plant point after §1: balanced, d-scaled, D12 = [0; I], D21 = [0 I], D22 = 0.

    Attributes
    ----------
    A, B1, B2, C1, C2, D11 : np.ndarray
        Normalised plant data; e = (e1, e2) with dim e2 = n_u, w = (w1, w2) with dim w2 = n_y.
    T_R, T_L, F_T : np.ndarray
        u = T_R u_n, y_n = T_Lᵀ y, and the loop shift F_T = −T_Lᵀ D22 T_R.
    """

    A: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    C1: np.ndarray
    C2: np.ndarray
    D11: np.ndarray
    T_R: np.ndarray
    T_L: np.ndarray
    F_T: np.ndarray

    @property
    def n_x(self):
        """Number of states."""
        return self.A.shape[0]

    @property
    def n_e1(self):
        """Number of performance outputs e₁ (those without the control input)."""
        return self.C1.shape[0] - self.B2.shape[1]

    @property
    def n_w1(self):
        """Number of disturbance inputs w₁ (those without the measurement noise)."""
        return self.B1.shape[1] - self.C2.shape[0]

    @property
    def D12(self):
        """[0; I] (n_e × n_u)."""
        n_u = self.B2.shape[1]
        return np.vstack([np.zeros((self.n_e1, n_u)), np.eye(n_u)])

    @property
    def D21(self):
        """[0 I] (n_y × n_w)."""
        n_y = self.C2.shape[0]
        return np.hstack([np.zeros((n_y, self.n_w1)), np.eye(n_y)])

    # Partition and the derived matrices of docs/LPV_SYNTHESIS.md §1, step 4.
    @property
    def C11(self):
        """Rows of C₁ for e₁."""
        return self.C1[:self.n_e1]

    @property
    def C12(self):
        """Rows of C₁ for e₂."""
        return self.C1[self.n_e1:]

    @property
    def B11(self):
        """Columns of B₁ for w₁."""
        return self.B1[:, :self.n_w1]

    @property
    def B12(self):
        """Columns of B₁ for w₂."""
        return self.B1[:, self.n_w1:]

    @cached_property
    def A_hat(self):
        """Â = A − B2 C12."""
        return self.A - self.B2 @ self.C12

    @cached_property
    def B_hat(self):
        """B̂ = B1 − B2 [D1121 D1122]."""
        return self.B1 - self.B2 @ self.D11[self.n_e1:, :]

    @cached_property
    def A_tilde(self):
        """Ã = A − B12 C2."""
        return self.A - self.B12 @ self.C2

    @cached_property
    def C_tilde(self):
        """C̃ = C1 − [D1112; D1122] C2."""
        return self.C1 - self.D11[:, self.n_w1:] @ self.C2

    @property
    def D_r(self):
        """D_r = [D1111 D1112]."""
        return self.D11[:self.n_e1, :]

    @property
    def D_c(self):
        """D_c = [D1111; D1121]."""
        return self.D11[:, :self.n_w1]


@dataclass(frozen=True)
class PlantScaling:
    """The grid-wide scalings of §1 (state similarity, (w, e) scalar, θ normalisation).

    Attributes
    ----------
    T : np.ndarray, shape (n, n)
        State similarity x = T x_s (diag(t) of the Osborne balancing, times the Riccati
        balancing T_b when used).
    d : float
        Scalar on the exogenous channels, w = d w_s and e_s = e / d.
    rho_mid, rho_half : float
        θ = (ρ − ρ_mid)/ρ_half; ρ_half = 1 for a single grid point.
    balance : str
        The state balancing applied: "riccati" or "diagonal" (also when the Riccati balancing
        was asked for but a Riccati equation had no stabilising solution).
    """

    T: np.ndarray
    d: float
    rho_mid: float
    rho_half: float
    balance: str = "diagonal"

    @cached_property
    def T_inv(self):
        """T⁻¹."""
        return np.linalg.inv(self.T)

    def theta(self, rho):
        """Normalised scheduling variable θ = (ρ − ρ_mid)/ρ_half (§1 step 2)."""
        return (np.asarray(rho, dtype=float) - self.rho_mid) / self.rho_half

    def normalise(self, point):
        """Apply the state and (w, e) scalings, then orthogonalise (§1 steps 1 and 4).

        Parameters
        ----------
        point : PlantPoint
            One grid point of the plant.

        Returns
        -------
        NormalisedPoint

        Raises
        ------
        PlantDataError
            If D12 lacks full column rank or D21 full row rank.
        """
        A = self.T_inv @ point.A @ self.T                  # T⁻¹ A T
        B = self.T_inv @ point.B                           # T⁻¹ B
        C = point.C @ self.T                               # C T
        n_w, n_e = point.n_w, point.n_e
        D = point.D.copy()
        B[:, :n_w] *= self.d                              # B1 d
        D[n_e:, :n_w] *= self.d                           # D21 d
        C[:n_e, :] /= self.d                              # C1 / d
        D[:n_e, n_w:] /= self.d                           # D12 / d
        return _orthogonalise(A, B, C, D, point)


def _orthogonalise(A, B, C, D, sizes):
    """Pointwise QR normalisation to D12 = [0; I], D21 = [0 I], D22 = 0 (§1 step 4).

    U_e D12 = [0; R12] with U_e orthogonal, T_R = R12⁻¹; D21 U_w = [0 R21ᵀ], T_L = R21⁻¹.
    The triangular factors are taken with a positive diagonal, which makes the factorisation
    unique and hence continuous in ρ.
    """
    n_w, n_u, n_e, n_y = sizes.n_w, sizes.n_u, sizes.n_e, sizes.n_y
    B1, B2 = B[:, :n_w], B[:, n_w:]
    C1, C2 = C[:n_e, :], C[n_e:, :]
    D11, D12, D21, D22 = D[:n_e, :n_w], D[:n_e, n_w:], D[n_e:, :n_w], D[n_e:, n_w:]
    _require_full_rank(D12, "D12 must have full column rank at every grid point")
    _require_full_rank(D21, "D21 must have full row rank at every grid point")
    Q_e, R12 = _positive_qr(D12)
    Q_w, R21 = _positive_qr(D21.T)
    U_e = np.vstack([Q_e[:, n_u:].T, Q_e[:, :n_u].T])   # U_e D12 = [0; R12]
    U_w = np.hstack([Q_w[:, n_y:], Q_w[:, :n_y]])       # D21 U_w = [0 R21ᵀ]
    T_R = np.linalg.inv(R12[:n_u])
    T_L = np.linalg.inv(R21[:n_y])
    return NormalisedPoint(
        A=A.copy(),
        B1=B1 @ U_w,
        B2=B2 @ T_R,
        C1=U_e @ C1,
        C2=T_L.T @ C2,
        D11=U_e @ D11 @ U_w,
        T_R=T_R,
        T_L=T_L,
        F_T=-T_L.T @ D22 @ T_R,
    )


def _require_full_rank(M, message):
    """Raise PlantDataError(message) unless M has full rank min(M.shape)."""
    s = np.linalg.svd(M, compute_uv=False)
    if s.size == 0 or s[-1] <= _RANK_RTOL * max(1.0, s[0]):
        raise PlantDataError(message)


def _positive_qr(M):
    """Complete QR M = Q R with the diagonal of R non-negative."""
    Q, R = np.linalg.qr(M, mode="complete")
    k = min(M.shape)
    signs = np.ones(Q.shape[1])
    signs[:k] = np.where(np.diag(R)[:k] < 0.0, -1.0, 1.0)
    return Q * signs[None, :], R * signs[:, None]


def plant_scaling(plant, balance="riccati"):
    """Compute the grid-wide scalings of §1 for a gridded plant.

    Parameters
    ----------
    plant : GriddedPlant
        The plant on its grid.
    balance : {"riccati", "diagonal"}
        "diagonal": only the Osborne balancing of §1; "riccati" (default): followed by the
        constant Riccati balancing of the module docstring (skipped if a Riccati equation has
        no stabilising solution at some grid point).

    Returns
    -------
    PlantScaling

    Notes
    -----
    The diagonal part is found by an Osborne iteration (powers of two) on the elementwise peak
    over the grid of |[A B; C D]| of the orthogonalised plant, balancing for each state the
    2-norm of its row and of its column; the input and output indices are not scaled. In the
    orthogonalised coordinates the scalar d acts like a uniform state scaling (B ∝ d, C ∝ 1/d);
    it is chosen so that the peaks of ‖[B1 B2]‖₂ and ‖[C1; C2]‖₂ are equal, which balances X
    against Y (the Riccati balancing, invariant to such a scaling, then subsumes it).
    """
    if not isinstance(plant, GriddedPlant):
        raise PlantDataError("plant must be a GriddedPlant")
    if balance not in ("riccati", "diagonal"):
        raise ValueError(f"balance must be 'riccati' or 'diagonal', got {balance!r}")
    n = plant.n_x
    rho = plant.rho
    rho_half = 0.5 * (rho[-1] - rho[0]) if rho.size > 1 else 1.0
    rho_mid = 0.5 * (rho[-1] + rho[0])
    unit = PlantScaling(T=np.eye(n), d=1.0, rho_mid=rho_mid, rho_half=rho_half)
    points = [unit.normalise(plant.point(i)) for i in range(plant.n_grid)]
    peak = np.max([np.abs(np.block([[p.A, p.B1, p.B2], [p.C1, p.D11, p.D12],
                                    [p.C2, p.D21, np.zeros_like(p.F_T)]])) for p in points],
                  axis=0)
    t = _osborne(peak, n)
    b_peak = max(np.linalg.norm(np.hstack([p.B1, p.B2]) / t[:, None], 2) for p in points)
    c_peak = max(np.linalg.norm(np.vstack([p.C1, p.C2]) * t[None, :], 2) for p in points)
    d = float(np.sqrt(c_peak / b_peak)) if b_peak > 0.0 and c_peak > 0.0 else 1.0
    diagonal = PlantScaling(T=np.diag(t), d=d, rho_mid=rho_mid, rho_half=rho_half)
    if balance == "diagonal":
        return diagonal
    T_b = _riccati_balancing([diagonal.normalise(plant.point(i)) for i in range(plant.n_grid)])
    if T_b is None:
        return diagonal
    return PlantScaling(T=np.diag(t) @ T_b, d=d, rho_mid=rho_mid, rho_half=rho_half,
                        balance="riccati")


def _riccati_balancing(points, mu=1e-6):
    """Constant T_b with T_b⁻¹ X_g T_b⁻ᵀ = T_bᵀ Y_g T_b = Σ (module docstring); None on failure.

    P_i, S_i: stabilising solutions of the H2 control and filter Riccati equations of the
    normalised point i (a tiny multiple of I added to C11ᵀC11 and B11B11ᵀ makes them unique
    when those are singular); μ regularises their inverses relative to their norms.
    """
    n = points[0].n_x
    X_g, Y_g = np.zeros((n, n)), np.zeros((n, n))
    for p in points:
        Q_c = p.C11.T @ p.C11
        Q_f = p.B11 @ p.B11.T
        try:
            P = scipy.linalg.solve_continuous_are(
                p.A_hat, p.B2, Q_c + 1e-9 * max(1.0, np.linalg.norm(Q_c, 2)) * np.eye(n),
                np.eye(p.B2.shape[1]))
            S = scipy.linalg.solve_continuous_are(
                p.A_tilde.T, p.C2.T, Q_f + 1e-9 * max(1.0, np.linalg.norm(Q_f, 2)) * np.eye(n),
                np.eye(p.C2.shape[0]))
        except (np.linalg.LinAlgError, ValueError):
            return None
        if not (np.all(np.isfinite(P)) and np.all(np.isfinite(S))):
            return None
        X_g += np.linalg.inv(P + mu * np.linalg.norm(P, 2) * np.eye(n)) / len(points)
        Y_g += np.linalg.inv(S + mu * np.linalg.norm(S, 2) * np.eye(n)) / len(points)
    try:
        L_x = np.linalg.cholesky(0.5 * (X_g + X_g.T))                   # X_g = L_x L_xᵀ
    except np.linalg.LinAlgError:
        return None
    sigma2, U = np.linalg.eigh(L_x.T @ Y_g @ L_x)                        # = U Σ² Uᵀ
    if not np.all(sigma2 > 0.0):
        return None
    return L_x @ U * sigma2[None, :] ** -0.25                            # T_b = L_x U Σ^(−1/2)


def _osborne(M, n, max_sweeps=200):
    """Diagonal t (powers of two) balancing row and column 2-norms of the first n indices of M.

    M is non-negative, square; the similarity acts on indices < n only: row i of the state
    part is divided by t_i, column i multiplied by t_i.
    """
    M = np.array(M, dtype=float)
    np.fill_diagonal(M, 0.0)
    log2_t = np.zeros(n)
    for _ in range(max_sweeps):
        changed = False
        for i in range(n):
            row = np.linalg.norm(M[i, :])
            col = np.linalg.norm(M[:, i])
            if row == 0.0 or col == 0.0:
                continue
            step = int(np.round(0.5 * np.log2(row / col)))   # t_i ← t_i · 2^step
            if step != 0:
                scale = 2.0 ** step
                M[i, :] /= scale
                M[:, i] *= scale
                log2_t[i] += step
                changed = True
        if not changed:
            break
    return 2.0 ** log2_t
