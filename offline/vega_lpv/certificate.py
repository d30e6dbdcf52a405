"""Solver-independent verification of an LPV synthesis (docs/LPV_SYNTHESIS.md §5).

The closed-loop certificate: in (x_s, x_K) coordinates (x_s the balanced plant state) the
parameter-dependent Lyapunov matrix

    P_cl = [[Y, −Q], [−Q, Q]],   Q = Y − γ⁻² X⁻¹,   Q̇ = Ẏ + γ⁻² X⁻¹ Ẋ X⁻¹,

must satisfy P_cl > 0 and the scaled bounded-real inequality

    [A_clᵀP_cl + P_cl A_cl + Ṗ_cl,  P_cl B_cl,  γ⁻¹C_clᵀ]
    [B_clᵀP_cl,                    −I,         γ⁻¹D_clᵀ] < 0
    [γ⁻¹C_cl,                      γ⁻¹D_cl,    −I      ]

at every (ρ, ρ̇), which proves an induced L2 gain below γ for every parameter trajectory whose
rate stays in the box (Wu et al. 1996; Apkarian & Adams 1998). It is the γ-form certificate
P_γ = γ·P_cl of the g-form LMIs divided by γ. The inequality is affine in ρ̇, so the rate
vertices suffice; in ρ it is checked pointwise, on any grid the caller chooses.
"""

from __future__ import annotations

import numpy as np

from vega_lpv.gridded_plant import GriddedPlant, PlantDataError, PlantPoint

__all__ = ["closed_loop", "hinf_norm", "certificate_check"]


def closed_loop(plant_point, controller):
    """Lower LFT F_l(P, K) of a plant point and a controller u = K y (thesis Eq. 4.4).

    Parameters
    ----------
    plant_point : PlantPoint
        Plant with inputs [w; u] and outputs [e; y]; D22 may be non-zero.
    controller : tuple of np.ndarray
        (A_K, B_K, C_K, D_K).

    Returns
    -------
    tuple of np.ndarray
        (A_cl, B_cl, C_cl, D_cl) with state (x, x_K), input w, output e.

    Raises
    ------
    PlantDataError
        If the loop is ill-posed (I − D_K D22 singular).
    """
    p = plant_point
    A_K, B_K, C_K, D_K = (np.asarray(m, dtype=float) for m in controller)
    n, n_K = p.n_x, A_K.shape[0]
    B1, B2 = p.B[:, :p.n_w], p.B[:, p.n_w:]
    C1, C2 = p.C[:p.n_e], p.C[p.n_e:]
    D11, D12 = p.D[:p.n_e, :p.n_w], p.D[:p.n_e, p.n_w:]
    D21, D22 = p.D[p.n_e:, :p.n_w], p.D[p.n_e:, p.n_w:]
    well_posed = np.eye(p.n_u) - D_K @ D22
    if np.linalg.cond(well_posed) > 1e12:
        raise PlantDataError("closed loop is ill-posed: I - D_K D22 is singular")
    # u = Φ (D_K C2 x + C_K x_K + D_K D21 w),  Φ = (I − D_K D22)⁻¹
    u_map = np.linalg.solve(well_posed, np.hstack([D_K @ C2, C_K, D_K @ D21]))
    # y = C2 x + D21 w + D22 u
    y_map = np.hstack([C2, np.zeros((p.n_y, n_K)), D21]) + D22 @ u_map
    # ẋ = A x + B1 w + B2 u,  ẋ_K = A_K x_K + B_K y
    open_loop = np.block([[p.A, np.zeros((n, n_K)), B1],
                          [np.zeros((n_K, n)), A_K, np.zeros((n_K, p.n_w))]])
    rows_x = open_loop + np.vstack([B2 @ u_map, B_K @ y_map])
    # e = C1 x + D11 w + D12 u
    rows_e = np.hstack([C1, np.zeros((p.n_e, n_K)), D11]) + D12 @ u_map
    m = n + n_K
    return rows_x[:, :m], rows_x[:, m:], rows_e[:, :m], rows_e[:, m:]


def hinf_norm(A, B, C, D):
    """H∞ norm of a continuous-time system; ``inf`` if A is not Hurwitz.

    Uses SLICOT ``ab13dd`` (Bruinsma & Steinbuch two-step algorithm) through python-control's
    :func:`control.linfnorm`, with relative tolerance 1e-10.

    Raises
    ------
    ValueError
        If a matrix holds a NaN or an infinity (ab13dd does not return on such input: a
        defect upstream would otherwise hang the verification).
    """
    import control

    A = np.asarray(A, dtype=float)
    for name, M in (("A", A), ("B", B), ("C", C), ("D", D)):
        if not np.all(np.isfinite(np.asarray(M, dtype=float))):
            raise ValueError(f"hinf_norm: {name} is not finite")
    if A.size and np.max(np.linalg.eigvals(A).real) >= 0.0:
        return float("inf")
    gpeak, _ = control.linfnorm(control.ss(A, B, C, D), tol=1e-10)
    return float(gpeak)


def certificate_check(plant, result, rho_points, rate_vertices, controller="exact",
                      rate_term=None):
    """Largest eigenvalue of the closed-loop certificate at each (ρ, ρ̇) (docs/LPV_SYNTHESIS.md §5).

    Parameters
    ----------
    plant : GriddedPlant or callable
        The ORIGINAL (unscaled) plant: a :class:`GriddedPlant` (then every ρ must be a grid
        value) or ``plant_at(ρ)`` returning a :class:`PlantPoint` or a tuple (A, B, C, D) with
        the synthesis' partition sizes — e.g. an interpolation of the model, for dense checks.
    result : LpvSynthesisResult
        Output of :func:`~vega_lpv.lpv_synthesis.synthesize`.
    rho_points : array_like
        Scheduling values to check.
    rate_vertices : array_like
        Values of ρ̇ to check (the vertices of the rate box suffice: the inequality is affine
        in ρ̇).
    controller : {"exact", "interpolated"}
        "exact" reconstructs K(ρ, ρ̇) from X(ρ), Y(ρ) and the plant at ρ (§4); "interpolated"
        uses the linear interpolation of the grid controllers (what flight software runs).
    rate_term : callable, optional
        ``rate_term(ρ)`` → N(ρ) (n × n, original plant coordinates): checks the plant
        ẋ = (A(ρ) + ρ̇ N(ρ)) x + … instead of ẋ = A(ρ) x + … — the term a ρ-dependent state
        transformation of the model adds along a trajectory (the synthesis leaves it out;
        verification.bending_rate_term). The controller is unchanged; the inequality stays
        affine in ρ̇, so the rate vertices still suffice.

    Returns
    -------
    np.ndarray, shape (len(rho_points), len(rate_vertices))
        max(λ_max(BRL), λ_max(−P_cl)): negative means certified at that point.
    """
    if controller not in ("exact", "interpolated"):
        raise ValueError(f"controller must be 'exact' or 'interpolated', got {controller!r}")
    rho_points = np.atleast_1d(np.asarray(rho_points, dtype=float))
    rate_vertices = np.atleast_1d(np.asarray(rate_vertices, dtype=float))
    plant_at = _plant_lookup(plant, result)
    sc = result.scaling
    gamma = result.gamma
    g2 = gamma ** -2
    worst = np.empty((rho_points.size, rate_vertices.size))
    for i, rho in enumerate(rho_points):
        point = plant_at(rho)
        X, Y = result.X(rho), result.Y(rho)
        X_inv = np.linalg.inv(X)
        Q = Y - g2 * X_inv                                        # Q = Y − γ⁻²X⁻¹
        P_cl = np.block([[Y, -Q], [-Q, Q]])
        n_K = Q.shape[0]
        S = _block_diag(sc.T, np.eye(n_K))                       # (x, x_K) = S (x_s, x_K)
        S_inv = _block_diag(sc.T_inv, np.eye(n_K))
        for j, rho_dot in enumerate(rate_vertices):
            N = None if rate_term is None else rate_term(rho)
            if controller == "exact":
                K = result.controller(rho, rho_dot, plant_point=point, rate_term=N)
            else:
                K = result.controller(rho, rho_dot)
            A_cl, B_cl, C_cl, D_cl = closed_loop(point, K)
            if N is not None:
                A_cl = A_cl.copy()
                A_cl[:point.n_x, :point.n_x] += rho_dot * N
            # to balanced coordinates: x = T x_s, w = d w_s, e_s = e/d
            A_s = S_inv @ A_cl @ S
            B_s = S_inv @ B_cl * sc.d
            C_s = C_cl @ S / sc.d
            X_dot, Y_dot = rho_dot * result.dX_drho(rho), rho_dot * result.dY_drho(rho)
            Q_dot = Y_dot + g2 * X_inv @ X_dot @ X_inv           # Q̇ = Ẏ + γ⁻²X⁻¹ẊX⁻¹
            P_dot = np.block([[Y_dot, -Q_dot], [-Q_dot, Q_dot]])
            n_w, n_e = B_s.shape[1], C_s.shape[0]
            brl = np.block([
                [A_s.T @ P_cl + P_cl @ A_s + P_dot, P_cl @ B_s, C_s.T / gamma],
                [B_s.T @ P_cl, -np.eye(n_w), D_cl.T / gamma],
                [C_s / gamma, D_cl / gamma, -np.eye(n_e)],
            ])
            worst[i, j] = max(np.linalg.eigvalsh(0.5 * (brl + brl.T))[-1],
                              -np.linalg.eigvalsh(0.5 * (P_cl + P_cl.T))[0])
    return worst


def _block_diag(M1, M2):
    """blockdiag(M1, M2)."""
    return np.block([[M1, np.zeros((M1.shape[0], M2.shape[1]))],
                     [np.zeros((M2.shape[0], M1.shape[1])), M2]])


def _plant_lookup(plant, result):
    """A function ρ ↦ PlantPoint for a GriddedPlant (grid values only) or a callable."""
    n_w, n_u, n_e, n_y = result.sizes
    if isinstance(plant, GriddedPlant):
        def plant_at(rho):
            index = np.flatnonzero(np.isclose(plant.rho, rho, rtol=1e-12, atol=0.0))
            if index.size != 1:
                raise PlantDataError(
                    f"rho = {rho:g} is not a grid value; pass a callable plant_at(rho) instead")
            return plant.point(index[0])
        return plant_at
    if not callable(plant):
        raise PlantDataError("plant must be a GriddedPlant or a callable plant_at(rho)")

    def plant_at(rho):
        point = plant(rho)
        if isinstance(point, PlantPoint):
            return point
        return PlantPoint(*point, n_w, n_u, n_e, n_y)
    return plant_at
