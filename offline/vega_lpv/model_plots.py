"""Views of the vehicle model: frozen-time Bode θ_INS/β and pole-zero maps (thesis Fig. 2.11).

The transfer θ_INS/β includes the tail-wags-dog input with β̈ = s²β, i.e. the response to
the physical nozzle angle: G(s) = C₂ (sI − A)⁻¹ (B_β + s² B_β̈).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vega_lpv.interconnection import GRID_TIMES_S

__all__ = ["theta_ins_over_beta", "plot_model"]


def theta_ins_over_beta(A, B, C, w_radps):
    """Frequency response, poles and zeros of θ_INS/β with β̈ = s²β.

    The response is evaluated by direct solves, G(jω) = c (jωI − A)⁻¹ (b_β − ω² b_β̈).
    The zeros are the finite generalised eigenvalues of the Rosenbrock pencil of the
    augmented system with input β̈ and states [x, β, β̇] (its transfer is G(s)/s², so it
    has the same zeros): no polynomial root finding.

    Returns
    -------
    response, poles, zeros : numpy.ndarray
    """
    from scipy.linalg import eigvals

    b0, b2, c = B[:, 0], B[:, 1], C[1, :]
    response = np.array([c @ np.linalg.solve(1j * w * np.eye(len(A)) - A, b0 - w * w * b2)
                         for w in w_radps])
    n = len(A)
    Aa = np.zeros((n + 2, n + 2))
    Aa[:n, :n] = A
    Aa[:n, n] = b0
    Aa[n, n + 1] = 1.0
    ba = np.concatenate((b2, [0.0, 1.0]))
    ca = np.concatenate((c, [0.0, 0.0]))
    pencil = np.block([[Aa, ba[:, None]], [ca[None, :], np.zeros((1, 1))]])
    mass = np.zeros_like(pencil)
    mass[:n + 2, :n + 2] = np.eye(n + 2)
    z = eigvals(pencil, mass)
    zeros = z[np.isfinite(z) & (np.abs(z) < 1e6)]
    return response, np.linalg.eigvals(A), zeros


def plot_model(out_dir: str | Path, times_s=GRID_TIMES_S, context=None) -> list[Path]:
    """Write ``bode_theta_ins_beta.png`` and ``pole_zero.png`` into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vega_model.dynamics import linear_model
    from vega_model.parameters import default_context

    ctx = context or default_context()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    w = np.logspace(-2, 3, 2000)
    fig_b, (ax_m, ax_p) = plt.subplots(2, 1, sharex=True, figsize=(8, 7))
    fig_z, (ax_z, ax_zoom) = plt.subplots(1, 2, figsize=(12, 5.5))
    colors = plt.cm.viridis(np.linspace(0, 1, len(times_s)))
    for t, col in zip(times_s, colors):
        A, B, C, _ = linear_model(ctx.parameters(t))
        g, poles, zeros = theta_ins_over_beta(A, B, C, w)
        ax_m.semilogx(w, 20 * np.log10(np.abs(g)), color=col, label=f"t = {t:g} s")
        ax_p.semilogx(w, np.degrees(np.unwrap(np.angle(g))), color=col)
        for ax in (ax_z, ax_zoom):
            ax.plot(poles.real, poles.imag, "x", color=col, label=f"t = {t:g} s")
            ax.plot(zeros.real, zeros.imag, "o", mfc="none", color=col)
    ax_m.set_ylabel("|θ_INS/β| [dB]")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("ω [rad/s]")
    ax_m.legend(fontsize=7, ncol=3)
    ax_m.set_title("Frozen-time θ_INS/β (with the TWD term), thesis Fig. 2.11A")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    ax_z.set_title("Poles (x) and zeros (o) of θ_INS/β, thesis Fig. 2.11B")
    ax_zoom.set_title("zoom near the origin (rigid body)")
    ax_zoom.set_xlim(-3, 3)
    ax_zoom.set_ylim(-3, 3)
    for ax in (ax_z, ax_zoom):
        ax.axvline(0, color="k", lw=0.5)
        ax.set_xlabel("Re [1/s]")
        ax.set_ylabel("Im [rad/s]")
        ax.grid(True, alpha=0.3)
    ax_z.legend(fontsize=7, ncol=2)
    paths = [out / "bode_theta_ins_beta.png", out / "pole_zero.png"]
    fig_b.tight_layout()
    fig_b.savefig(paths[0], dpi=110)
    fig_z.tight_layout()
    fig_z.savefig(paths[1], dpi=110)
    plt.close(fig_b)
    plt.close(fig_z)
    return paths
