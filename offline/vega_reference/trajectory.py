"""Reference ascent of the VEGA first stage (P80) and the flight-condition table it yields.

A pitch-plane, 3-DOF point-mass simulation over 0-110 s (docs/TRAJECTORY.md):

* **Phases.** On the pad until the lift-off time; a vertical rise until the pitch-over
  start (thesis §2.2: vertical for the first four seconds); a short pitch-over *kick* in
  which the body attitude follows a programmed pitch rate down to an end attitude and holds
  it, the velocity lagging behind (α < 0); from the instant the velocity has turned down to
  that attitude, a **zero-lift gravity turn**: thrust along the velocity, α = 0, which is the
  operating point of the linearised model (thesis §2.10.1, Table 2.2).
* **Forces.** Thrust from a breakpoint table T(t) along the body axis; aerodynamic axial
  and normal force (thesis Eq. 2.13, body axes, :class:`vega_model.aero.Aerodynamics`) with
  US76 density and Mach (:mod:`vega_model.atmosphere`); inverse-square gravity
  g(h) = g_s·(R/(R+h))² over a spherical, non-rotating Earth.
* **Mass.** ṁ = −(T + p_a·A_e)/(Isp_vac·g0): the vacuum thrust T + p_a·A_e over the vacuum
  specific impulse (thesis Table 2.1), i.e. an effective Isp that rises with altitude.
  x_CG and J_yy are tables of the propellant burnt.

Equations of motion (γ flight-path angle above the local horizontal, α = θ − γ, D and L the
aerodynamic drag and lift in wind axes from the body-axis axial force q·S·C_A and normal force
q·S·C_N(α)):

    v̇ = (T cos α − D)/m − g sin γ
    γ̇ = (T sin α + L)/(m v) − (g/v − v/(R+h)) cos γ
    ḣ = v sin γ,  ẋ = v cos γ · R/(R+h)

integrated with a classical fixed-step Runge-Kutta scheme (0.01 s) — deterministic, so the
committed table is reproduced byte for byte by :func:`write_flight_conditions`.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vega_core.errors import BadInput
from vega_model import aero as _aero_module
from vega_model import atmosphere as _atmosphere_module
from vega_model import flight_conditions as _fc_module
from vega_model.aero import Aerodynamics
from vega_model.atmosphere import atmosphere
from vega_model.flight_conditions import COLUMNS, format_table
from vega_model.vehicle_data import VehicleData, default_vehicle_path, load_vehicle_data

__all__ = [
    "AscentModel",
    "OUTPUT_STEP_S",
    "RK4_STEP_S",
    "T_END_S",
    "TrajectoryError",
    "simulate",
    "table_text",
    "write_flight_conditions",
]

T_END_S = 110.0
"""End of the simulated flight [s] (the thesis' thrust and pitch program spans −2...110 s)."""

OUTPUT_STEP_S = 0.1
"""Time step of the flight-condition table [s]."""

_SUBSTEPS = 10
RK4_STEP_S = OUTPUT_STEP_S / _SUBSTEPS
"""Integration step [s]: 0.01 s; halving it changes the velocity by < 1e-4 m/s (a test)."""

_GENERATOR = "vega_reference.trajectory"
_REGENERATE = "vega trajectory --out ros2_ws/src/vega_model/vega_model/data/flight_conditions.csv"


class TrajectoryError(BadInput):
    """The ascent cannot be simulated with the given data, or the table cannot be written."""


@dataclass(frozen=True)
class AscentModel:
    """Every number of the ascent simulation, SI units, from the vehicle data file.

    Field names follow ``vehicle.yaml``; see :meth:`from_vehicle` for the paths.
    """

    thrust_time_s: np.ndarray
    thrust_n: np.ndarray
    isp_vacuum_s: float
    nozzle_exit_area_m2: float
    propellant_mass_kg: float
    liftoff_mass_kg: float
    burnt_kg: np.ndarray
    x_cg_m: np.ndarray
    jyy_kgm2: np.ndarray
    standard_gravity_mps2: float
    surface_gravity_mps2: float
    earth_radius_m: float
    liftoff_time_s: float
    pitchover_start_s: float
    pitchover_rate_radps: float
    pitchover_end_pitch_rad: float
    aero: Aerodynamics

    @classmethod
    def from_vehicle(cls, vehicle: VehicleData) -> "AscentModel":
        """Collect the ``propulsion``, ``mass``, ``trajectory``, ``environment`` and
        ``aerodynamics`` sections of validated vehicle data."""
        return cls(
            thrust_time_s=vehicle["propulsion.thrust_time_s"],
            thrust_n=vehicle["propulsion.thrust_n"],
            isp_vacuum_s=vehicle["propulsion.isp_vacuum_s"],
            nozzle_exit_area_m2=vehicle["propulsion.nozzle_exit_area_m2"],
            propellant_mass_kg=vehicle["propulsion.propellant_mass_kg"],
            liftoff_mass_kg=vehicle["mass.liftoff_mass_kg"],
            burnt_kg=vehicle["mass.propellant_burnt_kg"],
            x_cg_m=vehicle["mass.x_cg_m"],
            jyy_kgm2=vehicle["mass.jyy_kgm2"],
            standard_gravity_mps2=vehicle["environment.standard_gravity_mps2"],
            surface_gravity_mps2=vehicle["environment.surface_gravity_mps2"],
            earth_radius_m=vehicle["environment.earth_radius_m"],
            liftoff_time_s=vehicle["trajectory.liftoff_time_s"],
            pitchover_start_s=vehicle["trajectory.pitchover_start_s"],
            pitchover_rate_radps=vehicle["trajectory.pitchover_rate_radps"],
            pitchover_end_pitch_rad=vehicle["trajectory.pitchover_end_pitch_rad"],
            aero=Aerodynamics(vehicle),
        )


class _Ascent:
    """Right-hand side of the equations of motion; state (v, γ, h, x, m) as floats."""

    def __init__(self, model: AscentModel):
        self.model = model
        self._tt = model.thrust_time_s
        self._tv = model.thrust_n
        self._s = model.aero.s_ref_m2
        self._exhaust = model.isp_vacuum_s * model.standard_gravity_mps2
        self._ae = model.nozzle_exit_area_m2
        self._gs = model.surface_gravity_mps2
        self._r = model.earth_radius_m

    def pitch_program(self, t: float) -> float:
        """Commanded body attitude above the horizontal [rad] (thesis §2.2, Fig. 2.2)."""
        m = self.model
        if t <= m.pitchover_start_s:
            return 0.5 * math.pi
        return max(0.5 * math.pi - m.pitchover_rate_radps * (t - m.pitchover_start_s),
                   m.pitchover_end_pitch_rad)

    def phase(self, t: float) -> tuple[bool, bool, bool]:
        """(on the pad, burning, turning) at time t.

        The integrator evaluates this once per step, at the step's midpoint: a switch
        (ignition, lift-off, pitch-over start) never falls inside a Runge-Kutta step, so the
        scheme keeps its accuracy; switch times are rounded to the 0.01 s step grid (those
        of the vehicle data lie on it).
        """
        m = self.model
        thrust = float(np.interp(t, self._tt, self._tv))
        return t < m.liftoff_time_s, thrust > 0.0, t > m.pitchover_start_s

    def evaluate(self, t: float, y: tuple, phase: tuple[bool, bool, bool]) -> tuple[tuple, dict]:
        """Derivatives of the state and the quantities of the table row at (t, y)."""
        on_pad, burning, turning = phase
        v, gamma, h, _, m = y
        thrust = float(np.interp(t, self._tt, self._tv))
        rho, p, _, a = atmosphere(h)
        mach = v / a
        q = 0.5 * rho * v * v
        g = self._gs * (self._r / (self._r + h)) ** 2
        aero = self.model.aero
        c_a = float(aero.c_a(mach))
        # Attitude: vertical until the pitch-over starts, then the programmed attitude until
        # the velocity has turned down to it (alpha < 0), then the zero-lift gravity turn.
        alpha = min(0.0, self.pitch_program(t) - gamma) if turning else 0.0
        axial = q * self._s * c_a
        normal = q * self._s * float(aero.cn(alpha, mach)) if alpha else 0.0
        ca, sa = math.cos(alpha), math.sin(alpha)
        drag = axial * ca + normal * sa
        lift = normal * ca - axial * sa
        vdot = 0.0 if on_pad else (thrust * ca - drag) / m - g * math.sin(gamma)
        gdot = 0.0
        if turning:
            gdot = ((thrust * sa + lift) / m - (g - v * v / (self._r + h)) * math.cos(gamma)) / v
        mdot = -(thrust + p * self._ae) / self._exhaust if burning else 0.0
        r_ratio = self._r / (self._r + h)
        deriv = (vdot, gdot, v * math.sin(gamma), v * math.cos(gamma) * r_ratio, mdot)
        row = dict(vdot_mps2=vdot, mach=mach, rho_kgpm3=rho, pressure_pa=p, sound_speed_mps=a,
                   q_pa=q, thrust_n=thrust, mass_flow_kgps=-mdot, axial_force_n=axial,
                   c_a=c_a, flight_path_rate_radps=gdot, pitch_rad=gamma + alpha,
                   alpha_rad=alpha, gravity_mps2=g)
        return deriv, row


def _rk4(ascent: _Ascent, t: float, y: tuple, dt: float) -> tuple:
    """One classical Runge-Kutta step, the phase frozen at the step's midpoint."""
    phase = ascent.phase(t + 0.5 * dt)
    k1 = ascent.evaluate(t, y, phase)[0]
    k2 = ascent.evaluate(t + 0.5 * dt, tuple(a + 0.5 * dt * b for a, b in zip(y, k1)), phase)[0]
    k3 = ascent.evaluate(t + 0.5 * dt, tuple(a + 0.5 * dt * b for a, b in zip(y, k2)), phase)[0]
    k4 = ascent.evaluate(t + dt, tuple(a + dt * b for a, b in zip(y, k3)), phase)[0]
    return tuple(a + dt / 6.0 * (b + 2.0 * c + 2.0 * d + e)
                 for a, b, c, d, e in zip(y, k1, k2, k3, k4))


def simulate(model: AscentModel, substeps: int = _SUBSTEPS) -> dict[str, np.ndarray]:
    """Simulate the ascent 0-110 s and tabulate the flight conditions every 0.1 s.

    Parameters
    ----------
    model : AscentModel
        Vehicle, propulsion, aerodynamic and trajectory data.
    substeps : int
        Runge-Kutta steps per table step (default 10, i.e. 0.01 s).

    Returns
    -------
    dict
        One array per name of :data:`vega_model.flight_conditions.COLUMNS`.

    Raises
    ------
    TrajectoryError
        Thrust below weight at lift-off, or more propellant burnt than loaded.
    """
    t_lo = model.liftoff_time_s
    weight = model.liftoff_mass_kg * model.surface_gravity_mps2
    if float(np.interp(t_lo, model.thrust_time_s, model.thrust_n)) <= weight:
        raise TrajectoryError(f"thrust at lift-off (t = {t_lo:g} s) does not exceed the weight")
    ascent = _Ascent(model)
    n_out = int(round(T_END_S / OUTPUT_STEP_S))
    dt = OUTPUT_STEP_S / substeps
    y = (0.0, 0.5 * math.pi, 0.0, 0.0, model.liftoff_mass_kg)
    rows = []
    for k in range(n_out + 1):
        t = k * OUTPUT_STEP_S
        _, row = ascent.evaluate(t, y, ascent.phase(t))
        v, gamma, h, x, m = y
        row.update(t_s=t, v_mps=v, h_m=h, downrange_m=x, mass_kg=m,
                   flight_path_angle_rad=gamma)
        rows.append(row)
        if k == n_out:
            break
        for j in range(substeps):
            y = _rk4(ascent, t + j * dt, y, dt)
    table = {name: np.array([r[name] for r in rows]) for name in rows[0]}
    burnt = model.liftoff_mass_kg - table["mass_kg"]
    if burnt[-1] > model.propellant_mass_kg:
        raise TrajectoryError(f"{burnt[-1]:.0f} kg of propellant burnt by {T_END_S:g} s, "
                              f"more than the {model.propellant_mass_kg:.0f} kg loaded")
    table["x_cg_m"] = np.interp(burnt, model.burnt_kg, model.x_cg_m)
    table["jyy_kgm2"] = np.interp(burnt, model.burnt_kg, model.jyy_kgm2)
    table["x_cp_m"] = model.aero.x_cp(table["mach"])
    table["cn_alpha_per_rad"] = model.aero.cn_alpha(table["mach"])
    return {name: table[name] for name in COLUMNS}


def _sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _sources_sha256() -> str:
    """SHA-256 over the source files that determine the table's numbers."""
    digest = hashlib.sha256()
    for module in (_atmosphere_module, _aero_module, _fc_module):
        digest.update(Path(module.__file__).read_bytes())
    digest.update(Path(__file__).read_bytes())
    return digest.hexdigest()


def table_text(vehicle_path: str | Path | None = None) -> tuple[str, dict[str, np.ndarray]]:
    """Simulate and format the flight-condition table with its provenance header.

    Parameters
    ----------
    vehicle_path : path, optional
        Vehicle data file (default: the one shipped with vega_plant).

    Returns
    -------
    text, columns
        The file text (no timestamp: the same inputs give the same bytes) and the columns.
    """
    path = Path(vehicle_path) if vehicle_path is not None else default_vehicle_path()
    vehicle = load_vehicle_data(vehicle_path)
    columns = simulate(AscentModel.from_vehicle(vehicle))
    provenance = {
        "generator": f"{_GENERATOR} (3-DOF point-mass pitch-plane ascent, RK4 "
                     f"{RK4_STEP_S:g} s; docs/TRAJECTORY.md)",
        "vehicle_yaml_sha256": _sha256_file(path),
        "generator_sources_sha256": _sources_sha256() + " (atmosphere.py, aero.py, "
                                    "flight_conditions.py, trajectory.py)",
        "regenerate": _REGENERATE,
        "units": "SI as named by each column's suffix; angles in rad from the local horizontal",
    }
    return format_table(columns, provenance), columns


def write_flight_conditions(path: str | Path,
                            vehicle_path: str | Path | None = None) -> dict[str, np.ndarray]:
    """Simulate the ascent and write the flight-condition table to ``path``.

    Returns
    -------
    dict
        The columns written (see :func:`simulate`).

    Raises
    ------
    TrajectoryError
        The file cannot be written (one line naming it), or the simulation fails.
    """
    out = Path(path)
    if not out.parent.is_dir():
        raise TrajectoryError(f"{out}: cannot write flight conditions (no directory {out.parent})")
    text, columns = table_text(vehicle_path)
    try:
        out.write_text(text, encoding="utf-8", newline="\n")
    except OSError as exc:
        raise TrajectoryError(f"{out}: cannot write flight conditions ({exc.strerror})") from None
    return columns
