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

**Envelope** (docs/REQUIREMENTS.md §2). Qα is a structural load indicator, not an α limit.
The thesis' Fig. 3.1 envelope (from ESA) is not public; after the public precedent of Trotta,
Zavoli and De Matteis (Rocket-Attitude-Dynamics, ``Qmax.mat``) the envelope is
4° × Q_nom(M) along our trajectory for M ≥ 0.31 and held at its value there (the floor,
4° × Q_nom(0.31)) below, stored as a Mach table and interpolated linearly, end values held
(:func:`envelope_table` regenerates it; definition and provenance in the file). The load check
is ``≤`` (the other bounds keep Table 3.1's strict ``<``).

**Informational line.** The thesis' design objective α_max = 3° at the nominal dynamic pressure
(its load weight, Eq. 4.24), |Qα| ≤ 3° × Q_nom(M), is evaluated the same way when the file has
``q_alpha_objective`` (:attr:`RequirementReport.informational`) and printed, but it never
changes :attr:`RequirementReport.passed`.

**Margins.** For each requirement the binding sample is the one with the smallest margin
``bound − |value|``; the report gives the signed value there, the bound there, the margin and
the time, and also the largest |value| and its time (for Qα the two differ: the envelope varies).
The thesis' Table 5.1 figures are reported side by side; its β was the controller
command and its ∫β a signed integral (docs/THESIS_NOTES.md §4), so the report also gives
those two figures for the command when it is passed (``beta_cmd_rad``).

**Sensitivity** (:func:`q_alpha_flip`). With the envelope family "α_allow × Q_nom(M) for
M ≥ M₀, floor F below", the verdict on a run flips at α_allow = max over M ≥ M₀ of
α_max·|Qα|/envelope(M), and at F = max |Qα| below M₀; both are in the report.
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

__all__ = ["REQUIREMENT_KEYS", "ThesisFigure", "EnvelopeDefinition", "RequirementSpec",
           "RequirementResult", "QAlphaFlip", "RequirementReport", "default_requirements_path",
           "load_requirements", "q_alpha_flip",
           "envelope_from_trajectory", "envelope_table", "evaluate_requirements"]

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
# informational (never gating) lines: key -> (file key, SI unit, requirement, metric, display)
_INFO_ROWS = {
    "q_alpha_objective": ("q_alpha_objective", "Pa*rad", "Load objective 3°·Q (Eq. 4.24)", "Qα",
                          "Pa*deg"),
    "q_alpha_allowable": ("q_alpha_allowable", "Pa*rad", "Load allowable (max-Q sized)", "Qα",
                          "Pa*deg"),
}


@dataclass(frozen=True)
class ThesisFigure:
    """One figure of thesis Table 5.1 (SI units) and what it measured."""

    value: float
    note: str = ""


@dataclass(frozen=True)
class EnvelopeDefinition:
    """The parameters the Qα envelope table was generated from (docs/REQUIREMENTS.md §2).

    ``alpha_max_rad`` is the load allowance (envelope = α_max·Q_nom(M) for M ≥ ``mach_min``),
    ``floor_pa_rad`` the value held below ``mach_min``.
    """

    alpha_max_rad: float
    mach_min: float
    floor_pa_rad: float


@dataclass(frozen=True)
class RequirementSpec:
    """The validated requirement bounds (SI units: m, m/s, rad, rad·s, Pa·rad).

    ``objective_mach``/``objective_pa_rad`` are the informational Qα line (the thesis' 3°
    objective; None when the file has no ``q_alpha_objective``); ``envelope_definition`` the
    envelope's parameters (None when the file gives none); ``allowable_pa_rad`` the constant
    Qα allowable sized at max-Q (docs/REQUIREMENTS.md §6; None when the file has no
    ``q_alpha_allowable``): evaluated as an informational line, and the load requirement of
    :attr:`RequirementReport.passed_with_allowable`.
    """

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
    objective_mach: np.ndarray | None = None
    objective_pa_rad: np.ndarray | None = None
    envelope_definition: EnvelopeDefinition | None = None
    allowable_pa_rad: float | None = None

    def envelope(self, mach):
        """Qα envelope [Pa·rad] at Mach ``mach`` (linear in Mach, end values held)."""
        return np.interp(mach, self.envelope_mach, self.envelope_pa_rad)

    def objective(self, mach):
        """Informational Qα bound [Pa·rad] at Mach ``mach`` (None without an objective)."""
        if self.objective_mach is None:
            return None
        return np.interp(mach, self.objective_mach, self.objective_pa_rad)


@dataclass(frozen=True)
class RequirementResult:
    """One row of the requirement table (values in SI units, see ``unit``).

    ``value`` is the signed metric at the binding sample (time ``time_s``), ``bound`` the
    bound there, ``margin = bound − |value|`` (negative: violated); ``peak_value`` the signed
    metric at the largest |value| (time ``peak_time_s``, bound there ``peak_bound``; for a
    constant bound the same sample); ``display_scale`` converts SI values to
    ``display_unit``; ``thesis`` is the Table 5.1 figure (SI). ``gating`` is False for an
    informational line (it never changes the verdict).
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
    peak_value: float = math.nan
    peak_time_s: float = math.nan
    peak_bound: float = math.nan
    gating: bool = True

    def excess_text(self) -> str:
        """How the binding sample fails its bound, in display units ('' if it passes)."""
        if self.passed:
            return ""
        s, u = self.display_scale, self.display_unit
        if not math.isfinite(self.value):
            return f"is {self.value} (bound {self.bound * s:.6g} {u})"
        excess = -self.margin * s
        if excess > 0.0:
            return f"exceeds its bound {self.bound * s:.6g} {u} by {excess:.6g} {u}"
        return f"reaches its bound {self.bound * s:.6g} {u} (the bound is strict)"


@dataclass(frozen=True)
class QAlphaFlip:
    """Where the Qα verdict of a run flips, in the envelope's parameters (SI units).

    The family: envelope(M; α, F) = (α/α_max)·table(M) for M ≥ ``mach_min`` (= α·Q_nom(M) for
    the shipped table), F below. The run meets it iff α ≥ ``alpha_flip_rad`` and
    F ≥ ``floor_flip_pa_rad``; with the floor tied to α (F = α·Q_nom(M₀), the shipped
    construction) iff α ≥ ``alpha_flip_tied_rad``. ``*_time_s``/``*_mach`` locate the binding
    sample (NaN when no sample lies on that side of ``mach_min``; the flip value is then 0).
    ``mach_min_flip`` is the smallest Mach threshold M₀' ≥ ``mach_min`` at which the run meets
    the file's envelope with the floor tied (table(M₀') held below M₀'), resolved to the
    run's Mach samples: ``mach_min`` itself for a run that passes, NaN if no threshold does.
    """

    alpha_max_rad: float
    mach_min: float
    floor_pa_rad: float
    alpha_flip_rad: float
    alpha_flip_time_s: float
    alpha_flip_mach: float
    floor_flip_pa_rad: float
    floor_flip_time_s: float
    alpha_flip_tied_rad: float
    mach_min_flip: float = math.nan

    @property
    def passed(self) -> bool:
        """True if the run meets the file's envelope (the same verdict as the Qα row)."""
        return (self.alpha_flip_rad <= self.alpha_max_rad
                and self.floor_flip_pa_rad <= self.floor_pa_rad)

    def text(self) -> str:
        """One line for the report."""
        d = math.degrees
        alpha = (f"α_allow ≥ {d(self.alpha_flip_rad):.4g}° (binding at "
                 f"{self.alpha_flip_time_s:.3f} s, M {self.alpha_flip_mach:.3f})"
                 if math.isfinite(self.alpha_flip_time_s) else "any α_allow (no sample)")
        floor = (f"floor ≥ {d(self.floor_flip_pa_rad):.6g} Pa*deg (max |Qα| below M "
                 f"{self.mach_min:g}, at {self.floor_flip_time_s:.3f} s)"
                 if math.isfinite(self.floor_flip_time_s)
                 else f"any floor (no sample below M {self.mach_min:g})")
        threshold = ("no Mach threshold" if not math.isfinite(self.mach_min_flip)
                     else f"Mach threshold ≥ {self.mach_min_flip:.3f}")
        return (f"Qα sensitivity: this run meets α_allow·Q_nom(M) with {alpha} and {floor}; "
                f"with the floor tied to α_allow·Q_nom({self.mach_min:g}): α_allow ≥ "
                f"{d(self.alpha_flip_tied_rad):.4g}°; at α_allow = {d(self.alpha_max_rad):g}° "
                f"with the tied floor: {threshold} (file: {d(self.alpha_max_rad):g}°, M "
                f"{self.mach_min:g}, floor {d(self.floor_pa_rad):.6g} Pa*deg)")


@dataclass(frozen=True)
class RequirementReport:
    """All requirement results, and the thesis-definition figures of the command (if given).

    ``informational`` holds the non-gating lines (the thesis' 3° Qα objective), ``q_alpha_flip``
    the sensitivity of the Qα verdict (:func:`q_alpha_flip`; None without an envelope
    definition in the file).
    """

    results: tuple[RequirementResult, ...]
    command_peak_rad: float | None = None
    command_signed_integral_rad_s: float | None = None
    informational: tuple[RequirementResult, ...] = ()
    q_alpha_flip: QAlphaFlip | None = None

    @property
    def passed(self) -> bool:
        """True if every requirement is met (informational lines do not count)."""
        return all(r.passed for r in self.results if r.gating)

    @property
    def with_allowable(self) -> tuple[RequirementResult, ...] | None:
        """The rows that judge a run with the constant Qα allowable (docs/REQUIREMENTS.md §6)
        as the load requirement: the allowable line, then every gating requirement but the Qα
        envelope; None when the file has no allowable."""
        line = next((r for r in self.informational if r.key == "q_alpha_allowable"), None)
        if line is None:
            return None
        return (line, *(r for r in self.results if r.gating and r.key != "q_alpha"))

    @property
    def passed_with_allowable(self) -> bool | None:
        """The verdict of :attr:`with_allowable` (None when the file has no allowable)."""
        rows = self.with_allowable
        return None if rows is None else all(r.passed for r in rows)

    def __getitem__(self, key: str) -> RequirementResult:
        for r in self.results:
            if r.key == key:
                return r
        raise KeyError(f"no requirement '{key}' (known: {', '.join(REQUIREMENT_KEYS)})")

    def table(self) -> str:
        """The results as a text table, the thesis' Table 5.1 figures side by side.

        "value … at [s]" is the binding (worst-margin) sample; "max |value|" the largest
        magnitude and its time. Informational lines follow, marked "info: yes/no".
        """
        head = ("requirement", "metric", "value", "bound", "margin", "at [s]", "max |value|",
                "pass", "thesis Table 5.1")
        rows = []
        for r in (*self.results, *self.informational):
            s, u = r.display_scale, r.display_unit
            thesis = "" if r.thesis is None else f"{r.thesis.value * s:.6g} {u}"
            rows.append((r.requirement, r.metric, f"{r.value * s:.6g} {u}",
                         f"{bound_op(r.key)} {r.bound * s:.6g} {u}", f"{r.margin * s:.6g} {u}",
                         f"{r.time_s:.3f}", peak_text(r), pass_text(r), thesis))
        widths = [max(len(str(row[i])) for row in [head, *rows]) for i in range(len(head))]
        lines = ["  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip()
                 for row in [head, *rows]]
        notes = [f"  {r.metric}: thesis {r.thesis.note}" for r in self.results
                 if r.thesis is not None and r.thesis.note]
        notes += [f"  {r.metric} ({r.requirement}): informational, never gates the verdict"
                  for r in self.informational]
        if self.q_alpha_flip is not None:
            notes.append("  " + self.q_alpha_flip.text())
        if self.command_peak_rad is not None:
            notes.append(f"  with the thesis' definitions (command, signed integral): "
                         f"max |β_cmd| = {math.degrees(self.command_peak_rad):.6g} deg, "
                         f"∫β_cmd dt = {math.degrees(self.command_signed_integral_rad_s):.6g} "
                         f"deg*s")
        return "\n".join(lines + (["notes:"] + notes if notes else []))


def bound_op(key: str) -> str:
    """The comparison of a requirement's bound: ``≤`` for the Qα lines, ``<`` otherwise."""
    return "≤" if key.startswith("q_alpha") else "<"


def pass_text(r: RequirementResult, no: str = "NO") -> str:
    """The pass cell of a row: yes / ``no`` for a requirement, info: yes/no for a line that
    does not gate."""
    if not r.gating:
        return "info: " + ("yes" if r.passed else "no")
    return "yes" if r.passed else no


def peak_text(r: RequirementResult) -> str:
    """The largest |value| of a row and its time, in display units."""
    if not math.isfinite(r.peak_time_s):
        return ""
    return f"{abs(r.peak_value) * r.display_scale:.6g} {r.display_unit} at {r.peak_time_s:.3f} s"


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
        if k not in top + _OPTIONAL_TOP:
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
        allowed = ("value", "unit", "source") + (("mach", "provenance", "definition")
                                                 if envelope else ())
        values[key] = _leaf(path, file_key, node, si_unit, allowed, vector=envelope)
        source = node.get("source")
        if not isinstance(source, str) or not source.strip():
            raise BadFile(f"{path}: field '{file_key}.source': must be a non-empty string")
        sources[key] = source.strip()
        if not envelope and not values[key] > 0.0:
            raise BadFile(f"{path}: field '{file_key}.value': must be > 0")
    env = tree["q_alpha_envelope"]
    mach = _mach_table(path, "q_alpha_envelope", env, values["q_alpha"])
    provenance = env.get("provenance", {})
    if not isinstance(provenance, Mapping):
        raise BadFile(f"{path}: field 'q_alpha_envelope.provenance': must be a mapping")
    definition = _definition(path, env.get("definition"))
    objective_mach = objective = None
    if "q_alpha_objective" in tree:
        node = tree["q_alpha_objective"]
        objective = _leaf(path, "q_alpha_objective", node, "Pa*rad",
                          ("value", "unit", "source", "mach", "provenance"), vector=True)
        objective_mach = _mach_table(path, "q_alpha_objective", node, objective)
        source = node.get("source")
        if not isinstance(source, str) or not source.strip():
            raise BadFile(f"{path}: field 'q_alpha_objective.source': "
                          f"must be a non-empty string")
        sources["q_alpha_objective"] = source.strip()
        for arr in (objective_mach, objective):
            arr.setflags(write=False)
    allowable = None
    if "q_alpha_allowable" in tree:
        node = tree["q_alpha_allowable"]
        allowable = _leaf(path, "q_alpha_allowable", node, "Pa*rad", ("value", "unit", "source"))
        if not allowable > 0.0:
            raise BadFile(f"{path}: field 'q_alpha_allowable.value': must be > 0")
        source = node.get("source")
        if not isinstance(source, str) or not source.strip():
            raise BadFile(f"{path}: field 'q_alpha_allowable.source': "
                          f"must be a non-empty string")
        sources["q_alpha_allowable"] = source.strip()
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
        thesis=thesis, sources=sources, provenance=dict(provenance),
        objective_mach=objective_mach, objective_pa_rad=objective,
        envelope_definition=definition, allowable_pa_rad=allowable)


_OPTIONAL_TOP = ("q_alpha_objective", "q_alpha_allowable")


def _mach_table(path: str, key: str, node: Mapping, values: np.ndarray) -> np.ndarray:
    """The validated Mach breakpoints of a Qα table (``values`` already validated)."""
    mach = node.get("mach")
    if (not isinstance(mach, list) or len(mach) < 2
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in mach)):
        raise BadFile(f"{path}: field '{key}.mach': must be a list of numbers")
    mach = np.array(mach, dtype=float)
    if mach.shape != values.shape:
        raise BadFile(f"{path}: field '{key}': mach and value differ in length")
    if not np.all(np.isfinite(mach)) or np.any(np.diff(mach) <= 0) or mach[0] < 0:
        raise BadFile(f"{path}: field '{key}.mach': must increase from >= 0")
    if np.any(values < 0):
        raise BadFile(f"{path}: field '{key}.value': must be >= 0")
    return mach


def _definition(path: str, node: Any) -> EnvelopeDefinition | None:
    """The envelope's ``definition`` block (alpha_max_deg, mach_min, floor_pa_deg) or None."""
    if node is None:
        return None
    keys = ("alpha_max_deg", "mach_min", "floor_pa_deg")
    if not isinstance(node, Mapping):
        raise BadFile(f"{path}: field 'q_alpha_envelope.definition': must be a mapping")
    for k in node:
        if k not in keys:
            raise BadFile(f"{path}: field 'q_alpha_envelope.definition.{k}': unknown key")
    out = []
    for k in keys:
        v = node.get(k)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v < 0 or (k == "alpha_max_deg" and v == 0):
            raise BadFile(f"{path}: field 'q_alpha_envelope.definition.{k}': must be a "
                          f"finite number {'> 0' if k == 'alpha_max_deg' else '>= 0'}, "
                          f"got {v!r}")
        out.append(float(v))
    return EnvelopeDefinition(math.radians(out[0]), out[1], math.radians(out[2]))


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


def _trajectory_q_of_mach(conditions: FlightConditions | None, t_max_s: float):
    """(Mach, Q [Pa]) on the part of the trajectory where the Mach number reaches a new maximum."""
    fc = conditions if conditions is not None else FlightConditions.load()
    t, mach, q = fc.t_s, fc.column("mach"), fc.column("q_pa")
    sel = t <= t_max_s
    mach, q = mach[sel], q[sel]
    keep = [0]
    for i in range(1, mach.size):
        if mach[i] > mach[keep[-1]]:
            keep.append(i)
    return mach[keep], q[keep]


def envelope_from_trajectory(mach_points, alpha_max_rad: float,
                             conditions: FlightConditions | None = None,
                             t_max_s: float = 100.0, *, mach_min: float = 0.0,
                             floor_pa_rad: float | None = None) -> np.ndarray:
    """A Qα envelope α_max·Q_nom(M) along the trajectory, at ``mach_points`` [Pa·rad].

    Parameters
    ----------
    mach_points
        Mach numbers at which to evaluate it.
    alpha_max_rad
        The load allowance α_max [rad] (the shipped requirement: 4°; the thesis' design
        weight, Eq. 4.24: 3°).
    conditions
        Flight-condition table (default: vega_model's).
    t_max_s
        Last flight time used (the thesis' flight ends at 100 s).
    mach_min
        Below this Mach number the envelope is the floor (0: no floor).
    floor_pa_rad
        The floor [Pa·rad] (default: α_max·Q_nom(mach_min), i.e. the envelope's value at
        ``mach_min`` held below it).

    Notes
    -----
    Q_nom(M) is taken on the part of the trajectory where the Mach number reaches a new maximum
    (it decreases slightly after ≈ 95 s, when the temperature rises above 20 km; Q is then
    small), interpolated linearly in Mach; beyond the largest Mach reached, Q is held.
    docs/REQUIREMENTS.md gives the definition and its sources.
    """
    m_traj, q_traj = _trajectory_q_of_mach(conditions, t_max_s)
    m = np.asarray(mach_points, dtype=float)
    env = alpha_max_rad * np.interp(m, m_traj, q_traj)
    if mach_min > 0.0:
        floor = (alpha_max_rad * float(np.interp(mach_min, m_traj, q_traj))
                 if floor_pa_rad is None else float(floor_pa_rad))
        env = np.where(m < mach_min, floor, env)
    return env


def envelope_table(alpha_max_rad: float, conditions: FlightConditions | None = None,
                   t_max_s: float = 100.0, *, mach_min: float = 0.0,
                   floor_pa_rad: float | None = None, rel_tol: float = 0.005,
                   abs_tol_pa_rad: float = math.radians(20.0), step: float = 0.001):
    """Breakpoints (Mach, envelope [Pa·rad]) of :func:`envelope_from_trajectory` for the file.

    Breakpoints are multiples of ``step`` in Mach from ``mach_min`` up to the first multiple at
    or above the largest Mach reached, chosen greedily (each segment as long as it can be) so
    that the linear interpolation of the table (values rounded to 0.1 Pa·deg) stays within
    ``max(rel_tol · exact, abs_tol)`` of the exact envelope at every trajectory sample; with a
    floor the table holds the floor value from Mach 0 (constant below ``mach_min``; a floor other
    than the envelope's value at ``mach_min`` ends one ``step`` below it, the jump a ramp over
    that step, since the file's Mach breakpoints must rise strictly).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Mach breakpoints and envelope values [Pa·rad] (values rounded to 0.1 Pa·deg).
    """
    m_traj, _ = _trajectory_q_of_mach(conditions, t_max_s)

    def exact(m):
        return envelope_from_trajectory(m, alpha_max_rad, conditions, t_max_s,
                                        mach_min=mach_min, floor_pa_rad=floor_pa_rad)

    def rounded(m):
        return np.radians(np.round(np.degrees(exact(m)), 1))

    n_end = math.ceil(round((float(m_traj[-1]) - mach_min) / step, 9))
    cand = np.round(mach_min + step * np.arange(n_end + 1), 9)
    check = m_traj[m_traj >= mach_min]
    want = exact(check)
    value = rounded(cand)
    tol = np.maximum(rel_tol * np.abs(want), abs_tol_pa_rad)

    def fits(i, j):
        sel = (check >= cand[i]) & (check <= cand[j])
        seg = np.interp(check[sel], cand[[i, j]], value[[i, j]])
        return not np.any(np.abs(seg - want[sel]) > tol[sel])

    points = [cand[0]]
    i = 0
    while i < cand.size - 1:
        j = i + 1
        while j + 1 < cand.size and fits(i, j + 1):
            j += 1
        points.append(cand[j])
        i = j
    mach = np.array(points)
    values = rounded(mach)
    if mach_min > 0.0:
        floor = float(rounded(np.array([0.0]))[0])      # the envelope below mach_min
        if floor == values[0] or mach_min <= step:
            mach = np.concatenate([[0.0], mach])
            values = np.concatenate([[floor], values])
        else:
            # a floor other than the value at mach_min: constant up to one step below it, then
            # the step as a ramp over that last Mach step (the file's Mach must rise strictly)
            mach = np.concatenate([[0.0, mach_min - step], mach])
            values = np.concatenate([[floor, floor], values])
    return mach, values


def _peak(values: np.ndarray) -> int:
    """Index of the largest |value| (a non-finite value first)."""
    mag = np.where(np.isfinite(values), np.abs(values), np.inf)
    return int(np.argmax(mag))


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
        One :class:`RequirementResult` per :data:`REQUIREMENT_KEYS`, in that order; the
        informational 3°·Q line (if the file has one; never gating) and the Qα sensitivity
        (:func:`q_alpha_flip`, if the envelope has a definition).
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

    def row(key, values, bounds, times, passed_fn, value=None, bound=None, time=None,
            out=results):
        gating = key in REQUIREMENT_KEYS
        _, unit, requirement, metric, display = (_ROWS if gating else _INFO_ROWS)[key]
        if value is None:
            i = _binding(values, bounds)
            value = float(values[i])
            bound = float(bounds[i] if np.ndim(bounds) else bounds)
            time = float(times[i])
            k = _peak(values)
            peak, peak_time = float(values[k]), float(times[k])
            peak_bound = float(bounds[k] if np.ndim(bounds) else bounds)
        else:
            peak, peak_time, peak_bound = value, time, bound
        margin = bound - abs(value) if math.isfinite(value) else -math.inf
        out.append(RequirementResult(
            key=key, requirement=requirement, metric=metric, value=value, bound=bound,
            margin=margin, passed=bool(passed_fn(margin)), time_s=time, unit=unit,
            display_unit=display, display_scale=_display_scale(display),
            thesis=spec.thesis.get(key) if gating else None, peak_value=peak,
            peak_time_s=peak_time, peak_bound=peak_bound, gating=gating))

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
    informational = []
    if spec.objective_mach is not None:
        row("q_alpha_objective", qa, spec.objective(m), t, lambda mg: mg >= 0.0,
            out=informational)
    if spec.allowable_pa_rad is not None:
        row("q_alpha_allowable", qa, spec.allowable_pa_rad, t, lambda mg: mg >= 0.0,
            out=informational)
    flip = (q_alpha_flip(t, qa, m, spec=spec) if spec.envelope_definition is not None
            else None)
    return RequirementReport(tuple(results), peak, signed, tuple(informational), flip)


def q_alpha_flip(t_s, q_alpha_pa_rad, mach, *, spec: RequirementSpec | None = None
                 ) -> QAlphaFlip:
    """The envelope parameters at which a run's Qα verdict flips (docs/REQUIREMENTS.md §4).

    Family: envelope(M; α, F) = (α/α_max)·table(M) for M ≥ M₀ (the shipped table is
    α_max·Q_nom(M) there), F for M < M₀ (α_max, M₀ from the file's ``definition``; the file's F
    is the table's value below M₀). A sample at M ≥ M₀ meets it iff
    α ≥ α_max·|Qα|/table(M), a sample below M₀ iff F ≥ |Qα|; so

    * ``alpha_flip`` = α_max · max over M ≥ M₀ of |Qα|/table(M) (0 without such samples),
    * ``floor_flip`` = max over M < M₀ of |Qα| (0 without such samples),
    * ``alpha_flip_tied`` = max(alpha_flip, α_max·floor_flip/table(M₀)): the α at which the
      verdict flips when the floor is α·Q_nom(M₀), as shipped;
    * ``mach_min_flip``: the smallest threshold M₀' ≥ M₀ (a sample's Mach) such that every
      sample at M ≥ M₀' is within table(M) and every sample below within table(M₀').

    A non-finite Qα gives an infinite flip value.

    Parameters
    ----------
    t_s, q_alpha_pa_rad, mach
        Truth samples: time [s], Qα [Pa·rad], Mach [-].
    spec
        Requirement bounds with an envelope ``definition`` (default: the shipped file).

    Raises
    ------
    ValueError
        Arrays of different lengths, or a file without an envelope definition.
    """
    spec = spec if spec is not None else load_requirements()
    d = spec.envelope_definition
    if d is None:
        raise ValueError(f"{spec.path}: the Qα envelope has no 'definition' block")
    t = _as_array("t_s", t_s)
    qa = np.abs(_as_array("q_alpha_pa_rad", q_alpha_pa_rad, t.size))
    m = _as_array("mach", mach, t.size)
    qa = np.where(np.isfinite(qa), qa, np.inf)
    above = m >= d.mach_min
    env = spec.envelope(m)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(qa == 0.0, 0.0, qa / env)
    ratio = np.where(np.isnan(ratio), np.inf, ratio)
    alpha_flip, at_t, at_m = 0.0, math.nan, math.nan
    if np.any(above):
        i = int(np.flatnonzero(above)[np.argmax(ratio[above])])
        alpha_flip, at_t, at_m = d.alpha_max_rad * float(ratio[i]), float(t[i]), float(m[i])
    floor_flip, floor_t = 0.0, math.nan
    if np.any(~above):
        j = int(np.flatnonzero(~above)[np.argmax(qa[~above])])
        floor_flip, floor_t = float(qa[j]), float(t[j])
    floor = float(spec.envelope(0.0))   # the table is constant below M₀ (as generated)
    at_min = float(spec.envelope(d.mach_min))
    tied = alpha_flip
    if floor_flip > 0.0:
        tied = max(tied, d.alpha_max_rad * floor_flip / at_min if at_min > 0 else math.inf)
    return QAlphaFlip(alpha_max_rad=d.alpha_max_rad, mach_min=d.mach_min, floor_pa_rad=floor,
                      alpha_flip_rad=alpha_flip, alpha_flip_time_s=at_t, alpha_flip_mach=at_m,
                      floor_flip_pa_rad=floor_flip, floor_flip_time_s=floor_t,
                      alpha_flip_tied_rad=tied,
                      mach_min_flip=_mach_min_flip(spec, d, qa, m, ratio, floor))


def _mach_min_flip(spec: RequirementSpec, d: EnvelopeDefinition, qa: np.ndarray,
                   m: np.ndarray, ratio: np.ndarray, floor: float) -> float:
    """Smallest sample Mach M₀' ≥ M₀ at which the run meets the table with the floor tied."""
    above = m >= d.mach_min
    if (not np.any(above) or float(np.max(ratio[above])) <= 1.0) and \
            (np.all(above) or float(np.max(qa[~above])) <= floor):
        return d.mach_min
    order = np.argsort(m, kind="stable")
    ms, qs, rs = m[order], qa[order], ratio[order]
    suffix = np.maximum.accumulate(rs[::-1])[::-1]          # max ratio over M ≥ ms[k]
    prefix = np.concatenate([[0.0], np.maximum.accumulate(qs)[:-1]])  # max |Qα| below ms[k]
    ok = (ms >= d.mach_min) & (suffix <= 1.0) & (prefix <= spec.envelope(ms))
    # equal Mach values: only the first of a run of equal values is a threshold
    ok &= np.concatenate([[True], np.diff(ms) > 0])
    return float(ms[np.argmax(ok)]) if np.any(ok) else math.nan


def _display_scale(unit: str) -> float:
    """Factor from the SI unit to the display unit (degrees for angles)."""
    return 1.0 / _UNITS[unit][1] if unit in _UNITS else 1.0
