"""Figures of ``vega robust``.

* ``robust_over_time.png`` — per frozen time: the disk margin α of the nominal plant and of
  the worst case found (with the disk phase margin it means), the rigid-body classical margins
  of the worst case (PM: the distance of the phase from −180°; the crossover frequencies are in
  robust.csv), and the μ bounds (lower: the destabilising scale along the worst-case ray;
  upper: the LFT + ab13md bound) against 1;
* ``mu_max_q.png`` — the μ upper bound over frequency at the computed time nearest max-Q (and
  at every other computed time, faint), the lower bound of that time as a level;
* ``time_margins.png`` — the time-domain margins per flight segment (gain increase, gain
  reduction, extra delay) beside the frequency-domain margins of the nominal plant there.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

__all__ = ["plot_robust_over_time", "plot_time_margins", "plot_mu_frequency"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _col(rows, key):
    out = np.array([np.nan if r.get(key) is None else r[key] for r in rows], dtype=float)
    out[~np.isfinite(out)] = np.nan
    return out


def plot_robust_over_time(path, rows: Sequence[Mapping]) -> Path:
    """Write ``robust_over_time.png``; return its path."""
    plt = _plt()
    t = _col(rows, "t_s")
    fig, axes = plt.subplots(3, 1, figsize=(10, 10), sharex=True)
    ax = axes[0]
    ax.plot(t, _col(rows, "nominal_disk_alpha"), "C0", label="disk margin α, nominal plant")
    ax.plot(t, _col(rows, "worst_disk_alpha"), "C3", label="disk margin α, worst case found")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylabel("balanced disk margin α [-]")
    ax.legend(loc="upper right", fontsize=8)
    ax2 = ax.twinx()
    ax2.plot(t, _col(rows, "worst_disk_pm_deg"), "C3:", lw=1)
    ax2.set_ylabel("worst-case disk phase margin [deg] (dotted)")
    ax = axes[1]
    ax.plot(t, _col(rows, "worst_gm_low_db"), "C0", label="GM low (reduction), worst case")
    ax.plot(t, _col(rows, "worst_gm_high_db"), "C1", label="GM high (increase), worst case")
    ax.plot(t, _col(rows, "worst_pm_deg") / 5.0, "C2",
            label="PM (distance of the phase from −180°) / 5, worst case [deg/5]")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylabel("rigid-body margins of the worst case [dB]")
    ax.set_ylim(-10, 30)
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[2]
    ax.plot(t, _col(rows, "mu_lower"), "C0", marker=".", ls="none",
            label="μ lower bound (destabilising scale along the worst-case ray)")
    if any(r.get("mu_upper") is not None for r in rows):
        ax.plot(t, _col(rows, "mu_upper"), "C3", lw=1.2, marker=".", ms=3,
                label="μ upper bound (LFT of the set, ab13md; fit error covered)")
    ax.axhline(1.0, color="k", ls="--", lw=1, label="μ = 1: the whole set")
    ax.set_ylabel("μ bounds [-]")
    ax.set_xlabel("flight time [s]")
    ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("vega robust: worst case over the uncertainty set per frozen time")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_time_margins(path, rows: Sequence[Mapping]) -> Path:
    """Write ``time_margins.png`` from the rows of the time-domain margins."""
    plt = _plt()
    names = [r["segment"] for r in rows]
    x = np.arange(len(rows))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    ax = axes[0]
    ax.bar(x - 0.2, _col(rows, "gm_up_db"), 0.4, label="time domain: gain increase")
    ax.bar(x + 0.2, -_col(rows, "gm_down_db"), 0.4, label="time domain: gain reduction (−)")
    ax.plot(x - 0.2, _col(rows, "fd_gm_up_db"), "k^", label="frequency domain: GM high")
    ax.plot(x + 0.2, -_col(rows, "fd_gm_down_db"), "kv", label="frequency domain: GM low (−)")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xticks(x, names)
    ax.set_ylabel("gain margin [dB] (bars at the bracket end: none found)")
    ax.legend(fontsize=7)
    ax = axes[1]
    ax.bar(x, _col(rows, "dm_ms"), 0.5, label="time domain: extra delay")
    ax.plot(x, _col(rows, "fd_dm_ms"), "k^", label="frequency domain: delay margin (PM/ω_c)")
    ax.set_xticks(x, names)
    ax.set_ylabel("delay margin [ms]")
    ax.legend(fontsize=7)
    fig.suptitle("time-domain margins (nonlinear loop) beside the frequency-domain ones")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_mu_frequency(path, rows: Sequence[Mapping], t_max_q_s: float) -> Path:
    """Write ``mu_max_q.png``: the μ upper bound over frequency at the row nearest
    ``t_max_q_s`` (bold) and at the other rows (faint), with that row's lower bound; return
    its path."""
    plt = _plt()
    rows = [r for r in rows if "mu_curve" in r]
    if not rows:
        raise ValueError("plot_mu_frequency: no row carries a mu curve")
    near = min(rows, key=lambda r: abs(r["t_s"] - t_max_q_s))
    fig, ax = plt.subplots(figsize=(10, 5))
    for r in rows:
        if r is not near:
            ax.semilogx(r["mu_curve"]["w_radps"], r["mu_curve"]["mu_upper"], color="0.8", lw=0.6)
    ax.semilogx(near["mu_curve"]["w_radps"], near["mu_curve"]["mu_upper"], "C3", lw=1.5,
                label=f"μ upper bound at t = {near['t_s']:g} s (max-Q {t_max_q_s:g} s)")
    if near.get("mu_lower") is not None:
        ax.axhline(near["mu_lower"], color="C0", lw=1.2,
                   label=f"μ lower bound at t = {near['t_s']:g} s (worst-case ray)")
    ax.axhline(1.0, color="k", ls="--", lw=1, label="μ = 1")
    ax.set_xlabel("frequency [rad/s]")
    ax.set_ylabel("μ [-]")
    ax.set_title("μ bounds over frequency (grey: the upper bound at the other computed times)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
