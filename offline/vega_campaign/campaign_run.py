"""Running a Monte Carlo campaign on Dask: inputs, per-sample results that survive a kill,
the Parquet table, the statistics and the plots.

Layout of a campaign directory::

    DIR/campaign.json      the inputs: scenario (YAML text), dispersions (text), campaign seed,
                           runs, controller table (path, SHA-256), created
    DIR/samples/NNNNNN.json  one results row per finished sample, written atomically as it comes
    DIR/results.parquet    every row, sorted by sample (rebuilt from samples/ at the end)
    DIR/summary.json, DIR/summary.md, DIR/*.png

A flights campaign is flown in batches (:func:`~vega_campaign.campaign.fly_batch_samples`,
the batched engine :func:`vega_sim.batch.fly_batch`), one Dask task each, or one flight per task
(``batch=1``: :func:`~vega_campaign.campaign.fly_sample`); the rows are the same either way
(the engine equals the per-flight path bit for bit), except their ``wall_s``. A batch's rows are
written as soon as its task returns.

A killed campaign loses at most the samples in flight (the batches running): ``--resume DIR``
reads campaign.json, skips the samples already in samples/ and flies the rest, in new batches.
The cluster: a Dask ``LocalCluster`` of worker processes on 127.0.0.1 (no dashboard), or an
existing scheduler by address.

Statistics: the pass fraction k/n and its one-sided Clopper–Pearson lower bounds at 90 % and
95 % confidence (the exact binomial bound: p_lo = Beta⁻¹(1 − c; k, n − k + 1)); "99.73 %
demonstrated at 90 %" when p_lo,90 ≥ 0.9973 (Hanson & Beard, NASA/TP-2010-216447: 852 flights
without failure, 1 440 with one).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from vega_core.errors import BadArgument

from vega_campaign.campaign import (MARGIN_COLUMNS, METRICS, STATUS_COLUMNS,
                                    fly_batch_samples, fly_sample, margins_sample)

__all__ = ["clopper_pearson_lower", "runs_needed", "run_campaign", "summarise",
           "summarise_margins", "margins_markdown", "MARGIN_COLUMNS",
           "write_results", "read_rows", "PERCENTILES", "DEFAULT_BATCH", "batches"]

PERCENTILES = (50.0, 95.0, 99.0, 99.73, 100.0)
CAMPAIGN_FILE = "campaign.json"
SAMPLES_DIR = "samples"

DEFAULT_BATCH = 64
"""Most samples in one batched task of a flights campaign. The batched engine's CPU per flight
falls as the controller's per-step array work is shared by more samples and flattens from
about 64 on (docs/MONTE_CARLO.md §8); a batch holds ≈ 9 MB of records per 100-s sample while
it flies (≈ 0.6 GB per worker at 64), and a killed campaign loses at most one batch per
worker."""


ENVIRONMENT_BATCH = 32
"""Most samples in one task of a campaign flown by an environment's task (the flight day,
whose task flies its samples' predicted flights as one batch and their flights as another):
smaller than :data:`DEFAULT_BATCH` because a sample also costs its re-biasing, so that rows
reach the disk and the progress line every ≈ 10 CPU s; the task's fixed cost (the guidance
problem's assembly and the LCC's drift sensitivity, 62 flights: ≈ 10 CPU s) is paid once per
worker process, not per task."""


def batches(todo: Sequence[int], size: int, workers: int) -> list[list[int]]:
    """The samples ``todo`` cut into consecutive batches of at most ``size``.

    The number of batches is the fewest that respects ``size``, rounded up to a multiple of
    ``workers`` (at most one batch per sample), and their sizes differ by at most one: the
    workers get equal shares and finish together instead of one flying the last, larger
    batch alone (852 flights, 64, 2 workers: 14 batches of 60–61)."""
    n = len(todo)
    if n == 0:
        return []
    workers = max(int(workers), 1)
    count = -(-n // max(int(size), 1))
    count = min(-(-count // workers) * workers, n)
    small, extra = divmod(n, count)
    out, start = [], 0
    for k in range(count):
        stop = start + small + (k < extra)
        out.append([int(i) for i in todo[start:stop]])
        start = stop
    return out


def clopper_pearson_lower(k: int, n: int, confidence: float) -> float:
    """One-sided exact (Clopper–Pearson) lower confidence bound of a binomial proportion."""
    from scipy.stats import beta

    if n <= 0:
        return 0.0
    if k <= 0:
        return 0.0
    return float(beta.ppf(1.0 - confidence, k, n - k + 1))


def runs_needed(p: float, confidence: float, failures: int = 0) -> int:
    """Smallest n whose lower bound with ``failures`` failures reaches ``p`` (order statistics)."""
    n = failures + 1
    while clopper_pearson_lower(n - failures, n, confidence) < p:
        n += 1
    return n


def _sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _write_json(path: Path, data) -> None:
    fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
    with os.fdopen(fd, "w") as f:
        json.dump(data, f, sort_keys=True, allow_nan=True)
    os.replace(tmp, path)


def read_rows(out: Path) -> list[dict]:
    """Every finished sample's row, by sample index."""
    rows = []
    for f in sorted((out / SAMPLES_DIR).glob("*.json")):
        rows.append(json.loads(f.read_text()))
    return sorted(rows, key=lambda r: r["sample"])


def _inputs(scenario, dispersions, seed: int, runs: int, table_path: Path,
            kind: str = "flights", times_s=None) -> dict:
    from vega_sim.scenario import dump_scenario

    return {"kind": kind, "times_s": None if times_s is None else [float(t) for t in times_s],
            "scenario": scenario.name, "scenario_yaml": dump_scenario(scenario),
            "dispersions_yaml": dispersions.text, "dispersions_path": dispersions.path,
            "seed": int(seed), "runs": int(runs), "table": str(table_path),
            "table_sha256": _sha256(table_path)}


def _cluster(workers: int | None, scheduler: str | None):
    """A Dask client: on ``scheduler``, or on a new LocalCluster of worker processes."""
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler, timeout="30s"), None
    cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                           processes=True, host="127.0.0.1", dashboard_address=None,
                           silence_logs=40)
    return Client(cluster), cluster


def _failed(row: dict) -> bool:
    """Whether a row counts as a failure in the progress line: a flight-day row by its
    flight-day verdict (a scrubbed sample is no failure), any other by ``verdict``."""
    if "flight_day_verdict" in row:
        return row["flight_day_verdict"] == "fail"
    return row["verdict"] != "pass"


def run_campaign(scenario, dispersions, *, runs: int, seed: int, out: Path, table_path: Path,
                 workers: int | None = None, scheduler: str | None = None, resume: bool = False,
                 progress: Callable[[str], None] = print, kind: str = "flights",
                 times_s=None, batch: int = DEFAULT_BATCH, environment: dict | None = None,
                 task: Callable | None = None) -> list[dict]:
    """Fly the campaign's missing samples on Dask; return every row (finished before or now).

    ``kind``: ``"flights"`` (:func:`~vega_campaign.campaign.fly_batch_samples` on
    :func:`batches` of at most ``batch`` samples, or :func:`~vega_campaign.campaign.fly_sample`
    per sample when ``batch`` is 1) or ``"margins"``
    (:func:`~vega_campaign.campaign.margins_sample` at ``times_s``; the scenario only
    names the campaign). ``progress`` gets a line per finished batch (per twentieth of the
    samples when they are flown one per task).

    ``environment`` and ``task``: a flights campaign in another wind environment (the flight
    day, :mod:`vega_signoff.flight_day`, which sits above this package). ``environment`` is
    stored in campaign.json (on a resume, the stored one is used); ``task`` flies a list of
    samples and returns their rows, called as ``task(scenario_yaml, table, dispersions_yaml,
    seed, environment, out_dir, indices)`` — one Dask task per batch (a batch of one sample
    when ``batch`` is 1).

    Raises
    ------
    BadArgument
        ``out`` holds another campaign (resume) or is not empty (new campaign).
    """
    out = Path(out)
    inputs = _inputs(scenario, dispersions, seed, runs, Path(table_path), kind, times_s)
    if environment is not None:
        inputs["environment"] = environment
    campaign_file = out / CAMPAIGN_FILE
    if resume:
        if not campaign_file.is_file():
            raise BadArgument(f"--resume {out}: no {CAMPAIGN_FILE} (not a campaign directory)")
        inputs = json.loads(campaign_file.read_text())
        if _sha256(inputs["table"]) != inputs["table_sha256"]:
            raise BadArgument(f"--resume {out}: the controller table {inputs['table']} changed "
                              f"since the campaign started")
    else:
        if out.exists() and any(out.iterdir()):
            raise BadArgument(f"--out {out}: exists and is not empty (campaigns never "
                              f"overwrite; use --resume to finish one)")
        out.mkdir(parents=True, exist_ok=True)
        (out / SAMPLES_DIR).mkdir()
        inputs["created_utc"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        _write_json(campaign_file, inputs)
    (out / SAMPLES_DIR).mkdir(exist_ok=True)
    done = {r["sample"] for r in read_rows(out)}
    todo = [i for i in range(inputs["runs"]) if i not in done]
    progress(f"mc: {inputs['runs']} samples of '{inputs['scenario']}' (seed {inputs['seed']}), "
             f"{len(done)} already flown, {len(todo)} to fly")
    if not todo:
        return read_rows(out)
    if inputs.get("environment") is not None and task is None:
        raise ValueError("run_campaign: a campaign with an environment needs its task")
    from distributed import as_completed

    client, cluster = _cluster(workers, scheduler)
    t0 = time.monotonic()
    failures = sum(1 for r in read_rows(out) if _failed(r))
    try:
        n_workers = len(client.scheduler_info().get("workers", {}))
        progress(f"mc: Dask {'scheduler ' + scheduler if scheduler else 'LocalCluster'}, "
                 f"{n_workers} workers")
        args = (inputs["scenario_yaml"], inputs["table"], inputs["dispersions_yaml"],
                inputs["seed"])
        if inputs.get("environment") is not None:
            groups = batches(todo, min(batch, ENVIRONMENT_BATCH), n_workers)
            progress(f"mc: {inputs['environment'].get('name')} environment, {len(groups)} "
                     f"task(s) of up to {max(map(len, groups))} samples (batched)")
            futures = [client.submit(task, *args, inputs["environment"], str(out.resolve()),
                                     group, pure=False, key=f"batch-{group[0]}-{len(group)}")
                       for group in groups]
        elif inputs.get("kind", "flights") == "margins":
            futures = [client.submit(margins_sample, inputs["table"], inputs["dispersions_yaml"],
                                     inputs["seed"], i, inputs["times_s"], pure=False,
                                     key=f"sample-{i}") for i in todo]
        elif batch > 1:
            groups = batches(todo, batch, n_workers)
            progress(f"mc: batched engine, {len(groups)} task(s) of up to "
                     f"{max(map(len, groups))} flights")
            futures = [client.submit(fly_batch_samples, *args, group, pure=False,
                                     key=f"batch-{group[0]}-{len(group)}") for group in groups]
        else:
            futures = [client.submit(fly_sample, *args, i, pure=False, key=f"sample-{i}")
                       for i in todo]
        k = 0
        for fut in as_completed(futures):
            try:
                got = fut.result()
            except Exception as exc:  # a flight that raises is a defect, never bad input
                raise RuntimeError(f"{fut.key}: {type(exc).__name__}: {exc}") from exc
            fut.release()
            rows = got if isinstance(got, list) else [got]
            for row in rows:
                _write_json(out / SAMPLES_DIR / f"{row['sample']:06d}.json", row)
                failures += _failed(row)
            before, k = k, k + len(rows)
            step = max(1, len(todo) // 20)
            if k == len(todo) or isinstance(got, list) or k // step > before // step:
                elapsed = time.monotonic() - t0
                eta = elapsed / k * (len(todo) - k)
                progress(f"mc: {k}/{len(todo)} done, {failures} failed so far, "
                         f"{k / elapsed:.2f} flights/s, ETA {eta:.0f} s")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return read_rows(out)


def write_results(out: Path, rows: Sequence[dict]) -> Path:
    """``DIR/results.parquet``: one row per sample, sorted by sample."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist(sorted(rows, key=lambda r: r["sample"]))
    path = Path(out) / "results.parquet"
    pq.write_table(table, path)
    return path


def _bounds() -> dict[str, float]:
    """The requirement bound of each metric in its column's unit (None: no bound)."""
    from vega_sim.requirements import load_requirements

    spec = load_requirements()
    from vega_campaign.campaign import STABILITY_LIMITS

    return {**STABILITY_LIMITS, "q_alpha_margin": 1.0, "max_abs_z_m": spec.drift_m,
            "max_abs_zdot_mps": spec.drift_rate_mps,
            "max_abs_beta_deg": math.degrees(spec.deflection_rad),
            "int_abs_beta_deg_s": math.degrees(spec.deflection_integral_rad_s)}


def summarise(rows: Sequence[dict], inputs: dict, wall_s: float | None = None) -> dict:
    """The campaign's statistics (module docstring)."""
    n = len(rows)
    k = sum(1 for r in rows if r["verdict"] == "pass")
    lo90, lo95 = clopper_pearson_lower(k, n, 0.90), clopper_pearson_lower(k, n, 0.95)
    bounds = _bounds()
    metrics = {}
    for name in METRICS:
        values = np.array([r[name] for r in rows], dtype=float)
        metrics[name] = {"percentiles": {f"p{p:g}": float(np.percentile(values, p))
                                         for p in PERCENTILES},
                         "bound": bounds.get(name), "unit": METRICS[name]}
    failed = [r for r in rows if r["verdict"] != "pass"]
    worst = sorted(rows, key=lambda r: -r["q_alpha_margin"])[:5]
    return {
        "scenario": inputs["scenario"], "seed": inputs["seed"], "runs": n,
        "passed": k, "pass_fraction": k / n if n else math.nan,
        "pass_fraction_lower_90": lo90, "pass_fraction_lower_95": lo95,
        "demonstrated_99_73_at_90": bool(lo90 >= 0.9973),
        "runs_needed_99_73_at_90": {"0_failures": runs_needed(0.9973, 0.90, 0),
                                    "1_failure": runs_needed(0.9973, 0.90, 1)},
        "metrics": metrics,
        "failed_samples": [{"sample": r["sample"], "failed": r["failed"]} for r in failed],
        "worst_q_alpha_samples": [{"sample": r["sample"], "q_alpha_margin": r["q_alpha_margin"]}
                                  for r in worst],
        "unstable": sum(1 for r in rows if not r["stable"]),
        "status_totals": {c: int(sum(r[c] for r in rows)) for c in STATUS_COLUMNS},
        "wall_s": wall_s, "flights_per_s": (n / wall_s) if wall_s else None,
        "table": inputs["table"], "table_sha256": inputs["table_sha256"],
    }


def summarise_margins(rows: Sequence[dict], inputs: dict, wall_s: float | None = None) -> dict:
    """Statistics of a margins campaign: the fraction of dispersed plants whose frozen loops
    are stable at every analysed time (with its Clopper–Pearson bounds), per time the
    unstable count, and the percentiles of each worst margin against its heritage bound."""
    from vega_loops.margins import DISPERSED_CRITERION, REQUIREMENTS

    n = len(rows)
    k = sum(1 for r in rows if r["verdict"] == "pass")
    times = inputs["times_s"]
    bounds = {"worst_pm_deg": REQUIREMENTS["pm_deg"], "worst_gm_low_db": REQUIREMENTS["gm_db"],
              "worst_gm_high_db": REQUIREMENTS["gm_db"],
              "worst_b1_peak_db": REQUIREMENTS["bending_db"],
              "worst_b2_peak_db": REQUIREMENTS["bending_db"]}
    metrics = {}
    for name, bound in bounds.items():
        values = np.array([r[name] for r in rows], dtype=float)
        values = values[np.isfinite(values)]
        metrics[name] = {"percentiles": {f"p{p:g}": float(np.percentile(values, 100 - p)
                                                          if "peak" not in name else
                                                          np.percentile(values, p))
                                         for p in PERCENTILES} if values.size else {},
                         "bound": bound, "unit": "dB" if name.endswith("db") else "deg"}
    return {
        "kind": "margins", "scenario": inputs["scenario"], "seed": inputs["seed"], "runs": n,
        "passed": k, "pass_fraction": k / n if n else math.nan,
        "pass_fraction_lower_90": clopper_pearson_lower(k, n, 0.90),
        "pass_fraction_lower_95": clopper_pearson_lower(k, n, 0.95),
        "demonstrated_99_73_at_90": bool(clopper_pearson_lower(k, n, 0.90) >= 0.9973),
        "runs_needed_99_73_at_90": {"0_failures": runs_needed(0.9973, 0.90, 0),
                                    "1_failure": runs_needed(0.9973, 0.90, 1)},
        "times_s": times,
        "unstable_per_time": {f"{t:g}": sum(1 for r in rows if r[f"n_unstable@{t:g}"])
                              for t in times},
        "metrics": metrics, "heritage": REQUIREMENTS, "dispersed_criterion": DISPERSED_CRITERION,
        "failed_samples": [{"sample": r["sample"], "failed": r["unstable_times"]}
                           for r in rows if r["verdict"] != "pass"],
        "unstable": n - k, "wall_s": wall_s, "flights_per_s": (n / wall_s) if wall_s else None,
        "table": inputs["table"], "table_sha256": inputs["table_sha256"],
    }


def margins_markdown(s: dict) -> str:
    """``summary.md`` of a margins campaign (worst margins: the low end is the bad one for
    PM and GM — the percentile p is of the worst p %)."""
    lines = [f"# Dispersed-margins campaign (seed {s['seed']}), frozen times "
             f"{', '.join(f'{t:g}' for t in s['times_s'])} s", "",
             f"- plants {s['runs']}, stable at every time {s['passed']} "
             f"(fraction {s['pass_fraction']:.4f}); Clopper–Pearson lower bound "
             f"{s['pass_fraction_lower_90']:.4f} at 90 %, {s['pass_fraction_lower_95']:.4f} "
             f"at 95 %",
             "- unstable plants per time: " + ", ".join(
                 f"{t} s: {n}" for t, n in s["unstable_per_time"].items()), "",
             "| worst over the times | unit | p50 | p95 | p99 | p99.73 | worst | heritage bound |",
             "|---|---|---|---|---|---|---|---|"]
    for name, m in s["metrics"].items():
        p = m["percentiles"]
        if not p:
            continue
        lines.append(f"| {name} | {m['unit']} | {p['p50']:.3g} | {p['p95']:.3g} | "
                     f"{p['p99']:.3g} | {p['p99.73']:.3g} | {p['p100']:.3g} | {m['bound']:g} |")
    return "\n".join(lines) + "\n"


def summary_markdown(s: dict) -> str:
    """``summary.md`` of a summary."""
    lines = [f"# Monte Carlo campaign: {s['scenario']} (seed {s['seed']})", "",
             f"- runs {s['runs']}, passed {s['passed']} "
             f"(pass fraction {s['pass_fraction']:.4f}); unstable flights {s['unstable']}",
             f"- Clopper–Pearson lower bound: {s['pass_fraction_lower_90']:.4f} at 90 %, "
             f"{s['pass_fraction_lower_95']:.4f} at 95 %",
             f"- 99.73 % at 90 % confidence demonstrated: "
             f"**{'yes' if s['demonstrated_99_73_at_90'] else 'no'}** (needs "
             f"{s['runs_needed_99_73_at_90']['0_failures']} runs without failure, "
             f"{s['runs_needed_99_73_at_90']['1_failure']} with one)", "",
             "| metric | unit | p50 | p95 | p99 | p99.73 | max | bound |",
             "|---|---|---|---|---|---|---|---|"]
    for name, m in s["metrics"].items():
        p = m["percentiles"]
        bound = "—" if m["bound"] is None else f"{m['bound']:.4g}"
        lines.append(f"| {name} | {m['unit']} | {p['p50']:.4g} | {p['p95']:.4g} | "
                     f"{p['p99']:.4g} | {p['p99.73']:.4g} | {p['p100']:.4g} | {bound} |")
    failed = s["failed_samples"]
    shown = ", ".join(f"{f['sample']} ({f['failed']})" for f in failed[:20])
    more = f" … and {len(failed) - 20} more (summary.json)" if len(failed) > 20 else ""
    lines += ["", f"Failed samples ({len(failed)}): " + (shown + more if failed else "none"),
              "", "Worst Qα samples: " + ", ".join(f"{w['sample']} ({w['q_alpha_margin']:.3f})"
                                                  for w in s["worst_q_alpha_samples"])]
    if s.get("wall_s"):
        lines += ["", f"Wall time {s['wall_s']:.1f} s, {s['flights_per_s']:.2f} flights/s."]
    return "\n".join(lines) + "\n"


def _plot_q_alpha_band(out: Path, profiles: np.ndarray) -> Path:
    """Max |Qα| per Mach bin over the samples: median, 95 %, 99.73 % and max against the
    structural envelope (``q_alpha_band.png``)."""
    import warnings

    import matplotlib.pyplot as plt

    from vega_campaign.campaign import MACH_BIN
    from vega_sim.requirements import load_requirements

    spec = load_requirements()
    centre = (np.arange(profiles.shape[1]) + 0.5) * MACH_BIN
    keep = np.isfinite(profiles).any(axis=0)
    fig, ax = plt.subplots(figsize=(8, 4.5))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # bins a sample never reached
        for p, style in ((50, "-"), (95, "--"), (99.73, "-."), (100, ":")):
            ax.plot(centre[keep], np.nanpercentile(profiles[:, keep], p, axis=0) / 1e3, style,
                    label=f"{'max' if p == 100 else f'p{p:g}'} of max |Qα| per Mach bin")
    ax.plot(spec.envelope_mach, np.degrees(spec.envelope_pa_rad) / 1e3, "k", lw=2,
            label="envelope")
    ax.set_xlim(0, centre[keep].max() + MACH_BIN)
    ax.set_xlabel("Mach")
    ax.set_ylabel("kPa·deg")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(out) / "q_alpha_band.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_campaign(out: Path, rows: Sequence[dict], summary: dict,
                  not_dispersed: Sequence[str] = ()) -> list[Path]:
    """Histograms of the metrics against their bounds, and a tornado chart of the rank
    correlation of each dispersed parameter with the Qα ratio (``not_dispersed``: result
    columns beyond the thesis-box row's, left out of it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import spearmanr

    paths = []
    names = [n for n in METRICS if summary["metrics"][n]["bound"] is not None]
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 2.4 * len(names)))
    for ax, name in zip(np.atleast_1d(axes), names):
        ax.hist([r[name] for r in rows], bins=40)
        ax.axvline(summary["metrics"][name]["bound"], color="k", ls="--", label="bound")
        ax.set_xlabel(f"{name} [{METRICS[name]}]")
        ax.legend(fontsize=8)
    fig.tight_layout()
    paths.append(Path(out) / "histograms.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)

    profiles = [r["q_alpha_profile_pa_deg"] for r in rows if "q_alpha_profile_pa_deg" in r]
    if profiles:
        paths.append(_plot_q_alpha_band(out, np.array(profiles, dtype=float)))

    params = [k for k in rows[0] if k not in METRICS and k not in STATUS_COLUMNS
              and k not in ("sample", "seed", "verdict", "failed", "wall_s", "stable",
                            "q_alpha_profile_pa_deg", *not_dispersed)
              and np.ptp([r[k] for r in rows if not math.isnan(r[k])] or [0]) > 0]
    rho = []
    for k in params:
        x = np.array([r[k] for r in rows], dtype=float)
        x = np.where(np.isnan(x), -1.0, x)
        rho.append(float(spearmanr(x, [r["q_alpha_margin"] for r in rows]).statistic))
    order = np.argsort(np.abs(rho))
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(params) + 1.2))
    ax.barh([params[i] for i in order], [rho[i] for i in order])
    ax.set_xlabel("Spearman rank correlation with the worst Qα/envelope ratio")
    fig.tight_layout()
    paths.append(Path(out) / "sensitivity_q_alpha.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    return paths
