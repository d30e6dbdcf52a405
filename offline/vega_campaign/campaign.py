"""Monte Carlo dispersion campaigns: the dispersion file, the samples and one dispersed flight.

A campaign flies N dispersed copies of a scenario in process (the closed loop of
:mod:`vega_sim.closed_loop`, bit-identical to the SIL). Sample *i* is a function of the campaign
seed and *i* only (NumPy ``SeedSequence(seed, spawn_key=(i,))``), so it is the same whatever the
worker count or the order samples run in. The draws of one sample come in a fixed order and a
fixed number (two per uncertain parameter, then the wind, the initial attitude and the flight
seed), so changing one parameter's distribution does not move any other draw.

Dispersion file (YAML, ``schema_version: 1``; the shipped default is
``offline/vega_campaign/data/dispersions.yaml``, every number with its source)::

    schema_version: 1
    uncertainty:                    # every parameter of the uncertainty set (vega_model)
      default: uniform              # uniform | normal | nominal
      overrides: {}                 # name: uniform | normal | nominal
    wind:
      profile_scale: [0.7, 1.3]     # uniform: the flown profile is S·V_w(h − H)
      profile_shift_m: [-1000, 1000]
      profile_reverse_probability: 0.0   # the profile blows toward −z with this probability
      turbulence: light             # none | light | moderate | severe (thesis Table 2.4)
      gust: null                    # or {probability, amplitude_mps: [lo, hi], start_s: [lo, hi]}
    initial_pitch_sigma_deg: 0.1    # normal, initial attitude error
    sensor_noise: true

``uniform``: the deviation uniform within its bounds; ``normal``: zero mean with the larger
bound at 3σ, truncated at the bounds; ``nominal``: 0. The delay deviation is then rounded to
whole milliseconds (the loop's time grid, vega_bus.timing).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from vega_core.documents import field_error as _fail
from vega_core.documents import finite_number as _number
from vega_core.documents import mapping_keys as _keys
from vega_core.documents import parse_yaml, read_text

__all__ = ["Dispersions", "load_dispersions", "parse_dispersions", "default_dispersions_path",
           "sample_scenario", "fly_sample", "fly_batch_samples", "flight_metrics", "METRICS",
           "STATUS_COLUMNS", "STABILITY_LIMITS", "MARGIN_COLUMNS", "margins_sample", "MACH_BIN",
           "N_MACH_BINS"]

DISTRIBUTIONS = ("uniform", "normal", "nominal")
_INTENSITIES = ("none", "light", "moderate", "severe")

# Per-sample metrics of the results table: name -> (bound key in the requirement spec or None,
# unit). The ratio columns are the worst |value|/bound over the flight (1 = the requirement).
METRICS = {
    "max_abs_q_alpha_pa_deg": "Pa*deg",
    "q_alpha_margin": "1 (worst |Qα|/envelope)",
    "max_abs_z_m": "m",
    "max_abs_zdot_mps": "m/s",
    "max_abs_beta_deg": "deg",
    "int_abs_beta_deg_s": "deg*s",
    "max_abs_theta_deg": "deg",
    "max_abs_bending_q1": "modal",
    "max_abs_bending_q2": "modal",
    "rate_limited_s": "s (nozzle at >= 99 % of its rate limit)",
}
# A flight is STABLE when no bending mode and no nozzle loop runs away (thesis Table 3.1 does
# not catch a bending limit cycle, docs/MONTE_CARLO.md §2). Assumption: "bending amplitudes
# within a few times nominal and the nozzle never riding its rate limit", i.e.
# |q1| <= 1.0 and |q2| <= 0.1 modal units, about ten times the nominal flight's 0.08 and
# 0.0095, and at most 0.5 s in total at the rate limit.
STABILITY_LIMITS = {"max_abs_bending_q1": 1.0, "max_abs_bending_q2": 0.1,
                    "rate_limited_s": 0.5}
# Mach bins of the per-sample Qα profile (the band plot): max |Qα| in [k·0.1, (k+1)·0.1)
MACH_BIN = 0.1
N_MACH_BINS = 60
STATUS_COLUMNS = ("n_ok", "n_velocity_clamped", "n_limited", "n_hold_last", "n_safe_zero")


@dataclass(frozen=True)
class Dispersions:
    """A validated dispersion file (module docstring)."""

    path: str
    text: str
    uncertainty: tuple[tuple[str, str], ...]          # (name, distribution), set order
    profile_scale: tuple[float, float]
    profile_shift_m: tuple[float, float]
    profile_reverse_probability: float
    turbulence: str
    gust: Mapping[str, Any] | None
    initial_pitch_sigma_deg: float
    sensor_noise: bool


def default_dispersions_path() -> Path:
    """The shipped dispersion file."""
    return Path(__file__).resolve().parent / "data" / "dispersions.yaml"


def _interval(path, key, value, lo_limit=-math.inf, hi_limit=math.inf) -> tuple[float, float]:
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value)):
        raise _fail(path, key, f"must be [low, high], got {value!r}")
    lo, hi = float(value[0]), float(value[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise _fail(path, key, f"must be finite with low <= high, got {value!r}")
    if lo < lo_limit or hi > hi_limit:
        raise _fail(path, key, f"must lie within [{lo_limit:g}, {hi_limit:g}], got {value!r}")
    return lo, hi


def parse_dispersions(text: str, path: str = "<dispersions>") -> Dispersions:
    """Parse and validate a dispersion file's text (one line naming the file and the field
    on any problem, :class:`vega_core.errors.BadFile`)."""
    from vega_model.uncertainty import UNCERTAINTY_NAMES

    tree = parse_yaml(text, path)
    _keys(path, "", tree, ("schema_version", "uncertainty", "wind", "initial_pitch_sigma_deg",
                           "sensor_noise"))
    if tree["schema_version"] != 1:
        raise _fail(path, "schema_version", f"must be 1, got {tree['schema_version']!r}")
    unc = _keys(path, "uncertainty", tree["uncertainty"], ("default",), ("overrides",))
    default = unc["default"]
    if default not in DISTRIBUTIONS:
        raise _fail(path, "uncertainty.default", f"must be one of {', '.join(DISTRIBUTIONS)}, "
                                                 f"got {default!r}")
    overrides = unc.get("overrides") or {}
    if not isinstance(overrides, Mapping):
        raise _fail(path, "uncertainty.overrides", "must be a mapping")
    for name, kind in overrides.items():
        if name not in UNCERTAINTY_NAMES:
            raise _fail(path, f"uncertainty.overrides.{name}",
                        f"unknown parameter (known: {', '.join(UNCERTAINTY_NAMES)})")
        if kind not in DISTRIBUTIONS:
            raise _fail(path, f"uncertainty.overrides.{name}",
                        f"must be one of {', '.join(DISTRIBUTIONS)}, got {kind!r}")
    wind = _keys(path, "wind", tree["wind"], ("profile_scale", "profile_shift_m",
                                              "profile_reverse_probability", "turbulence",
                                              "gust"))
    turbulence = wind["turbulence"]
    if turbulence not in _INTENSITIES:
        raise _fail(path, "wind.turbulence", f"must be one of {', '.join(_INTENSITIES)}, "
                                             f"got {turbulence!r}")
    gust = wind["gust"]
    if gust is not None:
        g = _keys(path, "wind.gust", gust, ("probability", "amplitude_mps", "start_s"))
        gust = {"probability": _number(path, "wind.gust.probability", g["probability"], 0, 1),
                "amplitude_mps": _interval(path, "wind.gust.amplitude_mps", g["amplitude_mps"],
                                           -50.0, 50.0),
                "start_s": _interval(path, "wind.gust.start_s", g["start_s"], 0.0, 110.0)}
    sensor_noise = tree["sensor_noise"]
    if not isinstance(sensor_noise, bool):
        raise _fail(path, "sensor_noise", f"must be true or false, got {sensor_noise!r}")
    return Dispersions(
        path=path, text=text,
        uncertainty=tuple((n, str(overrides.get(n, default))) for n in UNCERTAINTY_NAMES),
        profile_scale=_interval(path, "wind.profile_scale", wind["profile_scale"], -3.0, 3.0),
        profile_shift_m=_interval(path, "wind.profile_shift_m", wind["profile_shift_m"],
                                  -10_000.0, 10_000.0),
        profile_reverse_probability=_number(path, "wind.profile_reverse_probability",
                                            wind["profile_reverse_probability"], 0.0, 1.0),
        turbulence=turbulence, gust=gust,
        initial_pitch_sigma_deg=_number(path, "initial_pitch_sigma_deg",
                                        tree["initial_pitch_sigma_deg"], 0.0, 10.0),
        sensor_noise=sensor_noise)


def load_dispersions(path: str | Path | None = None) -> Dispersions:
    """Load and validate a dispersion file (default: the shipped one)."""
    p = Path(path) if path is not None else default_dispersions_path()
    return parse_dispersions(read_text(p, "dispersion file"), str(p))


def _draw_deviation(kind: str, lower: float, upper: float, u: float, n: float) -> float:
    if kind == "nominal":
        return 0.0
    if kind == "uniform":
        return lower + (upper - lower) * u
    sigma = max(abs(lower), abs(upper)) / 3.0          # normal: the larger bound at 3σ
    return float(min(max(sigma * n, lower), upper))     # truncated at the bounds


def sample_scenario(base, disp: Dispersions, campaign_seed: int, index: int):
    """Scenario of sample ``index`` and its dispersed values (a flat dict).

    Parameters
    ----------
    base
        The scenario dispersed (:class:`vega_sim.scenario.Scenario`).
    disp
        The dispersions.
    campaign_seed, index
        Campaign seed (≥ 0) and sample index (≥ 0).
    """
    from vega_model.uncertainty import UncertaintySet
    from vega_model.vehicle_data import load_vehicle_data
    from vega_sim.scenario import GustSettings

    rng = np.random.default_rng(np.random.SeedSequence(int(campaign_seed),
                                                       spawn_key=(int(index),)))
    uset = UncertaintySet.from_vehicle(load_vehicle_data())
    values: dict[str, Any] = {}
    deviations = {}
    for name, kind in disp.uncertainty:
        u, n = float(rng.random()), float(rng.standard_normal())  # always two draws each
        par = uset[name]
        deviations[name] = _draw_deviation(kind, par.lower, par.upper, u, n)
        if name == "delay_s":   # the loop runs on a millisecond grid (vega_bus.timing)
            deviations[name] = round(deviations[name] * 1000.0) / 1000.0
        values[name] = deviations[name]
    u_scale, u_shift, u_rev, u_gust, u_amp, u_start = (float(u) for u in rng.random(6))
    scale = disp.profile_scale[0] + (disp.profile_scale[1] - disp.profile_scale[0]) * u_scale
    if u_rev < disp.profile_reverse_probability:
        scale = -scale
    shift = disp.profile_shift_m[0] + (disp.profile_shift_m[1] - disp.profile_shift_m[0]) * u_shift
    gust = None
    if disp.gust is not None and u_gust < disp.gust["probability"]:
        lo, hi = disp.gust["amplitude_mps"]
        s_lo, s_hi = disp.gust["start_s"]
        gust = GustSettings(start_s=round(s_lo + (s_hi - s_lo) * u_start, 3),
                            amplitude_mps=lo + (hi - lo) * u_amp,
                            duration_s=load_vehicle_data()["wind.gust.duration_s"])
    theta0 = math.radians(disp.initial_pitch_sigma_deg) * float(rng.standard_normal())
    seed = int(rng.integers(0, 2 ** 63 - 1))
    values.update(profile_scale=scale, profile_shift_m=shift,
                  gust_amplitude_mps=0.0 if gust is None else gust.amplitude_mps,
                  gust_start_s=math.nan if gust is None else gust.start_s,
                  initial_pitch_rad=base.initial_state.theta_rad + theta0)
    wind = dataclasses.replace(base.wind, profile_scale=scale, profile_shift_m=shift,
                               turbulence=disp.turbulence, gust=gust)
    scenario = dataclasses.replace(
        base, name=f"{base.name}_mc{index}", wind=wind, seed=seed,
        sensor_noise=disp.sensor_noise,
        uncertainty=tuple(sorted((k, float(v)) for k, v in deviations.items() if v != 0.0)),
        initial_state=dataclasses.replace(base.initial_state,
                                          theta_rad=base.initial_state.theta_rad + theta0))
    return scenario, values


@lru_cache(maxsize=4)
def _table(path: str):
    from vega_gnc.controller_table import load_controller_table

    return load_controller_table(path)


def flight_metrics(result) -> dict[str, Any]:
    """The per-sample metrics of one flight (:data:`METRICS`, status counts, verdict).

    ``verdict`` is ``pass`` when every gating requirement of Table 3.1 passes AND the flight is
    stable (:data:`STABILITY_LIMITS`); ``failed`` names what did not (requirement keys, and
    ``stability`` when a limit is exceeded)."""
    from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_LIMITED, STATUS_OK,
                                             STATUS_SAFE_ZERO, STATUS_VELOCITY_CLAMPED)
    from vega_model.vehicle_data import load_vehicle_data
    from vega_sim.requirements import load_requirements

    spec = load_requirements()
    report = result.metrics(spec)
    rate_limit = load_vehicle_data()["actuator.rate_limit_radps"]
    env = np.interp(result.mach, spec.envelope_mach, spec.envelope_pa_rad)
    qa = np.abs(result.q_alpha_pa_rad)
    beta = np.abs(result.beta_rad)
    dt = np.diff(result.act_t_s)
    row = {
        "max_abs_q_alpha_pa_deg": float(np.degrees(qa.max())),
        "q_alpha_margin": float((qa / env).max()),
        "max_abs_z_m": float(np.abs(result.z_m).max()),
        "max_abs_zdot_mps": float(np.abs(result.z_dot_mps).max()),
        "max_abs_beta_deg": float(np.degrees(beta.max())),
        "int_abs_beta_deg_s": float(np.degrees(np.sum(0.5 * (beta[1:] + beta[:-1]) * dt))),
        "max_abs_theta_deg": float(np.degrees(np.abs(result.theta_rad).max())),
        "max_abs_bending_q1": float(np.abs(result.bending_q[:, 0]).max()),
        "max_abs_bending_q2": float(np.abs(result.bending_q[:, 1]).max()),
        "rate_limited_s": float(np.sum(np.abs(result.beta_dot_radps[1:]) >= 0.99 * rate_limit)
                                * (dt.mean() if dt.size else 0.0)),
    }
    bins = np.minimum((np.asarray(result.mach) / MACH_BIN).astype(int), N_MACH_BINS - 1)
    profile = np.full(N_MACH_BINS, np.nan)
    np.fmax.at(profile, bins, np.degrees(qa))
    row["q_alpha_profile_pa_deg"] = [float(x) for x in profile]
    for col, status in zip(STATUS_COLUMNS, (STATUS_OK, STATUS_VELOCITY_CLAMPED, STATUS_LIMITED,
                                            STATUS_HOLD_LAST, STATUS_SAFE_ZERO)):
        row[col] = int(np.count_nonzero(result.cmd_status == status))
    failed = [r.key for r in report.results if r.gating and not r.passed]
    row["stable"] = all(row[k] <= v for k, v in STABILITY_LIMITS.items())
    if not row["stable"]:
        failed.append("stability")
    row.update(verdict="fail" if failed else "pass", failed=",".join(failed))
    return row


def _row(index: int, scenario, values: Mapping[str, Any], result) -> dict[str, Any]:
    """The results row of sample ``index`` (its scenario, dispersed values and flight)."""
    return {"sample": int(index), "seed": int(scenario.seed), **values, **flight_metrics(result)}


def fly_sample(scenario_yaml: str, table_path: str, dispersions_text: str, campaign_seed: int,
               index: int) -> dict[str, Any]:
    """Fly sample ``index`` in process and return its results row (picklable arguments, so
    that a Dask worker can run it)."""
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import parse_scenario

    t0 = time.perf_counter()
    base = parse_scenario(scenario_yaml, "<campaign scenario>")
    disp = parse_dispersions(dispersions_text, "<campaign dispersions>")
    scenario, values = sample_scenario(base, disp, campaign_seed, index)
    row = _row(index, scenario, values, run_scenario(scenario, _table(table_path)))
    row["wall_s"] = time.perf_counter() - t0
    return row


def fly_batch_samples(scenario_yaml: str, table_path: str, dispersions_text: str,
                      campaign_seed: int, indices) -> list[dict[str, Any]]:
    """Fly the samples ``indices`` as one batch (:func:`vega_sim.batch.fly_batch`) and return
    their results rows, in the order of ``indices``: for each sample the row
    :func:`fly_sample` returns, the same numbers (the batched engine equals the per-flight
    path bit for bit, tests/sim/test_batch.py), except ``wall_s``, which is the batch's wall
    time divided equally among its samples.

    Samples the batched engine does not fly (:func:`vega_sim.batch.batch_refusal`: a linear
    plant, the thesis' constant-driven Dryden wind, or anything not shared with the first
    batchable sample) are flown one by one through
    :func:`vega_sim.closed_loop.run_scenario`, as :func:`fly_sample` flies them. Only the
    rows leave the task: the flights' records are dropped once their metrics are formed.
    Picklable arguments, so that a Dask worker can run a batch as one task."""
    from vega_model.parameters import default_context
    from vega_sim.batch import batch_refusal, fly_batch
    from vega_sim.closed_loop import run_scenario
    from vega_sim.scenario import parse_scenario

    t0 = time.perf_counter()
    base = parse_scenario(scenario_yaml, "<campaign scenario>")
    disp = parse_dispersions(dispersions_text, "<campaign dispersions>")
    table = _table(table_path)
    context = default_context()
    indices = [int(i) for i in indices]
    drawn = [sample_scenario(base, disp, campaign_seed, i) for i in indices]
    lead = next((s for s, _ in drawn if batch_refusal(s, s, context) is None), None)
    together = [k for k, (s, _) in enumerate(drawn)
                if lead is not None and batch_refusal(s, lead, context) is None]
    rows: list[dict[str, Any] | None] = [None] * len(indices)
    if together:
        results = fly_batch([drawn[k][0] for k in together], table, context=context)
        for k, result in zip(together, results):
            rows[k] = _row(indices[k], *drawn[k], result)
        del results, result            # the batch's records (≈ 9 MB per 100-s flight)
    for k, row in enumerate(rows):
        if row is None:
            rows[k] = _row(indices[k], *drawn[k], run_scenario(drawn[k][0], table))
    wall = (time.perf_counter() - t0) / max(len(rows), 1)
    for row in rows:
        row["wall_s"] = wall
    return rows


MARGIN_COLUMNS = ("pm_deg", "gm_low_db", "gm_high_db", "b1_peak_db", "b2_peak_db")


def margins_sample(table_path: str, dispersions_text: str, campaign_seed: int, index: int,
                   times_s) -> dict[str, Any]:
    """Classical margins of the flown controller at frozen times for the plant of sample
    ``index`` (the deviations of :func:`sample_scenario`; the controller on the nominal
    schedule), as one row: the dispersed values, per time ``pm_deg@T`` … ``n_unstable@T``,
    and the worst over the times (``worst_pm_deg``, …, ``unstable_times``)."""
    from vega_loops import margins as mg
    from vega_model.parameters import default_context
    from vega_sim.scenario import load_scenario

    t0 = time.perf_counter()
    context = default_context()
    disp = parse_dispersions(dispersions_text, "<campaign dispersions>")
    _, values = sample_scenario(load_scenario("nominal"), disp, campaign_seed, index)
    deviations = {k: values[k] for k, _ in disp.uncertainty}
    table = _table(table_path)
    row: dict[str, Any] = {"sample": int(index), **deviations}
    worst = {c: math.inf for c in ("pm_deg", "gm_low_db", "gm_high_db")}
    worst.update(b1_peak_db=-math.inf, b2_peak_db=-math.inf)
    unstable = []
    for t in times_s:
        data = mg.loop_data(table, context, float(t))
        p, act, tau = mg.corner_plant(context, float(t), deviations)
        r = mg.analyse_loop(data, p, act, tau, nyquist=False)
        for c in MARGIN_COLUMNS:
            row[f"{c}@{t:g}"] = float(r[c])
        row[f"n_unstable@{t:g}"] = int(r["n_unstable"])
        if r["n_unstable"]:
            unstable.append(float(t))
        for c in ("pm_deg", "gm_low_db", "gm_high_db"):
            if math.isfinite(r[c]):
                worst[c] = min(worst[c], float(r[c]))
        for c in ("b1_peak_db", "b2_peak_db"):
            worst[c] = max(worst[c], float(r[c]))
    row.update({f"worst_{c}": v for c, v in worst.items()})
    row["unstable_times"] = ",".join(f"{t:g}" for t in unstable)
    row["verdict"] = "fail" if unstable else "pass"
    row["failed"] = "stability" if unstable else ""
    row["wall_s"] = time.perf_counter() - t0
    return row
