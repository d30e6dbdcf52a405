"""Two Monte Carlo campaigns of the same flights compared sample by sample
(docs/FLIGHT_DESIGN.md §6.5, "A held-out seed").

Two campaigns of ``vega mc run`` with the same scenario, dispersions, seed and number of runs
fly the same dispersed vehicles and winds with two controller tables. Their pass counts alone
hide how they differ: :func:`compare` pairs the samples and reports the flights one table loses
and the other wins (with the requirement each failed and its Qα ratio in both), McNemar's exact
test on those discordant flights (two-sided; under "the tables are equally good" a discordant
flight is lost or won with probability 1/2, so the count lost is binomial), and the median
change of the Qα ratio over all flights.

A is the reference (e.g. the shipped table), B the candidate: "lost" are the flights A passes
and B fails. Used by ``vega mc compare A B`` and by the held-out check of ``vega verify``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from vega_core.errors import BadInput, one_line

__all__ = ["SAME_INPUTS", "COLUMNS", "load_campaign", "check_same_samples", "compare",
           "report_lines", "plot"]

SAME_INPUTS = ("scenario_yaml", "dispersions_yaml", "seed", "runs", "environment")
"""The campaign inputs (``campaign.json``) that make two campaigns fly the same samples
(``environment``: absent for the thesis box, the flight day's settings and files otherwise)."""
COLUMNS = ("sample", "verdict", "failed", "q_alpha_margin", "max_abs_z_m", "max_abs_zdot_mps")
"""The columns of ``results.parquet`` a comparison reads."""


def load_campaign(directory: Path) -> tuple[dict, dict]:
    """A campaign's inputs (``campaign.json``) and its results as columns ordered by sample.

    Raises
    ------
    BadInput
        When ``directory`` is not a complete campaign of ``vega mc run`` (one line naming it).
    """
    import pyarrow.parquet as pq

    directory = Path(directory)
    inputs_path, results_path = directory / "campaign.json", directory / "results.parquet"
    for path in (inputs_path, results_path):
        if not path.is_file():
            raise BadInput(f"{directory}: no {path.name} (not a `vega mc run` campaign)")
    try:
        inputs = json.loads(inputs_path.read_text())
        table = pq.read_table(results_path, columns=list(COLUMNS)).to_pydict()
    except (ValueError, KeyError) as exc:
        raise BadInput(f"{directory}: unreadable campaign ({one_line(exc)})") from None
    order = np.argsort(table["sample"])
    results = {k: [v[i] for i in order] for k, v in table.items()}
    runs = int(inputs.get("runs", -1))
    if results["sample"] != list(range(runs)):
        raise BadInput(f"{directory}: {len(results['sample'])} of {runs} samples flown; finish "
                       f"it first (vega mc run --resume {directory})")
    return inputs, results


def check_same_samples(inputs_a: dict, inputs_b: dict, dir_a, dir_b) -> None:
    """:class:`BadInput` (naming ``dir_b`` and the first differing input) unless the two
    campaigns' inputs make them fly the same samples (:data:`SAME_INPUTS`)."""
    for key in SAME_INPUTS:
        if inputs_a.get(key) != inputs_b.get(key):
            raise BadInput(f"{dir_b}: its {key} is not that of {dir_a}: the campaigns do not "
                           "fly the same samples")


def compare(a: dict, b: dict) -> dict:
    """Paired comparison of two complete campaigns' results (columns by sample, as
    :func:`load_campaign` returns them): runs, passes of each, the flights B lost and won,
    McNemar's exact p and the median change of the Qα ratio."""
    from scipy.stats import binomtest

    fail_a = np.array([v != "pass" for v in a["verdict"]])
    fail_b = np.array([v != "pass" for v in b["verdict"]])
    lost = np.flatnonzero(~fail_a & fail_b)
    won = np.flatnonzero(fail_a & ~fail_b)
    n = len(lost) + len(won)
    p = binomtest(len(lost), n, 0.5).pvalue if n else 1.0
    ratio_a, ratio_b = np.array(a["q_alpha_margin"]), np.array(b["q_alpha_margin"])

    def flight(s):
        return {"sample": int(s), "failed_a": a["failed"][s], "failed_b": b["failed"][s],
                "q_alpha_ratio_a": float(ratio_a[s]), "q_alpha_ratio_b": float(ratio_b[s])}

    return {"runs": len(fail_a), "passed_a": int((~fail_a).sum()),
            "passed_b": int((~fail_b).sum()),
            "lost": [flight(s) for s in lost], "won": [flight(s) for s in won],
            "mcnemar_exact_p": float(min(1.0, p)),
            "median_q_alpha_ratio_change": float(np.median(ratio_b - ratio_a))}


def report_lines(report: dict, seed) -> list[str]:
    """The comparison as text: one summary line, then one line per flight lost or won."""
    lines = [f"{report['runs']} flights (seed {seed}): A passes {report['passed_a']}, B passes "
             f"{report['passed_b']}; B lost {len(report['lost'])}, won {len(report['won'])} "
             f"(McNemar exact p {report['mcnemar_exact_p']:.3f}); median Qα-ratio change "
             f"{report['median_q_alpha_ratio_change']:+.4f}"]
    for key in ("lost", "won"):
        for f in report[key]:
            lines.append(f"  {key} {f['sample']}: A {f['failed_a'] or 'pass'} "
                         f"{f['q_alpha_ratio_a']:.3f}, B {f['failed_b'] or 'pass'} "
                         f"{f['q_alpha_ratio_b']:.3f}")
    return lines


def plot(a: dict, b: dict, report: dict, path: Path, labels: tuple[str, str]) -> None:
    """The Qα ratio of every flight, B against A, the lost and won flights marked (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ra, rb = np.array(a["q_alpha_margin"]), np.array(b["q_alpha_margin"])
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.scatter(ra, rb, s=6, c="0.6", label="every flight")
    for key, colour in (("lost", "tab:red"), ("won", "tab:green")):
        idx = [f["sample"] for f in report[key]]
        ax.scatter(ra[idx], rb[idx], s=24, c=colour, label=f"{key} by B ({len(idx)})")
    lim = [0, max(1.2, float(np.nanmax([ra.max(), rb.max()])) * 1.02)]
    ax.plot(lim, lim, "k:", lw=0.8)
    ax.axhline(1.0, c="k", lw=0.6)
    ax.axvline(1.0, c="k", lw=0.6)
    ax.set(xlim=lim, ylim=lim, xlabel=f"Qα ratio, A = {labels[0]}",
           ylabel=f"Qα ratio, B = {labels[1]}",
           title=f"passes A {report['passed_a']}, B {report['passed_b']} of {report['runs']}; "
                 f"McNemar p {report['mcnemar_exact_p']:.2f}")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
