"""The vehicle's wind capability: the largest wind change per altitude band, the largest upper wind.

Two curves that describe the vehicle (controller table, guidance, plant), not a launch site's
climatology (docs/WINDS.md, "The vehicle's capability"):

* **Wind change per altitude band.** The guidance is re-biased on a measured profile
  (:func:`vega_reference.rebias.rebias_reference`); the vehicle then flies that profile plus a
  change confined to one band [h_lo, h_hi]: a raised-cosine bump
  Δw · ½(1 − cos(2π (h − h_lo)/(h_hi − h_lo))), zero outside the band, peak Δw at its centre.
  Per band and sign, the largest |Δw| at which the flight still passes.
* **Upper wind.** The vehicle flies the measured profile plus a jet
  A · ½(1 + cos(π (h − h_c)/w)) for |h − h_c| ≤ w (zero outside; w = 3 km), with the guidance
  re-biased on exactly that profile (a perfect sounding) and, for comparison, with the shipped
  reference (designed for thesis Eq. 2.54, not re-biased) and with no bias. Per jet altitude
  h_c and sign, the largest |A| at which the flight passes: the difference is what
  day-of-launch biasing buys.

**Pass** is the flight-day verdict: every requirement of docs/REQUIREMENTS.md with the constant
Qα allowable of §6 in place of §2's envelope (``RequirementReport.passed_with_allowable``), and
stable and not rate-limited by the Monte Carlo campaign's limits
(:data:`vega_campaign.campaign.STABILITY_LIMITS`: bending q1 ≤ 1, q2 ≤ 0.1, nozzle at ≥ 99 % of
its rate limit for ≤ 0.5 s). The flights are deterministic: nominal plant (no uncertainty), no
turbulence, no gust, no INS noise — the capability of the vehicle against the steady profile
alone; the stochastic parts are the Monte Carlo campaign's.

**Search.** Bisection on the grid k · resolution, k = 0 … cap/resolution (:data:`CAP_MPS` for
the change, :data:`UPPER_CAP_MPS` for the jet): first the cap (if the flight passes there, the
result is "≥ cap"), then the midpoint of the last passing and the first
failing amplitude until they are one grid step apart. The amplitude 0 is the measured profile
itself, flown once per guidance; if it fails, no search of that guidance is run. It assumes
the verdict is monotone in |Δw| on each search (one threshold); it reports the largest passing
amplitude found and the requirements that failed at the smallest failing one. All searches
advance together, one round per bisection step: the flights of a round fly as batches
(:func:`vega_sim.batch.fly_batch`, each flight with its own reference, bit for bit the
per-flight results; the flights without a reference in batches of their own), shared out
over ``workers`` processes. The results do not depend on the number of workers.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["DEFAULT_BANDS_KM", "DEFAULT_JET_CENTRES_KM", "JET_HALF_WIDTH_M", "CAP_MPS",
           "UPPER_CAP_MPS", "check_amplitudes",
           "RESOLUTION_MPS", "PROFILE_STEP_M", "PROFILE_TOP_M", "Bisection",
           "bisect_largest_passing", "calm_profile", "month_mean_profile", "band_window",
           "jet_window", "Verdict", "flight_verdict", "Search", "CapabilityResult",
           "capability", "write_capability", "plot_wind_change", "plot_upper_wind"]

DEFAULT_BANDS_KM = ((0, 2), (2, 4), (4, 6), (6, 8), (8, 10), (10, 12), (12, 14), (14, 16),
                    (16, 18), (18, 20), (20, 25))
"""Altitude bands of the wind change [km]. Assumption: 2 km bands up to 20 km (the altitudes of
the flight's aerodynamic load: the nominal flight reaches ≈ 20 km at 60 s and max-Q, 47 s, at
≈ 11 km, docs/TRAJECTORY.md), one 5 km band above, where the dynamic pressure falls off."""

DEFAULT_JET_CENTRES_KM = (8, 10, 12, 14, 16)
"""Centres of the upper-wind jet [km] (assumption: the altitudes around max-Q, ≈ 11 km, where
the upper-tropospheric jets of docs/WINDS.md §2 peak, 10–15 km)."""

JET_HALF_WIDTH_M = 3000.0
"""Half-width of the jet [m] (assumption: a 6 km deep jet, of the depth of the 12 km peaks of
the site tables, docs/WINDS.md §2; the exact shape of a measured jet is the sounding's)."""

CAP_MPS = 60.0
"""Largest wind change searched [m/s]. Assumption: twice the largest p99 flown speed of the
Kourou analogue in docs/WINDS.md §2 (29.7 m/s), and 6× the 99th percentile of the assumed 4 h
change (9.6 m/s, §5); beyond it the result is reported as "≥ 60 m/s", a change no Kourou day
asks for."""

UPPER_CAP_MPS = 100.0
"""Largest jet peak searched [m/s]. Assumption: the tabulated-wind bound (vega_model.wind,
120 m/s) less a measured profile of ≤ 20 m/s (the largest monthly mean speed of the shipped
site file below 25 km, 20.5 m/s, is at 25 km, outside every jet); with the guidance re-biased on
the jet, 60 m/s does not bind at any altitude searched."""

RESOLUTION_MPS = 0.25
"""Resolution of the search [m/s] (assumption: well below the 0.5 m/s of a sounding's wind
resolution; 8 bisection steps from the cap)."""

PROFILE_STEP_M = 100.0
"""Spacing of the measured profile [m]: the sampled grid of docs/WINDS.md §1."""

PROFILE_TOP_M = 30_000.0
"""Top of the measured profile [m] (docs/WINDS.md §1; the plant holds the last value above)."""

_WINDOW_POINTS = 81     # extra table rows across a band or jet: its peak and edges exactly


# -- the search ------------------------------------------------------------------------------


class Bisection:
    """Bisection for the largest passing amplitude on the grid k · ``resolution``,
    k = 0 … round(``cap``/``resolution``), the amplitude 0 taken as passing (module docstring).

    :meth:`candidate` gives the next amplitude to fly (None: finished); :meth:`update` records
    its verdict. ``largest_passing`` is the result, ``smallest_failing`` the first failure
    (None: the cap passed), ``outcome`` the verdict object given with it.
    """

    def __init__(self, cap: float, resolution: float):
        if not (math.isfinite(cap) and math.isfinite(resolution) and 0 < resolution <= cap):
            raise ValueError(f"need 0 < resolution <= cap, got {resolution!r}, {cap!r}")
        self.resolution = float(resolution)
        self._top = int(round(cap / resolution))
        self._lo, self._hi = 0, None
        self._next: int | None = self._top
        self.outcome: Any = None            # the verdict at smallest_failing
        self.passing_outcome: Any = None    # the verdict at largest_passing (None: not flown)
        self.flights = 0

    def candidate(self) -> float | None:
        """The next amplitude to fly [the unit of cap], or None when finished."""
        return None if self._next is None else self._next * self.resolution

    def update(self, passed: bool, outcome: Any = None) -> None:
        """Record the verdict of :meth:`candidate`'s flight."""
        k = self._next
        if k is None:
            raise RuntimeError("bisection finished: nothing to update")
        self.flights += 1
        if passed:
            self._lo, self.passing_outcome = k, outcome
        else:
            self._hi, self.outcome = k, outcome
        self._next = (None if self._hi is None or self._hi - self._lo <= 1
                      else (self._lo + self._hi) // 2)

    @property
    def done(self) -> bool:
        """True when the search is finished."""
        return self._next is None

    @property
    def largest_passing(self) -> float:
        """The largest amplitude found passing (0 before any passing flight)."""
        return self._lo * self.resolution

    @property
    def smallest_failing(self) -> float | None:
        """The smallest amplitude found failing (None: none failed)."""
        return None if self._hi is None else self._hi * self.resolution


def bisect_largest_passing(passes: Callable[[float], bool], cap: float,
                           resolution: float) -> tuple[float, float | None, int]:
    """The largest amplitude ≤ ``cap`` on the ``resolution`` grid at which ``passes`` holds,
    for a verdict monotone in the amplitude with ``passes(0)`` true (:class:`Bisection`, one
    evaluation at a time). Returns (largest passing, smallest failing or None, evaluations)."""
    b = Bisection(cap, resolution)
    while not b.done:
        b.update(bool(passes(b.candidate())))
    return b.largest_passing, b.smallest_failing, b.flights


# -- the profiles ----------------------------------------------------------------------------


def _grid() -> np.ndarray:
    return np.arange(int(round(PROFILE_TOP_M / PROFILE_STEP_M)) + 1) * PROFILE_STEP_M


def calm_profile():
    """The calm measured profile: 0 m/s on 0–30 km every 100 m (a ``WindTable``)."""
    from vega_model.wind import WindTable

    h = _grid()
    return WindTable(h, np.zeros_like(h), "calm (0 m/s at every altitude)")


def month_mean_profile(site, month: int):
    """A month's mean measured profile of a site file (:func:`vega_campaign.wind_environment.
    load_site`): the table's mean wind speed (RRA Table I MEAN WS column) at each level,
    linear in altitude on the site's 100 m grid, + downrange. Why the speed: in the default
    ``full_speed`` mode (docs/WINDS.md §3) a sounding's whole speed is put in the pitch plane,
    positive along its own direction, so the month's typical sounding is its mean speed."""
    from vega_model.wind import WindTable

    rows = site.months[int(month)]
    h = site.fine_altitude_m
    return WindTable(h, np.interp(h, site.altitude_m, rows[:, 6]),
                     f"{site.path} month {int(month)}: mean wind speed (MEAN WS), in the pitch "
                     "plane, + downrange")


def band_window(h_m, lo_m: float, hi_m: float) -> np.ndarray:
    """Raised-cosine bump over [lo, hi]: ½(1 − cos(2π (h − lo)/(hi − lo))) inside, 0 outside
    (peak 1 at the band's centre; value and slope 0 at its edges)."""
    h = np.asarray(h_m, dtype=float)
    x = (h - lo_m) / (hi_m - lo_m)
    return np.where((x >= 0.0) & (x <= 1.0), 0.5 * (1.0 - np.cos(2.0 * np.pi * x)), 0.0)


def jet_window(h_m, centre_m: float, half_width_m: float = JET_HALF_WIDTH_M) -> np.ndarray:
    """Raised-cosine jet: ½(1 + cos(π (h − h_c)/w)) for |h − h_c| ≤ w, 0 outside (peak 1 at
    h_c)."""
    x = (np.asarray(h_m, dtype=float) - centre_m) / half_width_m
    return np.where(np.abs(x) <= 1.0, 0.5 * (1.0 + np.cos(np.pi * x)), 0.0)


def _with_window(base, lo_m: float, hi_m: float, shape: Callable[[np.ndarray], np.ndarray],
                 amplitude: float, source: str):
    """``base`` + amplitude · shape(h) as a WindTable: the base's rows plus
    :data:`_WINDOW_POINTS` rows across [lo, hi], the base read there as the plant reads it."""
    from vega_model.wind import WindTable

    h0, w0 = np.asarray(base.altitude_m), np.asarray(base.wind_mps)
    h = np.union1d(h0, np.linspace(lo_m, hi_m, _WINDOW_POINTS))
    return WindTable(h, np.interp(h, h0, w0) + amplitude * shape(h), source)


# -- one flight ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Verdict:
    """The flight-day verdict of one flight (module docstring).

    ``failed``: the requirements not met, most violated first (fraction over the bound), by
    the keys of the requirement file (``q_alpha_allowable``, ``drift``, ``drift_rate``,
    ``deflection``, ``deflection_integral``) and ``stability`` (bending) or ``rate_limit``.
    ``envelope_passed``: §2's verdict (the Mach-dependent envelope), for information.
    """

    passed: bool
    failed: tuple[str, ...]
    envelope_passed: bool
    max_abs_q_alpha_pa_deg: float
    max_abs_z_m: float
    max_abs_zdot_mps: float
    max_abs_beta_deg: float
    rate_limited_s: float


def flight_verdict(result) -> Verdict:
    """The :class:`Verdict` of a :class:`vega_sim.closed_loop.SimulationResult`."""
    from vega_campaign.campaign import STABILITY_LIMITS, flight_metrics
    from vega_sim.requirements import load_requirements

    report = result.metrics(load_requirements())
    row = flight_metrics(result)
    over: list[tuple[float, str]] = []
    lines = report.with_allowable
    if lines is None:
        raise ValueError("the requirement file has no q_alpha_allowable (docs/REQUIREMENTS.md "
                         "§6)")
    for r in lines:
        if not r.passed:
            over.append((-r.margin / abs(r.bound), r.key))
    for key in ("max_abs_bending_q1", "max_abs_bending_q2"):
        if row[key] > STABILITY_LIMITS[key]:
            over.append((row[key] / STABILITY_LIMITS[key] - 1.0, "stability"))
    limit = STABILITY_LIMITS["rate_limited_s"]
    if row["rate_limited_s"] > limit:
        over.append((row["rate_limited_s"] / limit - 1.0, "rate_limit"))
    failed: list[str] = []
    for _, key in sorted(over, reverse=True):
        if key not in failed:
            failed.append(key)
    return Verdict(passed=not failed, failed=tuple(failed),
                   envelope_passed=bool(report.passed),
                   max_abs_q_alpha_pa_deg=row["max_abs_q_alpha_pa_deg"],
                   max_abs_z_m=row["max_abs_z_m"], max_abs_zdot_mps=row["max_abs_zdot_mps"],
                   max_abs_beta_deg=row["max_abs_beta_deg"],
                   rate_limited_s=row["rate_limited_s"])


@lru_cache(maxsize=2)
def _table(path: str):
    from vega_gnc.controller_table import load_controller_table

    return load_controller_table(path)


def _fly_group(scenarios: Sequence, table_path: str) -> tuple[list[Verdict], float]:
    """Fly scenarios that all fly a guidance reference (each its own) or all none: as one
    batch (bit for bit the per-flight results), or one flight through ``run_scenario``.
    Returns their verdicts and the CPU time it took [s]."""
    from vega_sim.batch import fly_batch
    from vega_sim.closed_loop import run_scenario

    t0 = time.process_time()
    table = _table(table_path)
    if len(scenarios) == 1:
        verdicts = [flight_verdict(run_scenario(scenarios[0], table))]
    else:
        verdicts = [flight_verdict(r) for r in fly_batch(scenarios, table)]
    return verdicts, time.process_time() - t0


# -- the searches ----------------------------------------------------------------------------

KINDS = ("wind_change", "upper_wind_rebiased", "upper_wind_default", "upper_wind_none")
"""The searches: the band change (guidance re-biased on the measured profile); the jet with the
guidance re-biased on the flown profile, with the shipped reference (designed for thesis
Eq. 2.54, not re-biased), and with no bias at all (``guidance: none``: zero reference)."""

_GUIDANCE_OF = {"wind_change": "measured", "upper_wind_rebiased": "flown",
                "upper_wind_default": "default", "upper_wind_none": "none"}


@dataclass
class Search:
    """One capability search: a kind (:data:`KINDS`), its altitudes [m] (band [lo, hi] or jet
    centre ± half-width), its sign (+1: + downrange, the +z of vega_model.wind) and its
    bisection."""

    kind: str
    lo_m: float
    hi_m: float
    sign: int
    bisection: Bisection
    base_failed: tuple[str, ...] | None = None   # the flight without the change failed: these

    @property
    def centre_m(self) -> float:
        """Centre of the band or jet [m]."""
        return 0.5 * (self.lo_m + self.hi_m)

    @property
    def guidance(self) -> str:
        """Which reference the search flies: ``measured`` (re-biased on the measured profile),
        ``flown`` (re-biased on each flown profile), ``default`` (shipped) or ``none``."""
        return _GUIDANCE_OF[self.kind]

    def profile(self, base, amplitude: float):
        """The flown profile at ``amplitude`` [m/s] (≥ 0; the sign is the search's)."""
        if self.kind == "wind_change":
            shape = lambda h: band_window(h, self.lo_m, self.hi_m)   # noqa: E731
            what = f"band {self.lo_m / 1e3:g}-{self.hi_m / 1e3:g} km change"
        else:
            shape = lambda h: jet_window(h, self.centre_m, 0.5 * (self.hi_m - self.lo_m))  # noqa: E731
            what = f"jet at {self.centre_m / 1e3:g} km"
        return _with_window(base, self.lo_m, self.hi_m, shape, self.sign * amplitude,
                            f"capability: measured ({base.source}) + {what} of "
                            f"{self.sign * amplitude:+g} m/s")

    def row(self) -> dict[str, Any]:
        """The search's result as a flat row (csv/json)."""
        b = self.bisection
        failing, passing = b.outcome, b.passing_outcome
        base_fails = self.base_failed is not None
        row = {"kind": self.kind, "lo_km": self.lo_m / 1e3, "hi_km": self.hi_m / 1e3,
               "centre_km": self.centre_m / 1e3, "sign": self.sign,
               "max_mps": None if base_fails else b.largest_passing,
               "cap_reached": (not base_fails) and b.smallest_failing is None,
               "fail_at_mps": b.smallest_failing,
               "binding": (self.base_failed[0] if base_fails
                           else failing.failed[0] if failing is not None else ""),
               "failed": ",".join(self.base_failed if base_fails
                                  else failing.failed if failing is not None else ()),
               "flights": b.flights}
        for name, v in (("at_max", passing), ("at_fail", failing)):
            row[f"{name}_max_abs_q_alpha_pa_deg"] = None if v is None else v.max_abs_q_alpha_pa_deg
            row[f"{name}_max_abs_z_m"] = None if v is None else v.max_abs_z_m
            row[f"{name}_envelope_passed"] = None if v is None else v.envelope_passed
        return row


@dataclass
class CapabilityResult:
    """The searches' results and how they were obtained (:func:`capability`)."""

    base: dict[str, Any]
    settings: dict[str, Any]
    base_flights: dict[str, dict[str, Any]]
    rows: list[dict[str, Any]]
    flights: int
    rounds: int
    wall_s: float
    cpu_s: float          # this process's and the workers' flights [s]

    def to_json(self) -> dict[str, Any]:
        """Everything as plain JSON types."""
        return dataclasses.asdict(self)


def _scenario(base_scenario, name: str, profile, guidance: str):
    """The capability flight: nominal plant, the profile alone (no turbulence, gust or INS
    noise), the given guidance reference."""
    wind = dataclasses.replace(base_scenario.wind, profile=profile, turbulence="none",
                               gust=None, thesis_constant_dryden=False, profile_scale=1.0,
                               profile_shift_m=0.0)
    return dataclasses.replace(
        base_scenario, name=name, wind=wind, sensor_noise=False, uncertainty=(),
        guidance=guidance, off_design="",
        description="capability flight: nominal plant, steady tabulated wind only")


def check_amplitudes(base, bands_km, jet_centres_km, cap_mps: float, upper_cap_mps: float,
                     jet_half_width_m: float = JET_HALF_WIDTH_M) -> None:
    """Raise ValueError (one line) if a searched profile could exceed the tabulated-wind bound
    (:data:`vega_model.wind.MAX_TABLE_WIND_MPS`): the largest |measured| within a band or jet
    plus its cap."""
    from vega_model.wind import MAX_TABLE_WIND_MPS

    h, w = np.asarray(base.altitude_m), np.abs(np.asarray(base.wind_mps))
    spans = [(lo * 1e3, hi * 1e3, cap_mps, "--cap-mps") for lo, hi in bands_km]
    spans += [(c * 1e3 - jet_half_width_m, c * 1e3 + jet_half_width_m, upper_cap_mps,
               "--upper-cap-mps") for c in jet_centres_km]
    for lo, hi, cap, name in spans:
        inside = np.interp([lo, hi], h, w).tolist() + w[(h >= lo) & (h <= hi)].tolist()
        if max(inside) + cap > MAX_TABLE_WIND_MPS:
            raise ValueError(f"{name} {cap:g}: the measured profile ({max(inside):.1f} m/s at "
                             f"{lo / 1e3:g}-{hi / 1e3:g} km) plus the cap exceeds the "
                             f"tabulated-wind bound {MAX_TABLE_WIND_MPS:g} m/s")


def _verdict_word(v: Verdict) -> str:
    return "pass" if v.passed else "FAIL (" + ",".join(v.failed) + ")"


def _chunks(items: list, n: int) -> list[list]:
    """``items`` in ``n`` contiguous, near-equal, non-empty parts."""
    n = max(1, min(n, len(items)))
    size, extra = divmod(len(items), n)
    out, start = [], 0
    for i in range(n):
        stop = start + size + (1 if i < extra else 0)
        out.append(items[start:stop])
        start = stop
    return out


def capability(table_path: str | Path, base=None, *, bands_km=DEFAULT_BANDS_KM,
               jet_centres_km=DEFAULT_JET_CENTRES_KM, jet_half_width_m=JET_HALF_WIDTH_M,
               cap_mps: float = CAP_MPS, upper_cap_mps: float = UPPER_CAP_MPS,
               resolution_mps: float = RESOLUTION_MPS,
               workers: int = 1, base_description: dict | None = None,
               progress: Callable[[str], None] | None = None) -> CapabilityResult:
    """Run every capability search (module docstring).

    Parameters
    ----------
    table_path
        Controller table file.
    base
        The measured profile (a ``WindTable``; default: :func:`calm_profile`).
    bands_km, jet_centres_km, jet_half_width_m
        The altitude bands [km] of the wind change, the jet centres [km] and half-width [m]
        of the upper wind (empty: that part not run).
    cap_mps, upper_cap_mps, resolution_mps
        Largest wind change and jet peak searched, and the resolution [m/s]
        (:class:`Bisection`).
    workers
        Processes flying a round (1: in this process).
    base_description
        Recorded as the result's ``base`` (what the measured profile is).
    progress
        Called with one line per round.

    Returns
    -------
    CapabilityResult
        ``rows``: one per search (:meth:`Search.row`), bands first, then the jets re-biased
        and with the shipped reference, each by altitude then sign (+, −).
    """
    from vega_reference.rebias import rebias_reference, write_rebiased_reference
    from vega_sim.scenario import DEFAULT_GUIDANCE, NO_GUIDANCE, load_scenario

    t_wall, t_cpu = time.perf_counter(), time.process_time()
    base = base if base is not None else calm_profile()
    check_amplitudes(base, bands_km, jet_centres_km, cap_mps, upper_cap_mps, jet_half_width_m)
    say = progress if progress is not None else (lambda line: None)
    table_path = str(Path(table_path).resolve())
    nominal = load_scenario("nominal")
    searches: list[Search] = []
    for lo, hi in bands_km:
        for sign in (1, -1):
            searches.append(Search("wind_change", lo * 1e3, hi * 1e3, sign,
                                   Bisection(cap_mps, resolution_mps)))
    for kind in KINDS[1:]:
        for c in jet_centres_km:
            for sign in (1, -1):
                searches.append(Search(kind, c * 1e3 - jet_half_width_m,
                                       c * 1e3 + jet_half_width_m, sign,
                                       Bisection(upper_cap_mps, resolution_mps)))
    pool = None
    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    flights = rounds = 0
    worker_cpu = 0.0
    try:
        with tempfile.TemporaryDirectory(prefix="vega-capability-") as tmp:
            def rebiased(profile, name: str) -> str:
                path = Path(tmp) / f"{name}.npz"
                design = rebias_reference(profile.altitude_m, profile.wind_mps,
                                          source=profile.source)
                write_rebiased_reference(path, design, profile.altitude_m, profile.wind_mps,
                                         source=profile.source)
                return str(path)

            measured_ref = rebiased(base, "measured")
            guidance = {"measured": measured_ref, "default": DEFAULT_GUIDANCE,
                        "none": NO_GUIDANCE}
            # round 0: the measured profile itself, with each guidance (with "flown", the
            # flown profile is the measured one)
            needed = {"measured" if s.guidance == "flown" else s.guidance for s in searches}
            base_verdicts = {}
            for key, ref in guidance.items():
                if key not in needed:
                    continue
                base_verdicts[key] = _fly_group(
                    [_scenario(nominal, f"capability-base-{key}", base, ref)], table_path)[0][0]
                flights += 1
            if "measured" in base_verdicts:
                base_verdicts["flown"] = base_verdicts["measured"]
            for s in searches:
                v = base_verdicts[s.guidance]
                if not v.passed:
                    s.base_failed = v.failed
                    s.bisection._next = None
            say("measured profile alone: " + ", ".join(
                f"{what} " + _verdict_word(base_verdicts[key])
                for key, what in (("measured", "re-biased on it"),
                                  ("default", "shipped reference"), ("none", "no bias"))
                if key in base_verdicts))
            while True:
                active = [s for s in searches if not s.bisection.done]
                if not active:
                    break
                rounds += 1
                t0 = time.perf_counter()
                groups: dict[bool, list[tuple[Search, Any]]] = {}
                for i, s in enumerate(active):
                    amp = s.bisection.candidate()
                    profile = s.profile(base, amp)
                    name = f"capability-{s.kind}-{i}"
                    if s.guidance == "flown":
                        ref = rebiased(profile, f"r{rounds}-{i}")
                    else:
                        ref = guidance[s.guidance]
                    # one batch may mix references, not references with none (fly_batch)
                    groups.setdefault(ref == NO_GUIDANCE, []).append(
                        (s, _scenario(nominal, name, profile, ref)))
                tasks = []
                for members in groups.values():
                    for part in _chunks(members, workers if len(members) > 1 else 1):
                        tasks.append(part)
                if pool is None:
                    outcomes = [_fly_group([sc for _, sc in part], table_path)
                                for part in tasks]
                else:
                    futures = [pool.submit(_fly_group, [sc for _, sc in part], table_path)
                               for part in tasks]
                    outcomes = [f.result() for f in futures]
                for part, (verdicts, task_cpu) in zip(tasks, outcomes):
                    if pool is not None:
                        worker_cpu += task_cpu
                    for (s, _), v in zip(part, verdicts):
                        s.bisection.update(v.passed, v)
                flights += len(active)
                say(f"round {rounds}: {len(active)} flights in {len(tasks)} tasks, "
                    f"{sum(s.bisection.done for s in searches)}/{len(searches)} searches done, "
                    f"{time.perf_counter() - t0:.1f} s")
    finally:
        if pool is not None:
            pool.shutdown()
    cpu = time.process_time() - t_cpu + worker_cpu
    settings = {
        "table": table_path, "bands_km": [list(b) for b in bands_km],
        "jet_centres_km": list(jet_centres_km), "jet_half_width_m": jet_half_width_m,
        "cap_mps": cap_mps, "upper_cap_mps": upper_cap_mps, "resolution_mps": resolution_mps,
        "workers": workers,
        "flight": "nominal plant (no uncertainty), steady tabulated wind only (no turbulence, "
                  "gust or INS noise), 0-100 s",
        "pass": "RequirementReport.passed_with_allowable (docs/REQUIREMENTS.md §6), stable "
                "and not rate-limited (vega_campaign.campaign.STABILITY_LIMITS)",
        "wind_change_shape": "raised-cosine bump over the band, peak at its centre",
        "jet_shape": "raised-cosine jet, peak at the centre, zero beyond the half-width",
    }
    description = dict(base_description or {"kind": "calm"})
    description["source"] = base.source
    return CapabilityResult(
        base=description, settings=settings,
        base_flights={k: dataclasses.asdict(v) for k, v in base_verdicts.items()
                      if k != "flown"},
        rows=[s.row() for s in searches], flights=flights, rounds=rounds,
        wall_s=time.perf_counter() - t_wall, cpu_s=cpu)


# -- output ----------------------------------------------------------------------------------

CSV_COLUMNS = ("kind", "lo_km", "hi_km", "centre_km", "sign", "max_mps", "cap_reached",
               "fail_at_mps", "binding", "failed", "flights", "at_max_max_abs_q_alpha_pa_deg",
               "at_max_max_abs_z_m", "at_max_envelope_passed", "at_fail_max_abs_q_alpha_pa_deg",
               "at_fail_max_abs_z_m", "at_fail_envelope_passed")


def write_capability(result: CapabilityResult, out_dir: str | Path) -> list[Path]:
    """Write ``capability.csv`` (one row per search, :data:`CSV_COLUMNS`), ``capability.json``
    (everything) and the two plots into ``out_dir``; return the paths."""
    import csv

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "capability.csv", out / "capability.json"]
    with open(paths[0], "w", newline="") as f:
        w = csv.DictWriter(f, CSV_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for row in result.rows:
            w.writerow({k: ("" if row[k] is None else row[k]) for k in CSV_COLUMNS})
    data = result.to_json()
    paths[1].write_text(json.dumps(data, indent=1) + "\n")
    title = _base_title(result)
    if any(r["kind"] == "wind_change" for r in result.rows):
        paths.append(plot_wind_change(result.rows, out / "capability_wind_change.png", title,
                                      result.settings["cap_mps"]))
    if any(r["kind"] != "wind_change" for r in result.rows):
        paths.append(plot_upper_wind(result.rows, out / "capability_upper_wind.png", title,
                                     result.settings["upper_cap_mps"]))
    return paths


def _base_title(result: CapabilityResult) -> str:
    b = result.base
    if b.get("kind") == "month_mean":
        return f"measured profile: the mean speed of month {b['month']} in the site file"
    return "measured profile: calm"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


_SHORT = {"q_alpha_allowable": "Qα", "drift": "z", "drift_rate": "ż", "deflection": "β",
          "deflection_integral": "∫β", "stability": "stab", "rate_limit": "rate"}


def plot_wind_change(rows, path, title: str = "", cap_mps: float = CAP_MPS) -> Path:
    """Δw_max per altitude band, + (up) and − (down) changes, as steps over altitude, each
    band labelled with its binding requirement; a PNG at ``path``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for sign, colour, label in ((1, "C0", "+Δw (downrange)"), (-1, "C3", "−Δw (uprange)")):
        rs = sorted((r for r in rows if r["kind"] == "wind_change" and r["sign"] == sign),
                    key=lambda r: r["lo_km"])
        for i, r in enumerate(rs):
            v = sign * (r["max_mps"] or 0.0)
            ax.fill_between([r["lo_km"], r["hi_km"]], 0, v, step="pre", color=colour,
                            alpha=0.35, lw=0, label=label if i == 0 else None)
            ax.plot([r["lo_km"], r["hi_km"]], [v, v], colour, lw=2)
            text = "≥cap" if r["cap_reached"] else _SHORT.get(r["binding"], r["binding"])
            if r["max_mps"] is None:
                text = "fails at 0: " + text
            ax.annotate(text, (0.5 * (r["lo_km"] + r["hi_km"]), v), ha="center",
                        va="bottom" if sign > 0 else "top", fontsize=7,
                        xytext=(0, 2 * sign), textcoords="offset points")
    ax.axhline(0.0, color="k", lw=0.6)
    for y in (cap_mps, -cap_mps):
        ax.axhline(y, color="0.5", ls=":", lw=0.8)
    ax.set_ylim(-1.15 * cap_mps, 1.15 * cap_mps)
    ax.set_xlabel("altitude band of the wind change [km]")
    ax.set_ylabel("largest tolerable change Δw_max [m/s]")
    ax.set_title("Wind change tolerated after re-biasing, per band\n" + title, fontsize=9)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return Path(path)


def plot_upper_wind(rows, path, title: str = "", cap_mps: float = CAP_MPS) -> Path:
    """The largest jet peak against the jet's altitude, re-biased on it and with the shipped
    reference, both signs; a PNG at ``path``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    styles = {("upper_wind_rebiased", 1): ("C0", "-", "o", "re-biased, + (downrange)"),
              ("upper_wind_rebiased", -1): ("C0", "--", "s", "re-biased, − (uprange)"),
              ("upper_wind_default", 1): ("C1", "-", "o", "shipped reference, + (downrange)"),
              ("upper_wind_default", -1): ("C1", "--", "s", "shipped reference, − (uprange)"),
              ("upper_wind_none", 1): ("C2", "-", "o", "no bias, + (downrange)"),
              ("upper_wind_none", -1): ("C2", "--", "s", "no bias, − (uprange)")}
    for (kind, sign), (colour, ls, marker, label) in styles.items():
        rs = sorted((r for r in rows if r["kind"] == kind and r["sign"] == sign),
                    key=lambda r: r["centre_km"])
        if not rs:
            continue
        x = [r["centre_km"] for r in rs]
        y = [r["max_mps"] if r["max_mps"] is not None else 0.0 for r in rs]
        ax.plot(x, y, color=colour, ls=ls, marker=marker, label=label)
        for xi, yi, r in zip(x, y, rs):
            text = "≥cap" if r["cap_reached"] else _SHORT.get(r["binding"], r["binding"])
            if r["max_mps"] is None:
                text = "0: " + text
            ax.annotate(text, (xi, yi), fontsize=7, xytext=(3, 3 if sign > 0 else -9),
                        textcoords="offset points", color=colour)
    ax.axhline(cap_mps, color="0.5", ls=":", lw=0.8)
    ax.set_ylim(0, 1.1 * cap_mps)
    ax.set_xlabel("jet centre altitude [km]")
    ax.set_ylabel("largest tolerable jet peak [m/s]")
    ax.set_title("Upper-wind capability: guidance re-biased on the day's profile, the shipped "
                 "reference, no bias\n" + title + "; labelled 0: the measured profile alone "
                 "fails", fontsize=9)
    xs = [r["centre_km"] for r in rows if r["kind"] != "wind_change"]
    ax.set_xlim(min(xs) - 0.5, max(xs) + 1.0)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return Path(path)
