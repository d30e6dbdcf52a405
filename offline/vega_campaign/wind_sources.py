"""Published wind statistics turned into the rows of a wind site file (docs/WINDS.md §2).

Two public forms of upper-air statistics can feed a site file
(:mod:`vega_campaign.wind_environment`):

* **Range Reference Atmosphere (RRA) Table I** ("wind statistical parameters"), the monthly
  tables of the U.S. ranges distributed with NASA's Earth-GRAM: per month and altitude (0.5 km
  steps) the mean and standard deviation of the eastward (u) and northward (v) components, their
  correlation r(u, v), and the mean, standard deviation and skewness of the speed.
  :func:`read_rra_wind_table` reads one such text file into site-file rows as they are: the
  component moments are the per-level Gaussian vector wind of the sampler, the speed moments
  are kept beside them as the source's own check of that model.
* **CLIMAT TEMP monthly means** (WMO FM-75; the Met Office GUAN files): per standard pressure
  level the mean speed S̄, the direction of the mean vector and the steadiness
  q = |mean vector| / S̄. :func:`isotropic_level_from_steadiness` gives the isotropic Gaussian
  vector wind (mean vector and per-component spread) with the same mean speed and steadiness.
"""

from __future__ import annotations

import math

from vega_core.errors import BadFile

__all__ = ["MONTH_NAMES", "RRA_COLUMNS", "read_rra_wind_table",
           "isotropic_level_from_steadiness"]

MONTH_NAMES = ("January", "February", "March", "April", "May", "June", "July", "August",
               "September", "October", "November", "December")

RRA_COLUMNS = ("altitude_m", "u_mean_mps", "u_sd_mps", "r_uv", "v_mean_mps", "v_sd_mps",
               "speed_mean_mps", "speed_sd_mps")
"""The columns of a site-file row, in RRA Table I order (altitude converted km → m; the
skewness and the observation count of the table are left out)."""


def read_rra_wind_table(text: str, source: str = "<RRA table>") -> dict[int, list[list[float]]]:
    """The monthly rows of an RRA Table I text file (Earth-GRAM ``T1<site><yy>.txt``).

    Parameters
    ----------
    text
        The file's text: per month a header naming the month, then one line per altitude
        ``Z[km] MEAN_U SD_U R(U,V) MEAN_V SD_V MEAN_WS SD_WS SKEW_WS NOBS``.
    source
        Where the text comes from, for messages.

    Returns
    -------
    dict
        Month 1–12 → rows ``[altitude_m, u_mean, u_sd, r_uv, v_mean, v_sd, speed_mean,
        speed_sd]`` (:data:`RRA_COLUMNS`), altitude increasing. The table's 0-km row, a
        placeholder with no observations behind it (all moments 0), is left out; so is any row
        without observations (NOBS 0).

    Raises
    ------
    BadFile
        If a month is missing or a data line does not have ten numbers.
    """
    months: dict[int, list[list[float]]] = {}
    month = None
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if len(words) == 1 and words[0].isalpha():       # a table's title: a month, "Annual"
            month = MONTH_NAMES.index(words[0]) + 1 if words[0] in MONTH_NAMES else None
            if month is not None:
                months[month] = []
            continue
        if month is None or not words or not _is_number(words[0]):
            continue
        if len(words) != 10 or not all(_is_number(w) for w in words):
            raise BadFile(f"{source}: line {number}: expected 10 numbers, got {line.strip()!r}")
        z_km, u, su, r, v, sv, s, ss, _skew, nobs = (float(w) for w in words)
        if z_km <= 0.0 or nobs <= 0:
            continue
        months[month].append([round(1000.0 * z_km, 3), u, su, r, v, sv, s, ss])
    missing = [m for m in range(1, 13) if not months.get(m)]
    if missing:
        raise BadFile(f"{source}: no rows for month(s) {missing}")
    return months


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def isotropic_level_from_steadiness(mean_speed_mps: float, steadiness: float,
                                    direction_deg: float) -> tuple[float, float, float]:
    """The isotropic Gaussian vector wind with a given mean speed and steadiness.

    Parameters
    ----------
    mean_speed_mps
        Monthly mean of the scalar speed S̄ [m/s] (> 0).
    steadiness
        q = |mean vector| / S̄ [1], in [0, 1) (CLIMAT TEMP reports it in percent).
    direction_deg
        Direction the mean wind blows *from* [deg clockwise from north] (meteorological).

    Returns
    -------
    u_mean_mps, v_mean_mps, sigma_mps
        Eastward and northward components of the mean vector and the standard deviation of
        each component [m/s].

    Notes
    -----
    With V = (u, v) ~ N(m, σ² I), the speed |V| is Rice-distributed with
    E|V| = σ √(π/2) L½(−ν²/(2σ²)), ν = |m|, where
    L½(x) = e^{x/2} [(1 − x) I₀(−x/2) − x I₁(−x/2)] (Laguerre polynomial of order ½; I₀, I₁
    modified Bessel functions). The steadiness is q = ν / E|V|, so ν/σ = k solves
    k = q √(π/2) L½(−k²/2); the left side grows faster than the right, so the root is unique
    for 0 ≤ q < 1 and found by bisection. Then σ = S̄ / (√(π/2) L½(−k²/2)) and ν = q S̄.
    For q = 0 (no mean vector) the speed is Rayleigh, σ = S̄ √(2/π).
    """
    if not (mean_speed_mps > 0.0 and 0.0 <= steadiness < 1.0):
        raise ValueError(f"need mean speed > 0 and 0 <= steadiness < 1, got "
                         f"{mean_speed_mps!r}, {steadiness!r}")

    def mean_over_sigma(k: float) -> float:   # E|V| / σ for ν/σ = k
        from scipy.special import i0e, i1e

        x = -0.5 * k * k
        # e^{x/2} I_n(−x/2) = I_n(k²/4) e^{−k²/4} = i_ne(k²/4) (exponentially scaled Bessel)
        half = 0.25 * k * k
        return math.sqrt(0.5 * math.pi) * ((1.0 - x) * i0e(half) - x * i1e(half))

    lo, hi = 0.0, 1.0
    while hi < 1e6 and hi < steadiness * mean_over_sigma(hi):
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid < steadiness * mean_over_sigma(mid):
            lo = mid
        else:
            hi = mid
    k = 0.5 * (lo + hi)
    sigma = mean_speed_mps / mean_over_sigma(k)
    nu = steadiness * mean_speed_mps
    toward = math.radians(direction_deg + 180.0)       # the air moves toward this bearing
    return nu * math.sin(toward), nu * math.cos(toward), sigma
