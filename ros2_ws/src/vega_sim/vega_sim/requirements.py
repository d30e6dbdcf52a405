"""Performance requirements of the TVC loop (thesis Table 3.1): one definition, arrays in.

The bounds live in ``vega_sim/config/requirements.yaml`` (each with its unit and source) and
are loaded and validated by :func:`load_requirements`. :func:`evaluate_requirements` computes
the metrics, margins and pass/fail from time histories — plain arrays, no ROS — so the
in-process simulation and the bag check (``vega check``) use the same code.

Requirements (thesis Table 3.1):

============================  =====================================  ==========================
requirement                   metric                                 bound
============================  =====================================  ==========================
load performance              Qα(t) at every sample                  |Qα| ≤ envelope(Mach(t))
lateral control               drift z at every sample                |z| < 500 m
lateral control               drift rate ż at every sample           |ż| < 15 m/s
actuation                     nozzle angle β (actuator, not command)  |β| < 6.5°
actuation                     ∫|β| dt over the run (trapezoid)        < 250 °s
============================  =====================================  ==========================

**Envelope.** The thesis' Fig. 3.1 envelope (from ESA) is not public. The default is its own
load weight, α_max = 3° at the nominal dynamic pressure (thesis Eq. 4.24):
envelope(M) = 3° × Q(M) along our trajectory (the flight-condition table of vega_plant),
stored as a coarse Mach table and interpolated linearly, end values held
(:func:`envelope_from_trajectory` regenerates it; provenance in the file). The envelope is 0
at M = 0, where the dynamic pressure and so the load vanish; the load check is therefore
``≤`` (the other bounds keep Table 3.1's strict ``<``).

**Margins.** For each requirement the binding sample is the one with the smallest margin
``bound − |value|``; the report gives the signed value there, the bound there, the margin and
the time. The thesis' Table 5.1 figures are reported side by side; its β was the controller
command and its ∫β a signed integral (docs/THESIS_NOTES.md §4), so the report also gives
those two figures for the command when it is passed (``beta_cmd_rad``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from vega_model.flight_conditions import FlightConditions
from vega_core.documents import load_yaml
from vega_core.errors import BadFile

__all__ = ["REQUIREMENT_KEYS", "ThesisFigure", "RequirementSpec", "RequirementResult",
           "RequirementReport", "default_requirements_path", "load_requirements",
           "envelope_from_trajectory", "evaluate_requirements"]

REQUIREMENT_KEYS = ("q_alpha", "drift", "drift_rate", "deflection", "deflection_integral")

# unit in the file -> (SI unit, factor)
_UNITS = {
    "m": ("m", 1.0), "m/s": ("m/s", 1.0), "rad": ("rad", 1.0), "deg": ("rad", math.pi / 180.0),
    "rad*s": ("rad*s", 1.0), "deg*s": ("rad*s", math.pi / 180.0),
    "Pa*rad": ("Pa*rad", 1.0), "Pa*deg": ("Pa*rad", math.pi / 180.0),
}
# requirement key -> (file key, SI unit, table row: requirement, metric, display unit)
_ROWS = {
    "q_alpha": ("q_alpha_envelope", "Pa*rad", "Load performance", "Qα", "Pa*deg"),
    "drift": ("drift", "m", "Lateral control performance", "z", "m"),
    "drift_rate": ("drift_rate", "m/s", "Lateral control performance", "ż", "m/s"),
    "deflection": ("deflection", "rad", "Actuation performance", "β", "deg"),
    "deflection_integral": ("deflection_integral", "rad*s", "Actuation performance", "∫|β|dt",
                            "deg*s"),
}


@dataclass(frozen=True)
class ThesisFigure:
    """One figure of thesis Table 5.1 (SI units) and what it measured."""

    value: float
    note: str = ""


@dataclass(frozen=True)
class RequirementSpec:
    """The validated requirement bounds (SI units: m, m/s, rad, rad·s, Pa·rad)."""

    path: str
    envelope_mach: np.ndarray
    envelope_pa_rad: np.ndarray
    drift_m: float
    drift_rate_mps: float
    deflection_rad: float
    deflection_integral_rad_s: float
    thesis: Mapping[str, ThesisFigure]
    sources: Mapping[str, str] = field(repr=False)
    provenance: Mapping[str, Any] = field(repr=False)

    def envelope(self, mach):
        """Qα envelope [Pa·rad] at Mach ``mach`` (linear in Mach, end values held)."""
        return np.interp(mach, self.envelope_mach, self.envelope_pa_rad)


@dataclass(frozen=True)
class RequirementResult:
    """One row of the requirement table (values in SI units, see ``unit``).

    ``value`` is the signed metric at the binding sample (time ``time_s``), ``bound`` the
    bound there, ``margin = bound − |value|`` (negative: violated); ``display_scale``
    converts SI values to ``display_unit``; ``thesis`` is the Table 5.1 figure (SI).
    """

    key: str
    requirement: str
    metric: str
    value: float
    bound: float
    margin: float
    passed: bool
    time_s: float
    unit: str
    display_unit: str
    display_scale: float
    thesis: ThesisFigure | None


@dataclass(frozen=True)
class RequirementReport:
    """All requirement results, and the thesis-definition figures of the command (if given)."""

    results: tuple[RequirementResult, ...]
    command_peak_rad: float | None = None
    command_signed_integral_rad_s: float | None = None

    @property
    def passed(self) -> bool:
        """True if every requirement is met."""
        return all(r.passed for r in self.results)

    def __getitem__(self, key: str) -> RequirementResult:
        for r in self.results:
            if r.key == key:
                return r
        raise KeyError(f"no requirement '{key}' (known: {', '.join(REQUIREMENT_KEYS)})")

    def table(self) -> str:
        """The results as a text table, the thesis' Table 5.1 figures side by side."""
        head = ("requirement", "metric", "value", "bound", "margin", "at [s]", "pass",
                "thesis Table 5.1")
        rows = []
        for r in self.results:
            s, u = r.display_scale, r.display_unit
            op = "≤" if r.key == "q_alpha" else "<"
            thesis = "" if r.thesis is None else f"{r.thesis.value * s:.6g} {u}"
            rows.append((r.requirement, r.metric, f"{r.value * s:.6g} {u}",
                         f"{op} {r.bound * s:.6g} {u}", f"{r.margin * s:.6g} {u}",
                         f"{r.time_s:.3f}", "yes" if r.passed else "NO", thesis))
        widths = [max(len(str(row[i])) for row in [head, *rows]) for i in range(len(head))]
        lines = ["  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip()
                 for row in [head, *rows]]
        notes = [f"  {r.metric}: thesis {r.thesis.note}" for r in self.results
                 if r.thesis is not None and r.thesis.note]
        if self.command_peak_rad is not None:
            notes.append(f"  with the thesis' definitions (command, signed integral): "
                         f"max |β_cmd| = {math.degrees(self.command_peak_rad):.6g} deg, "
                         f"∫β_cmd dt = {math.degrees(self.command_signed_integral_rad_s):.6g} "
                         f"deg*s")
        return "\n".join(lines + (["notes:"] + notes if notes else []))


def default_requirements_path() -> Path:
    """Path of the shipped requirement file."""
    return Path(str(resources.files("vega_sim").joinpath("config", "requirements.yaml")))


def _leaf(path: str, key: str, node: Any, si_unit: str, allowed, vector: bool = False):
    def error(sub: str, problem: str) -> BadFile:
        return BadFile(f"{path}: field '{key}{'.' + sub if sub else ''}': {problem}")

    if not isinstance(node, Mapping):
        raise error("", "must be a mapping")
    for k in node:
        if k not in allowed:
            raise error(str(k), "unknown key")
    unit = node.get("unit")
    if unit not in _UNITS or _UNITS[unit][0] != si_unit:
        raise error("unit", f"{unit!r} is not a unit of {si_unit}")
    raw = node.get("value")
    factor = _UNITS[unit][1]
    if vector:
        if (not isinstance(raw, list) or not raw
                or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in raw)):
            raise error("value", "must be a list of numbers")
        value = np.array(raw, dtype=float) * factor
        if not np.all(np.isfinite(value)):
            raise error("value", "must be finite")
    else:
        if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
            raise error("value", f"must be a finite number, got {raw!r}")
        value = float(raw) * factor
    return value


def _parse(path: str, tree: Mapping) -> RequirementSpec:
    top = ("schema_version",) + tuple(row[0] for row in _ROWS.values()) + ("thesis_table_5_1",)
    for k in tree:
        if k not in top:
            raise BadFile(f"{path}: field '{k}': unknown key")
    for k in top:
        if k not in tree:
            raise BadFile(f"{path}: field '{k}': missing")
    if tree["schema_version"] != 1:
        raise BadFile(f"{path}: field 'schema_version': expected 1, "
                      f"got {tree['schema_version']!r}")
    values, sources = {}, {}
    for key, (file_key, si_unit, *_rest) in _ROWS.items():
        node = tree[file_key]
        envelope = key == "q_alpha"
        allowed = ("value", "unit", "source") + (("mach", "provenance") if envelope else ())
        values[key] = _leaf(path, file_key, node, si_unit, allowed, vector=envelope)
        source = node.get("source")
        if not isinstance(source, str) or not source.strip():
            raise BadFile(f"{path}: field '{file_key}.source': must be a non-empty string")
        sources[key] = source.strip()
        if not envelope and not values[key] > 0.0:
            raise BadFile(f"{path}: field '{file_key}.value': must be > 0")
    env = tree["q_alpha_envelope"]
    mach = env.get("mach")
    if (not isinstance(mach, list) or len(mach) < 2
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in mach)):
        raise BadFile(f"{path}: field 'q_alpha_envelope.mach': must be a list of numbers")
    mach = np.array(mach, dtype=float)
    if mach.shape != values["q_alpha"].shape:
        raise BadFile(f"{path}: field 'q_alpha_envelope': mach and value differ in length")
    if np.any(np.diff(mach) <= 0) or mach[0] < 0:
        raise BadFile(f"{path}: field 'q_alpha_envelope.mach': must increase from >= 0")
    if np.any(values["q_alpha"] < 0):
        raise BadFile(f"{path}: field 'q_alpha_envelope.value': must be >= 0")
    provenance = env.get("provenance", {})
    if not isinstance(provenance, Mapping):
        raise BadFile(f"{path}: field 'q_alpha_envelope.provenance': must be a mapping")
    thesis_node = tree["thesis_table_5_1"]
    if not isinstance(thesis_node, Mapping):
        raise BadFile(f"{path}: field 'thesis_table_5_1': must be a mapping")
    thesis = {}
    for k, node in thesis_node.items():
        if k not in _ROWS:
            raise BadFile(f"{path}: field 'thesis_table_5_1.{k}': unknown key")
        value = _leaf(path, f"thesis_table_5_1.{k}", node, _ROWS[k][1], ("value", "unit", "note"))
        note = node.get("note", "")
        if not isinstance(note, str):
            raise BadFile(f"{path}: field 'thesis_table_5_1.{k}.note': must be a string")
        thesis[k] = ThesisFigure(value, note.strip())
    for arr in (mach, values["q_alpha"]):
        arr.setflags(write=False)
    return RequirementSpec(
        path=path, envelope_mach=mach, envelope_pa_rad=values["q_alpha"],
        drift_m=values["drift"], drift_rate_mps=values["drift_rate"],
        deflection_rad=values["deflection"],
        deflection_integral_rad_s=values["deflection_integral"],
        thesis=thesis, sources=sources, provenance=dict(provenance))


def load_requirements(path: str | Path | None = None) -> RequirementSpec:
    """Load and validate a requirement file (default: the shipped one).

    Raises
    ------
    BadFile
        One line naming the file and the field (:mod:`vega_core.documents` for unreadable
        or non-YAML files).
    """
    if path is None:
        return _load_default()
    p = Path(path)
    return _parse(str(p), load_yaml(p, "requirements"))


@lru_cache(maxsize=1)
def _load_default() -> RequirementSpec:
    p = default_requirements_path()
    return _parse(str(p), load_yaml(p, "requirements"))


def envelope_from_trajectory(mach_points, alpha_max_rad: float,
                             conditions: FlightConditions | None = None,
                             t_max_s: float = 100.0) -> np.ndarray:
    """The default Qα envelope α_max·Q(M) along the trajectory, at ``mach_points`` [Pa·rad].

    Parameters
    ----------
    mach_points
        Mach numbers of the table.
    alpha_max_rad
        α_max (thesis Eq. 4.24: 3°).
    conditions
        Flight-condition table (default: vega_plant's).
    t_max_s
        Last flight time used (the thesis' flight ends at 100 s).

    Notes
    -----
    Q(M) is taken on the part of the trajectory where the Mach number reaches a new maximum
    (it decreases slightly after ≈ 95 s, when the temperature rises above 20 km; Q is then
    small), interpolated linearly in Mach; beyond the largest Mach reached, Q is held.
    """
    fc = conditions if conditions is not None else FlightConditions.load()
    t, mach, q = fc.t_s, fc.column("mach"), fc.column("q_pa")
    sel = t <= t_max_s
    mach, q = mach[sel], q[sel]
    keep = [0]
    for i in range(1, mach.size):
        if mach[i] > mach[keep[-1]]:
            keep.append(i)
    return alpha_max_rad * np.interp(np.asarray(mach_points, dtype=float), mach[keep], q[keep])


def _binding(values: np.ndarray, bounds) -> int:
    """Index of the smallest margin bound − |value| (a non-finite value binds first)."""
    margin = np.where(np.isfinite(values), bounds - np.abs(values), -np.inf)
    return int(np.argmin(margin))


def _as_array(name: str, x, n: int | None = None) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 1 or a.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array")
    if n is not None and a.size != n:
        raise ValueError(f"{name} has {a.size} samples, expected {n}")
    return a


def evaluate_requirements(t_s, q_alpha_pa_rad, mach, z_m, z_dot_mps, beta_t_s, beta_rad, *,
                          beta_cmd_rad=None, spec: RequirementSpec | None = None
                          ) -> RequirementReport:
    """Requirement metrics, margins and pass/fail from time histories (thesis Table 3.1).

    Parameters
    ----------
    t_s, q_alpha_pa_rad, mach, z_m, z_dot_mps
        Truth samples: time [s], Qα [Pa·rad], Mach [-], drift [m], drift rate [m/s].
    beta_t_s, beta_rad
        Nozzle (actuator) angle samples: time [s], angle [rad].
    beta_cmd_rad
        Optional command held at the ``beta_t_s`` instants [rad]: adds the thesis-definition
        figures (max |β_cmd|, signed ∫β_cmd dt) to the report.
    spec
        Requirement bounds (default: the shipped file).

    Returns
    -------
    RequirementReport
        One :class:`RequirementResult` per :data:`REQUIREMENT_KEYS`, in that order.
    """
    spec = spec if spec is not None else load_requirements()
    t = _as_array("t_s", t_s)
    n = t.size
    qa = _as_array("q_alpha_pa_rad", q_alpha_pa_rad, n)
    m = _as_array("mach", mach, n)
    z = _as_array("z_m", z_m, n)
    zd = _as_array("z_dot_mps", z_dot_mps, n)
    tb = _as_array("beta_t_s", beta_t_s)
    b = _as_array("beta_rad", beta_rad, tb.size)
    results = []

    def row(key, values, bounds, times, passed_fn, value=None, bound=None, time=None):
        _, unit, requirement, metric, display = _ROWS[key]
        if value is None:
            i = _binding(values, bounds)
            value = float(values[i])
            bound = float(bounds[i] if np.ndim(bounds) else bounds)
            time = float(times[i])
        margin = bound - abs(value) if math.isfinite(value) else -math.inf
        results.append(RequirementResult(
            key=key, requirement=requirement, metric=metric, value=value, bound=bound,
            margin=margin, passed=bool(passed_fn(margin)), time_s=time, unit=unit,
            display_unit=display, display_scale=_display_scale(display),
            thesis=spec.thesis.get(key)))

    row("q_alpha", qa, spec.envelope(m), t, lambda mg: mg >= 0.0)
    row("drift", z, spec.drift_m, t, lambda mg: mg > 0.0)
    row("drift_rate", zd, spec.drift_rate_mps, t, lambda mg: mg > 0.0)
    row("deflection", b, spec.deflection_rad, tb, lambda mg: mg > 0.0)
    integral = float(np.trapezoid(np.abs(b), tb)) if tb.size > 1 else 0.0
    row("deflection_integral", None, None, None, lambda mg: mg > 0.0, value=integral,
        bound=spec.deflection_integral_rad_s, time=float(tb[-1]))
    peak = signed = None
    if beta_cmd_rad is not None:
        c = _as_array("beta_cmd_rad", beta_cmd_rad, tb.size)
        peak = float(np.max(np.abs(c)))
        signed = float(np.trapezoid(c, tb)) if tb.size > 1 else 0.0
    return RequirementReport(tuple(results), peak, signed)


def _display_scale(unit: str) -> float:
    """Factor from the SI unit to the display unit (degrees for angles)."""
    return 1.0 / _UNITS[unit][1] if unit in _UNITS else 1.0
