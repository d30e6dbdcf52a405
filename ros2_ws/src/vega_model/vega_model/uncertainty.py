"""The uncertainty set: parameter ranges for robustness analysis and Monte Carlo campaigns.

Thesis Table 2.3 (rigid-body and bending parameters, ranges provided by ESA), §2.12.3
(10 % on the TVC actuator dynamics) and §2.12.4 (±10 ms on the total delay), read from
the ``uncertainty`` section of vehicle.yaml. This module is data only: a deviation is a
number per parameter name; :meth:`vega_model.parameters.ModelParameters.perturbed`,
:meth:`vega_model.actuator.ActuatorParams.from_vehicle` (``bandwidth_scale = 1 + δ``)
and the delay models apply them.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from vega_model.vehicle_data import VehicleData

__all__ = ["UncertainParameter", "UncertaintySet", "UNCERTAINTY_NAMES"]

# name -> (kind, what the deviation multiplies or shifts). Order = order of sampling.
_DEFINITIONS: dict[str, tuple[str, str]] = {
    "thrust": ("relative", "thrust T (thesis Table 2.3)"),
    "velocity": ("relative", "longitudinal velocity v_x (Table 2.3)"),
    "density": ("relative", "air density rho (Table 2.3)"),
    "x_cp": ("relative", "centre-of-pressure position x_CP from the base (Table 2.3)"),
    "x_cg": ("relative", "centre-of-gravity position x_CG from the base (Table 2.3)"),
    "mass": ("relative", "vehicle mass m (Table 2.3)"),
    "jyy": ("relative", "pitch inertia J_yy (Table 2.3)"),
    "bending_frequency_1": ("relative", "1st bending natural frequency (Table 2.3)"),
    "bending_frequency_2": ("relative", "2nd bending natural frequency (Table 2.3)"),
    "psi_mode_1": ("relative", "all 1st-mode shapes Psi_t, Psi_r at PVP and INS (Table 2.3)"),
    "psi_mode_2": ("relative", "all 2nd-mode shapes Psi_t, Psi_r at PVP and INS (Table 2.3)"),
    "actuator": ("relative", "TVC actuator natural frequency (thesis §2.12.3)"),
    "delay_s": ("absolute", "total loop delay, seconds added (thesis §2.12.4)"),
}

UNCERTAINTY_NAMES: tuple[str, ...] = tuple(_DEFINITIONS)


@dataclass(frozen=True)
class UncertainParameter:
    """One uncertain parameter: its deviation lies in [lower, upper].

    Attributes
    ----------
    name
        Key of the deviation (see :data:`UNCERTAINTY_NAMES`).
    lower, upper
        Bounds of the deviation, lower ≤ 0 ≤ upper (nominal = 0): fractions of the
        nominal value for ``kind = "relative"`` (x = x⁰(1 + δ)), seconds for the
        ``"absolute"`` delay (τ = τ⁰ + δ).
    kind
        ``"relative"`` or ``"absolute"``.
    applies_to
        What the deviation acts on.
    source
        Where the range comes from (the vehicle data file's source string).
    """

    name: str
    lower: float
    upper: float
    kind: str
    applies_to: str
    source: str = ""

    def __post_init__(self):
        if self.kind not in ("relative", "absolute"):
            raise ValueError(f"{self.name}: kind must be 'relative' or 'absolute', "
                             f"got {self.kind!r}")
        if not (math.isfinite(self.lower) and math.isfinite(self.upper)
                and self.lower <= 0.0 <= self.upper):
            raise ValueError(f"{self.name}: need finite lower <= 0 <= upper, "
                             f"got [{self.lower!r}, {self.upper!r}]")
        if self.kind == "relative" and self.lower <= -1.0:
            raise ValueError(f"{self.name}: a relative lower bound must be > -1, "
                             f"got {self.lower!r}")


class UncertaintySet:
    """An ordered set of :class:`UncertainParameter` (thesis Table 2.3, §2.12.3–2.12.4).

    Deviations are plain dicts ``name -> deviation``.
    """

    def __init__(self, parameters):
        self.parameters: tuple[UncertainParameter, ...] = tuple(parameters)
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate uncertain parameter names in {names}")

    @classmethod
    def from_vehicle(cls, data: VehicleData) -> "UncertaintySet":
        """The full set from the ``uncertainty`` section of the vehicle data file."""
        params = []
        for name, (kind, applies_to) in _DEFINITIONS.items():
            key = f"uncertainty.{name}"
            lower, upper = (float(v) for v in data[key])
            params.append(UncertainParameter(name, lower, upper, kind, applies_to,
                                              data.source(key)))
        return cls(params)

    def __len__(self) -> int:
        return len(self.parameters)

    def __iter__(self) -> Iterator[UncertainParameter]:
        return iter(self.parameters)

    def __getitem__(self, name: str) -> UncertainParameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"no uncertain parameter '{name}'")

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names in set order."""
        return tuple(p.name for p in self.parameters)

    def nominal(self) -> dict[str, float]:
        """All deviations zero (the nominal model)."""
        return {p.name: 0.0 for p in self.parameters}

    def sample(self, rng: np.random.Generator) -> dict[str, float]:
        """One draw, each deviation uniform in [lower, upper], drawn in set order.

        Parameters
        ----------
        rng
            A ``numpy.random.Generator`` (the caller owns the seed).
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        draws = rng.uniform(0.0, 1.0, size=len(self.parameters))
        return {p.name: p.lower + float(u) * (p.upper - p.lower)
                for p, u in zip(self.parameters, draws)}

    def corners(self, names=None) -> Iterator[dict[str, float]]:
        """All vertex combinations: each deviation at its lower or upper bound.

        Parameters
        ----------
        names
            Parameters to vary (default: all, 2^13 = 8192 vertices); the others stay at 0.
            The order is that of ``itertools.product`` over the set order, lower first.
        """
        chosen = self.names if names is None else tuple(names)
        bounds = [(self[n].lower, self[n].upper) for n in chosen]
        base = self.nominal()
        for combo in itertools.product(*bounds):
            corner = dict(base)
            corner.update(zip(chosen, combo))
            yield corner

    def to_dict(self) -> dict[str, dict]:
        """Plain-data view: name -> {lower, upper, kind, applies_to, source}."""
        return {p.name: {"lower": p.lower, "upper": p.upper, "kind": p.kind,
                         "applies_to": p.applies_to, "source": p.source}
                for p in self.parameters}
