"""Controller reconstruction from the LPV Lyapunov variables X(ρ), Y(ρ) (docs/LPV_SYNTHESIS.md §4).

Explicit output-feedback formulas of Wu, Yang, Packard & Becker (1996) for the normalised plant
(plant_scaling.py: D12 = [0; I], D21 = [0 I], D22 = 0), written with the variables X, Y of the
g = 1/γ form of the LMIs (X_std = γX, Y_std = γY), followed by the undoing of the D22 loop shift
and of the control/measurement normalisations T_R, T_L. The result connects to the original,
unscaled plant with u = K y. In the equality case (Riccati equations instead of inequalities,
ρ̇ = 0) the formulas reduce to the central controller of Doyle, Glover, Khargonekar & Francis
(1989) with X∞ = X⁻¹, Y∞ = Y⁻¹.
"""

from __future__ import annotations

import numpy as np

__all__ = ["normalised_controller", "undo_loop_shift", "controller_at"]


def normalised_controller(point, X, Y, X_dot, gamma):
    """Controller (A_K, B_K, C_K, D_K) for the normalised plant, docs/LPV_SYNTHESIS.md §4.

    Parameters
    ----------
    point : NormalisedPoint
        The plant at ρ after the pre-processing of §1.
    X, Y : np.ndarray
        X(ρ), Y(ρ) (scaled coordinates, g-form of §2).
    X_dot : np.ndarray
        Ẋ = Σ_j ρ̇_j ∂X/∂ρ_j at the chosen rate; the only ρ̇-dependent input.
    gamma : float
        The performance level at which X, Y satisfy the LMIs.

    Returns
    -------
    tuple of np.ndarray
        A_K, B_K, C_K, D_K with u_n = K y_n in the normalised channels (D22 = 0).

    Notes
    -----
    Ω = −D1122 − D1121 (γ²I − D1111ᵀD1111)⁻¹ D1111ᵀ D1112 is the feedthrough that makes
    ‖D̄11‖ < γ (Glover & Doyle); F and L are the state-feedback and output-injection gains of
    the Riccati inequalities in X⁻¹ and Y⁻¹; H is the slack of the X⁻¹ inequality including the
    rate term d(X⁻¹)/dt = −X⁻¹ẊX⁻¹, which is where ρ̇ enters A_K (affinely).
    """
    g2 = gamma ** -2
    p = point
    n_e1, n_w1 = p.n_e1, p.n_w1
    A, B1, B2, C1, C2, D11, D12, D21 = p.A, p.B1, p.B2, p.C1, p.C2, p.D11, p.D12, p.D21
    D1111, D1112 = D11[:n_e1, :n_w1], D11[:n_e1, n_w1:]
    D1121, D1122 = D11[n_e1:, :n_w1], D11[n_e1:, n_w1:]
    I_e, I_w = np.eye(D11.shape[0]), np.eye(D11.shape[1])

    # Ω = −D1122 − D1121 (γ²I − D1111ᵀD1111)⁻¹ D1111ᵀ D1112
    Omega = -D1122
    if n_e1 > 0 and n_w1 > 0:
        Omega = Omega - D1121 @ np.linalg.solve(gamma ** 2 * np.eye(n_w1) - D1111.T @ D1111,
                                                D1111.T @ D1112)
    # Ā, B̄1, C̄1, D̄11: the plant with u = Ω y closed
    A_bar = A + B2 @ Omega @ C2
    B1_bar = B1 + B2 @ Omega @ D21
    C1_bar = C1 + D12 @ Omega @ C2
    D11_bar = D11 + D12 @ Omega @ D21
    R_e = np.linalg.inv(I_e - g2 * D11_bar @ D11_bar.T)
    R_w = np.linalg.inv(I_w - g2 * D11_bar.T @ D11_bar)
    X_inv = _spd_inverse(X)
    Y_inv = _spd_inverse(Y)
    # F = −(D12ᵀR_eD12)⁻¹ [(B2 + γ⁻² B̄1 D̄11ᵀ R_e D12)ᵀ X⁻¹ + D12ᵀ R_e C̄1]
    F = -np.linalg.solve(D12.T @ R_e @ D12,
                         (B2 + g2 * B1_bar @ D11_bar.T @ R_e @ D12).T @ X_inv
                         + D12.T @ R_e @ C1_bar)
    # L = −[Y⁻¹ (C2 + γ⁻² D21 R_w D̄11ᵀ C̄1)ᵀ + B̄1 R_w D21ᵀ] (D21 R_w D21ᵀ)⁻¹
    L = -np.linalg.solve(D21 @ R_w @ D21.T,
                         (Y_inv @ (C2 + g2 * D21 @ R_w @ D11_bar.T @ C1_bar).T
                          + B1_bar @ R_w @ D21.T).T).T
    A_F = A_bar + B2 @ F
    C_F = C1_bar + D12 @ F
    Lam = X_inv @ B1_bar + C_F.T @ D11_bar                      # Λ = X⁻¹B̄1 + C_FᵀD̄11
    X_inv_dot = -X_inv @ X_dot @ X_inv                          # d(X⁻¹)/dt
    H = -(X_inv @ A_F + A_F.T @ X_inv + X_inv_dot + C_F.T @ C_F + g2 * Lam @ R_w @ Lam.T)
    Q = Y - g2 * X_inv                                          # Q = Y − γ⁻²X⁻¹
    Z = np.linalg.solve(Q, Y)                                   # Z = Q⁻¹Y
    M = (H + F.T @ (B2.T @ X_inv + D12.T @ C_F)
         + (Q @ (-Z @ L @ D21 - B1_bar) + g2 * F.T @ D12.T @ D11_bar) @ R_w @ Lam.T)
    A_K = A_F + Z @ L @ C2 - g2 * np.linalg.solve(Q, M)
    B_K = -Z @ L
    return A_K, B_K, F, Omega


def undo_loop_shift(controller, point):
    """Controller for the original channels from the normalised one (docs/LPV_SYNTHESIS.md §4).

    With Δ = (I − D_K F_T)⁻¹:
    A = A_K + B_K F_T Δ C_K,  B = B_K (I + F_T Δ D_K) T_Lᵀ,  C = T_R Δ C_K,  D = T_R Δ D_K T_Lᵀ.
    """
    A_K, B_K, C_K, D_K = controller
    F_T, T_R, T_L = point.F_T, point.T_R, point.T_L
    Delta = np.linalg.inv(np.eye(D_K.shape[0]) - D_K @ F_T)
    return (A_K + B_K @ F_T @ Delta @ C_K,
            B_K @ (np.eye(F_T.shape[0]) + F_T @ Delta @ D_K) @ T_L.T,
            T_R @ Delta @ C_K,
            T_R @ Delta @ D_K @ T_L.T)


def controller_at(point, X, Y, X_dot, gamma):
    """Controller for the original plant channels, u = K y (§4 followed by the loop shift)."""
    return undo_loop_shift(normalised_controller(point, X, Y, X_dot, gamma), point)


def _spd_inverse(S):
    """Inverse of a symmetric positive definite matrix, symmetrised."""
    S_inv = np.linalg.inv(S)
    return 0.5 * (S_inv + S_inv.T)
