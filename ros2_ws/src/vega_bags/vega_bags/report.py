"""The report of a run: bag → JSON + Markdown + PNG plots, and the verdict.

:func:`write_report` is what ``vega sil run`` calls after a flight (and ``vega check BAG
--report DIR``): it checks the bag (:func:`vega_bags.bagcheck.check_bag`) and writes into the
report directory

* ``report.json`` — the verdict (:meth:`vega_bags.bagcheck.BagCheck.to_dict`, the same as
  ``vega check --json``) plus the names of the plots;
* ``report.md`` — run metadata, the requirement table (thesis Table 5.1 form, with margins
  and the thesis' figures), the health checks, the controller status counts, the plots;
* the plots (matplotlib, Agg backend): :data:`PLOTS`.

It returns the :class:`~vega_bags.bagcheck.BagCheck` (``.passed``, ``.exit_code``). A bad bag
raises :class:`vega_bags.bagio.BagError` (one line) before anything is written.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from vega_bus.wire import STATUS_NAMES

from vega_bags import bagio
from vega_bags.bagcheck import BagCheck, check_bag
from vega_sim.requirements import RequirementSpec, bound_op, pass_text, peak_text

__all__ = ["PLOTS", "write_report", "markdown"]

PLOTS = {
    "attitude.png": "pitch attitude θ: truth and INS",
    "drift.png": "lateral drift z and drift rate ż with their limits",
    "q_alpha.png": "Qα over Mach against its envelope (and the informational 3° objective), "
                   "and over time",
    "nozzle.png": "nozzle angle β (actuator samples) against its limit, and the command",
    "schedule.png": "velocity: truth, INS and the controller's scheduling velocity",
    "status.png": "controller status flags (TvcCommand.status)",
}
"""Plot file → what it shows."""


def _row(*cells) -> str:
    """A Markdown table row (``|`` inside a cell escaped)."""
    return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"


def _fmt(x: float, scale: float = 1.0) -> str:
    return f"{x * scale:.6g}" if math.isfinite(x) else str(x)


def markdown(check: BagCheck, plots=PLOTS) -> str:
    """The Markdown report of a check (tables, metadata, plots by relative file name)."""
    meta = check.metadata
    lines = [f"# Run report: {meta.get(bagio.META_SCENARIO, 'unknown scenario')}", "",
             f"**Verdict: {'PASS' if check.passed else 'FAIL'}**", ""]
    lines += [f"- {f}" for f in check.failures]
    if check.failures:
        lines.append("")
    lines += ["## Run", "", "| item | value |", "|---|---|",
              f"| bag | `{check.bag}` |"]
    for key, label in ((bagio.META_SCENARIO, "scenario"), (bagio.META_SEED, "seed"),
                       (bagio.META_CONTROLLER_TABLE, "controller table"),
                       (bagio.META_CONTROLLER_TABLE_SHA256, "table SHA-256"),
                       (bagio.META_GUIDANCE_REFERENCE, "guidance reference"),
                       (bagio.META_GIT_REVISION, "git revision")):
        lines.append(_row(label, f"`{meta.get(key, '—')}`"))
    r = check.result
    if r.t_ms.size:
        lines.append(f"| span | {r.t_ms[0] / 1e3:.3f} … {r.t_ms[-1] / 1e3:.3f} s |")
    lines += ["", "## Requirements (thesis Table 3.1; figures as in Table 5.1)", "",
              "value, bound, margin and time at the binding (worst-margin) sample; max |value| "
              "and its time beside; informational lines (marked *info*) never gate the verdict "
              "(docs/REQUIREMENTS.md).", "",
              _row("requirement", "metric", "value", "bound", "margin", "at [s]", "max |value|",
                   "pass", "thesis Table 5.1"),
              "|---|---|---|---|---|---|---|---|---|"]
    rep = check.requirements
    for q in (*rep.results, *rep.informational):
        s, u = q.display_scale, q.display_unit
        thesis = "" if q.thesis is None else f"{_fmt(q.thesis.value, s)} {u}"
        lines.append(_row(q.requirement, q.metric, f"{_fmt(q.value, s)} {u}",
                          f"{bound_op(q.key)} {_fmt(q.bound, s)} {u}", f"{_fmt(q.margin, s)} {u}",
                          f"{q.time_s:.3f}", peak_text(q), pass_text(q, "**NO**"), thesis))
    notes = [f"{q.metric}: thesis {q.thesis.note}" for q in rep.results
             if q.thesis is not None and q.thesis.note]
    notes += [f"{q.metric} ({q.requirement}): *informational*, never gates the verdict"
              for q in rep.informational]
    if rep.q_alpha_flip is not None:
        notes.append(rep.q_alpha_flip.text())
    if rep.command_peak_rad is not None:
        notes.append(f"with the thesis' definitions (command, signed integral): max |β_cmd| = "
                     f"{math.degrees(rep.command_peak_rad):.6g} deg, ∫β_cmd dt = "
                     f"{math.degrees(rep.command_signed_integral_rad_s):.6g} deg·s")
    lines += [""] + [f"- {n}" for n in notes]
    lines += ["", "## Health", "", "| check | value | limit | pass | detail |",
              "|---|---|---|---|---|"]
    for h in check.health:
        lines.append(_row(h.check, h.value, h.limit, "yes" if h.passed else "**NO**",
                          h.detail))
    counts = check.status_counts()
    lines += ["", "Controller status: " + (", ".join(f"{k} {v}" for k, v in counts.items())
                                          or "no commands"), "", "## Plots", ""]
    for name, what in plots.items():
        lines += [f"### {what}", "", f"![{what}]({name})", ""]
    return "\n".join(lines)


def _fixed_margins(fig, left_in: float = 0.8, right_in: float = 0.2, bottom_in: float = 0.55,
                   top_in: float = 0.35, gap_in: float = 0.75) -> None:
    """Place the axes with fixed margins [inch] instead of ``tight_layout``, which measures
    every label by drawing the figure once more (≈ half of the plotting time: docs/SIL_SPEED.md).
    The margins hold the report's labels at 10 pt and the status names of the status plot
    (``left_in`` 1.8); ``gap_in`` between stacked axes holds a tick row and an x label."""
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=left_in / w, right=1.0 - right_in / w, bottom=bottom_in / h,
                        top=1.0 - top_in / h, hspace=gap_in / (h / len(fig.axes)))


PLOT_CHILD_TIMEOUT_S = 30.0
"""How long :func:`_plot` waits for the forked process drawing half of the plots before it
stops it and draws them itself [s] (assumption: 20× the ≈ 0.3 s they take on a loaded
machine)."""


def _save(check: BagCheck, spec: RequirementSpec | None, out: Path, names) -> None:
    import matplotlib.pyplot as plt

    for name, fig in _figures(check, spec, names).items():
        fig.savefig(out / name, dpi=100)
        plt.close(fig)


def _plot(check: BagCheck, spec: RequirementSpec | None, out: Path) -> list[Path]:
    """Write the :data:`PLOTS` into ``out``; return their paths.

    Drawing is ≈ 80 % of a report's CPU time (matplotlib: ticks, text, Agg; ≈ 0.5 s for the
    six plots, docs/SIL_SPEED.md), so on POSIX a forked child draws half of them while this
    process draws the other half: the two cores the nodes used are free by then. A child
    that fails or takes longer than :data:`PLOT_CHILD_TIMEOUT_S` is stopped and its plots
    are drawn here (an error then surfaces here, with its traceback)."""
    names = list(PLOTS)
    mine, theirs = names[::2], names[1::2]
    child = _fork_plots(check, spec, out, theirs)
    try:
        _save(check, spec, out, mine if child else names)
    finally:
        done = _child_done(child) if child else True   # reaped even when this half failed
    if not done:
        _save(check, spec, out, theirs)
    return [out / name for name in names]


def _fork_plots(check, spec, out: Path, names) -> int | None:
    """A child process drawing ``names`` (its pid), or None where fork is unavailable."""
    import os
    import sys

    if not hasattr(os, "fork"):
        return None
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid:
        return pid
    status = 1
    try:
        _save(check, spec, out, names)
        status = 0
    finally:
        os._exit(status)


def _child_done(pid: int) -> bool:
    """Wait for the plotting child; True if it drew its plots (exit 0) in time."""
    import os
    import select
    import signal

    try:
        fd = os.pidfd_open(pid)
    except (AttributeError, OSError):
        fd = None
    if fd is not None:
        try:
            poller = select.poll()
            poller.register(fd, select.POLLIN)
            if not poller.poll(PLOT_CHILD_TIMEOUT_S * 1000):
                os.kill(pid, signal.SIGKILL)
        finally:
            os.close(fd)
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status) == 0


def _figures(check: BagCheck, spec: RequirementSpec | None, names=None) -> dict:
    """The :data:`PLOTS` (or those of ``names``) as matplotlib figures (file name → figure),
    laid out."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vega_sim.requirements import load_requirements

    spec = spec if spec is not None else load_requirements()
    r = check.result
    t, ta, tc = r.t_ms / 1e3, r.act_t_ms / 1e3, r.cmd_stamp_ms / 1e3
    ti = r.ins_stamp_ms / 1e3
    title = (f"{check.metadata.get(bagio.META_SCENARIO, '?')}, seed "
             f"{check.metadata.get(bagio.META_SEED, '?')}")
    figs = {}
    names = set(PLOTS if names is None else names)

    def limits(ax, bound, label):
        ax.axhline(bound, color="r", ls="--", lw=0.8, label=label)
        ax.axhline(-bound, color="r", ls="--", lw=0.8)

    if "attitude.png" in names:
        fig, ax = plt.subplots(figsize=(8, 4))
        ax.plot(t, np.degrees(r.theta_rad), label="θ truth")
        if ti.size:
            ax.plot(ti, np.degrees(r.ins_theta_rad), lw=0.6, alpha=0.7,
                    label="θ INS (at its stamp)")
        ax.set_ylabel("θ [deg]")
        figs["attitude.png"] = fig

    if "drift.png" in names:
        fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
        a1.plot(t, r.z_m, label="z")
        limits(a1, spec.drift_m, f"|z| < {spec.drift_m:g} m")
        a1.set_ylim(-1.2 * spec.drift_m, 1.2 * spec.drift_m)
        a1.set_ylabel("z [m]")
        a2.plot(t, r.z_dot_mps, label="ż")
        limits(a2, spec.drift_rate_mps, f"|ż| < {spec.drift_rate_mps:g} m/s")
        a2.set_ylim(-1.2 * spec.drift_rate_mps, 1.2 * spec.drift_rate_mps)
        a2.set_ylabel("ż [m/s]")
        figs["drift.png"] = fig

    if "q_alpha.png" in names:
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 7))
        kpa_deg = 180.0 / math.pi / 1000.0  # Pa·rad → kPa·deg
        mach = np.linspace(0.0, max(float(np.nanmax(r.mach)) if r.mach.size else 1.0, 0.1), 400)
        env = spec.envelope(mach) * kpa_deg
        a1.plot(r.mach, r.q_alpha_pa_rad * kpa_deg, lw=0.8, label="Qα")
        a1.plot(mach, env, "r--", lw=0.8, label="envelope (config/requirements.yaml)")
        a1.plot(mach, -env, "r--", lw=0.8)
        if spec.objective_mach is not None:
            obj = spec.objective(mach) * kpa_deg
            a1.plot(mach, obj, ":", color="0.5", lw=0.8,
                    label="3°·Q objective (Eq. 4.24, informational)")
            a1.plot(mach, -obj, ":", color="0.5", lw=0.8)
        a1.set_xlabel("Mach [-]")
        a1.set_ylabel("Qα [kPa·deg]")
        a2.plot(t, r.q_alpha_pa_rad * kpa_deg, lw=0.8, label="Qα")
        a2.plot(t, spec.envelope(r.mach) * kpa_deg, "r--", lw=0.8, label="envelope(Mach(t))")
        a2.plot(t, -spec.envelope(r.mach) * kpa_deg, "r--", lw=0.8)
        a2.set_ylabel("Qα [kPa·deg]")
        figs["q_alpha.png"] = fig

    if "nozzle.png" in names:
        fig, ax = plt.subplots(figsize=(8, 4))
        ax.plot(ta, np.degrees(r.beta_rad), lw=0.8, label="β actuator")
        if tc.size:
            ax.step(tc, np.degrees(r.cmd_rad), where="post", lw=0.6, alpha=0.8,
                    label="β command (at its stamp)")
        limits(ax, math.degrees(spec.deflection_rad),
               f"|β| < {math.degrees(spec.deflection_rad):g}°")
        ax.set_ylabel("β [deg]")
        figs["nozzle.png"] = fig

    if "schedule.png" in names:
        fig, ax = plt.subplots(figsize=(8, 4))
        ax.plot(t, r.v_mps, label="v truth")
        if ti.size:
            ax.plot(ti, r.ins_v_mps, lw=0.6, label="v INS")
        if tc.size:
            ax.step(tc, r.cmd_v_mps, where="post", lw=0.8, label="scheduling velocity (command)")
        ax.set_ylabel("v [m/s]")
        figs["schedule.png"] = fig

    if "status.png" in names:
        fig, ax = plt.subplots(figsize=(8, 3.5))
        if tc.size:
            ax.step(tc, r.cmd_status, where="post", label="TvcCommand.status")
        ax.set_yticks(list(STATUS_NAMES), list(STATUS_NAMES.values()))
        ax.set_ylim(min(STATUS_NAMES) - 0.5, max(STATUS_NAMES) + 0.5)
        figs["status.png"] = fig

    for name, fig in figs.items():
        for ax in fig.axes:
            ax.grid(True, alpha=0.3)
            if ax.get_xlabel() == "":
                ax.set_xlabel("t [s]")
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=8, loc="upper right")
        fig.axes[0].set_title(f"{PLOTS[name]} ({title})", fontsize=9)
        _fixed_margins(fig, left_in=1.8 if name == "status.png" else 0.8)
    return figs


def write_report(bag: str | Path, out_dir: str | Path,
                 spec: RequirementSpec | None = None) -> BagCheck:
    """Check a run bag and write its report (JSON, Markdown, plots) into ``out_dir``.

    Parameters
    ----------
    bag
        Run bag directory.
    out_dir
        Report directory (created if needed; files in it are overwritten).
    spec
        Requirement bounds (default: the shipped file).

    Returns
    -------
    BagCheck
        The verdict (``.passed``, ``.exit_code``, ``.table()`` for the console).

    Raises
    ------
    BagError
        Missing, corrupt or foreign bag (one line); nothing is written then.
    """
    check = check_bag(bag, spec)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plots = _plot(check, spec, out)
    data = check.to_dict()
    data["plots"] = {p.name: PLOTS[p.name] for p in plots}
    (out / "report.json").write_text(json.dumps(data, indent=2, ensure_ascii=False) + "\n",
                                     encoding="utf-8")
    (out / "report.md").write_text(markdown(check) + "\n", encoding="utf-8")
    return check
