"""Scenarios: what one closed-loop run flies (span, initial state, plant, wind, noise, seed).

One YAML file per scenario in ``vega_sim/scenarios/`` (the file name is the scenario name);
:func:`load_scenario` validates a file completely — unknown or missing keys, wrong types,
values out of range — and reports the first problem as one line naming the file and the
field (:class:`vega_core.errors.BadFile`, a ``ValueError``). The in-process simulation and
the SIL read the same files.

File format (SI units, radians; ``#`` comments allowed)::

    name: thesis                    # = the file name without .yaml
    description: "..."
    t_start_s: 10.0                 # whole 10 ms frames, 0 <= t_start < t_end, both within
    t_end_s: 90.0                   # the flight-condition table (t_end <= its end - 1 frame)
    plant: linear                   # linear | nonlinear
    initial_state:                  # optional; missing states are 0; deviations from the
                                    # guidance reference flight at t_start (assembly.py)
      theta_rad: 0.0349             # also theta_dot_radps, z_m, z_dot_mps, q1, q2, q1_dot,
                                    # q2_dot, beta_rad (nozzle at rest); each within a
                                    # plausible range (_INITIAL_STATE_LIMITS)
    wind:
      profile: false                # steady profile: true (V_w(h), thesis Eq. 2.54), false
                                    # (none), or a table flown in its place (below)
      turbulence: light             # none | light | moderate | severe (thesis Table 2.4)
      thesis_constant_dryden: true  # optional (false): the thesis' deterministic wind, below
      gust: null                    # or {start_s: 46.3, amplitude_mps: 9, duration_s: 2};
                                    # amplitude and duration default to vehicle.yaml wind.gust
      profile_scale: 1.0            # optional (1): the flown profile is
      profile_shift_m: 0.0          #   scale * V_w(h - shift), a changed day-of-launch wind
    guidance: default               # optional (default): the wind-biased guidance reference
                                    # the controller tracks: default (the installed one,
                                    # designed for V_w(h)), none (zero bias), or a file path
                                    # (relative: to the scenario file's folder)
    sensor_noise: true              # INS noise (thesis Eq. 4.18)
    seed: 1                         # integer >= 0
    uncertainty: {}                 # optional: deviations by name (vega_model.uncertainty)
    off_design: "reason"            # optional: the scenario lies outside the design envelope;
                                    # `vega sil run` reports its requirement verdict but
                                    # does not gate on it (health checks still gate)

A tabulated profile (:class:`vega_model.wind.WindTable`: linear in altitude, end values
held; ``profile_scale``/``profile_shift_m`` apply to it as to Eq. 2.54) is given inline::

      profile:
        altitude_m: [0.0, 100.0, ...]   # strictly increasing, >= 2 rows
        wind_mps: [0.0, 1.2, ...]       # along +z, finite, within ±MAX_TABLE_WIND_MPS
        source: "..."                   # optional: where it came from (one line)

Inline, not a file beside the scenario: a scenario's text travels alone — the SIL recorder
stores it in the bag, ``vega check`` and ``vega replay`` parse it from there, ``vega mc rerun``
writes it anew — so it must hold everything it flies.

``thesis_constant_dryden``: the thesis (§5.2, Fig. 5.2) set its wind input to a constant 1,
which its weight W_w = 3 (§4.5.1) scaled before the Dryden filter (Eq. 2.53). Here: 3 × the
response of the Dryden filter of the given intensity (airspeed form, docs/ENVIRONMENT_MODELS.md
§3.2) to a unit step at t_start, discretised exactly per physics step — it rises to
3·σ_w·√(2L_w/(πV)) (3 × the filter's DC gain) with time constant L_w/V. It replaces the random
turbulence; the profile and the gust still add if switched on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

from vega_bus.timing import LoopTiming, seconds_to_ms

from vega_model.dynamics import STATES
from vega_model.flight_conditions import FlightConditions
from vega_sim.plant_step import PLANT_MODELS, table_span_ms
from vega_core.documents import parse_yaml, read_text
from vega_core.errors import BadArgument, BadFile, BadInput
from vega_model.uncertainty import UncertaintySet
from vega_model.vehicle_data import VehicleData, load_vehicle_data
from vega_model.wind import INTENSITIES, WindTable, WindTableError
from vega_gnc.guidance_reference import DEFAULT_GUIDANCE, NO_GUIDANCE
# Largest profile change a scenario may fly (assumption: beyond three times the design speed
# or a 10 km shift it is another wind, not a change of this one).
_MAX_PROFILE_SCALE = 3.0
_MAX_PROFILE_SHIFT_M = 10_000.0
# Plausible initial deviations from the reference flight, per field (assumptions: the linear
# model is a small-perturbation model about the reference attitude (docs/MODEL.md §2) and the
# nonlinear plant keeps its small-angle aerodynamics, so 0.35 rad (20°) of attitude error and
# 0.35 rad/s of rate are far beyond any launch dispersion and still inside where the models
# mean something; drift 1 000 m and 50 m/s are twice the drift budget and > 3× the drift-rate
# budget (docs/REQUIREMENTS.md); modal amplitudes 10 are 10× the Monte Carlo stability limit
# of mode 1 (|q1| > 1), modal rates 1 000 /s about 10× that amplitude at the highest bending
# frequency (≈ 75 rad/s)). Bounded, not only finite: a finite but absurd value (1e300) flies
# and produces NaN (docs/ADVERSARIAL.md, case 1).
_INITIAL_STATE_LIMITS = {"theta_rad": 0.35, "theta_dot_radps": 0.35, "z_m": 1000.0,
                         "z_dot_mps": 50.0, "q1": 10.0, "q2": 10.0, "q1_dot": 1000.0,
                         "q2_dot": 1000.0}
# Largest gust amplitude a scenario may fly [m/s] (assumption: 5× the 9 m/s design gust of
# vehicle.yaml wind.gust, i.e. beyond any discrete design gust) and its longest duration [s]
# (assumption: a gust longer than the 100 s flight is a profile, not a gust).
_MAX_GUST_MPS = 45.0
_MAX_GUST_DURATION_S = 100.0

__all__ = ["DEFAULT_GUIDANCE", "NO_GUIDANCE", "GustSettings", "WindSettings", "InitialState",
           "Scenario", "scenario_names", "scenario_path", "scenario_file", "load_scenario",
           "parse_scenario", "dump_scenario"]


@dataclass(frozen=True)
class GustSettings:
    """A 1-cosine gust (:class:`vega_model.wind.GustProfile`): onset [s], peak [m/s], length [s]."""

    start_s: float
    amplitude_mps: float
    duration_s: float


@dataclass(frozen=True)
class WindSettings:
    """Wind of a scenario (thesis §2.12.5; see the module docstring)."""

    profile: bool | WindTable = True
    turbulence: str = "light"
    thesis_constant_dryden: bool = False
    gust: GustSettings | None = None
    profile_scale: float = 1.0
    profile_shift_m: float = 0.0


@dataclass(frozen=True)
class InitialState:
    """Initial plant state (:data:`vega_model.dynamics.STATES`) and nozzle angle, SI units."""

    theta_rad: float = 0.0
    theta_dot_radps: float = 0.0
    z_m: float = 0.0
    z_dot_mps: float = 0.0
    q1: float = 0.0
    q2: float = 0.0
    q1_dot: float = 0.0
    q2_dot: float = 0.0
    beta_rad: float = 0.0

    def plant_state(self) -> tuple[float, ...]:
        """The 8 plant states in :data:`vega_model.dynamics.STATES` order."""
        return tuple(getattr(self, name) for name in _STATE_FIELDS)


# InitialState field of each plant state, in STATES order.
_STATE_FIELDS = ("theta_rad", "theta_dot_radps", "z_m", "z_dot_mps", "q1", "q2", "q1_dot",
                 "q2_dot")
assert len(_STATE_FIELDS) == len(STATES)


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (build it with :func:`load_scenario` or :func:`parse_scenario`).

    ``uncertainty`` holds (name, deviation) pairs, sorted by name; :attr:`deviations` gives
    them as a dict.
    """

    name: str
    description: str
    t_start_s: float
    t_end_s: float
    plant: str = "nonlinear"
    initial_state: InitialState = field(default_factory=InitialState)
    wind: WindSettings = field(default_factory=WindSettings)
    sensor_noise: bool = True
    seed: int = 0
    uncertainty: tuple[tuple[str, float], ...] = ()
    guidance: str = DEFAULT_GUIDANCE
    off_design: str = ""

    def __post_init__(self):
        try:
            _validate(self, load_vehicle_data())
        except _FieldError as exc:
            raise BadInput(f"scenario '{self.name}': {exc}") from exc

    @property
    def t_start_ms(self) -> int:
        """Start of the run [ms]."""
        return seconds_to_ms(self.t_start_s, "t_start_s")

    @property
    def t_end_ms(self) -> int:
        """End of the run [ms]."""
        return seconds_to_ms(self.t_end_s, "t_end_s")

    @property
    def deviations(self) -> dict[str, float]:
        """Uncertainty deviations by name (empty: nominal)."""
        return dict(self.uncertainty)


def _scenario_dir() -> Path:
    return Path(str(resources.files("vega_sim").joinpath("scenarios")))


def scenario_names() -> tuple[str, ...]:
    """Names of the shipped scenarios, sorted."""
    return tuple(sorted(p.stem for p in _scenario_dir().glob("*.yaml")))


def scenario_path(name: str) -> Path:
    """Path of the shipped scenario ``name``.

    Raises
    ------
    BadArgument
        If there is no such scenario (the message lists the shipped ones).
    """
    path = _scenario_dir() / f"{name}.yaml"
    if not path.is_file():
        raise BadArgument(f"unknown scenario '{name}' (shipped: {', '.join(scenario_names())})")
    return path


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario by shipped name (``"thesis"``) or by file path.

    Parameters
    ----------
    name_or_path
        A shipped scenario name, or a path to a ``.yaml`` file.

    Raises
    ------
    BadInput
        One line: an unknown scenario name (:class:`~vega_core.errors.BadArgument`), or a
        file that is unreadable or invalid, naming the file and the field
        (:class:`~vega_core.errors.BadFile`).
    """
    path = scenario_file(name_or_path)
    return parse_scenario(read_text(path, "scenario"), str(path), expected_name=path.stem)


def scenario_file(name_or_path: str | Path) -> Path:
    """The file a scenario argument names: a path (``.yaml``/``.yml`` or containing ``/``)
    as given, else the shipped scenario of that name (:func:`scenario_path`)."""
    text_path = str(name_or_path)
    if isinstance(name_or_path, Path) or text_path.endswith((".yaml", ".yml")) or "/" in text_path:
        return Path(name_or_path)
    return scenario_path(text_path)


# ----------------------------------------------------------------------------- parsing
_TOP_REQUIRED = ("name", "description", "t_start_s", "t_end_s", "plant", "wind",
                 "sensor_noise", "seed")
_TOP_OPTIONAL = ("initial_state", "uncertainty", "guidance", "off_design")
_WIND_REQUIRED = ("profile", "turbulence", "gust")
_WIND_OPTIONAL = ("thesis_constant_dryden", "profile_scale", "profile_shift_m")
_GUST_KEYS = ("start_s", "amplitude_mps", "duration_s")
_INITIAL_KEYS = tuple(f.name for f in fields(InitialState))


class _FieldError(ValueError):
    """A range check failed: ``field '<key>': <problem>`` (the caller names the source)."""

    def __init__(self, key: str, problem: str):
        super().__init__(f"field '{key}': {problem}")


class _Where:
    """Error messages ``<source>: field '<key>': <problem>``."""

    def __init__(self, source: str):
        self.source = source

    def error(self, key: str, problem: str) -> BadFile:
        return BadFile(f"{self.source}: field '{key}': {problem}")


def _mapping(value: Any, key: str, where: _Where, required, optional=()) -> Mapping:
    if not isinstance(value, Mapping):
        raise where.error(key, f"must be a mapping, got {type(value).__name__}")
    prefix = f"{key}." if key else ""
    for k in value:
        if k not in required and k not in optional:
            raise where.error(f"{prefix}{k}", "unknown key")
    for k in required:
        if k not in value:
            raise where.error(f"{prefix}{k}", "missing")
    return value


def _number(value: Any, key: str, where: _Where) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise where.error(key, f"must be a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise where.error(key, f"must be finite, got {value!r}")
    return x


def _boolean(value: Any, key: str, where: _Where) -> bool:
    if not isinstance(value, bool):
        raise where.error(key, f"must be true or false, got {value!r}")
    return value


def _string(value: Any, key: str, where: _Where) -> str:
    if not isinstance(value, str):
        raise where.error(key, f"must be a string, got {value!r}")
    return value


_TABLE_KEYS = ("altitude_m", "wind_mps")


def _profile(value: Any, where: _Where) -> bool | WindTable:
    """``wind.profile``: true/false, or a table (module docstring)."""
    key = "wind.profile"
    if isinstance(value, bool):
        return value
    if not isinstance(value, Mapping):
        raise where.error(key, f"must be true, false or a table, got {value!r}")
    _mapping(value, key, where, _TABLE_KEYS, ("source",))
    source = _string(value.get("source", ""), f"{key}.source", where)
    try:
        return WindTable(value["altitude_m"], value["wind_mps"], source)
    except WindTableError as exc:
        raise where.error(f"{key}.{exc.key}", exc.problem) from None


def parse_scenario(text: str, source: str = "<scenario>",
                   expected_name: str | None = None) -> Scenario:
    """Parse and validate the YAML text of a scenario.

    Parameters
    ----------
    text
        YAML text (format: module docstring).
    source
        Name used in error messages (the file path).
    expected_name
        If given, the scenario's ``name`` must equal it (the file name).

    Raises
    ------
    BadFile
        One line: ``<source>: field '<key>': <problem>`` (or not valid YAML, or not a
        mapping: :func:`vega_core.documents.parse_yaml`).
    """
    data = load_vehicle_data()   # gust defaults; the range checks use the same file
    where = _Where(source)
    tree = parse_yaml(text, source)
    _mapping(tree, "", where, _TOP_REQUIRED, _TOP_OPTIONAL)
    name = _string(tree["name"], "name", where)
    if expected_name is not None and name != expected_name:
        raise where.error("name", f"'{name}' differs from the file name '{expected_name}'")
    plant = _string(tree["plant"], "plant", where)

    initial = tree.get("initial_state")
    initial = {} if initial is None else initial
    _mapping(initial, "initial_state", where, (), _INITIAL_KEYS)
    state = InitialState(**{k: _number(v, f"initial_state.{k}", where) for k, v in initial.items()})

    wind = _mapping(tree["wind"], "wind", where, _WIND_REQUIRED, _WIND_OPTIONAL)
    gust = None
    if wind["gust"] is not None:
        g = _mapping(wind["gust"], "wind.gust", where, ("start_s",), _GUST_KEYS)
        gust = GustSettings(
            start_s=_number(g["start_s"], "wind.gust.start_s", where),
            amplitude_mps=_number(g.get("amplitude_mps", data["wind.gust.amplitude_mps"]),
                                  "wind.gust.amplitude_mps", where),
            duration_s=_number(g.get("duration_s", data["wind.gust.duration_s"]),
                               "wind.gust.duration_s", where))
    wind_settings = WindSettings(
        profile=_profile(wind["profile"], where),
        turbulence=_string(wind["turbulence"], "wind.turbulence", where),
        thesis_constant_dryden=_boolean(wind.get("thesis_constant_dryden", False),
                                        "wind.thesis_constant_dryden", where),
        gust=gust,
        profile_scale=_number(wind.get("profile_scale", 1.0), "wind.profile_scale", where),
        profile_shift_m=_number(wind.get("profile_shift_m", 0.0), "wind.profile_shift_m", where))
    guidance = _string(tree.get("guidance", DEFAULT_GUIDANCE), "guidance", where)
    if guidance not in (DEFAULT_GUIDANCE, NO_GUIDANCE):
        if not guidance.strip():
            raise where.error("guidance", "must be default, none or a file path, got ''")
        if source != "<scenario>":  # a relative path is relative to the scenario's folder
            guidance = str(Path(source).parent / guidance)

    off_design = _string(tree.get("off_design", ""), "off_design", where).strip()
    if "off_design" in tree and not off_design:
        raise where.error("off_design", "must be the reason the scenario is off-design, got ''")
    if len(off_design) > 500 or "\n" in off_design:
        raise where.error("off_design", "must be one line of at most 500 characters")

    uncertainty = tree.get("uncertainty")
    uncertainty = {} if uncertainty is None else uncertainty
    if not isinstance(uncertainty, Mapping):
        raise where.error("uncertainty", f"must be a mapping, got {type(uncertainty).__name__}")
    deviations = tuple(sorted(
        (str(k), _number(v, f"uncertainty.{k}", where)) for k, v in uncertainty.items()))

    seed = tree["seed"]
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise where.error("seed", f"must be an integer, got {seed!r}")
    values = dict(
        name=name, description=_string(tree["description"], "description", where),
        t_start_s=_number(tree["t_start_s"], "t_start_s", where),
        t_end_s=_number(tree["t_end_s"], "t_end_s", where),
        plant=plant, initial_state=state, wind=wind_settings,
        sensor_noise=_boolean(tree["sensor_noise"], "sensor_noise", where),
        seed=seed, uncertainty=deviations, guidance=guidance, off_design=off_design)
    try:
        return Scenario(**values)
    except ValueError as exc:  # the range checks of the constructor: name the file instead
        if isinstance(exc.__cause__, _FieldError):
            raise BadFile(f"{source}: {exc.__cause__}") from None
        raise


def dump_scenario(scenario: Scenario) -> str:
    """YAML text of a scenario that :func:`parse_scenario` reads back (the same scenario)."""
    wind = scenario.wind
    gust = None if wind.gust is None else {
        "start_s": float(wind.gust.start_s), "amplitude_mps": float(wind.gust.amplitude_mps),
        "duration_s": float(wind.gust.duration_s)}
    tree = {
        "name": scenario.name, "description": scenario.description,
        "t_start_s": float(scenario.t_start_s), "t_end_s": float(scenario.t_end_s),
        "plant": scenario.plant,
        "initial_state": {k: float(v) for k, v in vars(scenario.initial_state).items()},
        "wind": {"profile": _dump_profile(wind.profile), "turbulence": wind.turbulence,
                 "thesis_constant_dryden": wind.thesis_constant_dryden, "gust": gust,
                 "profile_scale": float(wind.profile_scale),
                 "profile_shift_m": float(wind.profile_shift_m)},
        "sensor_noise": scenario.sensor_noise, "seed": int(scenario.seed),
        "uncertainty": {k: float(v) for k, v in scenario.uncertainty},
        "guidance": scenario.guidance,
    }
    if scenario.off_design:
        tree["off_design"] = scenario.off_design
    import yaml

    return yaml.safe_dump(tree, sort_keys=False)


def _dump_profile(profile: bool | WindTable):
    if not isinstance(profile, WindTable):
        return profile
    out = {"altitude_m": list(profile.altitude_m), "wind_mps": list(profile.wind_mps)}
    if profile.source:
        out["source"] = profile.source
    return out


def _table_time_range_s() -> tuple[float, float]:
    """First and last time [s] of the shipped flight-condition table (the one the plant flies
    on, :class:`vega_model.parameters.ModelContext`'s default; loaded once)."""
    t = FlightConditions.load().t_s
    return float(t[0]), float(t[-1])


def _validate(s: Scenario, data: VehicleData) -> None:
    """Range, type and consistency checks of a scenario's fields (raises :class:`_FieldError`)."""
    if not s.name or not isinstance(s.name, str):
        raise _FieldError("name", "must be a non-empty string")
    if s.plant not in PLANT_MODELS:
        raise _FieldError("plant", f"must be one of {', '.join(PLANT_MODELS)}, got {s.plant!r}")
    frame_ms = LoopTiming.from_vehicle(data).frame_ms
    for key in ("t_start_s", "t_end_s"):
        value = getattr(s, key)
        try:
            ms = seconds_to_ms(value, key)
        except (TypeError, ValueError):
            raise _FieldError(key, f"must be a whole number of ms, got {value!r}") from None
        if ms < 0 or ms % frame_ms:
            raise _FieldError(key, f"must be >= 0 and a multiple of the {frame_ms} ms frame, "
                                   f"got {value!r}")
    if not s.t_end_s > s.t_start_s:
        raise _FieldError("t_end_s", f"must be later than t_start_s ({s.t_start_s!r})")
    first_ms, last_ms = table_span_ms(_table_time_range_s(), frame_ms)
    if seconds_to_ms(s.t_start_s, "t_start_s") < first_ms:
        raise _FieldError("t_start_s", f"must be >= {first_ms / 1000:g} s, the start of the "
                                       f"flight-condition table, got {s.t_start_s!r}")
    if seconds_to_ms(s.t_end_s, "t_end_s") > last_ms:
        raise _FieldError("t_end_s", f"must be <= {last_ms / 1000:g} s (the flight-condition "
                                     f"table ends at {(last_ms + frame_ms) / 1000:g} s and the "
                                     f"plant needs one {frame_ms} ms frame past t_end), "
                                     f"got {s.t_end_s!r}")
    for f in fields(InitialState):
        value = getattr(s.initial_state, f.name)
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or not math.isfinite(value)):
            raise _FieldError(f"initial_state.{f.name}", f"must be a finite number, got {value!r}")
    for name, bound in _INITIAL_STATE_LIMITS.items():
        value = getattr(s.initial_state, name)
        if not abs(value) <= bound:
            raise _FieldError(f"initial_state.{name}", f"must be within ±{bound:g} (a plausible "
                                                       f"initial deviation), got {value!r}")
    limit = data["actuator.position_limit_rad"]
    if abs(s.initial_state.beta_rad) > limit:
        raise _FieldError("initial_state.beta_rad", f"|beta| must be <= the stop {limit:.6g} rad")
    if not isinstance(s.wind.profile, (bool, WindTable)):
        raise _FieldError("wind.profile", f"must be true, false or a WindTable, "
                                          f"got {s.wind.profile!r}")
    if s.wind.turbulence not in INTENSITIES:
        raise _FieldError("wind.turbulence", f"must be one of {', '.join(INTENSITIES)}, "
                                             f"got {s.wind.turbulence!r}")
    if s.wind.gust is not None and not 0.0 < s.wind.gust.duration_s <= _MAX_GUST_DURATION_S:
        raise _FieldError("wind.gust.duration_s", f"must be > 0 and <= {_MAX_GUST_DURATION_S:g} "
                                                  f"s, got {s.wind.gust.duration_s!r}")
    if s.wind.gust is not None and not abs(s.wind.gust.amplitude_mps) <= _MAX_GUST_MPS:
        raise _FieldError("wind.gust.amplitude_mps", f"must be within ±{_MAX_GUST_MPS:g} m/s, "
                                                     f"got {s.wind.gust.amplitude_mps!r}")
    if not abs(s.wind.profile_scale) <= _MAX_PROFILE_SCALE:
        raise _FieldError("wind.profile_scale", f"must be within ±{_MAX_PROFILE_SCALE:g}, "
                                                f"got {s.wind.profile_scale!r}")
    if not abs(s.wind.profile_shift_m) <= _MAX_PROFILE_SHIFT_M:
        raise _FieldError("wind.profile_shift_m", f"must be within ±{_MAX_PROFILE_SHIFT_M:g} m, "
                                                  f"got {s.wind.profile_shift_m!r}")
    if not isinstance(s.sensor_noise, bool):
        raise _FieldError("sensor_noise", f"must be true or false, got {s.sensor_noise!r}")
    if isinstance(s.seed, bool) or not isinstance(s.seed, int) or s.seed < 0:
        raise _FieldError("seed", f"must be an integer >= 0, got {s.seed!r}")
    uset = UncertaintySet.from_vehicle(data)
    for name, value in s.uncertainty:
        if name not in uset.names:
            raise _FieldError(f"uncertainty.{name}", f"unknown (known: {', '.join(uset.names)})")
        par = uset[name]
        if not par.lower <= value <= par.upper:
            raise _FieldError(f"uncertainty.{name}",
                              f"{value!r} is outside [{par.lower:g}, {par.upper:g}]")
    delay = dict(s.uncertainty).get("delay_s", 0.0)
    try:
        LoopTiming.from_vehicle(data, delay)
    except ValueError as exc:
        raise _FieldError("uncertainty.delay_s", str(exc)) from None
