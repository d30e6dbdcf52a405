"""Robust analysis of the flown controller over the whole uncertainty set (docs/ROBUST_ANALYSIS.md).

Per frozen flight time, with the flown controller on the *nominal* schedule (it knows only the
nominal velocity of that time) and the loop of :mod:`vega_loops.margins` (exact
sampled-data loop: hold, delay, actuator, plant of ``vega linearize``, the table's discrete
controller interpolated as the runtime does):

(a) **worst case over the set**: the 642 plants of :func:`.margins.dispersed_corners` and then
    an optimisation-based search over all 13 parameters of the set (thesis Table 2.3 + TVC
    ±10 % + delay ±10 ms), box-normalised around the centre of each range
    (deviation_i = c_i + h_i·u_i, u ∈ [−1, 1]^13): differential evolution (scipy) started from
    the worst corners, minimising the **disk margin** α of the exact sampled-data loop (skew 0:
    α = 1/max_ω |S − 1/2|, S = 1/(1 + L_d); Seiler, Packard & Gahinet, "An introduction to disk
    margins", IEEE Control Systems 2020) with every unstable loop ranked below every stable one
    by its largest closed-loop |eigenvalue| — so the search returns an unstable plant if it
    finds one and the smallest disk margin otherwise. The largest spectral radius met over all
    evaluations is reported too.
(b) **μ lower bound from (a)**: along the ray from the centre through the worst case found,
    u(s) = s·u*, the smallest scale s* at which the exact loop is unstable (scan, then bisection)
    gives μ ≥ 1/s* over the box (the box scaled by s* contains an unstable plant). Scales are
    capped where a parameter would leave its physical domain (relative deviations > −0.9, total
    delay ≥ 0) and at :data:`S_MAX`; if none is found the bound is reported as ``None`` (not
    established along that ray). The μ *upper* bound over an LFT of the set (Slycot's
    ``ab13md``, :mod:`.mu_analysis`) is computed beside it unless switched off: μ_upper < 1
    with a stable centre proves every plant of the set stable (to the fit-error cover, a
    sampled bound); the gap between the two bounds is reported.
(c) **disk margins** at the actuator input, nominal and at the worst case: α, the disk gain
    margin DGM = (2 + α)/(2 − α) (a simultaneous gain change in [1/DGM, DGM] …) and disk
    phase margin DPM = 2·atan(α/2) (… or a phase change up to ±DPM, or any combination in the
    disk, keeps the loop stable). :func:`disk_margin` is checked against python-control's
    ``disk_margins`` on rational loops (tests/synthesis/test_robust.py).

The worst case found is analysed with the classical margins of :func:`.margins.analyse_loop`
(rigid-body GM/PM, bending criteria) on the fine grid, each margin with the frequency of its
crossover; the phase margin is the distance of the phase from −180° at the closest gain
crossover at or above the frozen-time floor (:data:`vega_loops.margins.PM_FLOOR_RADPS`,
docs/FLIGHT_DESIGN.md §3.1).
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from vega_loops import margins as M

__all__ = ["S_MAX", "SEARCH", "disk_margin", "disk_gm_pm", "RobustPoint", "robust_point",
           "worst_case", "destabilising_scale", "analyse_time", "worst_case_bending_ok", "sweep",
           "SUMMARY_KEYS",
           "summarise"]

S_MAX = 3.0
"""Largest box scale searched for a destabilising plant along the worst-case ray (assumption:
three times the set's ranges, e.g. the first bending frequency −55 %, is far beyond anything
the set claims; the bound is reported as not established beyond it)."""

SEARCH = {"popsize": 6, "maxiter": 60, "n_corners_init": 20}
"""Differential-evolution budget per time (assumption, measured on the shipped table: doubling
it to 120 generations lowers the worst disk margin found by 0.06 %, 0.75 % and 0.03 % at 10, 50
and 95 s; ≈ 5 400 loop evaluations ≈ 2.5 s per time on one core)."""

_UNSTABLE_EPS = 1e-6    # |z| > 1 + ε: unstable (as margins.sampled_data_stability)


# ---------------------------------------------------------------------------- disk margins
def disk_margin(L: np.ndarray) -> tuple[float, int]:
    """Balanced (skew 0) disk margin of a SISO loop sampled on a frequency grid.

    α = 1 / max_ω |S(jω) − 1/2|, S = 1/(1 + L) (Seiler et al. 2020, Eq. for σ = 0). Valid for a
    loop whose closed loop is stable (the caller checks); 0 where 1 + L vanishes.

    Returns
    -------
    alpha, index
        The disk margin and the grid index of the critical frequency.
    """
    L = np.asarray(L, dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        dev = np.abs(1.0 / (1.0 + L) - 0.5)
    dev = np.where(np.isfinite(dev), dev, np.inf)
    k = int(np.argmax(dev))
    return (0.0 if not np.isfinite(dev[k]) else float(1.0 / dev[k])), k


def disk_gm_pm(alpha: float) -> tuple[float, float]:
    """Disk gain margin [dB] and disk phase margin [deg] of a balanced disk margin α:
    DGM = 20·log10((2 + α)/(2 − α)) (inf for α ≥ 2), DPM = 2·atan(α/2)."""
    gm = math.inf if alpha >= 2.0 else 20.0 * math.log10((2.0 + alpha) / (2.0 - alpha))
    return gm, math.degrees(2.0 * math.atan(alpha / 2.0))


# ------------------------------------------------------------------------- one frozen time
@dataclass
class RobustPoint:
    """One frozen time's loop pieces that do not depend on the plant."""

    t_s: float
    context: object
    uset: object
    names: tuple
    centre: np.ndarray          # c_i of each deviation
    half: np.ndarray            # h_i of each deviation
    data: M.LoopData            # fine-grid loop data (flown controller at the nominal velocity)
    w_search: np.ndarray        # search grid [rad/s]
    K_search: np.ndarray        # controller response on the search grid, (nw, ny)
    n_evals: int = 0
    max_radius: float = 0.0          # over the in-box evaluations of worst_case only
    max_radius_dev: dict | None = None
    tracking: bool = False


def robust_point(table, context, t_s: float, uset=None) -> RobustPoint:
    """Precompute the plant-independent parts at flight time ``t_s``."""
    from vega_model.uncertainty import UncertaintySet

    uset = uset if uset is not None else UncertaintySet.from_vehicle(context.vehicle)
    lo = np.array([p.lower for p in uset])
    hi = np.array([p.upper for p in uset])
    data = M.loop_data(table, context, t_s)
    w = M.design_grid(context.parameters(float(t_s)).omega_radps, table.dt_s)
    K = M.discrete_response(*data.K, w, table.dt_s)[:, 0, :]
    return RobustPoint(float(t_s), context, uset, uset.names, 0.5 * (lo + hi), 0.5 * (hi - lo),
                       data, w, K)


def _deviations(pt: RobustPoint, u) -> dict:
    return dict(zip(pt.names, (float(x) for x in pt.centre + pt.half * np.asarray(u))))


def _normalised(pt: RobustPoint, dev: Mapping[str, float]) -> np.ndarray:
    d = np.array([dev[n] for n in pt.names])
    return np.divide(d - pt.centre, pt.half, out=np.zeros_like(d), where=pt.half > 0)


def _evaluate(pt: RobustPoint, dev: Mapping[str, float]) -> tuple[float, float]:
    """(largest closed-loop |eigenvalue|, disk margin α on the search grid; 0 if unstable)."""
    p, act, tau = M.corner_plant(pt.context, pt.t_s, dev)
    A, B, C = M.plant_loop_ss(p, act, pt.data.input_names)
    model = M.sampled_data_model(A, B, pt.data.dt_s, tau)
    radius = M.sampled_data_stability(model, C, pt.data.K, pt.data.sign,
                                      nyquist=False)["max_abs_eig"]
    pt.n_evals += 1
    if pt.tracking and radius > pt.max_radius:
        pt.max_radius, pt.max_radius_dev = radius, dict(dev)
    if radius > 1.0 + _UNSTABLE_EPS:
        return radius, 0.0
    Gd = M.sampled_data_response(A, B, C, pt.data.dt_s, tau, pt.w_search, model)[:, :, 0]
    L = -pt.data.sign * np.sum(pt.K_search * Gd, axis=1)
    return radius, disk_margin(L)[0]


def _cost(radius: float, alpha: float) -> float:
    """Lower is worse for the vehicle: α for a stable loop, −|z|max ≤ −1 for an unstable one."""
    return -radius if radius > 1.0 + _UNSTABLE_EPS else alpha


def worst_case(pt: RobustPoint, seed: int = 0, search: Mapping = SEARCH) -> dict:
    """(a): the worst of the 642 corners and of a differential-evolution search.

    Returns
    -------
    dict
        ``corner_worst`` (index, deviations, radius, alpha) and ``worst`` (deviations,
        normalised u, radius, alpha, ``source`` "corner" or "search"), ``n_evals``.
    """
    from scipy.optimize import differential_evolution

    corners = M.dispersed_corners(pt.uset)
    pt.tracking = True
    scored = []
    for k, dev in enumerate(corners):
        r, a = _evaluate(pt, dev)
        scored.append((_cost(r, a), k, r, a))
    scored.sort()
    c_cost, c_k, c_r, c_a = scored[0]
    n = len(pt.names)
    pop = max(int(search["popsize"]) * n, 5)
    rng = np.random.default_rng(seed)
    init = [_normalised(pt, corners[k]) for _, k, _, _ in scored[:int(search["n_corners_init"])]]
    init += list(rng.uniform(-1.0, 1.0, size=(pop - len(init), n)))
    best: dict = {"cost": c_cost, "u": _normalised(pt, corners[c_k]), "radius": c_r,
                  "alpha": c_a, "source": "corner"}

    def f(u):
        r, a = _evaluate(pt, _deviations(pt, u))
        c = _cost(r, a)
        if c < best["cost"]:
            best.update(cost=c, u=np.array(u), radius=r, alpha=a, source="search")
        return c

    differential_evolution(f, [(-1.0, 1.0)] * n, init=np.array(init), maxiter=int(search[
        "maxiter"]), seed=seed, polish=False, tol=0.0, updating="immediate")
    pt.tracking = False
    return {"corner_worst": {"corner": int(c_k), "deviations": corners[c_k], "radius": c_r,
                             "alpha": c_a},
            "worst": {"deviations": _deviations(pt, best["u"]), "u": best["u"].tolist(),
                      "radius": best["radius"], "alpha": best["alpha"],
                      "source": best["source"]},
            "n_evals": pt.n_evals}


def _scale_limit(pt: RobustPoint, u: np.ndarray) -> float:
    """Largest s ≤ S_MAX keeping every relative deviation > −0.9 and the total delay ≥ 0."""
    s_max = S_MAX
    tau0 = M.total_delay_s(pt.context.vehicle)
    for i, p in enumerate(pt.uset):
        step = pt.half[i] * u[i]
        if step >= 0.0:
            continue
        floor = -tau0 if p.kind == "absolute" else -0.9
        s_max = min(s_max, (floor - pt.centre[i]) / step)
    return float(s_max)


def destabilising_scale(pt: RobustPoint, u, n_scan: int = 12, n_bisect: int = 10) -> dict:
    """(b): the smallest s (0 < s ≤ the physical limit) with an unstable loop at s·u.

    Returns
    -------
    dict
        ``s_limit`` (scales searched up to), ``s_star`` (None if none found) and
        ``mu_lower`` = 1/s* (None if none found).
    """
    u = np.asarray(u, dtype=float)
    s_lim = _scale_limit(pt, u)

    def unstable(s):
        return _evaluate(pt, _deviations(pt, s * u))[0] > 1.0 + _UNSTABLE_EPS

    scan = np.linspace(s_lim / n_scan, s_lim, n_scan)
    lo = 0.0
    for s in scan:
        if unstable(s):
            hi = s
            for _ in range(n_bisect):
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
            return {"s_limit": s_lim, "s_star": hi, "mu_lower": 1.0 / hi}
        lo = s
    return {"s_limit": s_lim, "s_star": None, "mu_lower": None}


def _fine(pt: RobustPoint, dev: Mapping[str, float]) -> dict:
    """Classical margins, bending criteria and disk margin of one plant on the fine grid."""
    p, act, tau = M.corner_plant(pt.context, pt.t_s, dev)
    loop = M.frozen_loop(pt.data, p, act, tau)
    row = M.extract_margins(pt.data.w_radps, loop.L_d, loop.omega_modes)
    row.update(M.sampled_data_stability(loop.model, loop.C, pt.data.K, pt.data.sign,
                                        nyquist=False))
    alpha, k = disk_margin(loop.L_d) if row["n_unstable"] == 0 else (0.0, 0)
    gm, pm = disk_gm_pm(alpha)
    ok = M.criteria_ok(row)
    row.update(disk_alpha=alpha, disk_gm_db=gm, disk_pm_deg=pm,
               disk_w_radps=float(pt.data.w_radps[k]) if alpha > 0 else float("nan"),
               bending_1_ok=bool(ok["bending_1"]), bending_2_ok=bool(ok["bending_2"]))
    return row


_FINE_KEYS = ("gm_low_db", "w_gm_low_radps", "gm_high_db", "w_gm_high_radps", "pm_deg",
              "w_pm_radps", "pm_signed_deg", "pm_low_deg", "w_pm_low_radps",
              "n_low_gain_crossovers", "b1_peak_db", "b1_w_peak_radps", "b1_pm_deg",
              "b1_w_pm_radps", "b1_gm_db", "b1_w_gm_radps", "b2_peak_db", "b2_w_peak_radps",
              "b2_pm_deg", "b2_w_pm_radps", "b2_gm_db", "b2_w_gm_radps", "bending_1_ok",
              "bending_2_ok", "max_abs_eig", "n_unstable", "disk_alpha", "disk_gm_db",
              "disk_pm_deg", "disk_w_radps")
"""The figures of one plant kept in a row (``nominal_`` / ``worst_`` + key), each margin followed
by the frequency of the crossover it belongs to (:func:`vega_loops.margins.extract_margins`):
``pm_deg`` is the distance of the phase from −180° at the closest gain crossover at or above
:data:`vega_loops.margins.PM_FLOOR_RADPS` (``pm_signed_deg`` its side), ``pm_low_deg`` the same
below the floor (the drift loop's; reported, not a criterion); ``disk_w_radps`` is the
frequency where the disk margin is set."""


def _mu_fields(table, context, t_s: float, uset) -> dict:
    """The μ upper bound of :func:`.mu_analysis.mu_at_time` as flat row fields, with its curve
    over frequency (``mu_curve``)."""
    from vega_analysis.mu_analysis import mu_at_time

    r = mu_at_time(table, context, t_s, uset)
    fit, whole = r["fit_error"], r["whole"]
    return {"mu_upper": r["mu_peak"], "mu_upper_w_radps": r["w_peak_radps"],
            "mu_centre_stable": r["centre_stable"], "mu_fit_loop_rel": fit["loop_rel"],
            "mu_fit_matrix_rel": fit["matrix_rel"], "mu_aliasing_rel": r["aliasing_centre_rel"],
            "mu_blocks": r["n_blocks"], "mu_fallbacks": r["n_fallback"],
            # the whole-matrix ab13md calls: made, whose certificate was the smaller, stopped
            # at the wall-clock limit (there the reduced call's certificate stands, and the
            # bound depends on the machine's speed), and their ab13md time
            "mu_whole_calls": whole["n_calls"], "mu_whole_won": whole["n_better"],
            "mu_whole_stopped": whole["n_timeout"], "mu_whole_time_s": whole["time_s"],
            "mu_time_s": r["time_s"]["total"],
            "mu_curve": {"w_radps": [float(x) for x in r["w_radps"]],
                         "mu_upper": [float(x) for x in r["mu_upper"]]}}


def analyse_time(table, context, t_s: float, seed: int = 0,
                 search: Mapping = SEARCH, mu: bool = True) -> dict:
    """(a), (b) and (c) at one frozen time, and with ``mu`` the μ upper bound
    (:mod:`.mu_analysis`): one flat row (plus ``worst_deviations``,
    ``max_radius_deviations`` and ``mu_curve``)."""
    start = _time.perf_counter()
    pt = robust_point(table, context, t_s)
    wc = worst_case(pt, seed=seed, search=search)
    worst = wc["worst"]
    ray = destabilising_scale(pt, np.array(worst["u"]))
    nominal = _fine(pt, pt.uset.nominal())
    fine = _fine(pt, worst["deviations"])
    row = {"t_s": float(t_s), "v_sched_mps": pt.data.v_sched_mps,
           "clamped": bool(pt.data.clamped), "n_evals": pt.n_evals,
           "worst_source": worst["source"], "worst_radius": worst["radius"],
           "worst_alpha_search": worst["alpha"], "max_radius": pt.max_radius,
           "corner_worst": wc["corner_worst"]["corner"],
           "corner_worst_alpha": wc["corner_worst"]["alpha"],
           "corner_worst_radius": wc["corner_worst"]["radius"],
           "s_limit": ray["s_limit"], "s_star": ray["s_star"], "mu_lower": ray["mu_lower"]}
    row.update({f"nominal_{k}": nominal[k] for k in _FINE_KEYS})
    row.update({f"worst_{k}": fine[k] for k in _FINE_KEYS})
    row["worst_deviations"] = worst["deviations"]
    row["max_radius_deviations"] = pt.max_radius_dev
    if mu:
        row.update(_mu_fields(table, context, t_s, pt.uset))
    row["run_time_s"] = _time.perf_counter() - start
    return row


def worst_case_bending_ok(table, context, t_s: float) -> bool:
    """The bending verdict of the worst case at ``t_s`` (:func:`analyse_time`, seed 0, no μ):
    the plant of smallest disk margin found over the uncertainty set meets the exact bending
    criterion of both modes (≤ −6 dB, or 6 dB / 30° at every in-band crossover). The
    structured design's drift-rate step refuses a scaling that loses it."""
    row = analyse_time(table, context, float(t_s), mu=False)
    return bool(row["worst_bending_1_ok"] and row["worst_bending_2_ok"])


# ---------------------------------------------------------------------------------- sweep
_WORKER: dict = {}


def _init_worker(table_path: str) -> None:
    from vega_gnc.controller_table import load_controller_table
    from vega_model.parameters import default_context

    _WORKER.update(table=load_controller_table(table_path), context=default_context())


def _task(args) -> dict:
    t_s, seed, mu = args
    return analyse_time(_WORKER["table"], _WORKER["context"], t_s, seed=seed, mu=mu)


def sweep(table_path: str, times: Sequence[float], workers: int = 2, seed: int = 0,
          progress: Callable[[str], None] | None = None, mu: bool = True) -> dict:
    """:func:`analyse_time` at every time (``mu``: with the μ upper bound), in ``workers``
    processes (``spawn``, one BLAS thread each; 0: in this process). Progress: one line per
    finished time.

    Returns
    -------
    dict
        ``rows`` (by time), ``run_time_s``, ``workers``.
    """
    start = _time.perf_counter()
    tasks = [(float(t), int(seed), bool(mu)) for t in times]
    rows: list[dict] = []

    def report(row):
        if progress is not None:
            mu_txt = f", mu <= {row['mu_upper']:.3f}" if "mu_upper" in row else ""
            if row.get("mu_whole_stopped"):
                mu_txt += (f" ({row['mu_whole_stopped']} of {row['mu_whole_calls']} whole-matrix "
                           "ab13md calls stopped)")
            progress(f"robust: {len(rows)}/{len(tasks)} t = {row['t_s']:g} s: worst disk "
                     f"margin {row['worst_disk_alpha']:.3f} (max |z| {row['max_radius']:.5f})"
                     f"{mu_txt}, {_time.perf_counter() - start:.0f} s elapsed")

    if workers <= 0:
        _init_worker(table_path)
        for task in tasks:
            rows.append(_task(task))
            report(rows[-1])
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with M.single_thread_blas(), ProcessPoolExecutor(
                max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                initializer=_init_worker, initargs=(str(table_path),)) as pool:
            for row in pool.map(_task, tasks):
                rows.append(row)
                report(row)
    return {"rows": rows, "run_time_s": _time.perf_counter() - start, "workers": workers}


SUMMARY_KEYS = ("nominal_disk_alpha", "worst_disk_alpha", "worst_disk_gm_db", "worst_disk_pm_deg",
                "worst_gm_low_db", "worst_gm_high_db", "worst_pm_deg", "max_radius")

_FREQUENCY_OF = {"nominal_disk_alpha": "nominal_disk_w_radps",
                 "worst_disk_alpha": "worst_disk_w_radps",
                 "worst_disk_gm_db": "worst_disk_w_radps",
                 "worst_disk_pm_deg": "worst_disk_w_radps",
                 "worst_gm_low_db": "worst_w_gm_low_radps",
                 "worst_gm_high_db": "worst_w_gm_high_radps", "worst_pm_deg": "worst_w_pm_radps"}
"""Summary figure -> the row key of the frequency it belongs to (its crossover; for a disk
margin the frequency where it is set)."""


def summarise(rows: Sequence[Mapping]) -> dict:
    """Worst value, time and frequency (``w_radps``: the crossover of a margin) per figure, the
    verdicts of the requirement (robust stability, bending criteria over the dispersed set;
    docs/ROBUST_ANALYSIS.md §1) and, with the μ upper bound, its whole-matrix ab13md calls
    (``mu_whole_*``: made, won, stopped at the wall-clock limit and at which times, time)."""
    out: dict = {"n_times": len(rows)}
    for key in SUMMARY_KEYS:
        pick = max if key == "max_radius" else min
        r = pick(rows, key=lambda row: row[key])
        out[key] = {"value": r[key], "t_s": r["t_s"]}
        if key in _FREQUENCY_OF:
            out[key]["w_radps"] = r.get(_FREQUENCY_OF[key])
    unstable = [r["t_s"] for r in rows if r["max_radius"] > 1.0 + _UNSTABLE_EPS]
    bend = [r["t_s"] for r in rows if not (r["worst_bending_1_ok"] and r["worst_bending_2_ok"])]
    out["unstable_times_s"] = unstable
    out["worst_case_bending_fail_times_s"] = bend
    lows = [r for r in rows if r["mu_lower"] is not None]
    out["mu_lower"] = ({"value": max(r["mu_lower"] for r in lows),
                        "t_s": max(lows, key=lambda row: row["mu_lower"])["t_s"]}
                       if lows else None)
    ups = [r for r in rows if r.get("mu_upper") is not None]
    if ups:
        top = max(ups, key=lambda row: row["mu_upper"])
        gap = [r for r in ups if r["mu_lower"] is not None]
        out["mu_upper"] = {"value": top["mu_upper"], "t_s": top["t_s"],
                           "w_radps": top["mu_upper_w_radps"]}
        out["mu_upper_below_1_times"] = sum(r["mu_upper"] < 1.0 and r["mu_centre_stable"]
                                            for r in ups)
        out["mu_fit_loop_rel"] = max(r["mu_fit_loop_rel"] for r in ups)
        low = max(gap, key=lambda r: r["mu_lower"]) if gap else None
        out["mu_gap"] = ({"lower": low["mu_lower"], "upper_at_same_time": low["mu_upper"],
                          "t_s": low["t_s"]} if low else None)
        # robust stability proved by the bound (to its fit-error cover, a sampled bound)
        out["mu_proves_stability"] = out["mu_upper_below_1_times"] == len(rows)
        for key in ("mu_whole_calls", "mu_whole_won", "mu_whole_stopped", "mu_whole_time_s"):
            out[key] = sum(r[key] for r in ups)
        out["mu_whole_stopped_times_s"] = [r["t_s"] for r in ups if r["mu_whole_stopped"]]
    else:
        out["mu_upper"] = None
    out["robust_stability_pass"] = not unstable
    out["worst_case_bending_pass"] = not bend
    return out
