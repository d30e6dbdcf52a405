"""Statistical wind environment of a launch site: the site file and the profile sampler.

A campaign sample flies two wind profiles (docs/WINDS.md):

* the **measured** one — the sounding the day-of-launch guidance is solved on: the true wind at
  the sounding time as a balloon reports it, averaged over a running window;
* the **flown** one — what the vehicle meets: the true wind at the sounding time plus its
  change over the lag to lift-off. ``flown − measured`` is the change plus the structure the
  sounding smoothed away (small-scale shear, embedded gusts); Dryden turbulence is added in
  flight by :mod:`vega_model.wind`, not here.

The true wind at the sounding time is a monthly Gaussian vector wind per level of the site
table, correlated across levels (exp(−|Δh|/L); Adelfang, *User's Guide for Monthly Vector Wind
Profile Model*, NASA/CR-1999-209759, for the per-month vector model), interpolated linearly to
:data:`FINE_STEP_M`, plus a small-scale part whose rms shear grows as Δh^0.7 (Fichtl 1972).
The change is a zero-mean Gaussian vector field whose rms grows as lag^(1/3) (Merceret 1997)
and saturates at the climatological spread. Every parameter comes from the site file
(``data/sites/kourou.yaml``, each number with its source).

The pitch-plane model flies one component (:data:`MODES`): ``in_plane`` projects the vector on
the flight azimuth; ``full_speed`` (the default) puts the whole speed in the plane, each part of
the wind projected on the direction of the measured wind at its altitude. Sign: v_w > 0 is air
moving toward +z (:mod:`vega_model.wind`), here the downrange direction (a tail wind).

Reproducibility: sample *i* is a function of (seed, month, i) only — NumPy
``SeedSequence(seed, spawn_key=(month, i, part))``, one stream per part (the climatological
profile, the small-scale part, the change), standard normals drawn in a fixed number — so it is
the same among 5 samples or 50, at any lag and in either mode (the lag scales the change, the
mode projects; neither moves a draw).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Mapping

import numpy as np

from vega_core.documents import field_error as _fail
from vega_core.documents import finite_number as _number
from vega_core.documents import mapping_keys as _keys
from vega_core.documents import parse_yaml, read_text
from vega_loops.blas import one_blas_thread
from vega_model.wind import WindTable

__all__ = ["FINE_STEP_M", "MODES", "DEFAULT_MODE", "DEFAULT_LAG_S", "COLUMNS", "Site",
           "WindSamples", "default_site_path", "load_site", "parse_site", "climate_levels",
           "level_moments", "in_plane_moments", "change_rms_mps", "small_scale_sigma_mps",
           "sample_profiles", "sample_table", "write_samples", "plot_samples"]

FINE_STEP_M = 100.0
"""Spacing of the sampled profiles [m]. Assumption: the vehicle climbs 100 m in 0.2–1 s over
the first stage, finer than the rigid-body loop's response; scales below it are Dryden
turbulence, flown by vega_model.wind."""

MODES = ("full_speed", "in_plane")
DEFAULT_MODE = "full_speed"
"""The conservative mode (docs/WINDS.md §3): the vehicle is axisymmetric, its structural load
follows the total angle of attack, and Kourou's winds are mostly zonal — across a northward
flight plane — so the in-plane component alone would leave most of the load out."""

DEFAULT_LAG_S = 5400.0
"""Lag from the last sounding to lift-off [s]. Assumption: 1.5 h, one of the pair intervals
of Decker & Barbré (NTRS 20140016701: 0.75, 1.5, 2, 3, 4 h)."""

COLUMNS = ("sample", "altitude_m", "measured_wind_mps", "flown_wind_mps")
"""Columns of ``vega wind sample``'s table, one row per sample and altitude."""

SCHEMA_VERSION = 1
_LEVEL_COLUMNS = ("altitude_m", "u_mean_mps", "u_sd_mps", "r_uv", "v_mean_mps", "v_sd_mps",
                  "speed_mean_mps", "speed_sd_mps")
_SAMPLE_CHUNK = 1000          # samples generated at a time (bounds the temporary arrays)


@dataclass(frozen=True, eq=False)
class Site:
    """A validated site file (module docstring; docs/WINDS.md §6 for the format)."""

    path: str
    text: str
    name: str
    flight_azimuth_deg: float
    altitude_m: np.ndarray                      # (K,) levels of the table, increasing
    months: Mapping[int, np.ndarray]            # month → (K, 8) rows, _LEVEL_COLUMNS
    vertical_correlation_m: float
    shear_exponent: float
    shear_anchor_m: float
    shear_resolved_m: float
    smoothing_window_m: float
    change_reference_lag_s: float
    change_rms_altitude_m: np.ndarray
    change_rms_mps: np.ndarray
    change_lag_exponent: float
    change_vertical_correlation_m: float
    fine_altitude_m: np.ndarray = field(repr=False)   # (k,) the sampled grid
    _factors: dict = field(repr=False)                 # Cholesky factors and interpolation


def default_site_path() -> Path:
    """The shipped site file (Kourou)."""
    return Path(__file__).resolve().parent / "data" / "sites" / "kourou.yaml"


def load_site(path: str | Path | None = None) -> Site:
    """Load and validate a site file (default: the shipped one)."""
    p = Path(path) if path is not None else default_site_path()
    return parse_site(read_text(p, "wind site file"), str(p))


def _source(path, key, block) -> None:
    text = block.get("source")
    if not isinstance(text, str) or not text.strip():
        raise _fail(path, f"{key}.source", "missing: every number needs its source "
                                          "(a citation, or 'assumption: why')")


def _valued(path, key, tree, lo, hi) -> float:
    block = _keys(path, key, tree, ("value", "source"))
    _source(path, key, block)
    return _number(path, f"{key}.value", block["value"], lo, hi)


def _positive(path, key, value, hi=math.inf) -> float:
    x = _number(path, key, value, 0.0, hi)
    if x <= 0.0:
        raise _fail(path, key, f"must be > 0, got {value!r}")
    return x


def _rows(path, key, rows, width) -> np.ndarray:
    if not isinstance(rows, list) or len(rows) < 2:
        raise _fail(path, key, "must be a list of at least 2 rows")
    for i, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != width:
            raise _fail(path, f"{key}[{i}]", f"must be a list of {width} numbers, got {row!r:.80}")
        for j, x in enumerate(row):
            _number(path, f"{key}[{i}][{j}]", x)
    table = np.array(rows, dtype=float)
    dz = np.diff(table[:, 0])
    if not np.all(dz > 0.0):
        i = int(np.argmax(dz <= 0.0)) + 1
        raise _fail(path, f"{key}[{i}][0]", f"altitudes must increase strictly, got "
                                            f"{table[i - 1, 0]:g} then {table[i, 0]:g}")
    return table


def parse_site(text: str, path: str = "<site>") -> Site:
    """Parse and validate a site file's text (the last few parsed are kept: the shipped file
    takes ≈ 0.5 s in PyYAML's pure-Python loader, too long for libyaml's size limit of
    vega_core.documents).

    Raises
    ------
    vega_core.errors.BadFile
        One line naming the file and the field on any problem: a missing key or month, a
        number of the wrong type or out of its domain (a negative spread, |r(u, v)| > 1, a
        correlation scale ≤ 0), altitudes not strictly increasing or not the same in every
        month, a table not reaching from ≤ 1 km to ≥ 30 km, a block without its source.
    """
    return _parse_site(text, path)


@lru_cache(maxsize=4)
def _parse_site(text: str, path: str) -> Site:
    tree = parse_yaml(text, path)
    _keys(path, "", tree, ("schema_version", "site", "flight_azimuth_deg", "levels",
                           "vertical_correlation_m", "small_scale_shear", "sounding",
                           "wind_change", "months"))
    if tree["schema_version"] != SCHEMA_VERSION:
        raise _fail(path, "schema_version", f"must be {SCHEMA_VERSION}, got "
                                            f"{tree['schema_version']!r}")
    site = _keys(path, "site", tree["site"], ("name", "source"), ("latitude_deg",))
    _source(path, "site", site)
    if not isinstance(site["name"], str):
        raise _fail(path, "site.name", "must be a string")
    if "latitude_deg" in site:
        _number(path, "site.latitude_deg", site["latitude_deg"], -90.0, 90.0)
    azimuth = _valued(path, "flight_azimuth_deg", tree["flight_azimuth_deg"], 0.0, 360.0)
    levels = _keys(path, "levels", tree["levels"], ("columns", "source"),
                   ("substitution", "speed_columns"))
    _source(path, "levels", levels)
    if levels["columns"] != list(_LEVEL_COLUMNS):
        raise _fail(path, "levels.columns", f"must be {list(_LEVEL_COLUMNS)}")
    corr = _valued(path, "vertical_correlation_m", tree["vertical_correlation_m"], 0.0, 1e6)
    if corr <= 0.0:
        raise _fail(path, "vertical_correlation_m.value", f"must be > 0, got {corr!r}")
    shear = _keys(path, "small_scale_shear", tree["small_scale_shear"],
                  ("exponent", "anchor_separation_m", "resolved_separation_m", "source"))
    _source(path, "small_scale_shear", shear)
    exponent = _positive(path, "small_scale_shear.exponent", shear["exponent"], 1.0)
    anchor = _positive(path, "small_scale_shear.anchor_separation_m",
                       shear["anchor_separation_m"], 1e5)
    resolved = _positive(path, "small_scale_shear.resolved_separation_m",
                         shear["resolved_separation_m"], anchor)
    sounding = _keys(path, "sounding", tree["sounding"], ("smoothing_window_m", "source"))
    _source(path, "sounding", sounding)
    window = _number(path, "sounding.smoothing_window_m", sounding["smoothing_window_m"],
                     0.0, 5000.0)
    change = _keys(path, "wind_change", tree["wind_change"],
                   ("reference_lag_s", "rms_at_reference_lag_mps", "lag_exponent",
                    "vertical_correlation_m", "source"))
    _source(path, "wind_change", change)
    ref_lag = _positive(path, "wind_change.reference_lag_s", change["reference_lag_s"], 86400.0)
    rms = _rows(path, "wind_change.rms_at_reference_lag_mps",
                change["rms_at_reference_lag_mps"], 2)
    if np.any(rms[:, 1] < 0.0):
        i = int(np.argmax(rms[:, 1] < 0.0))
        raise _fail(path, f"wind_change.rms_at_reference_lag_mps[{i}][1]",
                    f"must be >= 0, got {rms[i, 1]:g}")
    lag_exponent = _positive(path, "wind_change.lag_exponent", change["lag_exponent"], 1.0)
    change_corr = _positive(path, "wind_change.vertical_correlation_m",
                            change["vertical_correlation_m"], 1e6)
    months = tree["months"]
    if not isinstance(months, Mapping):
        raise _fail(path, "months", "must be a mapping of month 1-12 to rows")
    for m in months:
        if isinstance(m, bool) or not isinstance(m, int) or not 1 <= m <= 12:
            raise _fail(path, f"months.{m}", "unknown key (months are 1-12)")
    tables: dict[int, np.ndarray] = {}
    for m in range(1, 13):
        if m not in months:
            raise _fail(path, f"months.{m}", "missing")
        table = _rows(path, f"months.{m}", months[m], len(_LEVEL_COLUMNS))
        for col in (2, 5, 6, 7):                     # spreads and the mean speed
            bad = table[:, col] < 0.0
            if bad.any():
                i = int(np.argmax(bad))
                raise _fail(path, f"months.{m}[{i}][{col}]",
                            f"{_LEVEL_COLUMNS[col]} must be >= 0, got {table[i, col]:g}")
        bad = np.abs(table[:, 3]) > 1.0
        if bad.any():
            i = int(np.argmax(bad))
            raise _fail(path, f"months.{m}[{i}][3]", f"r_uv must lie within [-1, 1], got "
                                                     f"{table[i, 3]:g}")
        if m > 1 and not np.array_equal(table[:, 0], tables[1][:, 0]):
            raise _fail(path, f"months.{m}", "altitudes must be those of month 1")
        tables[m] = table
    z = tables[1][:, 0]
    if z[0] > 1000.0 or z[-1] < 30000.0:
        raise _fail(path, "months.1", f"levels must reach from <= 1000 m to >= 30000 m, got "
                                      f"{z[0]:g}-{z[-1]:g} m")
    if rms[0, 0] > z[0] or rms[-1, 0] < z[-1]:
        raise _fail(path, "wind_change.rms_at_reference_lag_mps",
                    f"must cover the levels' altitudes {z[0]:g}-{z[-1]:g} m")
    fine = np.arange(0.0, math.floor(z[-1] / FINE_STEP_M) * FINE_STEP_M + 0.5 * FINE_STEP_M,
                     FINE_STEP_M)
    factors = _factors(z, fine, corr, exponent, resolved, change_corr)
    return Site(path=path, text=text, name=site["name"], flight_azimuth_deg=azimuth,
                altitude_m=z, months=tables, vertical_correlation_m=corr,
                shear_exponent=exponent, shear_anchor_m=anchor, shear_resolved_m=resolved,
                smoothing_window_m=window, change_reference_lag_s=ref_lag,
                change_rms_altitude_m=rms[:, 0], change_rms_mps=rms[:, 1],
                change_lag_exponent=lag_exponent, change_vertical_correlation_m=change_corr,
                fine_altitude_m=fine, _factors=factors)


def _cholesky(corr: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of a correlation matrix (a 1e-10 diagonal added: the powered
    exponential is positive definite but ill-conditioned on a fine grid)."""
    return np.linalg.cholesky(corr + 1e-10 * np.eye(corr.shape[0]))


@one_blas_thread
def _factors(z, fine, corr_m, exponent, resolved_m, change_corr_m) -> dict:
    dz = np.abs(z[:, None] - z[None, :])
    df = np.abs(fine[:, None] - fine[None, :])
    interp = np.array([np.interp(fine, z, e) for e in np.eye(z.size)]).T   # (k, K)
    return {
        # Climatological profile: exp(−|Δh|/L) between the table's levels (Kochanski 1961)
        "climate": _cholesky(np.exp(-dz / corr_m)),
        # Small-scale part: powered exponential exp(−(|Δh|/L_r)^(2·0.7)), whose structure
        # function grows as Δh^1.4, i.e. rms shear ∝ Δh^0.7 below L_r (Fichtl 1972)
        "small": _cholesky(np.exp(-(df / resolved_m) ** (2.0 * exponent))),
        "change": _cholesky(np.exp(-df / change_corr_m)),
        "interp": interp,
    }


def _month(site: Site, month: int) -> np.ndarray:
    if isinstance(month, bool) or not isinstance(month, (int, np.integer)) or not 1 <= month <= 12:
        raise ValueError(f"month must be an integer 1-12, got {month!r}")
    return site.months[int(month)]


def level_moments(site: Site, month: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean vector (K, 2) [m/s] and covariance (K, 2, 2) [m²/s²] of the wind (u east, v north)
    at each level of the site table in ``month`` (the table's numbers)."""
    t = _month(site, month)
    mean = t[:, [1, 4]]
    su, r, sv = t[:, 2], t[:, 3], t[:, 5]
    cov = np.empty((t.shape[0], 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = su * su, sv * sv
    cov[:, 0, 1] = cov[:, 1, 0] = r * su * sv
    return mean, cov


def _unit(azimuth_deg: float) -> np.ndarray:
    a = math.radians(azimuth_deg)
    return np.array([math.sin(a), math.cos(a)])           # (east, north)


def in_plane_moments(site: Site, month: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation [m/s] of the in-plane component (projection on the flight
    azimuth; + downrange) at each level of the table, from the table's numbers."""
    mean, cov = level_moments(site, month)
    e = _unit(site.flight_azimuth_deg)
    return mean @ e, np.sqrt(np.einsum("i,kij,j->k", e, cov, e))


def _component_sigma(site: Site, month: int) -> np.ndarray:
    """Per-component climatological spread σ_c = √((σ_u² + σ_v²)/2) [m/s] on the fine grid."""
    t = _month(site, month)
    return np.interp(site.fine_altitude_m, site.altitude_m,
                     np.sqrt(0.5 * (t[:, 2] ** 2 + t[:, 5] ** 2)))


def small_scale_sigma_mps(site: Site, month: int) -> np.ndarray:
    """Per-component rms of the small-scale part on the fine grid [m/s] (docs/WINDS.md §4).

    σ_s = σ_c √(1 − e^(−A/L)) (L_r/A)^p: the small-scale part's rms shear over a layer Δh ≪
    L_r is σ_s √2 (Δh/L_r)^p, and this σ_s makes it the climatological profile's rms shear
    over the anchor A = 1 km, σ_c √(2(1 − e^(−A/L))), carried down as (Δh/A)^p (Fichtl 1972:
    rawinsonde shear is adequate over ≥ 1 km, and shear grows as Δh^0.7 below).
    """
    s = site
    return (_component_sigma(s, month)
            * math.sqrt(1.0 - math.exp(-s.shear_anchor_m / s.vertical_correlation_m))
            * (s.shear_resolved_m / s.shear_anchor_m) ** s.shear_exponent)


def change_rms_mps(site: Site, month: int, lag_s: float) -> np.ndarray:
    """Per-component rms of the wind change over ``lag_s`` [s] on the fine grid [m/s].

    σ_Δ² = 2σ_c² (1 − exp(−a² (τ/τ₀)^(2q) / (2σ_c²))): a (τ/τ₀)^q for short lags (a the
    file's rms at the reference lag τ₀, q = 1/3 after Merceret 1997), and at most √2 σ_c, the
    spread of the difference of two independent climatological profiles.
    """
    lag = float(lag_s)
    if not (math.isfinite(lag) and lag >= 0.0):
        raise ValueError(f"lag_s must be finite and >= 0, got {lag_s!r}")
    s = site
    a = np.interp(s.fine_altitude_m, s.change_rms_altitude_m, s.change_rms_mps)
    short = a * a * (lag / s.change_reference_lag_s) ** (2.0 * s.change_lag_exponent)
    two_var = 2.0 * _component_sigma(s, month) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        var = np.where(two_var > 0.0, two_var * -np.expm1(-short / two_var), 0.0)
    return np.sqrt(var)


def _normals(seed: int, month: int, indices, part: int, size: int) -> np.ndarray:
    """Standard normals (n, size) of one part of samples ``indices``: each row a function of
    (seed, month, index, part) only."""
    out = np.empty((len(indices), size))
    for row, i in enumerate(indices):
        ss = np.random.SeedSequence(int(seed), spawn_key=(int(month), int(i), part))
        out[row] = np.random.default_rng(ss).standard_normal(size)
    return out


def _indices(n, indices) -> np.ndarray:
    if indices is None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"n must be an integer >= 1, got {n!r}")
        return np.arange(int(n))
    idx = np.asarray(indices, dtype=np.int64).ravel()
    if idx.size == 0 or np.any(idx < 0):
        raise ValueError("indices must be a non-empty list of integers >= 0")
    return idx


@one_blas_thread
def climate_levels(site: Site, month: int, seed: int, n: int | None = None,
                   indices=None) -> np.ndarray:
    """The climatological vector wind at the table's levels, (n, K, 2) [m/s] (u east, v north).

    Per level a bivariate normal with the table's means, spreads and r(u, v); across levels
    the two driving standard fields are correlated as exp(−|Δh|/L), so u is correlated exactly
    so and v as exp(−|Δh|/L)·(r_i r_j + √(1 − r_i²) √(1 − r_j²)).
    """
    idx = _indices(n, indices)
    mean, cov = level_moments(site, month)
    k = site.altitude_m.size
    z = _normals(seed, month, idx, 0, 2 * k).reshape(idx.size, 2, k)
    y = z @ site._factors["climate"].T                    # (n, 2, K) correlated fields
    su = np.sqrt(cov[:, 0, 0])
    sv = np.sqrt(cov[:, 1, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(su * sv > 0.0, cov[:, 0, 1] / (su * sv), 0.0)
    u = mean[:, 0] + su * y[:, 0]
    v = mean[:, 1] + sv * (r * y[:, 0] + np.sqrt(1.0 - r * r) * y[:, 1])
    return np.stack([u, v], axis=-1)


def _smooth(x: np.ndarray, window_m: float) -> np.ndarray:
    """Centred running mean over ``window_m`` [m] along the last-but-one axis (altitude) of
    (n, k, 2); the window shrinks at the ends of the profile."""
    half = int(round(0.5 * window_m / FINE_STEP_M))
    if half == 0:
        return x.copy()
    k = x.shape[1]
    c = np.concatenate([np.zeros_like(x[:, :1]), np.cumsum(x, axis=1)], axis=1)
    hi = np.minimum(np.arange(k) + half + 1, k)
    lo = np.maximum(np.arange(k) - half, 0)
    return (c[:, hi] - c[:, lo]) / (hi - lo)[None, :, None]


@dataclass(frozen=True, eq=False)
class WindSamples:
    """Sampled profiles, each (n, k) [m/s] in the pitch plane (+: air moving downrange, the
    +z of vega_model.wind), on ``altitude_m`` (k,) [m].

    ``flown_wind_mps = climate_mps + small_scale_mps + change_mps``;
    ``measured_wind_mps`` = the running mean of ``climate_mps + small_scale_mps``.
    """

    month: int
    seed: int
    lag_s: float
    mode: str
    indices: np.ndarray
    altitude_m: np.ndarray
    measured_wind_mps: np.ndarray
    flown_wind_mps: np.ndarray
    climate_mps: np.ndarray
    small_scale_mps: np.ndarray
    change_mps: np.ndarray


@one_blas_thread
def sample_profiles(site: Site, month: int, n: int | None = None, seed: int = 0,
                    lag_s: float = DEFAULT_LAG_S, mode: str = DEFAULT_MODE,
                    indices=None) -> WindSamples:
    """Draw measured and flown wind profiles of a site and month.

    Parameters
    ----------
    site
        The site (:func:`load_site`).
    month
        1–12.
    n, indices
        Samples 0 … n−1, or the given sample indices (one of the two).
    seed
        Seed (≥ 0); sample i depends on (seed, month, i) only.
    lag_s
        Time from the sounding to lift-off [s] (≥ 0).
    mode
        ``"full_speed"`` or ``"in_plane"`` (module docstring).

    Returns
    -------
    WindSamples
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    idx = _indices(n, indices)
    rms = change_rms_mps(site, month, lag_s)
    small_sigma = small_scale_sigma_mps(site, month)
    f = site._factors
    kf = site.fine_altitude_m.size
    parts = {key: np.empty((idx.size, kf)) for key in ("measured", "flown", "climate",
                                                         "small", "change")}
    for start in range(0, idx.size, _SAMPLE_CHUNK):
        chunk = idx[start:start + _SAMPLE_CHUNK]
        m = chunk.size
        levels = climate_levels(site, month, seed, indices=chunk)          # (m, K, 2)
        climate = np.einsum("fk,nkc->nfc", f["interp"], levels)           # (m, k, 2)
        z = _normals(seed, month, chunk, 1, 2 * kf).reshape(m, 2, kf)
        small = np.swapaxes(z @ f["small"].T, 1, 2) * small_sigma[None, :, None]
        z = _normals(seed, month, chunk, 2, 2 * kf).reshape(m, 2, kf)
        change = np.swapaxes(z @ f["change"].T, 1, 2) * rms[None, :, None]
        measured = _smooth(climate + small, site.smoothing_window_m)
        if mode == "in_plane":
            e = np.broadcast_to(_unit(site.flight_azimuth_deg), measured.shape)
        else:
            speed = np.linalg.norm(measured, axis=-1, keepdims=True)
            e = np.where(speed > 1e-9, measured / np.where(speed > 1e-9, speed, 1.0),
                         _unit(site.flight_azimuth_deg))
        sl = slice(start, start + m)
        parts["climate"][sl] = np.sum(climate * e, axis=-1)
        parts["small"][sl] = np.sum(small * e, axis=-1)
        parts["change"][sl] = np.sum(change * e, axis=-1)
        parts["measured"][sl] = np.sum(measured * e, axis=-1)
        parts["flown"][sl] = np.sum((climate + small + change) * e, axis=-1)
    return WindSamples(month=int(month), seed=int(seed), lag_s=float(lag_s), mode=mode,
                       indices=idx, altitude_m=site.fine_altitude_m.copy(),
                       measured_wind_mps=parts["measured"], flown_wind_mps=parts["flown"],
                       climate_mps=parts["climate"], small_scale_mps=parts["small"],
                       change_mps=parts["change"])


def sample_table(samples: WindSamples, sample: int, profile: str = "flown") -> WindTable:
    """One sample's profile as a table a scenario flies (``wind.profile``, vega_sim.scenario)
    or the guidance is re-biased to (vega_reference.rebias).

    Parameters
    ----------
    samples
        Drawn profiles (:func:`sample_profiles`).
    sample
        The sample index i (one of ``samples.indices``).
    profile
        ``"flown"`` (what the vehicle meets) or ``"measured"`` (the sounding).

    Returns
    -------
    vega_model.wind.WindTable
        On ``samples.altitude_m``, in the plant's sign (+: air toward +z); its ``source``
        names the month, seed, sample, lag, mode and profile.
    """
    columns = {"flown": samples.flown_wind_mps, "measured": samples.measured_wind_mps}
    if profile not in columns:
        raise ValueError(f"profile must be 'flown' or 'measured', got {profile!r}")
    rows = np.flatnonzero(samples.indices == int(sample))
    if rows.size != 1:
        raise ValueError(f"sample {sample} is not among the drawn samples")
    return WindTable(samples.altitude_m, columns[profile][rows[0]],
                     f"vega_campaign.wind_environment month {samples.month} seed "
                     f"{samples.seed} sample {int(sample)} lag {samples.lag_s:g} s "
                     f"{samples.mode} {profile}")


def write_samples(samples: WindSamples, out: str | Path) -> Path:
    """Write the table of :data:`COLUMNS` (one row per sample and altitude, sorted by sample
    then altitude) as Parquet (``.parquet``) or CSV (``.csv``)."""
    import pyarrow as pa

    out = Path(out)
    n, k = samples.measured_wind_mps.shape
    table = pa.table({
        "sample": np.repeat(samples.indices, k),
        "altitude_m": np.tile(samples.altitude_m, n),
        "measured_wind_mps": samples.measured_wind_mps.ravel(),
        "flown_wind_mps": samples.flown_wind_mps.ravel(),
    })
    if out.suffix == ".parquet":
        import pyarrow.parquet as pq

        pq.write_table(table, out)
    elif out.suffix == ".csv":
        import pyarrow.csv as pcsv

        pcsv.write_csv(table, out)
    else:
        raise ValueError(f"output must end in .parquet or .csv, got {out}")
    return out


def plot_samples(samples: WindSamples, path: str | Path, site_name: str = "") -> Path:
    """Percentile bands (1–99 %, 5–95 %, median) of the measured and flown profiles against
    altitude, and the rms of flown − measured; a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h_km = samples.altitude_m / 1000.0
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 6), sharey=True,
                                  gridspec_kw={"width_ratios": [2, 1]})
    for data, colour, label in ((samples.flown_wind_mps, "tab:red", "flown"),
                                (samples.measured_wind_mps, "tab:blue", "measured")):
        p = np.percentile(data, [1, 5, 50, 95, 99], axis=0)
        ax.fill_betweenx(h_km, p[0], p[4], color=colour, alpha=0.12)
        ax.fill_betweenx(h_km, p[1], p[3], color=colour, alpha=0.25,
                         label=f"{label}: 5–95 % (light 1–99 %)")
        ax.plot(p[2], h_km, color=colour, label=f"{label}: median")
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlabel("wind in the pitch plane [m/s] (+: toward downrange, +z)")
    ax.set_ylabel("altitude [km]")
    ax.legend(loc="lower right", fontsize=8)
    diff = samples.flown_wind_mps - samples.measured_wind_mps
    ax2.plot(np.sqrt(np.mean(diff ** 2, axis=0)), h_km, color="k", label="flown − measured")
    ax2.plot(np.sqrt(np.mean(samples.change_mps ** 2, axis=0)), h_km, color="tab:green",
             label="change over the lag")
    ax2.set_xlabel("rms [m/s]")
    ax2.legend(loc="lower right", fontsize=8)
    fig.suptitle(f"{site_name} month {samples.month}: {samples.indices.size} samples, seed "
                 f"{samples.seed}, lag {samples.lag_s:g} s, mode {samples.mode}", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
