"""Flight-day campaign: statistical winds, day-of-launch re-biasing, launch commit criterion.

Sample *i* of a flight-day campaign (docs/MONTE_CARLO.md, "Flight-day campaign"):

* its **month**: the campaign's one month, or the months in turn (i mod 12 + 1), so that every
  month gets the same share of the samples;
* its **wind**: sample i of that month from the site's statistical wind environment
  (:func:`vega_campaign.wind_environment.sample_profiles`, the campaign seed; sample i depends
  on (seed, month, i) only): the *measured* profile (the sounding) and the *flown* one;
* its **plant, INS, turbulence, gust and initial attitude**: exactly the draws of
  :func:`vega_campaign.campaign.sample_scenario` for (seed, i) — the same plant as sample i of
  the thesis-box campaign — except the steady wind: the flown profile replaces the thesis
  profile's scale and shift;
* its **guidance reference**: re-biased on the measured profile
  (:func:`vega_reference.rebias.rebias_reference`) and written to
  ``DIR/flight_day/NNNNNN_guidance.npz``, which the sample's scenario names; the scenario
  flown is recorded beside it (``NNNNNN_scenario.yaml``), and ``vega mc rerun`` flies that
  file through the ROS 2 nodes;
* its **launch commit criterion** (:mod:`vega_signoff.lcc`) on the measured profile, before it
  flies. Every sample is flown; a no-go sample is *scrubbed*: it counts against the month's
  availability, not against flight-day success, and its row says what would have happened.

Verdicts per row: ``passed_allowable`` (docs/REQUIREMENTS.md §6: the constant Qα allowable in
place of the envelope), ``passed_envelope`` (§2, the thesis-box definition), ``stable``
(:data:`vega_campaign.campaign.STABILITY_LIMITS`) and ``flight_day_verdict``: ``scrubbed``
(LCC no-go), else ``pass`` when the §6 verdict passes and the flight is stable, else ``fail``.
The per-sample references differ, so the batched engine (one reference per batch) refuses them:
a flight-day batch task flies its samples one by one (:func:`vega_sim.closed_loop.run_scenario`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from vega_core.errors import BadArgument, BadFile

__all__ = ["ENVIRONMENTS", "THESIS_BOX", "FLIGHT_DAY", "environment_settings",
           "parse_environment", "sample_month", "FlightDaySample", "flight_day_sample",
           "reference_path", "scenario_path", "fly_flight_day_batch", "flight_day_metrics",
           "summarise_flight_day", "flight_day_markdown", "plot_flight_day",
           "FLIGHT_DAY_METRICS", "NOT_DISPERSED", "PROGRAMME_REASONS"]

THESIS_BOX = "thesis-box"
FLIGHT_DAY = "flight-day"
ENVIRONMENTS = (THESIS_BOX, FLIGHT_DAY)
"""``vega mc run --environment``: the thesis' one profile scaled and shifted (``vega verify``'s
regression campaign) or the flight day (the default: the sign-off)."""

PROGRAMME_REASONS = ("ground_wind",)
"""No-go reasons set by the programme, not by the design: the ground-wind limit is a number
from a precedent (lcc.yaml) that no change of the controller or the guidance moves. The
design's availability (``availability_design``) leaves them out."""

FLIGHT_DAY_METRICS = ("passed_allowable", "passed_envelope", "failed_allowable",
                      "max_abs_q_alpha_time_s", "max_abs_q_alpha_mach")
"""Flight metrics a flight-day row adds to :func:`vega_campaign.campaign.flight_metrics`'s
(``vega mc rerun`` compares both with the bag)."""

NOT_DISPERSED = ("lcc_go", "lcc_reasons", "lcc_predicted_max_q_alpha_pa_deg",
                 "lcc_q_alpha_with_allowance_pa_deg", "lcc_allowance_pa_deg",
                 "lcc_predicted_drift_m", "lcc_drift_with_allowance_m", "lcc_low_speed_ratio",
                 "lcc_ground_wind_mps", "flight_day_verdict", *FLIGHT_DAY_METRICS)
"""Columns of a flight-day row that are results, not dispersed inputs (left out of the
sensitivity plot)."""

SAMPLES_DIR = "flight_day"
"""Where a flight-day campaign records, per sample, the guidance reference it flew and the
scenario it flew (``DIR/flight_day/NNNNNN_guidance.npz``, ``NNNNNN_scenario.yaml``)."""


def environment_settings(site_path=None, month=None, lag_s=None, mode=None,
                         lcc_path=None) -> dict:
    """The ``environment`` block of a flight-day campaign's campaign.json, every input file
    loaded and checked now (one line, exit 2, on a bad one): the site file's and the LCC
    file's text travel with the campaign, so a resume or a rerun uses what the campaign
    used."""
    from vega_campaign.wind_environment import DEFAULT_LAG_S, DEFAULT_MODE, MODES, load_site

    from vega_signoff.lcc import load_lcc

    site = load_site(site_path)
    lcc = load_lcc(lcc_path)
    if month is not None and not 1 <= int(month) <= 12:
        raise BadArgument(f"--month {month}: must be 1..12")
    lag = DEFAULT_LAG_S if lag_s is None else float(lag_s)
    if not (math.isfinite(lag) and 0.0 <= lag <= 86_400.0):
        raise BadArgument(f"--lag-s {lag_s}: must be within 0..86400 s")
    mode = DEFAULT_MODE if mode is None else mode
    if mode not in MODES:
        raise BadArgument(f"--mode {mode}: must be one of {', '.join(MODES)}")
    return {"name": FLIGHT_DAY, "site_path": site.path, "site_yaml": site.text,
            "month": None if month is None else int(month), "lag_s": lag, "mode": mode,
            "lcc_path": lcc.path, "lcc_yaml": lcc.text}


@dataclass(frozen=True, eq=False)
class _Environment:
    site: Any
    lcc: Any
    month: int | None
    lag_s: float
    mode: str


def parse_environment(env: Mapping, where: str = "<campaign.json>") -> _Environment:
    """The environment block of a campaign.json, checked (one line, BadFile, otherwise)."""
    from vega_campaign.wind_environment import MODES

    if not isinstance(env, Mapping) or env.get("name") != FLIGHT_DAY:
        raise BadFile(f"{where}: field 'environment.name': must be {FLIGHT_DAY!r}")
    for key, kind in (("site_path", str), ("site_yaml", str), ("lcc_path", str),
                      ("lcc_yaml", str), ("mode", str)):
        if not isinstance(env.get(key), kind):
            raise BadFile(f"{where}: field 'environment.{key}': must be a JSON string")
    month = env.get("month")
    if month is not None and (isinstance(month, bool) or not isinstance(month, int)
                              or not 1 <= month <= 12):
        raise BadFile(f"{where}: field 'environment.month': must be null or 1..12")
    lag = env.get("lag_s")
    if isinstance(lag, bool) or not isinstance(lag, (int, float)) or not 0 <= lag <= 86_400:
        raise BadFile(f"{where}: field 'environment.lag_s': must be a number in 0..86400")
    if env["mode"] not in MODES:
        raise BadFile(f"{where}: field 'environment.mode': must be one of {', '.join(MODES)}")
    return _cached_environment(env["site_yaml"], env["site_path"], env["lcc_yaml"],
                               env["lcc_path"], month, float(lag), env["mode"])


@lru_cache(maxsize=4)
def _cached_environment(site_yaml, site_path, lcc_yaml, lcc_path, month, lag,
                        mode) -> _Environment:
    from vega_campaign.wind_environment import parse_site

    from vega_signoff.lcc import parse_lcc

    return _Environment(site=parse_site(site_yaml, site_path), lcc=parse_lcc(lcc_yaml, lcc_path),
                        month=month, lag_s=lag, mode=mode)


def sample_month(index: int, month: int | None) -> int:
    """The month of sample ``index``: ``month``, or the months in turn (index mod 12 + 1)."""
    return int(month) if month is not None else int(index) % 12 + 1


def reference_path(out_dir: str | Path, index: int) -> Path:
    """Where sample ``index``'s re-biased guidance reference is written."""
    return Path(out_dir) / SAMPLES_DIR / f"{int(index):06d}_guidance.npz"


def scenario_path(out_dir: str | Path, index: int) -> Path:
    """Where the scenario sample ``index`` flew is recorded (its flown profile inline, its
    reference by absolute path): ``vega mc rerun`` flies this file, not a new draw, because
    the wind sampler's matrix products (BLAS) round differently with another thread count —
    a Dask worker runs one thread, the command line several — and a last-bit change of the
    profile moves the flight's last bits."""
    return Path(out_dir) / SAMPLES_DIR / f"{int(index):06d}_scenario.yaml"


def _record_scenario(path: Path, scenario) -> None:
    """Write the scenario's text atomically (a killed task leaves no half file)."""
    import os
    import tempfile

    from vega_sim.scenario import dump_scenario

    fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
    with os.fdopen(fd, "w") as f:
        f.write(dump_scenario(scenario))
    os.replace(tmp, path)


@dataclass(frozen=True, eq=False)
class FlightDaySample:
    """One flight-day sample: the scenario it flies, its dispersed values (a flat dict), its
    month and its measured and flown profiles (:class:`vega_model.wind.WindTable`)."""

    scenario: Any
    values: dict
    month: int
    measured: Any
    flown: Any


def flight_day_sample(base, disp, campaign_seed: int, index: int, env: _Environment,
                      out_dir: str | Path) -> FlightDaySample:
    """Sample ``index`` of a flight-day campaign (module docstring). Writes its re-biased
    reference to :func:`reference_path` unless the file is there already (a resumed campaign
    or a rerun flies the file the campaign flew; the file is written atomically)."""
    from vega_campaign.campaign import sample_scenario
    from vega_campaign.wind_environment import sample_profiles, sample_table
    from vega_reference.rebias import rebias_reference, write_rebiased_reference

    scenario, values = sample_scenario(base, disp, campaign_seed, index)
    month = sample_month(index, env.month)
    samples = sample_profiles(env.site, month, seed=int(campaign_seed), lag_s=env.lag_s,
                              mode=env.mode, indices=[int(index)])
    measured = sample_table(samples, index, "measured")
    flown = sample_table(samples, index, "flown")
    ref = reference_path(out_dir, index).resolve()
    if not ref.is_file():
        ref.parent.mkdir(parents=True, exist_ok=True)
        design = rebias_reference(measured.altitude_m, measured.wind_mps,
                                  source=measured.source)
        write_rebiased_reference(ref, design, measured.altitude_m, measured.wind_mps,
                                 source=measured.source)
    wind = dataclasses.replace(scenario.wind, profile=flown, profile_scale=1.0,
                               profile_shift_m=0.0)
    scenario = dataclasses.replace(scenario, name=f"{base.name}_fd{int(index)}", wind=wind,
                                   guidance=str(ref))
    values = {k: v for k, v in values.items() if k not in ("profile_scale", "profile_shift_m")}
    w_m, w_f = np.asarray(measured.wind_mps), np.asarray(flown.wind_mps)
    values.update(month=month, measured_max_wind_mps=float(np.abs(w_m).max()),
                  flown_max_wind_mps=float(np.abs(w_f).max()),
                  change_max_mps=float(np.abs(w_f - w_m).max()))
    return FlightDaySample(scenario=scenario, values=values, month=month, measured=measured,
                           flown=flown)


def flight_day_metrics(result, spec=None) -> dict[str, Any]:
    """The verdicts and the Qα peak a flight-day row adds (:data:`FLIGHT_DAY_METRICS`):
    ``passed_allowable`` (§6), ``passed_envelope`` (§2), ``failed_allowable`` (the gating
    requirements missed under §6, and ``stability``), and the time and Mach of max |Qα|."""
    from vega_campaign.campaign import STABILITY_LIMITS, flight_metrics
    from vega_sim.requirements import load_requirements

    spec = spec if spec is not None else load_requirements()
    report = result.metrics(spec)
    failed = [r.key for r in report.with_allowable or () if not r.passed]
    base = flight_metrics(result)
    if not all(base[k] <= v for k, v in STABILITY_LIMITS.items()):
        failed.append("stability")
    qa = np.abs(np.asarray(result.q_alpha_pa_rad))
    i = int(np.argmax(qa))
    return {"passed_allowable": bool(report.passed_with_allowable),
            "passed_envelope": bool(report.passed), "failed_allowable": ",".join(failed),
            "max_abs_q_alpha_time_s": float(result.t_ms[i]) / 1000.0,
            "max_abs_q_alpha_mach": float(result.mach[i])}


@lru_cache(maxsize=4)
def _controller_table(path: str):
    from vega_gnc.controller_table import load_controller_table

    return load_controller_table(path)


def _fly_all(scenarios: list, table) -> list:
    """Every scenario's flight, in order: those the batched engine flies with the first it
    flies in one :func:`vega_sim.batch.fly_batch` call, any other by
    :func:`vega_sim.closed_loop.run_scenario` (the same numbers either way, bit for bit:
    tests/sim/test_batch.py)."""
    from vega_model.parameters import default_context
    from vega_sim.batch import batch_refusal, fly_batch
    from vega_sim.closed_loop import run_scenario

    context = default_context()
    lead = next((s for s in scenarios if batch_refusal(s, s, context) is None), None)
    together = [k for k, s in enumerate(scenarios)
                if lead is not None and batch_refusal(s, lead, context) is None]
    out: list = [None] * len(scenarios)
    if together:
        for k, result in zip(together, fly_batch([scenarios[k] for k in together], table,
                                                 context=context)):
            out[k] = result
    for k, result in enumerate(out):
        if result is None:
            out[k] = run_scenario(scenarios[k], table, context=context)
    return out


def fly_flight_day_batch(scenario_yaml: str, table_path: str, dispersions_text: str,
                         campaign_seed: int, environment: Mapping, out_dir: str,
                         indices) -> list[dict[str, Any]]:
    """Draw, judge (LCC) and fly the flight-day samples ``indices``; their rows, in order.

    Per sample: :func:`flight_day_sample` (its reference re-biased and written), the
    predicted flight and :func:`vega_signoff.lcc.evaluate_lcc` on the measured profile, then
    the sample's flight (go or no-go alike). The predicted flights of the samples fly as one
    batch, then their flights as another (:func:`vega_sim.batch.fly_batch`, each sample with
    its own re-biased reference; equal to ``run_scenario`` bit for bit). ``wall_s`` is the
    task's wall time divided equally among its samples. Picklable arguments, one Dask task
    per call."""
    from vega_campaign.campaign import flight_metrics, parse_dispersions
    from vega_campaign.wind_environment import change_rms_mps
    from vega_sim.requirements import load_requirements
    from vega_sim.scenario import parse_scenario

    from vega_signoff.lcc import drift_allowance_m, evaluate_lcc, predicted_scenario

    t0 = time.perf_counter()
    base = parse_scenario(scenario_yaml, "<campaign scenario>")
    disp = parse_dispersions(dispersions_text, "<campaign dispersions>")
    env = parse_environment(environment)
    table = _controller_table(str(table_path))
    spec = load_requirements()
    alt = env.site.fine_altitude_m
    indices = [int(i) for i in indices]
    samples = []
    for index in indices:
        s = flight_day_sample(base, disp, campaign_seed, index, env, out_dir)
        _record_scenario(scenario_path(out_dir, index), s.scenario)
        samples.append(s)
    verdicts = []
    sigma: dict[int, Any] = {}
    dz: dict[int, Any] = {}
    predicted = _fly_all([predicted_scenario(base, s.measured, s.scenario.guidance)
                          for s in samples], table)
    for k, s in enumerate(samples):
        if s.month not in sigma:
            sigma[s.month] = change_rms_mps(env.site, s.month, env.lag_s)
            dz[s.month] = drift_allowance_m(scenario_yaml, table_path, alt, sigma[s.month],
                                            env.site.change_vertical_correlation_m, env.lcc)
        verdicts.append(evaluate_lcc(predicted[k], s.measured, alt, sigma[s.month],
                                     dz[s.month], env.lcc, spec))
        predicted[k] = None
    del predicted
    flights = _fly_all([s.scenario for s in samples], table)
    rows = []
    for k, (index, s, lcc) in enumerate(zip(indices, samples, verdicts)):
        result, flights[k] = flights[k], None
        row = {"sample": index, "seed": int(s.scenario.seed), **s.values,
               **flight_metrics(result), **flight_day_metrics(result, spec), **lcc.row()}
        del result
        row["flight_day_verdict"] = ("scrubbed" if not row["lcc_go"] else
                                     "pass" if row["passed_allowable"] and row["stable"]
                                     else "fail")
        rows.append(row)
    wall = (time.perf_counter() - t0) / max(len(rows), 1)
    for row in rows:
        row["wall_s"] = wall
    return rows


# ------------------------------------------------------------------------------ statistics

def summarise_flight_day(rows: Sequence[Mapping]) -> dict:
    """``flight_day``, ``availability`` and the side-by-side counts of a flight-day campaign.

    ``flight_day``: n = go samples (flown and judged), passed = go samples passing the §6
    verdict and stable (no bending or nozzle run-away, at most 0.5 s on the rate limit:
    :data:`vega_campaign.campaign.STABILITY_LIMITS`, as the thesis-box summary counts
    ``unstable``), failed = n − passed, scrubbed = no-go samples, lower_bound_90 = the
    one-sided Clopper–Pearson lower bound of the success probability at 90 % confidence.
    ``availability``: per month, the fraction of its samples the LCC lets fly;
    ``availability_design``: the same with the programme limits (:data:`PROGRAMME_REASONS`:
    the ground wind, which the design does not move) left out — what ``vega verify`` gates;
    ``scrub_reasons_by_month``: per month, the count of each no-go reason;
    ``availability_without``: per reason, the availability per month were that criterion
    alone waived (what each criterion costs).
    ``definitions``: pass counts under §6 and under §2 (both with stability), over the go
    samples and over every sample flown (scrubbed ones: "what would have happened")."""
    from vega_campaign.campaign import STABILITY_LIMITS
    from vega_campaign.campaign_run import clopper_pearson_lower

    go = [r for r in rows if r["lcc_go"]]
    n, passed = len(go), sum(1 for r in go if r["flight_day_verdict"] == "pass")
    lo90 = clopper_pearson_lower(passed, n, 0.90)
    months = sorted({int(r["month"]) for r in rows})
    availability = {str(m): sum(1 for r in rows if r["month"] == m and r["lcc_go"])
                    / sum(1 for r in rows if r["month"] == m) for m in months}
    reasons: dict[str, int] = {}
    by_month: dict[str, dict[str, int]] = {str(m): {} for m in months}
    for r in rows:
        for why in filter(None, r["lcc_reasons"].split(",")):
            reasons[why] = reasons.get(why, 0) + 1
            month = by_month[str(int(r["month"]))]
            month[why] = month.get(why, 0) + 1
    # the design's availability: samples whose reasons are programme limits only
    design = {str(m): sum(1 for r in rows if r["month"] == m
                          and set(filter(None, r["lcc_reasons"].split(",")))
                          <= set(PROGRAMME_REASONS))
              / sum(1 for r in rows if r["month"] == m) for m in months}
    # availability if one criterion were waived: samples whose reasons are that one only
    waived = {why: {str(m): sum(1 for r in rows if r["month"] == m
                                and set(filter(None, r["lcc_reasons"].split(","))) <= {why})
                    / sum(1 for r in rows if r["month"] == m) for m in months}
              for why in sorted(reasons)}
    failed_by: dict[str, int] = {}
    for r in go:
        for why in filter(None, r["failed_allowable"].split(",")):
            failed_by[why] = failed_by.get(why, 0) + 1

    def counts(subset, key):
        k = sum(1 for r in subset if r[key] and r["stable"])
        return {"n": len(subset), "passed": k,
                "lower_bound_90": clopper_pearson_lower(k, len(subset), 0.90)}

    scrubbed = [r for r in rows if not r["lcc_go"]]
    return {
        "flight_day": {
            "n": n, "passed": passed, "failed": n - passed, "scrubbed": len(rows) - n,
            "lower_bound_90": lo90,
            "lower_bound_95": clopper_pearson_lower(passed, n, 0.95),
            "demonstrated_99_73_at_90": bool(lo90 >= 0.9973),
            "unstable": sum(1 for r in go if not r["stable"]),
            "rate_limited": sum(1 for r in go
                                if r["rate_limited_s"] > STABILITY_LIMITS["rate_limited_s"]),
            "failed_by_requirement": failed_by,
            "failed_samples": [{"sample": r["sample"], "month": r["month"],
                                "failed": r["failed_allowable"]}
                               for r in go if r["flight_day_verdict"] == "fail"],
            "scrub_reasons": reasons,
        },
        "availability": availability,
        "availability_design": design,
        "scrub_reasons_by_month": by_month,
        "availability_without": waived,
        "definitions": {
            "allowable_section_6": {"go": counts(go, "passed_allowable"),
                                    "all_flown": counts(rows, "passed_allowable"),
                                    "scrubbed": counts(scrubbed, "passed_allowable")},
            "envelope_section_2": {"go": counts(go, "passed_envelope"),
                                   "all_flown": counts(rows, "passed_envelope"),
                                   "scrubbed": counts(scrubbed, "passed_envelope")},
        },
        "max_abs_q_alpha_pa_deg": {
            "go_max": max((r["max_abs_q_alpha_pa_deg"] for r in go), default=math.nan),
            "all_max": max(r["max_abs_q_alpha_pa_deg"] for r in rows),
        },
    }


def flight_day_markdown(s: Mapping, settings: Mapping | None = None) -> str:
    """The flight-day section of ``summary.md`` (``s``: :func:`summarise_flight_day`)."""
    f, d = s["flight_day"], s["definitions"]
    by = ", ".join(f"{k}: {v}" for k, v in sorted(f["failed_by_requirement"].items()))
    lines = ["", "## Flight day", ""]
    if settings:
        month = settings.get("month")
        lines += [f"Site {settings['site_path']}, "
                  f"{'month ' + str(month) if month else 'the 12 months in turn'}, lag "
                  f"{settings['lag_s']:g} s, mode {settings['mode']}; LCC {settings['lcc_path']}.",
                  ""]
    lines += [
        f"- Of {f['n'] + f['scrubbed']} samples the launch commit criterion let "
        f"{f['n']} fly and scrubbed {f['scrubbed']} "
        f"({', '.join(f'{k}: {v}' for k, v in sorted(f['scrub_reasons'].items())) or 'none'}; "
        "a sample can have several reasons).",
        f"- Flight-day success: **{f['passed']} of {f['n']}** go samples pass the load "
        f"allowable (REQUIREMENTS.md §6) and every other requirement, stable; {f['failed']} "
        f"fail ({by or 'none'}); {f['unstable']} unstable, {f['rate_limited']} over 0.5 s on "
        "the nozzle rate limit.",
        f"- Clopper–Pearson lower bound of the success probability: {f['lower_bound_90']:.4f} "
        f"at 90 %, {f['lower_bound_95']:.4f} at 95 %; 99.73 % at 90 % demonstrated: "
        f"**{'yes' if f['demonstrated_99_73_at_90'] else 'no'}**.",
        "- Availability (fraction of a month's samples the LCC lets fly): "
        + ", ".join(f"{m}: {v:.3f}" for m, v in s["availability"].items()) + ".",
        "- The design's availability (the criteria but the programme's ground-wind limit): "
        + ", ".join(f"{m}: {v:.3f}" for m, v in s["availability_design"].items()) + ".",
        *(f"- Availability were `{why}` waived: "
          + ", ".join(f"{m}: {v:.3f}" for m, v in by.items()) + "."
          for why, by in s["availability_without"].items()),
        "", "| definition (with stability) | go samples | all flown | scrubbed (what would have "
        "happened) |", "|---|---|---|---|"]
    for key, name in (("allowable_section_6", "§6 allowable (gating)"),
                      ("envelope_section_2", "§2 envelope (thesis-box)")):
        c = d[key]
        lines.append(f"| {name} | {c['go']['passed']} / {c['go']['n']} | "
                     f"{c['all_flown']['passed']} / {c['all_flown']['n']} | "
                     f"{c['scrubbed']['passed']} / {c['scrubbed']['n']} |")
    failed = f["failed_samples"]
    lines += ["", f"Failed go samples ({len(failed)}): "
              + (", ".join(f"{x['sample']} (month {x['month']}: {x['failed']})"
                           for x in failed[:20]) or "none")
              + (f" … and {len(failed) - 20} more" if len(failed) > 20 else "")]
    return "\n".join(lines) + "\n"


def plot_flight_day(out: str | Path, rows: Sequence[Mapping]) -> list[Path]:
    """``availability_by_month.png`` (availability per month, and were each criterion waived;
    the no-go reasons per month) and ``q_alpha_allowable.png``: the
    histogram of max |Qα| per flight, go and scrubbed, against the allowable, and the
    LCC's predicted load (with its allowance) against the flown max |Qα|."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vega_sim.requirements import load_requirements

    allowable = math.degrees(load_requirements().allowable_pa_rad) / 1e3
    s = summarise_flight_day(rows)
    paths = []
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 3.8))
    months = [int(m) for m in s["availability"]]
    ax.bar(months, [s["availability"][str(m)] for m in months], label="go")
    for why, mark in zip(s["availability_without"], "o^sv"):
        by = s["availability_without"][why]
        ax.plot(months, [by[str(m)] for m in months], mark, ms=5,
                label=f"were {why} waived")
    ax.axhline(0.9, color="k", ls="--", lw=1, label="90 %")
    ax.set_xticks(range(1, 13))
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("month")
    ax.set_ylabel("fraction of samples go")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title("Launch availability by month (LCC on the measured profile)", fontsize=9)
    names = sorted(s["flight_day"]["scrub_reasons"])
    width = 0.8 / max(len(names), 1)
    for j, why in enumerate(names):
        ax2.bar(np.array(months) - 0.4 + (j + 0.5) * width,
                [s["scrub_reasons_by_month"][str(m)].get(why, 0) for m in months], width,
                label=why)
    ax2.set_xticks(range(1, 13))
    ax2.set_xlabel("month")
    ax2.set_ylabel("samples scrubbed for it")
    if names:
        ax2.legend(fontsize=7)
    ax2.set_title("No-go reasons (a sample may have several)", fontsize=9)
    fig.tight_layout()
    paths.append(Path(out) / "availability_by_month.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)

    go = [r for r in rows if r["lcc_go"]]
    no = [r for r in rows if not r["lcc_go"]]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    top = max(allowable, max(r["max_abs_q_alpha_pa_deg"] for r in rows) / 1e3) * 1.05
    bins = np.linspace(0, top, 41)
    a1.hist([[r["max_abs_q_alpha_pa_deg"] / 1e3 for r in go],
             [r["max_abs_q_alpha_pa_deg"] / 1e3 for r in no]], bins=bins, stacked=True,
            label=["go", "scrubbed (flown anyway)"])
    a1.axvline(allowable, color="k", ls="--", label="allowable A (§6)")
    a1.set_xlabel("max |Qα| of the flight [kPa·deg]")
    a1.set_ylabel("flights")
    a1.legend(fontsize=8)
    for subset, mark, label in ((go, "o", "go"), (no, "x", "scrubbed")):
        a2.plot([r["lcc_q_alpha_with_allowance_pa_deg"] / 1e3 for r in subset],
                [r["max_abs_q_alpha_pa_deg"] / 1e3 for r in subset], mark, ms=3, label=label)
    a2.axhline(allowable, color="k", ls="--", lw=1)
    a2.axvline(allowable, color="k", ls=":", lw=1)
    a2.set_xlabel("LCC: predicted max(|Qα| + allowance) [kPa·deg]")
    a2.set_ylabel("flown max |Qα| [kPa·deg]")
    a2.legend(fontsize=8)
    fig.tight_layout()
    paths.append(Path(out) / "q_alpha_allowable.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    return paths
