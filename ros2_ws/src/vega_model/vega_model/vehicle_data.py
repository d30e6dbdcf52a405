"""Vehicle data: the one file that holds every physical number, and its loader.

Every leaf of ``data/vehicle.yaml`` is a mapping ``{value, unit, source}``. The loader
checks every field named in :data:`FIELDS` is present, numeric, finite, of the right
shape and in a unit convertible to the SI unit the code expects, converts it to SI and
returns a read-only :class:`VehicleData`. Any problem is reported as one line naming the
file and the field (:class:`VehicleDataError`, a :class:`vega_core.errors.BadFile`).

Units accepted in the file (converted on load): the SI unit itself, and ``deg``,
``deg/s``, ``deg/s^2``, ``kN``, ``t``, ``km``, ``ms``, ``%`` where they make sense.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Mapping

import numpy as np

from vega_core.documents import load_yaml
from vega_core.errors import BadFile

__all__ = [
    "FIELDS",
    "EQUAL_LENGTH",
    "INCREASING",
    "VehicleData",
    "VehicleDataError",
    "default_vehicle_path",
    "load_vehicle_data",
]


class VehicleDataError(BadFile):
    """A missing or malformed field in a vehicle data file (message is one line)."""


# Conversions from units allowed in the file to the SI unit the code uses.
_CONVERSIONS: dict[tuple[str, str], float] = {
    ("deg", "rad"): math.pi / 180.0,
    ("deg/s", "rad/s"): math.pi / 180.0,
    ("deg/s^2", "rad/s^2"): math.pi / 180.0,
    ("kN", "N"): 1.0e3,
    ("t", "kg"): 1.0e3,
    ("km", "m"): 1.0e3,
    ("ms", "s"): 1.0e-3,
    ("%", "1"): 1.0e-2,
}

# Field path -> (SI unit, shape). Shape: "scalar", "pair" (liftoff, end-of-data values,
# interpolated linearly in time), or "vector" (a table column; see EQUAL_LENGTH).
FIELDS: dict[str, tuple[str, str]] = {
    # --- geometry (x measured from the vehicle base, positive forward) ---
    "geometry.length_m": ("m", "scalar"),
    "geometry.diameter_m": ("m", "scalar"),
    "geometry.s_ref_m2": ("m^2", "scalar"),
    "geometry.x_pvp_m": ("m", "scalar"),
    "geometry.x_ins_m": ("m", "scalar"),
    # --- movable nozzle (tail-wags-dog, thesis §2.7) ---
    "nozzle.mass_kg": ("kg", "scalar"),
    "nozzle.inertia_about_pivot_kgm2": ("kg*m^2", "scalar"),
    "nozzle.cg_behind_pivot_m": ("m", "scalar"),
    # --- bending modes (thesis §2.8-2.9); pairs are [t_start, t_end] values ---
    "bending.t_start_s": ("s", "scalar"),
    "bending.t_end_s": ("s", "scalar"),
    "bending.damping_ratio": ("1", "scalar"),
    "bending.mode1.frequency_hz": ("Hz", "pair"),
    "bending.mode1.psi_t_pvp": ("m", "pair"),
    "bending.mode1.psi_r_pvp": ("rad", "pair"),
    "bending.mode1.psi_t_ins": ("m", "pair"),
    "bending.mode1.psi_r_ins": ("rad", "pair"),
    "bending.mode2.frequency_hz": ("Hz", "pair"),
    "bending.mode2.psi_t_pvp": ("m", "pair"),
    "bending.mode2.psi_r_pvp": ("rad", "pair"),
    "bending.mode2.psi_t_ins": ("m", "pair"),
    "bending.mode2.psi_r_ins": ("rad", "pair"),
    # --- TVC actuator (thesis §2.12.3 and its public code) ---
    "actuator.natural_frequency_radps": ("rad/s", "scalar"),
    "actuator.damping_ratio": ("1", "scalar"),
    "actuator.position_limit_rad": ("rad", "scalar"),
    "actuator.rate_limit_radps": ("rad/s", "scalar"),
    "actuator.physics_rate_hz": ("Hz", "scalar"),
    # --- delays (thesis §2.12.4) ---
    "delays.actuator_s": ("s", "scalar"),
    "delays.sensor_s": ("s", "scalar"),
    "delays.computing_s": ("s", "scalar"),
    "delays.uncertainty_s": ("s", "scalar"),
    "delays.pade_order": ("1", "scalar"),
    # --- INS (thesis §2.9, Eq. 4.18) ---
    "ins.rate_hz": ("Hz", "scalar"),
    "ins.noise_pitch_rad": ("rad", "scalar"),
    "ins.noise_pitch_rate_radps": ("rad/s", "scalar"),
    "ins.noise_drift_m": ("m", "scalar"),
    "ins.noise_drift_rate_mps": ("m/s", "scalar"),
    "ins.noise_velocity_mps": ("m/s", "scalar"),
    # --- flight computer ---
    "controller.rate_hz": ("Hz", "scalar"),
    # --- wind (thesis §2.12.5, Eqs. 2.53-2.54, Table 2.4) ---
    "wind.profile.amplitude_mps": ("m/s", "scalar"),
    "wind.profile.h_lower_m": ("m", "scalar"),
    "wind.profile.h_upper_m": ("m", "scalar"),
    "wind.profile.h_final_m": ("m", "scalar"),
    "wind.dryden.altitude_m": ("m", "vector"),
    "wind.dryden.length_scale_m": ("m", "vector"),
    "wind.dryden.sigma_light_mps": ("m/s", "vector"),
    "wind.dryden.sigma_moderate_mps": ("m/s", "vector"),
    "wind.dryden.sigma_severe_mps": ("m/s", "vector"),
    "wind.gust.amplitude_mps": ("m/s", "scalar"),
    "wind.gust.duration_s": ("s", "scalar"),
    # --- uncertainty set (thesis Table 2.3, §2.12.3-2.12.4); fractions of nominal ---
    "uncertainty.thrust": ("1", "pair"),
    "uncertainty.velocity": ("1", "pair"),
    "uncertainty.density": ("1", "pair"),
    "uncertainty.x_cp": ("1", "pair"),
    "uncertainty.x_cg": ("1", "pair"),
    "uncertainty.mass": ("1", "pair"),
    "uncertainty.jyy": ("1", "pair"),
    "uncertainty.bending_frequency_1": ("1", "pair"),
    "uncertainty.bending_frequency_2": ("1", "pair"),
    "uncertainty.psi_mode_1": ("1", "pair"),
    "uncertainty.psi_mode_2": ("1", "pair"),
    "uncertainty.actuator": ("1", "pair"),
    "uncertainty.delay_s": ("s", "pair"),
    # --- owned by the trajectory / propulsion / mass / aerodynamics work ---
    # (fields of the 'propulsion', 'mass', 'aerodynamics', 'trajectory' and
    #  'environment' sections are listed in _TRAJECTORY_FIELDS below)
}

_TRAJECTORY_FIELDS: dict[str, tuple[str, str]] = {
    # --- propulsion (P80; thesis Table 2.1, §2.6) ---
    "propulsion.thrust_time_s": ("s", "vector"),
    "propulsion.thrust_n": ("N", "vector"),
    "propulsion.isp_vacuum_s": ("s", "scalar"),
    "propulsion.nozzle_exit_area_m2": ("m^2", "scalar"),
    "propulsion.propellant_mass_kg": ("kg", "scalar"),
    "propulsion.burn_time_s": ("s", "scalar"),
    "propulsion.average_thrust_n": ("N", "scalar"),
    # --- mass properties against propellant burnt ---
    "mass.liftoff_mass_kg": ("kg", "scalar"),
    "mass.propellant_burnt_kg": ("kg", "vector"),
    "mass.x_cg_m": ("m", "vector"),
    "mass.jyy_kgm2": ("kg*m^2", "vector"),
    # --- aerodynamics (vega_model/aero.py) ---
    "aerodynamics.axial.mach": ("1", "vector"),
    "aerodynamics.axial.c_a": ("1", "vector"),
    "aerodynamics.normal.mach": ("1", "vector"),
    "aerodynamics.normal.cn_alpha_per_rad": ("1/rad", "vector"),
    "aerodynamics.normal.x_cp_m": ("m", "vector"),
    "aerodynamics.crossflow.eta": ("1", "scalar"),
    "aerodynamics.crossflow.c_dc": ("1", "scalar"),
    "aerodynamics.crossflow.planform_area_m2": ("m^2", "scalar"),
    # --- ascent trajectory (offline/vega_reference/trajectory.py) ---
    "trajectory.liftoff_time_s": ("s", "scalar"),
    "trajectory.pitchover_start_s": ("s", "scalar"),
    "trajectory.pitchover_rate_radps": ("rad/s", "scalar"),
    "trajectory.pitchover_end_pitch_rad": ("rad", "scalar"),
    # --- environment ---
    "environment.standard_gravity_mps2": ("m/s^2", "scalar"),
    "environment.surface_gravity_mps2": ("m/s^2", "scalar"),
    "environment.earth_radius_m": ("m", "scalar"),
}
FIELDS.update(_TRAJECTORY_FIELDS)

# Groups of table columns that must have equal lengths.
EQUAL_LENGTH: tuple[tuple[str, ...], ...] = (
    (
        "wind.dryden.altitude_m",
        "wind.dryden.length_scale_m",
        "wind.dryden.sigma_light_mps",
        "wind.dryden.sigma_moderate_mps",
        "wind.dryden.sigma_severe_mps",
    ),
    ("propulsion.thrust_time_s", "propulsion.thrust_n"),
    ("mass.propellant_burnt_kg", "mass.x_cg_m", "mass.jyy_kgm2"),
    ("aerodynamics.axial.mach", "aerodynamics.axial.c_a"),
    ("aerodynamics.normal.mach", "aerodynamics.normal.cn_alpha_per_rad",
     "aerodynamics.normal.x_cp_m"),
)

# Table axes that must be strictly increasing.
INCREASING: tuple[str, ...] = (
    "wind.dryden.altitude_m",
    "propulsion.thrust_time_s",
    "mass.propellant_burnt_kg",
    "aerodynamics.axial.mach",
    "aerodynamics.normal.mach",
)


@dataclass(frozen=True)
class VehicleData:
    """Validated vehicle data in SI units.

    Index with the dotted field path, e.g. ``data["geometry.x_pvp_m"]``: a float for
    scalars, a read-only ``numpy`` array for pairs and vectors.
    """

    path: str
    values: Mapping[str, float | np.ndarray]
    units: Mapping[str, str] = field(repr=False)
    sources: Mapping[str, str] = field(repr=False)

    def __getitem__(self, key: str):
        try:
            return self.values[key]
        except KeyError:
            raise KeyError(f"vehicle data has no field '{key}' (not in FIELDS)") from None

    def source(self, key: str) -> str:
        """The cited source of a field."""
        return self.sources[key]

    def unit(self, key: str) -> str:
        """The unit the field was written in (the value is held in SI)."""
        return self.units[key]


def default_vehicle_path() -> Path:
    """Path of the vehicle data file shipped with vega_plant."""
    return Path(str(resources.files("vega_model").joinpath("data", "vehicle.yaml")))


def _lookup(tree: Mapping, dotted: str):
    node = tree
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def _factor(unit: str, si_unit: str) -> float | None:
    if unit == si_unit:
        return 1.0
    return _CONVERSIONS.get((unit, si_unit))


def _convert(path: str, key: str, leaf, si_unit: str, shape: str):
    where = f"{path}: field '{key}'"
    if not isinstance(leaf, Mapping):
        raise VehicleDataError(f"{where}: expected a mapping with value, unit, source")
    for part in ("value", "unit", "source"):
        if part not in leaf:
            raise VehicleDataError(f"{where}: missing '{part}'")
    if not isinstance(leaf["source"], str) or not leaf["source"].strip():
        raise VehicleDataError(f"{where}: 'source' must be a non-empty string")
    unit = str(leaf["unit"])
    factor = _factor(unit, si_unit)
    if factor is None:
        raise VehicleDataError(f"{where}: unit '{unit}' is not convertible to '{si_unit}'")
    raw = leaf["value"]
    try:
        if shape == "scalar":
            if isinstance(raw, (list, tuple, dict, bool)) or raw is None:
                raise TypeError
            value = float(raw) * factor
            ok = math.isfinite(value)
        else:
            if not isinstance(raw, (list, tuple)) or any(isinstance(v, bool) for v in raw):
                raise TypeError
            arr = np.asarray(raw, dtype=float) * factor
            if arr.ndim != 1 or (shape == "pair" and arr.size != 2) or arr.size == 0:
                raise TypeError
            ok = bool(np.all(np.isfinite(arr)))
            arr.setflags(write=False)
            value = arr
    except (TypeError, ValueError):
        expected = {"scalar": "a number", "pair": "a list of 2 numbers",
                    "vector": "a list of numbers"}[shape]
        raise VehicleDataError(f"{where}: value must be {expected}, got {raw!r}") from None
    if not ok:
        raise VehicleDataError(f"{where}: value must be finite, got {raw!r}")
    return value, unit, leaf["source"].strip()


def _parse(path: str, tree: Mapping) -> VehicleData:
    values, units, sources = {}, {}, {}
    for key, (si_unit, shape) in FIELDS.items():
        leaf = _lookup(tree, key)
        if leaf is None:
            raise VehicleDataError(f"{path}: field '{key}' is missing")
        values[key], units[key], sources[key] = _convert(path, key, leaf, si_unit, shape)
    for group in EQUAL_LENGTH:
        sizes = {k: values[k].size for k in group}
        if len(set(sizes.values())) != 1:
            raise VehicleDataError(
                f"{path}: field '{group[0]}': table columns {', '.join(group)} "
                f"have different lengths {list(sizes.values())}")
    for key in INCREASING:
        if np.any(np.diff(values[key]) <= 0):
            raise VehicleDataError(f"{path}: field '{key}': must be strictly increasing")
    return VehicleData(path=path, values=values, units=units, sources=sources)


def load_vehicle_data(path: str | Path | None = None) -> VehicleData:
    """Load and validate a vehicle data file (default: the one shipped with vega_plant).

    Raises
    ------
    VehicleDataError
        One line naming the file and the offending field.
    """
    if path is None:
        return _load_default()
    p = Path(path)
    return _parse(str(p), load_yaml(p, "vehicle data", VehicleDataError))


@lru_cache(maxsize=1)
def _load_default() -> VehicleData:
    p = default_vehicle_path()
    return _parse(str(p), load_yaml(p, "vehicle data", VehicleDataError))
