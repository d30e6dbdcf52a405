"""Model parameters at one flight time: the frozen-time values every model uses.

:func:`model_parameters` combines three sources, each the single source of its facts:

* the vehicle data file (geometry, nozzle, bending data) — :mod:`vega_model.vehicle_data`;
* the committed flight-condition table (velocity, density, thrust, mass properties along our
  own trajectory) — :mod:`vega_model.flight_conditions`;
* the aerodynamic model (C_Nα(M), x_CP(M), C_A(M)) — :mod:`vega_model.aero`.

Derived quantities are computed here from *primary* interpolated columns so that the
linear and the nonlinear model see exactly the same numbers at any t (not only on table
rows): Q = ½ρv², M = v/a, C_Nα = C_Nα(M), x_CP = x_CP(M), axial force = Q·S·C_A(M).
Bending data are interpolated linearly in time between their lift-off and end values
(thesis §2.8) and held constant outside that interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from functools import lru_cache
from typing import Mapping

import numpy as np

from vega_model.aero import Aerodynamics
from vega_model.flight_conditions import COLUMNS, FlightConditions
from vega_model.vehicle_data import VehicleData, load_vehicle_data

__all__ = ["ModelParameters", "ModelContext", "model_parameters", "default_context",
           "PARAMETER_UNITS"]

# Scalar fields reported by `vega linearize` (name -> unit).
PARAMETER_UNITS: dict[str, str] = {
    "t_s": "s", "v_mps": "m/s", "q_pa": "Pa", "mach": "1", "rho_kgpm3": "kg/m^3",
    "h_m": "m", "sound_speed_mps": "m/s", "s_ref_m2": "m^2",
    "cn_alpha_per_rad": "1/rad", "x_cp_m": "m", "x_cg_m": "m", "x_pvp_m": "m",
    "x_ins_m": "m", "jyy_kgm2": "kg*m^2", "mass_kg": "kg", "thrust_n": "N",
    "axial_force_n": "N", "f1_hz": "Hz", "f2_hz": "Hz", "zeta": "1",
    "nozzle_mass_kg": "kg", "nozzle_inertia_kgm2": "kg*m^2", "nozzle_lever_m": "m",
}


# The deviations :meth:`ModelParameters.perturbed` applies (thesis Table 2.3).
_DEVIATION_NAMES = ("thrust", "velocity", "density", "x_cp", "x_cg", "mass", "jyy",
                    "bending_frequency_1", "bending_frequency_2", "psi_mode_1", "psi_mode_2")


@dataclass(frozen=True)
class ModelParameters:
    """Frozen-time parameters of the pitch-plane model (SI units, x from the base).

    The mode-shape arrays have one entry per bending mode: ``psi_t_*`` lateral
    displacement [m] and ``psi_r_*`` slope [rad] per unit modal coordinate, at the nozzle
    pivot (PVP) and the INS; ``psi_r = dpsi_t/dx`` (docs/MODEL.md).
    """

    t_s: float
    v_mps: float
    q_pa: float
    mach: float
    rho_kgpm3: float
    h_m: float
    sound_speed_mps: float
    s_ref_m2: float
    cn_alpha_per_rad: float
    x_cp_m: float
    x_cg_m: float
    x_pvp_m: float
    x_ins_m: float
    jyy_kgm2: float
    mass_kg: float
    thrust_n: float
    axial_force_n: float
    f1_hz: float
    f2_hz: float
    zeta: float
    nozzle_mass_kg: float
    nozzle_inertia_kgm2: float
    nozzle_lever_m: float
    psi_t_pvp: tuple[float, float]
    psi_r_pvp: tuple[float, float]
    psi_t_ins: tuple[float, float]
    psi_r_ins: tuple[float, float]
    aero: Aerodynamics = field(repr=False, compare=False)

    # --- derived lever arms and rates (one place) ---
    @property
    def l_cg_pvp_m(self) -> float:
        """Distance from the nozzle pivot forward to the CG, x_CG − x_PVP [m]."""
        return self.x_cg_m - self.x_pvp_m

    @property
    def l_cp_m(self) -> float:
        """Distance from the CG forward to the CP, x_CP − x_CG [m] (> 0: unstable)."""
        return self.x_cp_m - self.x_cg_m

    @property
    def l_ins_m(self) -> float:
        """Distance from the CG forward to the INS, x_INS − x_CG [m] (thesis l_INS)."""
        return self.x_ins_m - self.x_cg_m

    @property
    def omega_radps(self) -> tuple[float, float]:
        """Bending natural frequencies [rad/s]."""
        return (2.0 * math.pi * self.f1_hz, 2.0 * math.pi * self.f2_hz)

    @property
    def normal_force_slope_n(self) -> float:
        """N_α = Q·S_ref·C_Nα [N/rad]."""
        return self.q_pa * self.s_ref_m2 * self.cn_alpha_per_rad

    def scalars(self) -> dict[str, float]:
        """The scalar parameters as a plain dict (see :data:`PARAMETER_UNITS`)."""
        return {name: float(getattr(self, name)) for name in PARAMETER_UNITS}

    def perturbed(self, deviations: Mapping[str, float]) -> "ModelParameters":
        """Parameters with uncertainty deviations applied (thesis Table 2.3).

        Parameters
        ----------
        deviations
            Relative deviations by uncertainty name (as in :mod:`vega_model.uncertainty`):
            ``thrust, velocity, density, x_cp, x_cg, mass, jyy, bending_frequency_1,
            bending_frequency_2, psi_mode_1, psi_mode_2``. Missing names mean 0. Other
            names (``actuator``, ``delay_s``) belong to other models and are ignored here.
            Q is recomputed from the perturbed density and velocity; C_Nα, x_CP (before
            its own deviation) and the axial force follow the perturbed Mach.
        """
        d = {k: float(deviations.get(k, 0.0)) for k in _DEVIATION_NAMES}
        v = self.v_mps * (1.0 + d["velocity"])
        rho = self.rho_kgpm3 * (1.0 + d["density"])
        mach = v / self.sound_speed_mps
        q = 0.5 * rho * v * v
        s1, s2 = 1.0 + d["psi_mode_1"], 1.0 + d["psi_mode_2"]
        scale = lambda pair: (pair[0] * s1, pair[1] * s2)  # noqa: E731
        return replace(
            self, v_mps=v, rho_kgpm3=rho, mach=mach, q_pa=q,
            cn_alpha_per_rad=float(self.aero.cn_alpha(mach)),
            x_cp_m=float(self.aero.x_cp(mach)) * (1.0 + d["x_cp"]),
            axial_force_n=q * self.s_ref_m2 * float(self.aero.c_a(mach)),
            thrust_n=self.thrust_n * (1.0 + d["thrust"]),
            x_cg_m=self.x_cg_m * (1.0 + d["x_cg"]),
            mass_kg=self.mass_kg * (1.0 + d["mass"]),
            jyy_kgm2=self.jyy_kgm2 * (1.0 + d["jyy"]),
            f1_hz=self.f1_hz * (1.0 + d["bending_frequency_1"]),
            f2_hz=self.f2_hz * (1.0 + d["bending_frequency_2"]),
            psi_t_pvp=scale(self.psi_t_pvp), psi_r_pvp=scale(self.psi_r_pvp),
            psi_t_ins=scale(self.psi_t_ins), psi_r_ins=scale(self.psi_r_ins),
        )


class ModelContext:
    """The three data sources of the model, loaded once; ``parameters(t)`` per time."""

    def __init__(self, vehicle: VehicleData | None = None,
                 conditions: FlightConditions | None = None,
                 aero: Aerodynamics | None = None):
        self.vehicle = vehicle if vehicle is not None else load_vehicle_data()
        self.conditions = conditions if conditions is not None else FlightConditions.load()
        self.aero = aero if aero is not None else Aerodynamics(self.vehicle)
        v = self.vehicle
        self._t0 = v["bending.t_start_s"]
        self._t1 = v["bending.t_end_s"]
        self._pairs = {
            name: v[f"bending.mode{i}.{key}"]
            for i in (1, 2)
            for key, name in (("frequency_hz", f"f{i}"), ("psi_t_pvp", f"tp{i}"),
                              ("psi_r_pvp", f"rp{i}"), ("psi_t_ins", f"ti{i}"),
                              ("psi_r_ins", f"ri{i}"))
        }
        self._const = dict(
            s_ref_m2=v["geometry.s_ref_m2"], x_pvp_m=v["geometry.x_pvp_m"],
            x_ins_m=v["geometry.x_ins_m"], zeta=v["bending.damping_ratio"],
            nozzle_mass_kg=v["nozzle.mass_kg"],
            nozzle_inertia_kgm2=v["nozzle.inertia_about_pivot_kgm2"],
            nozzle_lever_m=v["nozzle.cg_behind_pivot_m"],
        )
        # (times, columns) of the last flight-condition interpolation on arrays
        # (_shared_conditions)
        self._conditions_memo: tuple[np.ndarray, dict[str, np.ndarray]] | None = None

    @property
    def time_range_s(self) -> tuple[float, float]:
        """First and last time of the flight-condition table [s]."""
        return float(self.conditions.t_s[0]), float(self.conditions.t_s[-1])

    def parameters_at_times(self, t_s, deviations: Mapping[str, float] | None = None,
                            columns: dict | None = None) -> list[ModelParameters]:
        """``[parameters(t).perturbed(deviations) for t in t_s]`` (without ``perturbed`` when
        no deviation is non-zero), the same numbers bit for bit, computed on arrays: a run's
        10 001 parameter sets in ≈ 0.03 s instead of ≈ 0.2 s (a Monte Carlo flight forms
        them all anew).

        ``columns``: a dict that receives the fields that vary with the time as float
        arrays by field name (mode-shape pairs as ``psi_t_pvp_0`` …), the numbers of the
        returned objects; left empty with a custom aerodynamic model."""
        if not isinstance(self.aero, Aerodynamics):
            return [self.parameters(float(t)).perturbed(deviations)
                    if deviations and any(deviations.values()) else self.parameters(float(t))
                    for t in np.asarray(t_s, dtype=float).ravel()]
        return _parameters_at_times(self, t_s, deviations, columns)

    def parameter_columns_at_times(self, t_s, deviations: Mapping[str, float] | None = None
                                   ) -> dict[str, np.ndarray] | None:
        """The ``columns`` of :meth:`parameters_at_times` without building the objects (None
        with a custom aerodynamic model); :meth:`parameters_from_columns` builds one."""
        if not isinstance(self.aero, Aerodynamics):
            return None
        columns: dict[str, np.ndarray] = {}
        _parameters_at_times(self, t_s, deviations, columns, build=False)
        return columns

    def parameters_from_columns(self, columns: Mapping[str, np.ndarray], index: int
                                ) -> ModelParameters:
        """Entry ``index`` of :meth:`parameter_columns_at_times`' columns: the object
        :meth:`parameters_at_times` builds there (equal, field by field)."""
        c = {name: float(column[index]) for name, column in columns.items()}
        pairs = {name: (c.pop(name + "_0"), c.pop(name + "_1"))
                 for name in ("psi_t_pvp", "psi_r_pvp", "psi_t_ins", "psi_r_ins")}
        values = {**c, **pairs, **self._const, "aero": self.aero}
        p = object.__new__(ModelParameters)
        object.__setattr__(p, "__dict__", {name: values[name] for name in _FIELD_NAMES})
        return p

    def parameters(self, t_s: float) -> ModelParameters:
        """Frozen-time model parameters at flight time ``t_s`` (clamped to the table)."""
        fc = self.conditions.at(t_s)
        v, rho, a = fc.v_mps, fc.rho_kgpm3, fc.sound_speed_mps
        mach = v / a
        q = 0.5 * rho * v * v
        s = min(max((t_s - self._t0) / (self._t1 - self._t0), 0.0), 1.0)
        lin = {k: float(p[0] + s * (p[1] - p[0])) for k, p in self._pairs.items()}
        return ModelParameters(
            t_s=float(t_s), v_mps=float(v), q_pa=float(q), mach=float(mach),
            rho_kgpm3=float(rho), h_m=float(fc.h_m), sound_speed_mps=float(a),
            cn_alpha_per_rad=float(self.aero.cn_alpha(mach)),
            x_cp_m=float(self.aero.x_cp(mach)),
            x_cg_m=float(fc.x_cg_m), jyy_kgm2=float(fc.jyy_kgm2), mass_kg=float(fc.mass_kg),
            thrust_n=float(fc.thrust_n),
            axial_force_n=float(q * self._const["s_ref_m2"] * self.aero.c_a(mach)),
            f1_hz=lin["f1"], f2_hz=lin["f2"],
            psi_t_pvp=(lin["tp1"], lin["tp2"]), psi_r_pvp=(lin["rp1"], lin["rp2"]),
            psi_t_ins=(lin["ti1"], lin["ti2"]), psi_r_ins=(lin["ri1"], lin["ri2"]),
            aero=self.aero, **self._const,
        )


def _conditions_at_times(conditions: FlightConditions, t: np.ndarray) -> dict[str, np.ndarray]:
    """:meth:`FlightConditions.at` for many times: each column, every number equal to
    ``at``'s (the same interpolation formula, element by element; the end rows outside the
    table)."""
    if np.isnan(t).any():
        raise ValueError("flight conditions: time is NaN")
    times = conditions.t_s
    data = np.column_stack([conditions.column(name) for name in COLUMNS])
    out = np.empty((t.size, data.shape[1]))
    low, high = ~(t > times[0]), t >= times[-1]
    out[low] = data[0]
    out[high & ~low] = data[-1]
    inside = ~(low | high)
    ti = t[inside]
    i = np.searchsorted(times, ti, side="right") - 1
    r0, r1 = data[i], data[i + 1]
    w = (ti - times[i]) / (times[i + 1] - times[i])
    out[inside] = r0 + w[:, None] * (r1 - r0)
    return {name: out[:, k] for k, name in enumerate(COLUMNS)}


def _shared_conditions(ctx: "ModelContext", t: np.ndarray) -> dict[str, np.ndarray]:
    """:func:`_conditions_at_times` of the context's table at the times ``t``, kept for the
    last times asked for (compared bit for bit) and returned again for the same times.

    The interpolation does not depend on the deviations, and every parameter track of one
    span asks for the same times (the samples of a batched flight, the flights of a
    campaign): it costs ≈ 5 ms for a 100-s track of 10 001 entries, a quarter of a batched
    sample's input building, and is done once per span instead. The columns are read-only
    (they are shared by the tracks built from them)."""
    memo = ctx._conditions_memo
    if memo is not None and memo[0].shape == t.shape and memo[0].tobytes() == t.tobytes():
        return memo[1]
    col = _conditions_at_times(ctx.conditions, t)
    for column in col.values():
        column.setflags(write=False)
    ctx._conditions_memo = (t.copy(), col)
    return col


# The fields _parameters_at_times computes per entry, in ModelParameters' order (the pairs as
# two columns each); the others are the context's constants.
_VARYING = ("t_s", "v_mps", "q_pa", "mach", "rho_kgpm3", "h_m", "sound_speed_mps",
            "cn_alpha_per_rad", "x_cp_m", "x_cg_m", "jyy_kgm2", "mass_kg", "thrust_n",
            "axial_force_n", "f1_hz", "f2_hz", "psi_t_pvp_0", "psi_t_pvp_1", "psi_r_pvp_0",
            "psi_r_pvp_1", "psi_t_ins_0", "psi_t_ins_1", "psi_r_ins_0", "psi_r_ins_1")


def _parameters_at_times(ctx: "ModelContext", t_s, deviations: Mapping[str, float] | None,
                         columns: dict | None = None, build: bool = True
                         ) -> list[ModelParameters]:
    """:meth:`ModelContext.parameters_at_times` (the formulas of :meth:`ModelContext.parameters`
    and :meth:`ModelParameters.perturbed`, on arrays: the same operations element by element,
    the aerodynamic tables through the same ``numpy.interp``)."""
    t = np.asarray(t_s, dtype=float).ravel()
    col = _shared_conditions(ctx, t)
    v, rho, a = col["v_mps"], col["rho_kgpm3"], col["sound_speed_mps"]
    aero = ctx.aero
    s_ref = ctx._const["s_ref_m2"]
    s = np.minimum(np.maximum((t - ctx._t0) / (ctx._t1 - ctx._t0), 0.0), 1.0)
    lin = {k: p[0] + s * (p[1] - p[0]) for k, p in ctx._pairs.items()}
    thrust, x_cg, mass, jyy = col["thrust_n"], col["x_cg_m"], col["mass_kg"], col["jyy_kgm2"]
    d = {k: float((deviations or {}).get(k, 0.0)) for k in _DEVIATION_NAMES}
    perturb = bool(deviations) and any(deviations.values())
    if perturb:
        v = v * (1.0 + d["velocity"])
        rho = rho * (1.0 + d["density"])
    mach = v / a
    q = 0.5 * rho * v * v
    cn_alpha, x_cp = aero.cn_alpha(mach), aero.x_cp(mach)
    axial = q * s_ref * aero.c_a(mach)
    if perturb:
        x_cp = x_cp * (1.0 + d["x_cp"])
        thrust = thrust * (1.0 + d["thrust"])
        x_cg = x_cg * (1.0 + d["x_cg"])
        mass = mass * (1.0 + d["mass"])
        jyy = jyy * (1.0 + d["jyy"])
        lin["f1"] = lin["f1"] * (1.0 + d["bending_frequency_1"])
        lin["f2"] = lin["f2"] * (1.0 + d["bending_frequency_2"])
        s1, s2 = 1.0 + d["psi_mode_1"], 1.0 + d["psi_mode_2"]
        for key in ("tp", "rp", "ti", "ri"):
            lin[key + "1"] = lin[key + "1"] * s1
            lin[key + "2"] = lin[key + "2"] * s2
    arrays = (t, v, q, mach, rho, col["h_m"], a, cn_alpha, x_cp, x_cg, jyy, mass, thrust, axial,
              lin["f1"], lin["f2"], lin["tp1"], lin["tp2"], lin["rp1"], lin["rp2"], lin["ti1"],
              lin["ti2"], lin["ri1"], lin["ri2"])
    if columns is not None:
        columns.update(zip(_VARYING, (np.asarray(c, dtype=float) for c in arrays)))
    if not build:
        return []
    const = ctx._const
    # ModelParameters(**fields) for each entry, built without the frozen dataclass' __init__
    # (one object.__setattr__ per field: ≈ 4 µs, the bulk of a run's 10 001 sets): its
    # instance dict set at once, the fields in the dataclass' order. The same object: the
    # class has no __post_init__ and compares, hashes and prints by its fields
    names = _FIELD_NAMES
    x_pvp, x_ins, zeta = const["x_pvp_m"], const["x_ins_m"], const["zeta"]
    n_mass, n_inertia = const["nozzle_mass_kg"], const["nozzle_inertia_kgm2"]
    n_lever = const["nozzle_lever_m"]
    new, cls, set_attr = object.__new__, ModelParameters, object.__setattr__
    out = []
    for (ts, vv, qq, mm, rr, hh, aa, cn, xp, xg, jj, ms, th, ax, f1, f2, tp1, tp2, rp1,
         rp2, ti1, ti2, ri1, ri2) in zip(*[c.tolist() for c in arrays]):
        p = new(cls)
        set_attr(p, "__dict__", dict(zip(names, (
            ts, vv, qq, mm, rr, hh, aa, s_ref, cn, xp, xg, x_pvp, x_ins, jj, ms, th, ax, f1,
            f2, zeta, n_mass, n_inertia, n_lever, (tp1, tp2), (rp1, rp2), (ti1, ti2),
            (ri1, ri2), aero))))
        out.append(p)
    return out


@lru_cache(maxsize=1)
def default_context() -> ModelContext:
    """The context built from the shipped vehicle data and flight-condition table."""
    return ModelContext()


def model_parameters(t_s: float, context: ModelContext | None = None) -> ModelParameters:
    """Frozen-time model parameters at ``t_s`` (default data sources)."""
    return (context or default_context()).parameters(t_s)


def _check_fields_cover_units() -> None:
    names = {f.name for f in fields(ModelParameters)}
    missing = set(PARAMETER_UNITS) - names
    if missing:  # pragma: no cover - programming error caught at import
        raise AssertionError(f"PARAMETER_UNITS names unknown fields {sorted(missing)}")


_check_fields_cover_units()

_FIELD_NAMES = tuple(f.name for f in fields(ModelParameters))
if _FIELD_NAMES != ("t_s", "v_mps", "q_pa", "mach", "rho_kgpm3", "h_m", "sound_speed_mps",
                    "s_ref_m2", "cn_alpha_per_rad", "x_cp_m", "x_cg_m", "x_pvp_m", "x_ins_m",
                    "jyy_kgm2", "mass_kg", "thrust_n", "axial_force_n", "f1_hz", "f2_hz",
                    "zeta", "nozzle_mass_kg", "nozzle_inertia_kgm2", "nozzle_lever_m",
                    "psi_t_pvp", "psi_r_pvp", "psi_t_ins", "psi_r_ins", "aero"):
    # pragma: no cover - programming error caught at import
    raise AssertionError("_parameters_at_times lists ModelParameters' fields in their order")
