"""Time-domain margins in the nonlinear in-process closed loop (docs/ROBUST_ANALYSIS.md §2.5).

Per flight segment, the loop gain is scaled, and separately a delay is added, at the actuator
input inside the segment's window until the flight goes unstable (NASA SLS practice: Kiefer
et al., NTRS 20160001833, "raise loop gain or delay in the nonlinear simulation until
instability"); the results stand beside the frequency-domain margins of the same loop
(:mod:`vega_loops.margins`, loop broken at the actuator input, frozen times).

What is flown: the scenario (default ``nominal``: wind profile, light turbulence, INS noise,
nonlinear plant) with the controller table, from the scenario's start (0 s) to the window's
end + :data:`SETTLE_S`, through :func:`vega_sim.closed_loop.run_scenario` with a
:class:`vega_sim.closed_loop.LoopPerturbation` on the window: there the actuator's input is
k·β_c(t − Δ), β_c the controller's command it would hold unperturbed (a gain k, or a
transport delay Δ in whole ms, inserted at the actuator input for the window's duration). The
actuator keeps its position (±6.5°) and rate (20 °/s) limits, and the controller its ±6.5°
command limit: the saturations are part of the nonlinear loop. Before the window the flight is
the unperturbed one, bit for bit.

Verdict (:func:`flight_stability`): the Monte Carlo campaign's stability definition
(:data:`vega_campaign.campaign.STABILITY_LIMITS` through
:func:`vega_campaign.campaign.flight_metrics`: |q1| ≤ 1.0 and |q2| ≤ 0.1 modal units, ≈ 10×
the nominal flight's peaks, and ≤ 0.5 s in total with the nozzle on its rate limit), and the
same ≈ 10× rule over the segment's own span: the peak |q1| or |q2| from the window's start on
at most :data:`GROWTH` = 10 times the unperturbed flight's over that span (the campaign's
limits were set on the lift-off transient, the largest amplitudes of the flight; at burn-out
the amplitudes are 40 times smaller and a runaway would have to grow 500-fold to reach them).
Every loss seen drives the bending modes through the nozzle, rigid-body oscillations included.
Two backstops for the rigid body: a non-finite state (a run-away integration) and the
controller's command on its ±6.5° limit (``STATUS_LIMITED``) for more than 0.5 s in total —
no authority left over the aerodynamically unstable airframe (assumption: the campaign's
rate-limit allowance applied to the position limit).

Search (:func:`bisect_margin`), per segment and kind, on the perturbation's size x ≥ 0:
``gain_up`` (k = 10^(x/20) > 1), ``gain_down`` (k = 10^(−x/20) < 1: the rigid body is
aerodynamically unstable, too little gain loses it too) and ``delay`` (x in whole ms). Both
ends of the bracket are flown first — x = 0 must be stable (the unperturbed flight), the upper
end unstable, else the margin is reported as beyond the bracket ("not found") — then bisection
until the bracket is at most the tolerance wide: :data:`GAIN_BRACKET_DB` = 20 dB (k from 0.1 to
10) with :data:`GAIN_TOL_DB` = 0.1 dB, :data:`DELAY_BRACKET_MS` = 1000 ms with
:data:`DELAY_TOL_MS` = 1 ms. The margin is the largest perturbation flown stable (the
conservative end). Assumption: one boundary in the bracket (stable below, unstable above), as
the frozen loops have (rigid-body GM and PM only: bending gain-stabilised, ≤ −11 dB).

Reading them: a time-domain margin is the perturbation the flight *tolerates for the window's
duration*. Just beyond a frozen margin the loop's divergence is slow (its growth rate is 0 at
the margin), so the amplitude has to grow tenfold within the window (or reach the campaign's
limits): the time-domain margin lies above the smallest frozen margin in the window, by the
growth rate ln(10)/10 s ≈ 0.23 /s needs, more where the unstable mode is slow (delay: the
rigid-body crossover, ≈ 2 rad/s) than where it is fast (gain increase: the phase crossover,
≈ 6 rad/s); the rate limit, a nonlinear gain loss, works the other way. The
frequency-domain columns (``fd_*``) are the smallest margins of the nominal frozen loops at
the flight times of ``vega margins``' 0.5 s grid inside the window (continuous-equivalent
loop, :func:`vega_loops.margins.frozen_loop`), each with its time and the frequency of the
crossover it belongs to (``fd_*_w_radps``); the phase margin is the distance of the phase from
−180° at the closest gain crossover at or above :data:`vega_loops.margins.PM_FLOOR_RADPS`.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np


from vega_campaign.campaign import STABILITY_LIMITS

__all__ = ["SEGMENTS",  # noqa: F822 (module __getattr__: computed on first use)
           "Segment", "flight_segments", "WINDOW_S", "SETTLE_S", "KINDS",
           "GAIN_BRACKET_DB", "GAIN_TOL_DB", "DELAY_BRACKET_MS", "DELAY_TOL_MS",
           "CONTROLLER_LIMITED_S", "GROWTH", "flight_stability", "fly_perturbed", "perturbation",
           "bisect_margin", "delay_margin_ms", "frequency_margins", "segment_margins",
           "time_domain_margins", "CSV_COLUMNS", "write_csv", "markdown"]

WINDOW_S = 10.0
"""Length of a segment's window [s]. Assumption: 3–5 periods of the rigid-body loop
(crossover 1.6–2.6 rad/s nominal, ``vega margins``: periods 2.4–3.9 s), long enough for an
oscillatory instability to grow visibly, short enough for the flight condition to stay close
(max-Q window: q ≥ 94 % of its peak)."""

SETTLE_S = 3.0
"""Flight time after a window's end [s] (assumption: about one rigid-body period, so that an
amplitude that reached a limit at the window's end, or 0.5 s on a limit, still shows; the
loop is the nominal one again then)."""

FLIGHT_END_S = 100.0
"""End of the analysed flight [s]: the 0–100 s span of the product and its scenarios."""

KINDS = ("gain_up", "gain_down", "delay")
"""The perturbations searched, each by its own bisection."""

GAIN_BRACKET_DB = 20.0
"""Gain search bracket [dB]: 0 … 20 dB each way (k from 1 to 10, or 1 to 0.1); the
frequency-domain rigid-body margins are 6–26 dB (``vega margins`` on the shipped table)."""

GAIN_TOL_DB = 0.1
"""Width of the final gain bracket [dB] (8 bisections of 20 dB)."""

DELAY_BRACKET_MS = 1000
"""Delay search bracket [ms]: 0 … 1000 ms; the frequency-domain delay margins of the shipped
table are 170–830 ms over the flight (:func:`delay_margin_ms`; the time-domain ones on 10 s
windows 440–620 ms)."""

DELAY_TOL_MS = 1
"""Width of the final delay bracket [ms]: the loop's 1 ms time grid (vega_bus.timing)."""


GROWTH = 10.0
"""Largest growth of a bending amplitude over the window and after it, relative to the same
flight unperturbed [1]: the factor the campaign's limits put on the nominal flight's peaks
(|q1| ≤ 1.0 vs 0.080, |q2| ≤ 0.1 vs 0.0095: ≈ 10×), applied over the segment's own span so
that a segment flown at small amplitudes (burn-out: |q1| ≈ 0.002) is judged by the same rule
as the lift-off transient the campaign's absolute limits were set on."""

CONTROLLER_LIMITED_S = STABILITY_LIMITS["rate_limited_s"]
"""Largest total time with the controller's command on its ±6.5° limit in a stable flight
[s]: 0.5 s (assumption: the campaign's allowance on the rate limit,
``STABILITY_LIMITS['rate_limited_s']``, applied to the position limit; the nominal flight has
0 s)."""


# -------------------------------------------------------------------------------- segments
@dataclass(frozen=True)
class Segment:
    """A flight segment: the window [t0_s, t1_s) of flight time where the loop is perturbed
    (the actuator's time, :class:`vega_sim.closed_loop.LoopPerturbation`), and why there."""

    name: str
    t0_s: float
    t1_s: float
    source: str

    @property
    def t0_ms(self) -> int:
        """Window start [ms]."""
        return round(self.t0_s * 1000.0)

    @property
    def t1_ms(self) -> int:
        """Window end [ms] (excluded)."""
        return round(self.t1_s * 1000.0)


def _row_time(t_s: float) -> float:
    """``t_s`` on the 0.1 s rows of the flight-condition table (whole ms, exact decimals)."""
    return round(float(t_s), 1)


def flight_segments(context=None, window_s: float = WINDOW_S, settle_s: float = SETTLE_S,
                    flight_end_s: float = FLIGHT_END_S) -> tuple[Segment, ...]:
    """The four segments of the nominal flight, from its flight-condition data.

    * **lift-off** [0, 10) s: from the ignition command (0 s, vega_bus.timing) through tower
      clearance and the low-speed flight; assumption: the common window length.
    * **transonic** [t(M ≥ 0.8), t(M > 1.2)): the first row with Mach ≥ 0.8 to the first
      with Mach > 1.2 (the usual 0.8–1.2 transonic band; Mach 1 near its middle), on the
      0.1 s rows of the flight-condition table (``context.conditions``, what
      ``context.parameters(t).mach`` interpolates).
    * **max-Q** [t_q − 5, t_q + 5) s around :func:`vega_loops.margins.max_q_time`.
    * **burn-out** the last window that leaves ``settle_s`` inside the analysed flight:
      [100 − 3 − 10, 100 − 3) s (assumption: the product's flight ends at 100 s). It holds
      the first stage's thrust tail-off (thrust 2.2 MN at 90 s, 0.84 MN at 95 s, the table's
      ``thrust_n``), at the flight's largest velocity and a dynamic pressure down to 3 kPa.

    Parameters
    ----------
    context
        Model data (default: the shipped vehicle data and flight conditions).
    window_s, settle_s, flight_end_s
        :data:`WINDOW_S`, :data:`SETTLE_S`, :data:`FLIGHT_END_S`.
    """
    from vega_model.parameters import default_context

    from vega_loops.margins import max_q_time

    context = context if context is not None else default_context()
    fc = context.conditions
    t_rows = np.asarray(fc.t_s, dtype=float)
    mach = np.asarray(fc.column("mach"), dtype=float)
    q = np.asarray(fc.column("q_pa"), dtype=float)
    thrust = np.asarray(fc.column("thrust_n"), dtype=float)

    def mach_at(t):
        return context.parameters(t).mach

    def q_at(t):
        return context.parameters(t).q_pa

    lift = (0.0, _row_time(window_s))
    m0 = _row_time(t_rows[np.argmax(mach >= 0.8)])
    m1 = _row_time(t_rows[np.argmax(mach > 1.2)])
    t_q = _row_time(max_q_time(context))
    maxq = (_row_time(t_q - window_s / 2), _row_time(t_q + window_s / 2))
    burn = (_row_time(flight_end_s - settle_s - window_s), _row_time(flight_end_s - settle_s))
    q_max = float(q.max())
    return (
        Segment("lift-off", *lift,
                f"ignition command at 0 s (vega_bus.timing) to Mach {mach_at(lift[1]):.2f}; "
                f"assumption: the {window_s:g} s window length"),
        Segment("transonic", m0, m1,
                f"Mach {mach_at(m0):.3f} … {mach_at(m1):.3f} (first 0.1 s rows with M >= 0.8 "
                "and M > 1.2 of the flight-condition table; Mach 1 at "
                f"{_row_time(t_rows[np.argmax(mach >= 1.0)]):g} s)"),
        Segment("max-Q", *maxq,
                f"max-Q {q_max / 1000:.1f} kPa at {t_q:g} s (margins.max_q_time) ± "
                f"{window_s / 2:g} s (q >= {min(q_at(maxq[0]), q_at(maxq[1])) / q_max:.0%} of "
                "its peak)"),
        Segment("burn-out", *burn,
                f"assumption: the last {window_s:g} s window leaving {settle_s:g} s inside the "
                f"0–{flight_end_s:g} s flight; thrust tail-off "
                f"{np.interp(burn[0], t_rows, thrust) / 1e6:.2f} → "
                f"{np.interp(burn[1], t_rows, thrust) / 1e6:.2f} MN, q "
                f"{q_at(burn[0]) / 1000:.1f} → {q_at(burn[1]) / 1000:.1f} kPa, Mach "
                f"{mach_at(burn[1]):.2f} at its end"),
    )


def __getattr__(name: str):
    """``SEGMENTS``: :func:`flight_segments` of the shipped data (computed on first use, so
    that importing this module reads no data file)."""
    if name == "SEGMENTS":
        return flight_segments()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# -------------------------------------------------------------------------------- verdict
def flight_stability(result, reference=None, since_s: float | None = None) -> dict:
    """Whether a flight stayed stable, and by which criteria it did not.

    Criteria (module docstring), each a failure name:

    * ``diverged``: a truth state or the nozzle angle not finite;
    * the Monte Carlo campaign's :data:`~vega_campaign.campaign.STABILITY_LIMITS` on
      :func:`~vega_campaign.campaign.flight_metrics` (``max_abs_bending_q1`` > 1.0,
      ``max_abs_bending_q2`` > 0.1 modal units, ``rate_limited_s`` > 0.5 s);
    * ``controller_limited_s``: the controller's command on its limit (``STATUS_LIMITED``) for
      more than :data:`CONTROLLER_LIMITED_S` in total (commands × the controller period);
    * with a ``reference`` (the same flight unperturbed): ``q1_growth`` / ``q2_growth``, the
      peak |q1| or |q2| from ``since_s`` on more than :data:`GROWTH` times the reference's
      over the same span.

    Parameters
    ----------
    result
        A :class:`vega_sim.closed_loop.SimulationResult`.
    reference
        The unperturbed flight of the same scenario and span (None: no growth criterion).
    since_s
        Start of the span the growth is measured over [s] (default: the flight's start).

    Returns
    -------
    dict
        ``stable`` (bool), ``failed`` (the criteria broken, comma-separated, "" if none) and the
        metrics ``max_abs_bending_q1``, ``max_abs_bending_q2``, ``rate_limited_s``,
        ``controller_limited_s``, ``max_abs_theta_deg``, ``max_abs_beta_deg`` and, with a
        reference, ``q1_growth``, ``q2_growth``.
    """
    from vega_gnc.controller_runtime import STATUS_LIMITED

    from vega_campaign.campaign import flight_metrics

    truth = (result.theta_rad, result.theta_dot_radps, result.z_m, result.z_dot_mps,
             result.bending_q, result.bending_qdot, result.beta_rad)
    period_s = (float(np.median(np.diff(result.cmd_stamp_ms))) / 1000.0
                if result.cmd_stamp_ms.size > 1 else 0.0)
    limited_s = float(np.count_nonzero(result.cmd_status == STATUS_LIMITED)) * period_s
    if not all(np.all(np.isfinite(x)) for x in truth):
        return {"stable": False, "failed": "diverged", "max_abs_bending_q1": math.inf,
                "max_abs_bending_q2": math.inf, "rate_limited_s": math.nan,
                "controller_limited_s": limited_s, "max_abs_theta_deg": math.inf,
                "max_abs_beta_deg": math.nan}
    metrics = flight_metrics(result)
    failed = [key for key, bound in STABILITY_LIMITS.items() if not metrics[key] <= bound]
    if not limited_s <= CONTROLLER_LIMITED_S:
        failed.append("controller_limited_s")
    out = {"controller_limited_s": limited_s}
    for key in ("max_abs_bending_q1", "max_abs_bending_q2", "rate_limited_s",
                "max_abs_theta_deg", "max_abs_beta_deg"):
        out[key] = float(metrics[key])
    if reference is not None:
        start = result.t_s[0] if since_s is None else since_s
        span, ref_span = result.t_s >= start, reference.t_s >= start
        for i, name in enumerate(("q1_growth", "q2_growth")):
            peak = float(np.max(np.abs(result.bending_q[span, i]), initial=0.0))
            ref = float(np.max(np.abs(reference.bending_q[ref_span, i]), initial=0.0))
            out[name] = peak / ref if ref > 0.0 else (math.inf if peak > 0.0 else 1.0)
            if not out[name] <= GROWTH:
                failed.append(name)
    out.update(stable=not failed, failed=",".join(failed))
    return out


# -------------------------------------------------------------------------------- flights
def _scenario(scenario):
    from vega_sim.scenario import Scenario, load_scenario

    return scenario if isinstance(scenario, Scenario) else load_scenario(scenario)


def _table(table):
    from vega_gnc.controller_table import ControllerTable, load_controller_table

    return table if isinstance(table, ControllerTable) else load_controller_table(table)


def perturbation(segment: Segment, kind: str, size: float):
    """The :class:`~vega_sim.closed_loop.LoopPerturbation` of ``kind`` and ``size`` on the
    segment's window: ``gain_up`` k = 10^(size/20), ``gain_down`` k = 10^(−size/20) (size
    in dB ≥ 0), ``delay`` ``size`` whole ms ≥ 0.

    Raises
    ------
    ValueError
        An unknown kind or a negative size.
    """
    from vega_sim.closed_loop import LoopPerturbation

    if kind not in KINDS:
        raise ValueError(f"perturbation kind {kind!r}: expected one of {', '.join(KINDS)}")
    if not size >= 0.0:
        raise ValueError(f"perturbation size {size!r}: need >= 0")
    if kind == "delay":
        return LoopPerturbation(segment.t0_ms, segment.t1_ms, delay_ms=int(size))
    sign = 1.0 if kind == "gain_up" else -1.0
    return LoopPerturbation(segment.t0_ms, segment.t1_ms, gain=10.0 ** (sign * size / 20.0))


def fly_perturbed(table, segment: Segment, kind: str = "gain_up", size: float = 0.0,
                  scenario="nominal", settle_s: float = SETTLE_S, context=None):
    """Fly ``scenario`` from its start to the window's end + ``settle_s`` with the loop
    perturbed inside the window (:func:`perturbation`; size 0 = the unperturbed loop).

    Parameters
    ----------
    table
        A controller table or its path.
    segment, kind, size
        The window and the perturbation (:func:`perturbation`).
    scenario
        A :class:`~vega_sim.scenario.Scenario` or a shipped name / YAML path; its ``t_end_s``
        is replaced by the window's end + ``settle_s``.
    settle_s
        Flight time after the window [s].
    context
        Model data (default: the shipped data).

    Returns
    -------
    vega_sim.closed_loop.SimulationResult

    Raises
    ------
    ValueError
        A window that is empty or starts before the scenario.
    """
    from vega_sim.closed_loop import run_scenario

    base = _scenario(scenario)
    if not base.t_start_s <= segment.t0_s < segment.t1_s:
        raise ValueError(f"segment {segment.name!r} [{segment.t0_s:g}, {segment.t1_s:g}) s: "
                         f"need a window within the flight from {base.t_start_s:g} s")
    flown = replace(base, t_end_s=round(segment.t1_ms + settle_s * 1000.0) / 1000.0)
    return run_scenario(flown, _table(table), context=context,
                        perturbation=perturbation(segment, kind, size))


def bisect_margin(table, segment: Segment, kind: str, scenario="nominal",
                  settle_s: float = SETTLE_S, bracket: float | None = None,
                  tol: float | None = None, context=None) -> dict:
    """The largest perturbation of ``kind`` inside ``segment`` the flight stays stable with.

    Flies size 0 (must be stable) and the bracket's end (must be unstable), then bisects until
    the bracket [stable, unstable] is at most ``tol`` wide (module docstring). Delays are
    bisected on whole milliseconds.

    Parameters
    ----------
    table
        A controller table or its path.
    segment, kind
        The window and the perturbation kind (:data:`KINDS`).
    scenario, settle_s, context
        See :func:`fly_perturbed`.
    bracket, tol
        Upper end of the search and final bracket width: dB for the gains
        (:data:`GAIN_BRACKET_DB`, :data:`GAIN_TOL_DB`), ms for the delay
        (:data:`DELAY_BRACKET_MS`, :data:`DELAY_TOL_MS`) by default.

    Returns
    -------
    dict
        ``segment``, ``kind``, ``unit`` ("dB" or "ms"), ``margin`` (the largest size flown
        stable; NaN if the unperturbed flight is not), ``unstable_at`` (the smallest size
        flown unstable; inf if none up to the bracket's end), ``found`` (a boundary inside
        the bracket), ``failed`` (the criteria broken at ``unstable_at``), ``flights``,
        ``bracket``, ``tol``, ``wall_s``.
    """
    start = _time.perf_counter()
    delay = kind == "delay"
    if kind not in KINDS:
        raise ValueError(f"margin kind {kind!r}: expected one of {', '.join(KINDS)}")
    bracket = (DELAY_BRACKET_MS if delay else GAIN_BRACKET_DB) if bracket is None else bracket
    tol = (DELAY_TOL_MS if delay else GAIN_TOL_DB) if tol is None else tol
    if delay:
        bracket, tol = int(bracket), max(1, int(tol))
    if not (bracket > 0 and tol > 0):
        raise ValueError(f"bracket {bracket!r} and tol {tol!r} must both be > 0")
    table = _table(table)
    scenario = _scenario(scenario)
    unperturbed = fly_perturbed(table, segment, kind, 0, scenario, settle_s, context)
    at_zero = flight_stability(unperturbed)
    flights = 1

    def verdict(size):
        """The verdict on the flight perturbed by ``size``, growth against the unperturbed."""
        nonlocal flights
        flights += 1
        flown = fly_perturbed(table, segment, kind, size, scenario, settle_s, context)
        return flight_stability(flown, unperturbed, segment.t0_s)

    out = {"segment": segment.name, "kind": kind, "unit": "ms" if delay else "dB",
           "bracket": bracket, "tol": tol}
    if not at_zero["stable"]:
        out.update(margin=math.nan, unstable_at=0, found=False, failed=at_zero["failed"])
    else:
        at_end = verdict(bracket)
        if at_end["stable"]:
            out.update(margin=bracket, unstable_at=math.inf, found=False, failed="")
        else:
            lo, hi, failed = 0, bracket, at_end["failed"]
            while hi - lo > tol:
                mid = (lo + hi) // 2 if delay else 0.5 * (lo + hi)
                v = verdict(mid)
                if v["stable"]:
                    lo = mid
                else:
                    hi, failed = mid, v["failed"]
            out.update(margin=lo, unstable_at=hi, found=True, failed=failed)
    out.update(flights=flights, wall_s=_time.perf_counter() - start)
    return out


# ---------------------------------------------------------------------- frequency domain
def delay_margin_ms(w_radps, L) -> tuple[float, float]:
    """Smallest extra delay that puts the loop L(jω) on −1, and its frequency.

    At every gain crossover ω_c (|L| = 1, located by linear interpolation in log ω as
    :func:`vega_loops.margins.extract_margins` does) a delay Δ turns L by −ω_cΔ, which
    reaches −180° after ((180° + ∠L(jω_c)) mod 360°)/ω_c; the margin is the smallest over the
    crossovers (inf if there is none).

    Returns
    -------
    (delay margin [ms], ω_c [rad/s])
    """
    w = np.asarray(w_radps, dtype=float)
    L = np.asarray(L, dtype=complex)
    mag_db = 20.0 * np.log10(np.maximum(np.abs(L), 1e-300))
    phase = np.degrees(np.unwrap(np.angle(L)))
    lw = np.log(w)
    best = (math.inf, math.nan)
    for k in np.nonzero(np.sign(mag_db[:-1]) != np.sign(mag_db[1:]))[0]:
        f = mag_db[k] / (mag_db[k] - mag_db[k + 1])
        wc = math.exp(lw[k] + f * (lw[k + 1] - lw[k]))
        margin_deg = (180.0 + phase[k] + f * (phase[k + 1] - phase[k])) % 360.0
        dm = math.radians(margin_deg) / wc * 1000.0
        if dm < best[0]:
            best = (dm, wc)
    return best


def frequency_margins(table, segment: Segment, scenario="nominal", context=None,
                      step_s: float = 0.5) -> dict:
    """The smallest frequency-domain margins of the frozen loops inside the window.

    At the flight times k·``step_s`` in [t0, t1] (``vega margins``' grid), the nominal plant
    with the scenario's deviations (:func:`vega_loops.margins.corner_plant`) and the
    flown controller at the nominal velocity, loop broken at the actuator input
    (continuous-equivalent loop, :func:`vega_loops.margins.frozen_loop`).

    Returns
    -------
    dict
        ``fd_gm_up_db`` (``gm_high_db``), ``fd_gm_down_db`` (``gm_low_db``), ``fd_pm_deg``
        (``pm_deg``: the distance of the phase from −180°), ``fd_dm_ms``
        (:func:`delay_margin_ms`), each the minimum over the times, with the time of the
        minimum (``*_t_s``) and the frequency of its crossover (``*_w_radps``: the phase
        crossover of a gain margin, the gain crossover of the phase and delay margins — for
        the delay margin the rigid-body one near 2 rad/s, or one above it); ``fd_times`` (how
        many times).
    """
    from vega_model.parameters import default_context

    from vega_loops import margins as M

    context = context if context is not None else default_context()
    table = _table(table)
    deviations = _scenario(scenario).deviations
    first = math.ceil(segment.t0_s / step_s - 1e-9)
    times = [round(k * step_s, 6) for k in range(first, int(segment.t1_s / step_s + 1e-9) + 1)]
    # column stem -> value at one time
    per_time = []
    for t in times:
        data = M.loop_data(table, context, t)
        p, act, tau = M.corner_plant(context, t, deviations)
        loop = M.frozen_loop(data, p, act, tau)
        m = M.extract_margins(data.w_radps, loop.L, loop.omega_modes)
        dm_ms, dm_w = delay_margin_ms(data.w_radps, loop.L)
        per_time.append((t, {"fd_gm_up": m["gm_high_db"], "fd_gm_up_w": m["w_gm_high_radps"],
                             "fd_gm_down": m["gm_low_db"], "fd_gm_down_w": m["w_gm_low_radps"],
                             "fd_pm": m["pm_deg"], "fd_pm_w": m["w_pm_radps"],
                             "fd_dm": dm_ms, "fd_dm_w": dm_w}))
    out: dict = {}
    for stem, unit in (("fd_gm_up", "db"), ("fd_gm_down", "db"), ("fd_pm", "deg"),
                       ("fd_dm", "ms")):
        t, values = min(per_time, key=lambda item: item[1][stem])
        out[f"{stem}_{unit}"], out[f"{stem}_t_s"] = float(values[stem]), t
        out[f"{stem}_w_radps"] = float(values[f"{stem}_w"])
    out["fd_times"] = len(times)
    return out


# ------------------------------------------------------------------------------ segments
_PREFIX = {"gain_up": "gm_up", "gain_down": "gm_down", "delay": "dm"}


def _row(segment: Segment, settle_s: float, results: Sequence[Mapping],
         fd: Mapping | None) -> dict:
    """One segment's row from its bisections (and frequency-domain margins)."""
    row = {"segment": segment.name, "t0_s": segment.t0_s, "t1_s": segment.t1_s,
           "t_end_s": round(segment.t1_s + settle_s, 3), "source": segment.source}
    flights = 0
    for r in results:
        stem = _PREFIX[r["kind"]]
        unit = "ms" if r["kind"] == "delay" else "db"
        row[f"{stem}_{unit}"] = r["margin"]
        row[f"{stem}_unstable_{unit}"] = r["unstable_at"]
        row[f"{stem}_found"] = r["found"]
        row[f"{stem}_failed"] = r["failed"]
        row[f"{stem}_flights"] = r["flights"]
        flights += r["flights"]
    row["flights"] = flights
    if fd is not None:
        row.update(fd)
    return row


def segment_margins(table, segment: Segment, scenario="nominal", kinds: Sequence[str] = KINDS,
                    settle_s: float = SETTLE_S, brackets: Mapping[str, float] | None = None,
                    tols: Mapping[str, float] | None = None, frequency_domain: bool = True,
                    context=None) -> dict:
    """Every margin of one segment in this process (:func:`bisect_margin` per kind, and
    :func:`frequency_margins`): one row as :func:`time_domain_margins` gives it.

    ``brackets`` and ``tols``: per kind, overriding the defaults (e.g. a coarse tolerance for a
    quick check)."""
    brackets, tols = dict(brackets or {}), dict(tols or {})
    table = _table(table)
    results = [bisect_margin(table, segment, kind, scenario, settle_s, brackets.get(kind),
                             tols.get(kind), context) for kind in kinds]
    fd = frequency_margins(table, segment, scenario, context) if frequency_domain else None
    return _row(segment, settle_s, results, fd)


_WORKER: dict = {}


def _init_worker(table_path: str) -> None:
    _WORKER["table"] = _table(table_path)


def _task(args):
    index, segment, kind, scenario, settle_s, bracket, tol = args
    table = _WORKER["table"]
    if kind == "frequency":
        return index, kind, frequency_margins(table, segment, scenario)
    return index, kind, bisect_margin(table, segment, kind, scenario, settle_s, bracket, tol)


def _describe(kind: str, res: Mapping) -> str:
    """One line about a finished task (:func:`time_domain_margins`' progress)."""
    if kind == "frequency":
        def at(stem):
            w = res[f"{stem}_w_radps"]
            return f" at {w:.3g} rad/s" if math.isfinite(w) else ""

        return (f"frequency domain GM +{res['fd_gm_up_db']:.2f} dB{at('fd_gm_up')}, "
                f"-{res['fd_gm_down_db']:.2f} dB{at('fd_gm_down')}, PM {res['fd_pm_deg']:.1f} "
                f"deg{at('fd_pm')}, DM {res['fd_dm_ms']:.0f} ms{at('fd_dm')} "
                f"({res['fd_times']} frozen times)")
    if math.isnan(res["margin"]):
        found = f"unperturbed flight unstable ({res['failed']})"
    elif not res["found"]:
        found = f"> {res['margin']:g} {res['unit']} (stable at the bracket's end)"
    else:
        found = (f"{res['margin']:g} {res['unit']} (unstable at {res['unstable_at']:g}: "
                 f"{res['failed']})")
    return f"{kind} {found}, {res['flights']} flights"


def time_domain_margins(table_path: str | Path, scenario="nominal",
                        segments: Sequence[Segment] | None = None, workers: int = 1,
                        progress: Callable[[str], None] | None = None,
                        settle_s: float = SETTLE_S, kinds: Sequence[str] = KINDS,
                        brackets: Mapping[str, float] | None = None,
                        tols: Mapping[str, float] | None = None,
                        frequency_domain: bool = True) -> list[dict]:
    """Time-domain gain and delay margins per flight segment, beside the frequency-domain ones.

    Parameters
    ----------
    table_path
        Controller table file (the flown one: ``vega_gnc.controller_table.default_table_path()``).
    scenario
        Shipped scenario name, YAML path or :class:`~vega_sim.scenario.Scenario` (default
        ``nominal``); flown from its start to each window's end + ``settle_s``.
    segments
        Windows (default: :func:`flight_segments` of the shipped data, :data:`SEGMENTS`).
    workers
        Processes (``spawn``, one BLAS thread each, one bisection per task); 0 runs in this
        process. The result does not depend on it.
    progress
        Called with one line per finished bisection (and frequency-domain sweep).
    settle_s
        Flight time after each window [s].
    kinds
        The searches (:data:`KINDS`).
    brackets, tols
        Per kind, the search's upper end and final bracket width (default: dB
        :data:`GAIN_BRACKET_DB`, :data:`GAIN_TOL_DB`; ms :data:`DELAY_BRACKET_MS`,
        :data:`DELAY_TOL_MS`).
    frequency_domain
        Also the frequency-domain margins in the windows (:func:`frequency_margins`).

    Returns
    -------
    list of dict
        One row per segment, in ``segments`` order: ``segment``, ``t0_s``, ``t1_s``,
        ``t_end_s``, ``source``; per kind (``gm_up_db``, ``gm_down_db``, ``dm_ms``) the margin
        (the largest perturbation flown stable), ``*_unstable_*`` (the smallest flown unstable;
        inf: none up to the bracket's end), ``*_found``, ``*_failed`` (criteria broken there),
        ``*_flights``; ``flights`` (total); with ``frequency_domain`` the ``fd_*`` columns.
    """
    start = _time.perf_counter()
    segments = tuple(flight_segments() if segments is None else segments)
    scenario = _scenario(scenario)
    kinds = tuple(dict.fromkeys(kinds))
    for kind in kinds:
        if kind not in KINDS:
            raise ValueError(f"margin kind {kind!r}: expected one of {', '.join(KINDS)}")
    brackets, tols = dict(brackets or {}), dict(tols or {})
    tasks = [(i, seg, kind, scenario, settle_s, brackets.get(kind), tols.get(kind))
             for i, seg in enumerate(segments) for kind in kinds]
    if frequency_domain:
        tasks += [(i, seg, "frequency", scenario, settle_s, None, None)
                  for i, seg in enumerate(segments)]
    done: dict = {}

    def report(index, kind, res):
        done[(index, kind)] = res
        if progress is not None:
            progress(f"time margins: {segments[index].name} {_describe(kind, res)} — "
                     f"{len(done)}/{len(tasks)} done, {_time.perf_counter() - start:.1f} s "
                     "elapsed")

    table_path = str(table_path)
    if workers <= 0:
        _init_worker(table_path)
        for task in tasks:
            report(*_task(task))
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        from vega_loops.margins import single_thread_blas

        # the longest flights first (burn-out), so that the last tasks are short ones
        order = sorted(tasks, key=lambda task: -task[1].t1_s)
        with single_thread_blas(), ProcessPoolExecutor(
                max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                initializer=_init_worker, initargs=(table_path,)) as pool:
            for future in as_completed([pool.submit(_task, task) for task in order]):
                report(*future.result())
    return [_row(seg, settle_s, [done[(i, kind)] for kind in kinds],
                 done[(i, "frequency")] if frequency_domain else None)
            for i, seg in enumerate(segments)]


# -------------------------------------------------------------------------------- output
CSV_COLUMNS = (
    "segment", "t0_s", "t1_s", "t_end_s",
    "gm_up_db", "gm_up_unstable_db", "gm_up_found", "gm_up_failed", "gm_up_flights",
    "gm_down_db", "gm_down_unstable_db", "gm_down_found", "gm_down_failed", "gm_down_flights",
    "dm_ms", "dm_unstable_ms", "dm_found", "dm_failed", "dm_flights", "flights",
    "fd_gm_up_db", "fd_gm_up_t_s", "fd_gm_up_w_radps", "fd_gm_down_db", "fd_gm_down_t_s",
    "fd_gm_down_w_radps", "fd_pm_deg", "fd_pm_t_s", "fd_pm_w_radps", "fd_dm_ms", "fd_dm_t_s",
    "fd_dm_w_radps", "source")
"""time_margins.csv columns; the unit is the name's suffix (_db, _ms, _deg, _s, _radps);
margins are the largest perturbation flown stable, ``*_unstable_*`` the smallest flown unstable
(inf: none), ``fd_*`` the smallest frequency-domain margin in the window, its time and the
frequency of its crossover (``fd_pm_deg``: the distance of the phase from −180°; nan: no
crossover)."""


def _csv_field(value) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return '"' + value.replace('"', '""') + '"' if ("," in value or '"' in value) else value
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return f"{float(value):.6g}"


def write_csv(path, rows: Sequence[Mapping], columns: Sequence[str] = CSV_COLUMNS) -> None:
    """Rows of :func:`time_domain_margins` as CSV (a missing value is an empty field, a text
    with a comma is quoted)."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(columns) + "\n")
        for r in rows:
            f.write(",".join(_csv_field(r.get(c)) for c in columns) + "\n")


def _cell(row: Mapping, stem: str, unit: str, digits: int) -> str:
    value = row.get(f"{stem}_{unit}")
    if value is None:
        return "–"
    if isinstance(value, float) and math.isnan(value):
        return "unperturbed flight unstable"
    text = f"{value:.{digits}f}"
    return text if row.get(f"{stem}_found") else f"> {text}"


def markdown(rows: Sequence[Mapping]) -> str:
    """A markdown table of :func:`time_domain_margins` rows: per segment the time-domain
    margins beside the smallest frequency-domain ones in the window ("freq"), each of those
    at its crossover (``@ω`` [rad/s])."""
    lines = ["| segment | window [s] | GM up [dB] time / freq @rad/s | GM down [dB] time / freq "
             "@rad/s | delay margin [ms] time / freq @rad/s | PM (distance) [deg] freq @rad/s "
             "| flights |",
             "|---|---|---|---|---|---|---|"]

    def fd(row, key, digits):
        value = row.get(key)
        if value is None:
            return "–"
        w = row.get(key.rsplit("_", 1)[0] + "_w_radps")
        at = "" if w is None or not math.isfinite(w) else f" @{w:.3g}"
        return f"{value:.{digits}f}{at}"

    for r in rows:
        lines.append(
            f"| {r['segment']} | {r['t0_s']:g}–{r['t1_s']:g} | {_cell(r, 'gm_up', 'db', 1)} / "
            f"{fd(r, 'fd_gm_up_db', 1)} | {_cell(r, 'gm_down', 'db', 1)} / "
            f"{fd(r, 'fd_gm_down_db', 1)} | {_cell(r, 'dm', 'ms', 0)} / {fd(r, 'fd_dm_ms', 0)} "
            f"| {fd(r, 'fd_pm_deg', 1)} | {r['flights']} |")
    return "\n".join(lines) + "\n"
