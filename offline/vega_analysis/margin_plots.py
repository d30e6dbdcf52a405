"""Figures of ``vega margins``: margins over flight time, and a Nichols chart at max-Q.

* ``margins_over_time.png`` — rigid-body gain margins (low and high), phase margin (distance
  from −180°; grey dots: the drift loop's crossovers below the frozen-time floor), bending
  peak loop gain per mode and closed-loop stability over the flight, nominal (lines) and, with
  the dispersed corners, the worst corner per time (dashed); the requirement lines of
  :data:`vega_loops.margins.REQUIREMENTS`; the times where the controller is clamped to
  an end of its velocity grid shaded;
* ``nichols_max_q.png`` — the continuous-equivalent loop L(jω) at the time of maximum dynamic
  pressure in Nichols co-ordinates (phase unwrapped, gain in dB), nominal and the worst
  corners, with the exclusion zone of the requirement (±6 dB × ±30° around every −180° + k·360°
  critical point) and the −6 dB bending line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from vega_loops.margins import PM_FLOOR_RADPS, REQUIREMENTS

__all__ = ["plot_margins_over_time", "plot_nichols"]


def _col(rows, key):
    out = np.array([r[key] for r in rows], dtype=float)
    out[~np.isfinite(out)] = np.nan
    return out


def _shade(ax, intervals, step):
    for a, b in intervals:
        ax.axvspan(a - step / 2, b + step / 2, color="0.9", zorder=0, lw=0)


def plot_margins_over_time(path, nominal: Sequence[Mapping], worst: Sequence[Mapping] | None,
                           clamped_intervals: Sequence[Sequence[float]] = ()) -> Path:
    """Write ``margins_over_time.png`` to ``path`` (a file name); return it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = _col(nominal, "t_s")
    step = float(np.min(np.diff(t))) if t.size > 1 else 1.0
    fig, axes = plt.subplots(4, 1, figsize=(10, 12), sharex=True)
    req = REQUIREMENTS
    ax = axes[0]
    ax.plot(t, _col(nominal, "gm_low_db"), "C0", label="GM low (gain reduction)")
    ax.plot(t, _col(nominal, "gm_high_db"), "C1", label="GM high (gain increase)")
    if worst:
        tw = _col(worst, "t_s")
        ax.plot(tw, _col(worst, "gm_low_db"), "C0--", label="GM low, worst corner")
        ax.plot(tw, _col(worst, "gm_high_db"), "C1--", label="GM high, worst corner")
    ax.axhline(req["gm_db"], color="r", lw=1, label=f"requirement {req['gm_db']:g} dB")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylabel("rigid-body gain margin [dB]")
    ax.set_ylim(-10, 40)
    ax = axes[1]
    ax.plot(t, _col(nominal, "pm_deg"), "C2",
            label=f"PM (distance from −180°, gain crossovers ≥ {PM_FLOOR_RADPS:g} rad/s)")
    if worst:
        ax.plot(tw, _col(worst, "pm_deg"), "C2--", label="PM, worst corner")
    below = _col(worst if worst else nominal, "pm_low_deg")
    if np.any(np.isfinite(below)):
        ax.plot(tw if worst else t, below, ".", color="0.5", ms=3,
                label=f"crossovers below {PM_FLOOR_RADPS:g} rad/s (drift; not a criterion)"
                      + (", worst corner" if worst else ""))
    ax.axhline(req["pm_deg"], color="r", lw=1, label=f"requirement {req['pm_deg']:g}°")
    ax.set_ylabel("rigid-body phase margin [deg]")
    ax.set_ylim(0, 90)
    ax = axes[2]
    for i, c in ((1, "C3"), (2, "C4")):
        y = _col(nominal, f"b{i}_peak_db")
        ax.plot(t, y, c, label=f"mode {i} peak loop gain")
        ph = np.array([bool(r[f"b{i}_phase_stabilised"]) for r in nominal])
        if ph.any():
            ax.plot(t[ph], y[ph], c + "o", ms=3, label=f"mode {i} above −6 dB (phase-stab.)")
        if worst:
            ax.plot(tw, _col(worst, f"b{i}_peak_db"), c + "--", label=f"mode {i}, worst corner")
    ax.axhline(req["bending_db"], color="r", lw=1,
               label=f"requirement {req['bending_db']:g} dB (gain-stabilised)")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylabel("bending peak |L| in band [dB]")
    ax.set_ylim(-50, 30)
    ax = axes[3]
    ax.step(t, _col(nominal, "n_unstable"), "k", where="mid",
            label="nominal: unstable closed-loop poles")
    if worst:
        ax.step(tw, _col(worst, "n_unstable_plants"), "C3--", where="mid",
                label=f"corners with an unstable loop (of {worst[0]['n_plants']})")
        ax.set_yscale("symlog", linthresh=1.0)
    ax.set_ylabel("unstable")
    ax.set_xlabel("flight time [s]")
    for ax in axes:
        _shade(ax, clamped_intervals, step)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[0].set_title("Margins of the flown controller at the actuator input "
                      "(grey: controller clamped to its grid end)")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def plot_nichols(path, w, curves: Mapping[int, np.ndarray], labels: Mapping[int, str],
                 t_s: float, omega_modes: Sequence[float]) -> Path:
    """Write the Nichols chart ``path``; ``curves`` index 0 is the nominal loop."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    req = REQUIREMENTS
    fig, ax = plt.subplots(figsize=(10, 8))
    lo, hi = np.inf, -np.inf
    for index, L in curves.items():
        ph = np.degrees(np.unwrap(np.angle(L)))
        db = 20 * np.log10(np.maximum(np.abs(L), 1e-12))
        # branch: the phase at the first rigid-body gain crossover (or at 1 rad/s) in (−360, 0]
        cross = np.nonzero(np.sign(db[:-1]) != np.sign(db[1:]))[0]
        ref = ph[cross[0]] if cross.size else np.interp(1.0, w, ph)
        ph = ph - 360.0 * np.ceil(ref / 360.0)
        keep = db > -60
        lo, hi = min(lo, ph[keep].min()), max(hi, ph[keep].max())
        nominal = index == 0
        ax.plot(ph, db, color="k" if nominal else None, lw=1.6 if nominal else 0.8,
                alpha=1.0 if nominal else 0.7, label=labels.get(index, str(index)))
        if nominal:
            for wm in (0.1, PM_FLOOR_RADPS, 1.0, 3.0, 10.0, *omega_modes):
                k = int(np.argmin(np.abs(w - wm)))
                ax.plot(ph[k], db[k], "k.", ms=5)
                floor = " (PM floor)" if wm == PM_FLOOR_RADPS else ""
                ax.annotate(f"{w[k]:.3g} rad/s{floor}", (ph[k], db[k]), fontsize=7,
                            xytext=(3, 3), textcoords="offset points")
    lo = max(lo, -900.0)
    hi = min(hi, 540.0)
    for k in range(int(np.floor((lo + 180) / 360)) - 1, int(np.ceil((hi + 180) / 360)) + 1):
        c = -180.0 + 360.0 * k
        ax.add_patch(Rectangle((c - req["pm_deg"], -req["gm_db"]), 2 * req["pm_deg"],
                               2 * req["gm_db"], color="r", alpha=0.2, lw=0))
        ax.plot(c, 0.0, "r+", ms=10)
    ax.axhline(req["bending_db"], color="r", lw=0.8, ls=":", label="bending −6 dB")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlim(lo - 20, hi + 20)
    ax.set_ylim(-60, 50)
    ax.set_xlabel("phase of L [deg] (unwrapped)")
    ax.set_ylabel("|L| [dB]")
    ax.set_title(f"Nichols chart at max-Q, t = {t_s:g} s (continuous-equivalent loop; red: "
                 f"exclusion zone ±{req['gm_db']:g} dB × ±{req['pm_deg']:g}°)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
