"""Wind: steady altitude profile, Dryden turbulence and a discrete 1-cosine gust.

Thesis §2.12.5: the profile V_w(h) (Eq. 2.54, A = 14 m/s up to 17.5 km, zero above 20 km)
— or, in its place, a tabulated profile (:class:`WindTable`: a sampled or measured sounding,
docs/WINDS.md) — and the Dryden filter (Eq. 2.53) with σ_w(h), L_w(h) from Table 2.4
(light, moderate, severe). Deviation, recorded in docs/ENVIRONMENT_MODELS.md: Eq. 2.53 converts the
spatial turbulence spectrum to time with the profile speed V_w(h); the standard Dryden
form uses the vehicle's airspeed V (the speed at which the vehicle flies through the
frozen turbulence field), and Eq. 2.53's gain is unbounded as V_w → 0 (17.5–20 km). Here
the wind is the steady profile *plus* Dryden turbulence converted with the airspeed:

    v_w(t) = V_w(h) + v_turb(t; σ_w(h), L_w(h), V) + v_gust(t)

All three parts act along +z (air moving toward +z, the sign convention of the plant;
the profile's direction in the pitch plane is an assumption — the thesis gives a
magnitude only). The altitude h is the vehicle's geometric altitude from the trajectory
(``ModelParameters.h_m``, from the atmosphere model), not an inversion of a density fit.
All numbers come from the ``wind`` section of vehicle.yaml.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from vega_core.errors import BadInput
from vega_model.vehicle_data import VehicleData

__all__ = [
    "INTENSITIES",
    "wind_profile_mps",
    "turbulence_params",
    "dryden_ss",
    "DrydenTurbulence",
    "GustProfile",
    "ProfileChange",
    "WindTable",
    "WindTableError",
    "MAX_TABLE_WIND_MPS",
    "MAX_TABLE_ROWS",
    "WindComponents",
    "WindModel",
]

# Turbulence intensities of thesis Table 2.4 (plus "none": σ_w = 0 everywhere).
INTENSITIES = ("light", "moderate", "severe", "none")

# Size of the block of standard normal draws taken from the generator at a time (a
# performance detail only: the sequence is the same as drawing one number per step).
_NOISE_BLOCK = 1024


def _profile_constants(data: VehicleData) -> tuple[float, float, float, float]:
    return (data["wind.profile.amplitude_mps"], data["wind.profile.h_lower_m"],
            data["wind.profile.h_upper_m"], data["wind.profile.h_final_m"])


def _profile_scalar(h: float, amp: float, h_l: float, h_u: float, h_f: float) -> float:
    """Eq. 2.54 at one altitude (NaN in, NaN out; h < 0 counts as h = 0)."""
    if h != h:
        return math.nan
    if h <= 0.0:
        return 0.0
    if h < h_l:
        x = h / h_l
        return 10.0 * amp * (x ** 0.9 - 0.9 * x)
    if h <= h_f - h_u:
        return amp
    if h <= h_f:
        return 0.5 * amp * (1.0 - math.cos(math.pi / h_u * (h - h_f)))
    return 0.0


def wind_profile_mps(h_m, data: VehicleData, scale: float = 1.0, shift_m: float = 0.0):
    """Steady wind profile V_w(h) [m/s] (thesis Eq. 2.54), optionally changed:
    ``scale · V_w(h − shift_m)``.

    Parameters
    ----------
    h_m
        Altitude(s) [m], scalar or array.
    data
        Vehicle data (section ``wind.profile``: A, H_l, H_u, H_f).
    scale, shift_m
        Profile change (:class:`ProfileChange`): factor on the speed [1] (negative: the
        opposite sense) and upward shift of the whole profile [m]. The defaults leave Eq. 2.54.

    Returns
    -------
    float or numpy.ndarray
        V_w(h), same shape as ``h_m``.

    Notes
    -----
    ::

        V_w = 10A[(h/H_l)^0.9 − 0.9 h/H_l]        0 ≤ h < H_l
            = A                                  H_l ≤ h ≤ H_f − H_u
            = A/2 [1 − cos(π (h − H_f)/H_u)]     H_f − H_u < h ≤ H_f
            = 0                                  h > H_f

    The formula is continuous: 10A(1 − 0.9) = A at H_l, A/2(1 − cos(−π)) = A at
    H_f − H_u, 0 at H_f, and 0 at h = 0; the leading edge has zero slope at H_l. Negative
    altitudes are treated as h = 0 (V_w = 0).
    """
    amp, h_l, h_u, h_f = _profile_constants(data)
    if np.ndim(h_m) == 0:
        return scale * _profile_scalar(float(h_m) - shift_m, amp, h_l, h_u, h_f)
    h = np.asarray(h_m, dtype=float) - shift_m
    amp = scale * amp
    x = np.clip(h, 0.0, h_l) / h_l
    lead = 10.0 * amp * (x ** 0.9 - 0.9 * x)
    trail = 0.5 * amp * (1.0 - np.cos(math.pi / h_u * (h - h_f)))
    out = np.where(h < h_l, lead, np.where(h <= h_f - h_u, amp, np.where(h <= h_f, trail, 0.0)))
    return np.where(np.isnan(h), np.nan, out)


def _check_intensity(intensity: str) -> None:
    if intensity not in INTENSITIES:
        raise ValueError(f"turbulence intensity must be one of {INTENSITIES}, got {intensity!r}")


class _TurbulenceTable:
    """Scalar σ_w(h), L_w(h) lookup for the per-step path (same law as turbulence_params)."""

    def __init__(self, data: VehicleData, intensity: str):
        _check_intensity(intensity)
        self.alt = [float(v) for v in data["wind.dryden.altitude_m"]]
        self.length = [float(v) for v in data["wind.dryden.length_scale_m"]]
        if intensity == "none":
            self.sigma = [0.0] * len(self.alt)
        else:
            self.sigma = [float(v) for v in data[f"wind.dryden.sigma_{intensity}_mps"]]
        self.h_cut = data["wind.profile.h_final_m"]

    def at(self, h: float) -> tuple[float, float]:
        alt, length, sigma = self.alt, self.length, self.sigma
        i = bisect_right(alt, h)
        if i == 0:
            s, ell = sigma[0], length[0]
        elif i == len(alt):
            s, ell = sigma[-1], length[-1]
        else:
            w = (h - alt[i - 1]) / (alt[i] - alt[i - 1])
            s = sigma[i - 1] + w * (sigma[i] - sigma[i - 1])
            ell = length[i - 1] + w * (length[i] - length[i - 1])
        return (0.0 if h > self.h_cut else s), ell


def turbulence_params(h_m, data: VehicleData, intensity: str = "light"):
    """Turbulence intensity σ_w(h) [m/s] and length scale L_w(h) [m] (thesis Table 2.4).

    Parameters
    ----------
    h_m
        Altitude(s) [m], scalar or array.
    data
        Vehicle data (section ``wind.dryden``; ``wind.profile.h_final_m``).
    intensity
        ``"light"``, ``"moderate"``, ``"severe"`` or ``"none"`` (σ_w = 0).

    Returns
    -------
    sigma_mps, length_m
        Floats for a scalar altitude, arrays otherwise.

    Notes
    -----
    Linear interpolation in altitude between the rows of Table 2.4 (1–20 km); below the
    first row (1 km) the first row is held; between the last row and H_f (equal, 20 km,
    in the thesis) the last row is held; above H_f, σ_w = 0 (thesis §2.12.5: no wind
    disturbance above 20 km) while L_w keeps the last value. σ_w is therefore bounded
    and steps to zero at H_f.
    """
    _check_intensity(intensity)
    alt = data["wind.dryden.altitude_m"]
    length = data["wind.dryden.length_scale_m"]
    h_cut = data["wind.profile.h_final_m"]
    if intensity == "none":
        sig_tab = np.zeros_like(alt)
    else:
        sig_tab = data[f"wind.dryden.sigma_{intensity}_mps"]
    h = np.asarray(h_m, dtype=float)
    sigma = np.where(h > h_cut, 0.0, np.interp(h, alt, sig_tab))
    ell = np.interp(h, alt, length)
    if np.ndim(h_m) == 0:
        return float(sigma), float(ell)
    return sigma, ell


def dryden_ss(h_m: float, airspeed_mps: float, data: VehicleData, intensity: str = "light"):
    """Continuous-time Dryden filter at one flight condition, for the synthesis.

    G(s) = σ_w √(2V/(π L_w)) / (s + V/L_w) — thesis Eq. 2.53 with the vehicle airspeed V
    in place of V_w(h) (see the module docstring).

    Parameters
    ----------
    h_m
        Altitude [m] (σ_w, L_w from :func:`turbulence_params`).
    airspeed_mps
        Vehicle airspeed V > 0 [m/s].
    data, intensity
        As in :func:`turbulence_params`.

    Returns
    -------
    A, B, C, D : numpy.ndarray
        1×1 each: A = −V/L_w, B = σ_w √(2V/(π L_w)), C = 1, D = 0; input n_w, output
        v_turb [m/s].

    Notes
    -----
    The gain is the MIL-HDBK-1797 convention: Φ(ω) = |G(jω)|² is a one-sided spectrum
    with ∫₀^∞ Φ dω = σ_w², i.e. the output variance is σ_w² when n_w is white noise of
    two-sided intensity π (and σ_w²/π for unit intensity). The time-domain simulation
    (:class:`DrydenTurbulence`) produces variance σ_w² exactly.
    """
    v = float(airspeed_mps)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"airspeed_mps must be finite and > 0, got {airspeed_mps!r}")
    sigma, ell = turbulence_params(float(h_m), data, intensity)
    return (np.array([[-v / ell]]), np.array([[sigma * math.sqrt(2.0 * v / (math.pi * ell))]]),
            np.array([[1.0]]), np.array([[0.0]]))


class DrydenTurbulence:
    """Discrete-time first-order Dryden turbulence along z, seeded and bounded.

    Parameters
    ----------
    data
        Vehicle data (sections ``wind`` and ``actuator.physics_rate_hz``).
    intensity
        One of :data:`INTENSITIES`.
    seed
        Seed of the ``numpy`` PCG64 generator: the same seed gives the same sequence.
    dt_s
        Step [s]; default 1/``actuator.physics_rate_hz``.

    Notes
    -----
    A unit-variance Gauss–Markov process η is propagated with the exact discretisation of
    the Dryden filter 1/(s + V/L_w) over one step,

        η_{k+1} = a η_k + √(1 − a²) n_k,   a = exp(−V dt / L_w(h)),   n_k ~ N(0, 1),

    and the turbulence is v_k = σ_w(h) η_k, so the variance is σ_w(h)² at every altitude
    (no transient when σ_w changes with h) and the autocorrelation is exp(−V τ / L_w). η₀
    is drawn from N(0, 1) (stationary start). V is the vehicle airspeed (|V| is used; a
    vehicle at rest sees frozen turbulence). Above H_f = 20 km σ_w = 0, so v_k = 0.
    """

    def __init__(self, data: VehicleData, intensity: str = "light", seed: int = 0,
                 dt_s: float | None = None):
        self._table = _TurbulenceTable(data, intensity)
        self.intensity = intensity
        self.seed = int(seed)
        self.dt_s = float(dt_s) if dt_s is not None else 1.0 / data["actuator.physics_rate_hz"]
        if not (math.isfinite(self.dt_s) and self.dt_s > 0.0):
            raise ValueError(f"dt_s must be finite and > 0, got {dt_s!r}")
        self.reset()

    def reset(self) -> None:
        """Restart the sequence from the seed."""
        self._rng = np.random.Generator(np.random.PCG64(self.seed))
        self._noise: list[float] = []
        self._next = 0
        self._eta = self._normal()

    def _normal(self) -> float:
        if self._next == len(self._noise):
            self._noise = self._rng.standard_normal(_NOISE_BLOCK).tolist()
            self._next = 0
        n = self._noise[self._next]
        self._next += 1
        return n

    def coefficients(self, h_m: float, airspeed_mps: float) -> tuple[float, float, float]:
        """(σ_w, a, √(1 − a²)) of one step at altitude ``h_m`` [m] and airspeed [m/s].

        Raises
        ------
        ValueError
            If the altitude or the airspeed is not finite.
        """
        if not (math.isfinite(h_m) and math.isfinite(airspeed_mps)):
            raise ValueError(f"non-finite altitude {h_m!r} or airspeed {airspeed_mps!r}")
        sigma, ell = self._table.at(h_m)
        a = math.exp(-abs(airspeed_mps) * self.dt_s / ell)
        return sigma, a, math.sqrt(1.0 - a * a)

    def step(self, h_m: float, airspeed_mps: float) -> float:
        """Advance one step at altitude ``h_m`` [m] and airspeed [m/s]; return v_turb [m/s].

        Raises
        ------
        ValueError
            If the altitude or the airspeed is not finite.
        """
        sigma, a, b = self.coefficients(h_m, airspeed_mps)
        self._eta = a * self._eta + b * self._normal()
        return sigma * self._eta

    def steps(self, n: int, coefficients: tuple[float, float, float]) -> list[float]:
        """``n`` steps with the :meth:`coefficients` of one altitude and airspeed: the numbers
        of ``n`` calls of :meth:`step` there."""
        sigma, a, b = coefficients
        eta, noise, i = self._eta, self._noise, self._next
        out = []
        for _ in range(n):
            if i == len(noise):
                noise = self._noise = self._rng.standard_normal(_NOISE_BLOCK).tolist()
                i = 0
            eta = a * eta + b * noise[i]
            i += 1
            out.append(sigma * eta)
        self._eta, self._next = eta, i
        return out

    def coefficients_many(self, h_m, airspeed_mps) -> tuple[list[float], list[float],
                                                            list[float]]:
        """:meth:`coefficients` at each of the altitudes ``h_m`` [m] with the airspeeds
        ``airspeed_mps`` [m/s]: lists (σ_w, a, √(1 − a²)), the same numbers (the table's
        interpolation element by element on arrays, ``math.exp`` per entry).

        Raises
        ------
        ValueError
            If an altitude or an airspeed is not finite.
        """
        h = np.asarray(h_m, dtype=float)
        v = np.asarray(airspeed_mps, dtype=float)
        if not (np.isfinite(h).all() and np.isfinite(v).all()):
            bad = ~(np.isfinite(h) & np.isfinite(v))
            k = int(np.argmax(bad))
            raise ValueError(f"non-finite altitude {float(h[k])!r} or airspeed "
                             f"{float(v[k])!r}")
        table = self._table
        alt = np.array(table.alt)
        sig_tab, len_tab = np.array(table.sigma), np.array(table.length)
        i = np.searchsorted(alt, h, side="right")          # bisect_right
        sigma, ell = np.empty_like(h), np.empty_like(h)
        low, high = i == 0, i == len(alt)
        sigma[low], ell[low] = sig_tab[0], len_tab[0]
        sigma[high], ell[high] = sig_tab[-1], len_tab[-1]
        mid = ~(low | high)
        j = i[mid]
        w = (h[mid] - alt[j - 1]) / (alt[j] - alt[j - 1])
        sigma[mid] = sig_tab[j - 1] + w * (sig_tab[j] - sig_tab[j - 1])
        ell[mid] = len_tab[j - 1] + w * (len_tab[j] - len_tab[j - 1])
        sigma[h > table.h_cut] = 0.0
        exp = math.exp
        a = [exp(x) for x in (-np.abs(v) * self.dt_s / ell).tolist()]
        b = np.sqrt(1.0 - np.square(a)).tolist()
        return sigma.tolist(), a, b

    def entry_steps(self, coefficients: tuple[list[float], list[float], list[float]],
                    steps_per_entry: int) -> list[float]:
        """:meth:`steps` of ``steps_per_entry`` steps with each entry's coefficients in turn
        (``coefficients``: lists σ_w, a, √(1 − a²) as :meth:`coefficients_many` returns
        them), concatenated: the numbers of those calls of :meth:`steps`."""
        eta, noise, i = self._eta, self._noise, self._next
        out = []
        append = out.append
        for sigma, a, b in zip(*coefficients):
            for _ in range(steps_per_entry):
                if i == len(noise):
                    noise = self._noise = self._rng.standard_normal(_NOISE_BLOCK).tolist()
                    i = 0
                eta = a * eta + b * noise[i]
                i += 1
                append(sigma * eta)
        self._eta, self._next = eta, i
        return out

    def entry_steps_array(self, coefficients, steps_per_entry: int) -> np.ndarray:
        """:meth:`entry_steps` as an array, the recursion compiled
        (:func:`vega_model.wind_kernel.dryden_entries`): the same numbers, and the generator
        left where :meth:`entry_steps` leaves it."""
        from vega_model.kernels import compiled

        dryden_entries = compiled().dryden_entries

        sigma, a, b = (np.asarray(c, dtype=float) for c in coefficients)
        n = sigma.size * int(steps_per_entry)
        parts = [np.array(self._noise[self._next:], dtype=float)]
        have = parts[0].size
        while have < n:                      # the blocks entry_steps would draw, in order
            parts.append(self._rng.standard_normal(_NOISE_BLOCK))
            have += _NOISE_BLOCK
        if len(parts) > 1:
            self._noise, self._next = parts[-1].tolist(), _NOISE_BLOCK - (have - n)
        else:
            self._next += n
        out, self._eta = dryden_entries(np.concatenate(parts)[:n], self._eta, sigma, a, b,
                                        int(steps_per_entry))
        return out


# Largest steady wind a table may hold [m/s] (assumption: ≈ 1.5 × the 99th-percentile speed
# of the windiest month and altitude of the site tables, Cape Canaveral at 12 km in January,
# 81 m/s (docs/WINDS.md §2); a faster value is an error in the table, not a wind).
MAX_TABLE_WIND_MPS = 120.0
# Largest number of rows of a table (assumption: 1 m spacing over 100 km; more is not a
# sounding).
MAX_TABLE_ROWS = 100_000


class WindTableError(BadInput):
    """A malformed :class:`WindTable`: ``<key>: <problem>`` (``key`` and ``problem`` kept, so
    that a file's loader can name its own field)."""

    def __init__(self, key: str, problem: str):
        super().__init__(f"{key}: {problem}")
        self.key, self.problem = key, problem


def _table_scalar(h: float, alt: tuple[float, ...], wind: tuple[float, ...]) -> float:
    """Linear interpolation of (alt, wind) at one altitude, end values held (NaN in, NaN out)."""
    if h != h:
        return math.nan
    if h <= alt[0]:
        return wind[0]
    if h >= alt[-1]:
        return wind[-1]
    i = bisect_right(alt, h)                       # alt[i − 1] <= h < alt[i]
    h0, w0, w1 = alt[i - 1], wind[i - 1], wind[i]
    return w0 + (w1 - w0) * ((h - h0) / (alt[i] - h0))


@dataclass(frozen=True)
class WindTable:
    """A steady wind profile tabulated over altitude: flown in place of Eq. 2.54.

    Attributes
    ----------
    altitude_m
        Geometric altitudes [m], strictly increasing, at least 2.
    wind_mps
        Wind along +z at each altitude [m/s] (the sign convention of :class:`WindModel`),
        finite, |v| <= :data:`MAX_TABLE_WIND_MPS`.
    source
        Where the table came from (free text, one line; e.g. a file and its SHA-256).

    Notes
    -----
    Between rows the wind is linear in altitude; below the first row the first value is held,
    above the last the last (a sounding ends somewhere: its last value is the best estimate
    above it, and above ≈ 30 km the dynamic pressure makes the wind's load negligible). The
    values are stored as tuples of floats, so a table is hashable and its evaluation is the
    same in every process. A malformed table raises :class:`WindTableError` naming the attribute.
    """

    altitude_m: tuple[float, ...]
    wind_mps: tuple[float, ...]
    source: str = ""

    def __post_init__(self):
        alt = _float_tuple(self.altitude_m, "altitude_m")
        wind = _float_tuple(self.wind_mps, "wind_mps")
        if len(alt) != len(wind):
            raise WindTableError("wind_mps", f"{len(wind)} values for {len(alt)} altitudes")
        if len(alt) < 2:
            raise WindTableError("altitude_m", f"needs at least 2 rows, got {len(alt)}")
        if len(alt) > MAX_TABLE_ROWS:
            raise WindTableError("altitude_m", f"at most {MAX_TABLE_ROWS} rows, got {len(alt)}")
        for key, values in (("altitude_m", alt), ("wind_mps", wind)):
            bad = next((i for i, v in enumerate(values) if not math.isfinite(v)), None)
            if bad is not None:
                raise WindTableError(f"{key}[{bad}]", f"must be finite, got {values[bad]!r}")
        bad = next((i for i in range(1, len(alt)) if not alt[i] > alt[i - 1]), None)
        if bad is not None:
            raise WindTableError(f"altitude_m[{bad}]", f"must be strictly increasing, got "
                                 f"{alt[bad]!r} after {alt[bad - 1]!r}")
        bad = next((i for i, v in enumerate(wind) if abs(v) > MAX_TABLE_WIND_MPS), None)
        if bad is not None:
            raise WindTableError(f"wind_mps[{bad}]", f"must be within ±{MAX_TABLE_WIND_MPS:g} "
                                 f"m/s, got {wind[bad]!r}")
        if not isinstance(self.source, str) or "\n" in self.source:
            raise WindTableError("source", "must be one line of text")
        object.__setattr__(self, "altitude_m", alt)
        object.__setattr__(self, "wind_mps", wind)

    def at(self, h_m: float) -> float:
        """The wind [m/s] at altitude ``h_m`` [m] (linear, ends held; NaN in, NaN out)."""
        return _table_scalar(float(h_m), self.altitude_m, self.wind_mps)

    def values(self, h_m) -> np.ndarray:
        """:meth:`at` at each of the altitudes ``h_m`` [m] (the same numbers, as an array)."""
        alt, wind = self.altitude_m, self.wind_mps
        h = np.asarray(h_m, dtype=float)
        return np.array([_table_scalar(x, alt, wind) for x in h.ravel().tolist()],
                        dtype=float).reshape(h.shape)


def _float_tuple(values, key: str) -> tuple[float, ...]:
    if isinstance(values, (str, bytes, dict)) or not hasattr(values, "__len__"):
        raise WindTableError(key, f"must be a list of numbers, got {type(values).__name__}")
    if isinstance(values, np.ndarray) and values.ndim != 1:
        raise WindTableError(key, f"must be one-dimensional, got shape {values.shape}")
    out = []
    for i, v in enumerate(values):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer,
                                                                  np.floating)):
            raise WindTableError(f"{key}[{i}]", f"must be a number, got {v!r}")
        out.append(float(v))
    return tuple(out)


@dataclass(frozen=True)
class GustProfile:
    """Discrete 1-cosine gust along +z.

    v(t) = A/2 [1 − cos(2π (t − t0)/D)] for t0 ≤ t ≤ t0 + D, else 0; peak A at t0 + D/2.

    Attributes
    ----------
    t_start_s
        Gust onset t0 [s] (flight time).
    duration_s
        Gust duration D > 0 [s].
    amplitude_mps
        Peak A [m/s] (signed: negative blows toward −z).
    """

    t_start_s: float
    duration_s: float
    amplitude_mps: float

    def __post_init__(self):
        if not (math.isfinite(self.duration_s) and self.duration_s > 0.0):
            raise ValueError(f"duration_s must be finite and > 0, got {self.duration_s!r}")
        if not (math.isfinite(self.t_start_s) and math.isfinite(self.amplitude_mps)):
            raise ValueError("t_start_s and amplitude_mps must be finite")

    @classmethod
    def from_vehicle(cls, data: VehicleData, t_start_s: float) -> "GustProfile":
        """The design gust of vehicle.yaml (``wind.gust``) starting at ``t_start_s``."""
        return cls(t_start_s=float(t_start_s), duration_s=data["wind.gust.duration_s"],
                   amplitude_mps=data["wind.gust.amplitude_mps"])

    def velocity_mps(self, t_s: float) -> float:
        """Gust velocity at flight time ``t_s`` [m/s]."""
        tau = t_s - self.t_start_s
        if 0.0 <= tau <= self.duration_s:
            phase = 2.0 * math.pi * tau / self.duration_s
            return 0.5 * self.amplitude_mps * (1.0 - math.cos(phase))
        return 0.0


@dataclass(frozen=True)
class ProfileChange:
    """A change of the steady profile: ``V(h) = scale · V_w(h − shift_m)``.

    How a day-of-launch wind differs from the one the guidance was designed for (scenario
    ``wind_change``, docs/GUIDANCE.md §5). ``scale`` [1] multiplies the speed (negative: the
    opposite sense); ``shift_m`` [m] moves the whole profile up (down if negative).
    """

    scale: float = 1.0
    shift_m: float = 0.0

    def __post_init__(self):
        if not (math.isfinite(self.scale) and math.isfinite(self.shift_m)):
            raise ValueError("profile scale and shift must be finite")


class WindComponents(NamedTuple):
    """The parts of the wind at one step [m/s], all along +z."""

    profile_mps: float
    turbulence_mps: float
    gust_mps: float
    total_mps: float


class WindModel:
    """Total wind v_w along +z: steady profile + Dryden turbulence + 1-cosine gust.

    Parameters
    ----------
    data
        Vehicle data.
    profile
        The steady profile: True, V_w(h) of Eq. 2.54; False, none; a :class:`WindTable`,
        that table (``change`` applies to either).
    turbulence
        Dryden intensity, one of :data:`INTENSITIES` (``"none"`` disables it).
    gust
        A discrete gust, or None.
    change
        Change of the steady profile (default: none, Eq. 2.54 as it is).
    seed
        Seed of the turbulence generator.
    dt_s
        Step [s] of :meth:`step` (the turbulence discretisation); default
        1/``actuator.physics_rate_hz``.
    """

    def __init__(self, data: VehicleData, profile: bool | WindTable = True,
                 turbulence: str = "none", gust: GustProfile | None = None, seed: int = 0,
                 dt_s: float | None = None, change: ProfileChange = ProfileChange()):
        self.table = profile if isinstance(profile, WindTable) else None
        self.profile = self.table is not None or bool(profile)
        self.gust = gust
        self.change = change
        # the steady profile's shape at one altitude and its constants (Eq. 2.54 or the table)
        if self.table is not None:
            self._shape = _table_scalar
            self._profile_const = (self.table.altitude_m, self.table.wind_mps)
        else:
            self._shape = _profile_scalar
            self._profile_const = _profile_constants(data)
        self.turbulence = DrydenTurbulence(data, turbulence, seed, dt_s)

    def reset(self) -> None:
        """Restart the turbulence sequence from its seed."""
        self.turbulence.reset()

    def step_components(self, t_s: float, h_m: float, airspeed_mps: float) -> WindComponents:
        """Advance one step; return every part of the wind at time ``t_s`` [s], altitude
        ``h_m`` [m] and airspeed [m/s]. Raises ValueError on non-finite altitude/airspeed."""
        turb = self.turbulence.step(h_m, airspeed_mps)
        prof = (self.change.scale * self._shape(h_m - self.change.shift_m,
                                                *self._profile_const)
                if self.profile else 0.0)
        gust = self.gust.velocity_mps(t_s) if self.gust is not None else 0.0
        return WindComponents(prof, turb, gust, prof + turb + gust)

    def step(self, t_s: float, h_m: float, airspeed_mps: float) -> float:
        """Advance one step; return the total wind v_w [m/s] (positive: air toward +z)."""
        return self.step_components(t_s, h_m, airspeed_mps).total_mps

    def steps(self, times_s, h_m: float, airspeed_mps: float) -> list[float]:
        """:meth:`step` at each of ``times_s`` [s] with one altitude and airspeed (the
        parameters held over a plant frame): the same numbers, computed once where they do
        not depend on the time."""
        turb = self.turbulence.steps(len(times_s),
                                     self.turbulence.coefficients(h_m, airspeed_mps))
        prof = (self.change.scale * self._shape(h_m - self.change.shift_m,
                                                *self._profile_const)
                if self.profile else 0.0)
        gust = self.gust
        if gust is None:
            return [prof + w + 0.0 for w in turb]
        return [prof + w + gust.velocity_mps(t) for t, w in zip(times_s, turb)]

    def entry_steps(self, t0_ms: int, dt_ms: int, steps_per_entry: int, h_m,
                    airspeed_mps) -> list[float]:
        """:meth:`steps` over consecutive parameter entries, concatenated: entry ``e`` holds
        altitude ``h_m[e]`` [m] and airspeed ``airspeed_mps[e]`` [m/s] over the steps
        ``e·steps_per_entry`` … ``(e + 1)·steps_per_entry − 1``, step ``j`` at the time
        (t0_ms + j·dt_ms) / 1000 [s]. The numbers of one :meth:`steps` call per entry in
        order (the per-entry values on arrays where the operations are exact, ``math``'s
        functions where they are not).

        Raises
        ------
        ValueError
            On a non-finite altitude or airspeed.
        """
        turb = self.turbulence
        n_e = len(h_m)
        values = turb.entry_steps_array(turb.coefficients_many(h_m, airspeed_mps),
                                        int(steps_per_entry))
        if self.profile:
            scale, shift, const = self.change.scale, self.change.shift_m, self._profile_const
            shifted = (np.asarray(h_m, dtype=float) - shift).tolist()
            shape = self._shape
            prof = np.array([scale * shape(h, *const) for h in shifted])
        else:
            prof = np.zeros(n_e)
        values = np.repeat(prof, steps_per_entry) + values
        gust = self.gust
        if gust is None:
            return (values + 0.0).tolist()
        times = (int(t0_ms) + int(dt_ms) * np.arange(values.size, dtype=np.int64)) / 1000.0
        tau = times - gust.t_start_s
        inside = np.flatnonzero((tau >= 0.0) & (tau <= gust.duration_s))
        gusts = np.zeros(values.size)
        gusts[inside] = [gust.velocity_mps(t) for t in times[inside].tolist()]
        return (values + gusts).tolist()
