"""``vega synth``: the whole offline chain from the vehicle model to the flight table.

Stages (each timed and reported): weighted plants on the grid → frozen-point LTI lower
bounds → rate-bounded LPV synthesis (γ_min, back-off γ) → quadratic synthesis (ordering
check) → verification (dense certificate, frozen-point sweep with the interpolated
controller, margins) → export of the controller table (Tustin at the controller rate).

Grids: ``thesis`` = t = 10, 20, …, 90 s (thesis §4.3.2); ``refined`` = those plus the kinks
of the plant data (thrust breakpoints, wind-profile altitudes), gaps ≤ 5 s; ``full`` = 0–100 s
placed evenly in
velocity between 2 s and 100 s (the thesis found no feasible design there; we report what we
get). Rate bounds: computed the thesis' way from our trajectory (§4.3.2: min/max of a moving
mean of dv/dt over 1–100 s, see :func:`rate_bounds_from_trajectory`).
"""

from __future__ import annotations

import dataclasses
import json
import time
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from vega_core.errors import BadArgument

from vega_loops.export import write_controller_table
from vega_lpv.frozen_point import frozen_point_gamma
from vega_lpv.gridded_plant import GriddedPlant
from vega_lpv.interconnection import GRID_TIMES_S, weighted_plant
from vega_lpv.lpv_synthesis import synthesize
from vega_lpv.verification import (bending_rate_term, dense_certificate,
                                            frozen_point_sweep, loop_margins, time_at_velocity)
from vega_lpv.weights import WEIGHT_SETS

__all__ = ["thesis_scenario_metrics", "GRIDS", "RATE_BOXES", "SOLVER_PATHS", "grid_times",
           "rate_bounds_from_trajectory", "rate_box", "gridded_plant", "SynthesisReport",
           "run_synthesis", "DEFAULT_TABLE", "DEFAULT_SOLVER_PATH"]

# Solver paths of the LPV synthesis (docs/SYNTHESIS.md §8): "ipm" = the in-house interior point
# (sdp_ipm.py) on the Schur-reduced stage-1 LMIs and, on the self-dual embedding, for stage 2,
# Clarabel then SCS as fallbacks (solves the 3-, 9- and 26-point problems); "hybrid" = Clarabel
# on the Schur-reduced stage 1, the IPM for stage 2; "clarabel" = the path that produced the
# shipped lpv_controller.npz. "ipm" is the default of `vega synth` (DEFAULT_SOLVER_PATH): it
# meets the time targets (9-point synthesis ≤ 60 s, `vega synth` ≤ 120 s) on the quiet 2-core
# machine with γ within 0.5 % and the certificate passing (docs/SYNTHESIS.md §8).
SOLVER_PATHS = {
    "ipm": {"solver": "IPM", "fallback": ("CLARABEL", "SCS"), "stage1_form": "reduced"},
    "hybrid": {"solver": "CLARABEL", "fallback": "SCS", "stage1_form": "reduced",
               "stage2_solvers": ("IPM", "CLARABEL", "SCS")},
    "clarabel": {"solver": "CLARABEL", "fallback": "SCS", "stage1_form": "full"},
}

DEFAULT_SOLVER_PATH = "ipm"

GRIDS = ("thesis", "refined", "full")
RATE_BOXES = ("with_frozen", "thesis")
DEFAULT_TABLE = (Path(__file__).resolve().parents[2] / "ros2_ws" / "src" / "vega_gnc" / "config"
                 / "lpv_controller.npz")
# Thesis: a 300-sample moving mean of its 4996 samples over 100 s ≈ 6.0 s, evaluated with
# end-shrinking windows (MATLAB movmean) on 0–100 s data, min/max taken over 1–100 s.
_RATE_WINDOW_S = 300 * 100.0 / 4995
_FULL_GRID_POINTS = 13  # assumption: ≈ 1.4× the thesis' density over a 25 % longer span


def grid_times(kind: str, context, weights=None) -> np.ndarray:
    """Flight times [s] of the grid points (``weights``: the weight set, for the ``refined``
    grid's weight kinks; default the shipped set)."""
    if kind == "thesis":
        return np.array(GRID_TIMES_S)
    if kind == "refined":
        return _refined_grid(context, weights or WEIGHT_SETS["shipped"])
    if kind == "full":
        fc = context.conditions
        v_lo, v_hi = np.interp([2.0, 100.0], fc.t_s, fc.column("v_mps"))
        return time_at_velocity(np.linspace(v_lo, v_hi, _FULL_GRID_POINTS), context)
    raise BadArgument(f"--grid {kind!r}: expected one of {', '.join(GRIDS)}")


def _refined_grid(context, weights, max_gap_s: float = 5.0) -> np.ndarray:
    """The thesis' points plus the kinks of the plant data in between, gaps ≤ ``max_gap_s``.

    The weighted plant is piecewise smooth in flight time: the thrust table is linear between
    its breakpoints (vehicle.yaml ``propulsion.thrust_time_s``), the steady wind profile
    (Eq. 2.54) changes form at H_l, H_f − H_u and H_f, and W_Qα = 1/(α_max max(Q, Q_floor))
    has a kink where Q crosses Q_floor. A Lyapunov matrix quadratic in ρ fitted on either side
    of such a kink did not hold across it (docs/SYNTHESIS.md §5), so the kinks are grid
    points; gaps longer than ``max_gap_s`` are split evenly.
    """
    data, fc = context.vehicle, context.conditions
    lo, hi = GRID_TIMES_S[0], GRID_TIMES_S[-1]
    thrust = np.asarray(data["propulsion.thrust_time_s"], dtype=float)
    h_l, h_u, h_f = (data[f"wind.profile.{k}"] for k in ("h_lower_m", "h_upper_m", "h_final_m"))
    moving = (fc.t_s >= 2.0) & (fc.t_s <= 100.0)          # h(t) increasing
    wind = np.interp([h_l, h_f - h_u, h_f], fc.column("h_m")[moving], fc.t_s[moving])
    q = fc.column("q_pa") - weights.q_alpha_q_floor_pa
    crossing = np.flatnonzero(np.sign(q[:-1]) * np.sign(q[1:]) < 0)
    q_floor = fc.t_s[crossing] - q[crossing] * (fc.t_s[crossing + 1] - fc.t_s[crossing]) / (
        q[crossing + 1] - q[crossing])
    knots = np.concatenate([thrust, wind, q_floor])
    grid = np.array(GRID_TIMES_S)
    # a kink within 1 s of a thesis point is represented by that point
    knots = knots[(knots > lo) & (knots < hi)
                  & (np.min(np.abs(knots[:, None] - grid[None, :]), axis=1) >= 1.0)]
    times = np.unique(np.round(np.concatenate([grid, knots]), 1))
    filled = [times[0]]
    for a, b in zip(times[:-1], times[1:]):
        pieces = int(np.ceil((b - a) / max_gap_s - 1e-9))
        filled += list(np.linspace(a, b, pieces + 1)[1:])
    return np.array(filled)


def rate_bounds_from_trajectory(context) -> tuple[float, float]:
    """Scheduling-rate bounds [m/s²] computed as the thesis did (§4.3.2)."""
    fc = context.conditions
    keep = fc.t_s <= 100.0 + 1e-9
    t, vdot = fc.t_s[keep], fc.column("vdot_mps2")[keep]
    half = int(round(_RATE_WINDOW_S / 2 / (t[1] - t[0])))
    csum = np.concatenate(([0.0], np.cumsum(vdot)))
    lo = np.maximum(np.arange(t.size) - half, 0)
    hi = np.minimum(np.arange(t.size) + half + 1, t.size)
    mean = (csum[hi] - csum[lo]) / (hi - lo)
    sel = t >= 1.0
    return float(mean[sel].min()), float(mean[sel].max())


def rate_box(bounds, kind: str = "with_frozen") -> tuple[float, float]:
    """The ρ̇ box of the synthesis from the trajectory's bounds (lo, hi) [m/s²].

    ``"thesis"``: [lo, hi] as the thesis (all positive; ρ̇ = 0 is not admissible, so the
    frozen-point LTI optima are not lower bounds of its γ, and a frozen closed loop is not
    covered by the certificate). ``"with_frozen"`` (default): [min(lo, 0), hi], which also
    covers constant velocity — frozen operation, the thrust tail-off after 90 s — and makes
    the frozen-point γ_i lower bounds (docs/SYNTHESIS.md §3).
    """
    lo, hi = (float(b) for b in bounds)
    if kind == "thesis":
        return lo, hi
    if kind == "with_frozen":
        return min(lo, 0.0), hi
    raise BadArgument(f"--rate-box {kind!r}: expected one of {', '.join(RATE_BOXES)}")


def gridded_plant(times_s, weights, context):
    """The weighted interconnection at each grid time, as the synthesis' input, with the rate
    term of its frequency-normalised bending coordinates (verification.bending_rate_term)."""
    pts = [weighted_plant(float(t), weights, context) for t in times_s]
    first = pts[0]
    rho = np.array([p.rho_mps for p in pts])
    rate_term = bending_rate_term(context, weights)
    plant = GriddedPlant(rho, np.array([p.A for p in pts]),
                         np.array([p.B for p in pts]), np.array([p.C for p in pts]),
                         np.array([p.D for p in pts]), first.n_w, first.n_u, first.n_e,
                         first.n_y, N=np.array([rate_term(r) for r in rho]))
    return plant, pts


@dataclass
class SynthesisReport:
    """Everything `vega synth` measured (JSON-serialisable via :meth:`as_dict`)."""

    grid: str
    weights: str
    times_s: list
    grid_v_mps: list
    rate_bounds_mps2: tuple
    trajectory_rate_bounds_mps2: tuple = ()
    rate_box: str = "with_frozen"
    gamma_lti: list = field(default_factory=list)
    gamma_min: float = float("nan")
    gamma: float = float("nan")
    gamma_quadratic: float = float("nan")
    conservatism: float = float("nan")
    certificate_grid_max: float = float("nan")
    certificate_dense_max: float = float("nan")
    certificate_dense: dict = field(default_factory=dict)
    frozen: dict = field(default_factory=dict)
    margins: list = field(default_factory=list)
    stage_times_s: dict = field(default_factory=dict)
    solver: dict = field(default_factory=dict)
    table: str = ""
    simulation: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """Plain-data form (floats, lists, dicts)."""
        return json.loads(json.dumps(self.__dict__, default=float))


def _plain(x):
    return [float(v) for v in np.ravel(x)]


def _lti_and_quadratic(points, plant, solver_options):
    """Stages 2 and 4 of the chain (frozen-point LTI bounds, quadratic synthesis): independent
    of the rate-bounded synthesis, so :func:`run_synthesis` runs them in a second process.
    Returns (γ_LTI per point, γ_quadratic, time of stage 2, time of stage 4)."""
    clock = time.perf_counter
    t0 = clock()
    gamma_lti = [float(frozen_point_gamma(p).gamma) for p in points]
    t_lti = clock() - t0
    t0 = clock()
    quadratic = synthesize(plant, rate_bounds=None, backoff=1.0, **solver_options)
    return gamma_lti, float(quadratic.gamma_min), t_lti, clock() - t0


def run_synthesis(grid: str = "refined", weights: str = "shipped", out: str | Path | None = None,
                  context=None, progress: Callable[[str], None] = print,
                  verify: bool = True, n_frozen: int = 121,
                  box: str = "with_frozen", solver_path: str = DEFAULT_SOLVER_PATH,
                  parallel: bool = True) -> SynthesisReport:
    """Run the chain and write the controller table (and ``<out>.json``, the report).

    ``solver_path``: a key of :data:`SOLVER_PATHS` (default :data:`DEFAULT_SOLVER_PATH`).
    ``parallel``: run the frozen-point LTI
    bounds and the quadratic synthesis in a second process while the rate-bounded synthesis
    runs (the machine has two cores); the results are the same either way.
    """
    from vega_model.dynamics import OUTPUTS
    from vega_model.parameters import default_context
    from vega_model.vehicle_data import load_vehicle_data

    if weights not in WEIGHT_SETS:
        raise BadArgument(f"--weights {weights!r}: expected one of {', '.join(WEIGHT_SETS)}")
    if solver_path not in SOLVER_PATHS:
        raise BadArgument(f"solver path {solver_path!r}: expected one of "
                          f"{', '.join(SOLVER_PATHS)}")
    ctx = context or default_context()
    ws = WEIGHT_SETS[weights]
    out = Path(out) if out else DEFAULT_TABLE
    times = grid_times(grid, ctx, ws)
    trajectory_rates = rate_bounds_from_trajectory(ctx)
    rates = rate_box(trajectory_rates, box)
    clock = time.perf_counter

    t0 = clock()
    plant, points = gridded_plant(times, ws, ctx)
    rep = SynthesisReport(grid, weights, _plain(times), _plain(plant.rho), rates,
                          trajectory_rates, box)
    rep.stage_times_s["interconnection"] = clock() - t0
    progress(f"[1/7] weighted plant M(rho): {len(times)} grid points, {plant.A.shape[-1]} states, "
             f"rate box [{rates[0]:.2f}, {rates[1]:.2f}] m/s^2 ({box}; trajectory "
             f"[{trajectory_rates[0]:.2f}, {trajectory_rates[1]:.2f}]) "
             f"({rep.stage_times_s['interconnection']:.1f} s)")

    options = SOLVER_PATHS[solver_path]
    # the quadratic synthesis (one stage, constant X, Y) is solved by the IPM on every path but
    # "clarabel" (on the 26-point grid: γ 1.78386 against Clarabel's 1.78374)
    quadratic_options = SOLVER_PATHS["clarabel" if solver_path == "clarabel" else "ipm"]
    worker = None
    if parallel:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        # spawn, not fork: a worker forked from a process that has run Clarabel (its thread
        # pool) can hang on an inherited lock (e.g. a second run_synthesis in the same process).
        # Spawn re-imports the caller's __main__, so a script without a main guard cannot
        # start the worker: then the two stages run here after all (below).
        worker = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
        side = worker.submit(_lti_and_quadratic, points, plant, quadratic_options)
    else:
        side_result = _lti_and_quadratic(points, plant, quadratic_options)
    try:
        t0 = clock()
        result = synthesize(plant, rate_bounds=rates, **options)
        rep.stage_times_s["lpv_rate_bounded"] = clock() - t0
        t0 = clock()
        if worker is not None:
            try:
                side_result = side.result()
            except BrokenProcessPool:
                progress("second process failed to start; LTI bounds and quadratic synthesis "
                         "run here")
                worker.shutdown()
                worker = None
                side_result = _lti_and_quadratic(points, plant, quadratic_options)
        waited = clock() - t0
    finally:
        if worker is not None:
            worker.shutdown()
    rep.gamma_lti, rep.gamma_quadratic, t_lti, t_quadratic = side_result
    rep.stage_times_s["lti_bounds"] = t_lti
    rep.stage_times_s["lpv_quadratic"] = t_quadratic
    if worker is not None:
        rep.stage_times_s["waited_for_second_process"] = waited
    progress(f"[2/7] frozen-point LTI lower bounds: max {max(rep.gamma_lti):.4f} "
             f"({t_lti:.1f} s{', in a second process' if worker else ''})")
    rep.gamma_min, rep.gamma = float(result.gamma_min), float(result.gamma)
    rep.conservatism = rep.gamma_min / max(rep.gamma_lti)
    rep.certificate_grid_max = float(result.certificate_max_eig)
    rep.solver = {"path": solver_path, "statuses": dict(result.statuses),
                  "solvers": dict(result.solvers),
                  "times_s": {k: float(v) for k, v in result.times_s.items()}}
    progress(f"[3/7] rate-bounded LPV synthesis: gamma_min {rep.gamma_min:.4f}, back-off gamma "
             f"{rep.gamma:.4f}, gamma_min/max gamma_LTI {rep.conservatism:.3f} "
             f"({rep.stage_times_s['lpv_rate_bounded']:.1f} s)")

    progress(f"[4/7] quadratic (rate-unbounded) synthesis: gamma {rep.gamma_quadratic:.4f} "
             f"({t_quadratic:.1f} s{', in a second process' if worker else ''})")

    if verify:
        t0 = clock()
        dense_t, _, worst = dense_certificate(result, ws, ctx, factor=4, physical_rates=True)
        rep.certificate_dense_max = float(worst.max())
        point_worst = worst.max(axis=1)
        rep.certificate_dense = {
            "factor": 4, "n_points": int(dense_t.size), "rate_vertices": list(
                result.rate_vertices or (0.0,)),
            "n_failed": int(np.sum(point_worst >= 0.0)),
            "failed_times_s": _plain(dense_t[point_worst >= 0.0]),
            "worst_t_s": float(dense_t[int(np.argmax(point_worst))]),
            "max_eig_per_time": _plain(point_worst), "times_s": _plain(dense_t)}
        frozen_times = np.linspace(times[0], times[-1], n_frozen)
        for label, rate in (("rate_low", rates[0]), ("rate_high", rates[1])):
            sweep = frozen_point_sweep(result, ws, ctx, frozen_times, rate)
            rep.frozen[label] = {"n": int(frozen_times.size), "all_stable": sweep.all_stable,
                                 "worst_hinf": sweep.worst_hinf,
                                 "worst_t_s": float(frozen_times[int(np.argmax(sweep.hinf))]),
                                 "max_real_eig": float(sweep.max_real_eig.max())}
        rep.margins = [loop_margins(result, ctx, float(t), rates[1]).as_dict() for t in times]
        rep.stage_times_s["verification"] = clock() - t0
        hi = rep.frozen["rate_high"]
        dense = rep.certificate_dense
        progress(f"[5/7] verification: certificate max eig {rep.certificate_grid_max:.2e} at the "
                 f"grid points, on the 4x denser grid {dense['n_failed']} of {dense['n_points']} "
                 f"points fail (worst {rep.certificate_dense_max:.2e} at t={dense['worst_t_s']:.1f}"
                 f" s); {hi['n']} frozen points stable={hi['all_stable']}, worst "
                 f"weighted Hinf {hi['worst_hinf']:.4f} at t={hi['worst_t_s']:.1f} s "
                 f"({rep.stage_times_s['verification']:.1f} s)")

    t0 = clock()
    rate_grid = np.array(rates)
    K = [[result.controller(float(r), float(rd)) for rd in rate_grid] for r in plant.rho]
    mats = [np.array([[k[m] for k in row] for row in K]) for m in range(4)]
    vehicle = load_vehicle_data()
    dt = 1.0 / vehicle["controller.rate_hz"]
    meta = {
        # M(ρ)'s y = r − y_INS with references 0: inputs θ_INS, θ̇_INS, z_INS, ż_INS, sign −1
        "input_names": list(OUTPUTS[1:]), "measurement_sign": -1, "output_name": "beta_cmd_rad",
        "units": {"input": ["rad", "rad/s", "m", "m/s"], "output": "rad",
                  "grid": "m/s", "rate": "m/s^2"},
        "weights": {f.name: getattr(ws, f.name) for f in dataclasses.fields(ws)},
        "weight_set": weights, "grid": grid, "grid_times_s": _plain(times),
        "rate_box": box, "trajectory_rate_bounds_mps2": list(trajectory_rates),
        "synthesis_model": ("M(rho) with bending states eta_i = omega_i(rho) q_i and their rate "
                            "term rho_dot*(d omega_i/d rho)/omega_i in the LMIs "
                            "(docs/SYNTHESIS.md section 2)"),
        "dense_certificate": rep.certificate_dense and {
            k: rep.certificate_dense[k] for k in ("factor", "n_points", "n_failed",
                                                  "failed_times_s", "worst_t_s")},
        "solver": rep.solver, "gamma_lti": rep.gamma_lti, "gamma_quadratic": rep.gamma_quadratic,
    }
    write_controller_table(out, plant.rho, *mats, dt_s=dt, gamma=rep.gamma,
                           gamma_min=rep.gamma_min, rate_bounds_mps2=rates, metadata=meta,
                           rate_grid_mps2=rate_grid)
    rep.table = str(out)
    rep.stage_times_s["export"] = clock() - t0
    progress(f"[6/7] exported {out} (Tustin, dt = {dt:g} s, "
             f"{rep.stage_times_s['export']:.1f} s)")
    if verify:
        t0 = clock()
        rep.simulation = thesis_scenario_metrics(out, ctx, progress)
        rep.stage_times_s["simulation"] = clock() - t0
    report_path = out.with_suffix(".json")
    report_path.write_text(json.dumps(rep.as_dict(), indent=1, sort_keys=True) + "\n")
    progress(f"report: {report_path}")
    return rep


def thesis_scenario_metrics(table_path, context, progress: Callable[[str], None] = print) -> dict:
    """Fly the exported table through the thesis scenario (θ0 = 2°, the thesis' Dryden wind,
    seeded INS noise, 10–90 s) on the linear and the nonlinear plant, in process, exactly as
    the flight software runs it (vega_sim.closed_loop); Table 5.1 metrics with the thesis'
    figures side by side."""
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import load_scenario

    base = load_scenario("thesis")
    out = {}
    for plant in ("linear", "nonlinear"):
        scenario = dataclasses.replace(base, plant=plant)
        report = run_scenario(scenario, table_path, context=context).metrics()
        out[plant] = {
            "passed": report.passed,
            "rows": [{"key": r.key, "value": r.value, "bound": r.bound, "margin": r.margin,
                      "passed": r.passed, "time_s": r.time_s, "unit": r.unit,
                      "thesis": None if r.thesis is None else r.thesis.value}
                     for r in report.results],
            "table": report.table(),
        }
        progress(f"[7/7] thesis scenario, {plant} plant: "
                 f"{'all requirements met' if report.passed else 'REQUIREMENT FAILED'}\n"
                 + report.table())
    return out
