"""Views of a synthesised controller table: weights, closed-loop Bode, pole maps, time histories.

Everything is computed from the exported table (what the flight software flies) and the
model — not from the synthesis' internal variables — so the figures of the committed
``lpv_controller.npz`` can be redrawn at any time without re-running the synthesis:

* ``weights.png`` — |W_θz|, |W_β(ρ)| at the grid points, and the static weights W_Qα(ρ)
  over the flight (thesis Figs. 4.8–4.10);
* ``closed_loop_bode.png`` — σ_max of the weighted closed loop F_l(M(ρ_i), K(ρ_i)) (the
  quantity bounded by γ) and the unweighted θ_INS/θ_c, β/v_w responses at the grid points;
* ``pole_map.png`` — closed-loop poles of F_l(M(ρ_i), K(ρ_i)) and controller poles;
* ``time_histories.png`` — the thesis scenario (linear and nonlinear plant) flown by the
  in-process closed loop: θ, z, ż, Qα and β (thesis Figs. 5.2–5.6).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from vega_lpv.certificate import closed_loop
from vega_lpv.interconnection import weight_ss, weighted_plant, plant_for_simulation
from vega_lpv.weights import WEIGHT_SETS

__all__ = ["plot_synthesis"]


def _response(A, B, C, D, w):
    """Frequency response, shape (len(w), outputs, inputs)."""
    eye = np.eye(A.shape[0])
    return np.array([C @ np.linalg.solve(1j * x * eye - A, B) + D for x in w])


def plot_synthesis(out_dir: str | Path, table_path: str | Path | None = None,
                   context=None, simulate: bool = True) -> list[Path]:
    """Write the figures of the module docstring into ``out_dir``; return their paths.

    Parameters
    ----------
    out_dir
        Output directory (created).
    table_path
        Controller table (default: the committed ``lpv_controller.npz``).
    context
        Model data sources (default: shipped data).
    simulate
        Also fly the thesis scenario for ``time_histories.png`` (≈ 10 s).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vega_gnc.controller_table import load_controller_table
    from vega_model.parameters import default_context

    from vega_lpv.pipeline import DEFAULT_TABLE

    ctx = context or default_context()
    table = load_controller_table(table_path or DEFAULT_TABLE)
    ws = WEIGHT_SETS[table.metadata["weight_set"]]
    times = [float(t) for t in table.metadata["grid_times_s"]]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    colors = plt.cm.viridis(np.linspace(0, 1, len(times)))
    w = np.logspace(-3, 3.3, 1500)
    paths = []

    # weights
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    for t, col in zip(times, colors):
        p = ctx.parameters(t)
        ax1.loglog(w, np.abs(_response(*weight_ss("beta", p, ws), w)[:, 0, 0]), color=col,
                   label=f"W_β, t = {t:g} s")
    p = ctx.parameters(times[0])
    ax1.loglog(w, np.abs(_response(*weight_ss("theta_z", p, ws), w)[:, 0, 0]), "k--",
               label="W_θz")
    ax1.set_xlabel("ω [rad/s]")
    ax1.set_ylabel("|W| [1/rad]")
    ax1.set_title(f"Dynamic weights ({ws.name} set)")
    ax1.legend(fontsize=7, ncol=2)
    ax1.grid(True, which="both", alpha=0.3)
    t_all = np.linspace(times[0], times[-1], 161)
    wq = [1.0 / (ws.alpha_max_deg * np.pi / 180 * max(ctx.parameters(t).q_pa,
                                                         ws.q_alpha_q_floor_pa)) for t in t_all]
    ax2.semilogy(t_all, wq)
    ax2.set_xlabel("flight time [s]")
    ax2.set_ylabel("W_Qα [1/(Pa·rad)]")
    ax2.set_title("W_Qα(ρ) = 1/(α_max · max(Q, Q_floor))")
    ax2.grid(True, which="both", alpha=0.3)
    paths.append(out / "weights.png")
    fig.tight_layout()
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    # closed-loop Bode and pole maps at the grid points (upper ρ̇ slice, as flown)
    fig_b, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    fig_p, (ax_p, ax_k) = plt.subplots(1, 2, figsize=(12, 5.5))
    for t, col in zip(times, colors):
        v = ctx.parameters(t).v_mps
        K = table.interpolate(v, discrete=False)
        A, B, C, D = closed_loop(weighted_plant(t, ws, ctx).as_point(), K)
        sv = np.array([np.linalg.svd(H, compute_uv=False)[0] for H in _response(A, B, C, D, w)])
        axes[0].semilogx(w, 20 * np.log10(sv), color=col, label=f"t = {t:g} s")
        sim = plant_for_simulation(t, ctx)
        As, Bs, Cs, Ds = sim.close_loop(*K)
        H = _response(As, Bs, Cs, Ds, w)
        axes[1].semilogx(w, 20 * np.log10(np.abs(H[:, 1, 0])), color=col)   # θ_INS / θ_c
        axes[2].semilogx(w, 20 * np.log10(np.abs(H[:, 5, 4])), color=col)   # β / v_w
        poles = np.linalg.eigvals(A)
        ax_p.plot(poles.real, poles.imag, "x", color=col, label=f"t = {t:g} s")
        kp = np.linalg.eigvals(K[0])
        ax_k.plot(kp.real, kp.imag, "+", color=col, label=f"t = {t:g} s")
    axes[0].axhline(20 * np.log10(table.gamma), color="r", ls="--", label=f"γ = {table.gamma:.3f}")
    axes[0].set_title("σ_max of the weighted closed loop")
    axes[1].set_title("θ_INS / θ_c (unweighted)")
    axes[2].set_title("β / v_w [rad/(m/s)] (unweighted)")
    for ax in axes:
        ax.set_xlabel("ω [rad/s]")
        ax.set_ylabel("[dB]")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    paths.append(out / "closed_loop_bode.png")
    fig_b.tight_layout()
    fig_b.savefig(paths[-1], dpi=110)
    plt.close(fig_b)
    ax_p.set_title("closed-loop poles F_l(M(ρ_i), K(ρ_i))")
    ax_k.set_title("controller poles (continuous, upper ρ̇ slice)")
    for ax in (ax_p, ax_k):
        ax.axvline(0, color="k", lw=0.5)
        ax.set_xscale("symlog", linthresh=1.0)
        ax.set_xlabel("Re [1/s]")
        ax.set_ylabel("Im [rad/s]")
        ax.grid(True, alpha=0.3)
    ax_p.legend(fontsize=7, ncol=2)
    paths.append(out / "pole_map.png")
    fig_p.tight_layout()
    fig_p.savefig(paths[-1], dpi=110)
    plt.close(fig_p)

    if simulate:
        from vega_sim.scenario import load_scenario
        from vega_sim.closed_loop import run_scenario

        fig, axes = plt.subplots(5, 1, sharex=True, figsize=(9, 12))
        base = load_scenario("thesis")
        for plant, style in (("linear", "-"), ("nonlinear", "--")):
            res = run_scenario(dataclasses.replace(base, plant=plant), table, context=ctx)
            series = [(res.t_s, np.degrees(res.theta_rad), "θ [deg]"),
                      (res.t_s, res.z_m, "z [m]"),
                      (res.t_s, res.z_dot_mps, "ż [m/s]"),
                      (res.t_s, np.degrees(res.q_alpha_pa_rad), "Qα [Pa·deg]"),
                      (res.act_t_s, np.degrees(res.beta_rad), "β [deg]")]
            for ax, (x, y, label) in zip(axes, series):
                ax.plot(x, y, style, lw=0.8, label=plant)
                ax.set_ylabel(label)
                ax.grid(True, alpha=0.3)
        axes[0].legend()
        axes[0].set_title("Thesis scenario (θ0 = 2°, Dryden wind, INS noise) with the table")
        axes[-1].set_xlabel("flight time [s]")
        paths.append(out / "time_histories.png")
        fig.tight_layout()
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths
