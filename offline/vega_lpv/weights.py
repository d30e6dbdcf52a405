"""Weight sets of the weighted interconnection M(ρ) (thesis §4.5, Eqs. 4.17–4.26).

A :class:`WeightSet` holds every number of the input and output weights, each field with
its unit and source in the field metadata (:meth:`WeightSet.table`). Two named sets:

* :data:`THESIS` — the text's weights exactly (Eqs. 4.17–4.26, W_w = 3 on the Dryden
  filter, α_max = 3°, the two W_β notches);
* :data:`SHIPPED` — the text's weights with a wind channel that covers the steady wind
  profile (a tightening) and two relaxations (docs/SYNTHESIS_WEIGHTS.md §4), chosen by the
  frozen-point LTI study (:mod:`vega_lpv.frozen_point`) so that the LPV synthesis
  can reach γ ≤ 1.

:data:`SINGLE_RELAXATIONS` lists the one-at-a-time changes to :data:`THESIS` that the study
ranks. Vehicle numbers (sensor noise, bending frequencies, dynamic pressure, wind tables)
are not here: they come from vega_plant at each grid point.

Angles in the thesis' weight equations are written in degrees inside a (π/180 · …)⁻¹;
the fields keep the equations' numbers and say so in their unit (``deg``), so that every
field can be compared with the text directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

__all__ = ["WeightSet", "THESIS", "SHIPPED", "WEIGHT_SETS", "SINGLE_RELAXATIONS",
           "WIND_CHANNELS"]

# Wind channel forms (see WeightSet.wind_channel).
WIND_CHANNELS = ("dryden", "profile")


def _w(default, unit: str, source: str):
    return field(default=default, metadata={"unit": unit, "source": source})


@dataclass(frozen=True)
class WeightSet:
    """All parameters of the weights of M(ρ) (thesis §4.5).

    Every field's unit and source are in ``dataclasses.fields(WeightSet)[i].metadata``;
    the defaults are the thesis' values (Eqs. 4.17–4.26).
    """

    name: str = _w("thesis", "-", "name of the set")
    description: str = _w("the text's weights, thesis Eqs. 4.17-4.26", "-", "one line")
    # --- W_c, command sizes (Eq. 4.17) ---
    command_theta_deg: float = _w(1.0, "deg", "Eq. 4.17: W_θc = π/180 (1° pitch command)")
    command_theta_dot_degps: float = _w(1.0, "deg/s", "Eq. 4.17: W_θ̇c = π/180 (1°/s)")
    command_z_m: float = _w(1.0, "m", "Eq. 4.17: W_zc = 1 (1 m drift command)")
    command_z_dot_mps: float = _w(1.0, "m/s", "Eq. 4.17: W_żc = 1 (1 m/s drift-rate command)")
    # --- W_n, sensor noise (Eq. 4.18) ---
    noise_scale: float = _w(1.0, "1", "Eq. 4.18: W_n = the INS noise of vehicle.yaml "
                                           "(ins.noise_*) times this")
    # --- W_w and the wind filter (§4.5.1, Eq. 2.53) ---
    wind_sigmas: float = _w(3.0, "1", "§4.5.1: W_w = 3 standard deviations")
    wind_channel: str = _w("dryden", "-", "'dryden': W_w × Dryden filter (Eq. 2.53, airspeed form, "
                           "docs/MODEL.md); 'profile': low-pass with DC gain V_w(h) + W_w·σ_w(h) "
                           "(Eq. 2.54 + Table 2.4) and corner V/L_w(h)")
    turbulence_intensity: str = _w("light", "-", "§2.12.5: light turbulence (Table 2.4)")
    wind_floor: float = _w(1e-5, "1", "regularity floor: σ_w(h) ≥ this × max σ_w of Table 2.4, "
                           "so the wind still reaches the drift above 20 km "
                           "(docs/LPV_SYNTHESIS.md §7)")
    # --- W_θe, sensitivity bound (Eqs. 4.19-4.20) ---
    sensitivity_peak: float = _w(3.16, "1", "Eq. 4.20: W_θe = (π/180 · 3.16)⁻¹ (‖S_θ‖ = 10 dB)")
    # --- W_θz, complementary-sensitivity bound (Eq. 4.21) ---
    theta_bandwidth_radps: float = _w(10.0, "rad/s", "Eq. 4.21: ω_θ = 10 rad/s")
    theta_hf_deg: float = _w(0.01, "deg", "Eq. 4.21: h_θ = 0.01 (−40 dB)")
    theta_lf_deg: float = _w(3.16, "deg", "Eq. 4.21: l_θ = 3.16 (10 dB)")
    # --- W_z, W_ż (Eq. 4.22) ---
    z_max_m: float = _w(500.0, "m", "Eq. 4.22 / Table 3.1: |z| < 500 m")
    z_dot_max_mps: float = _w(15.0, "m/s", "Eq. 4.22 / Table 3.1: |ż| < 15 m/s")
    # --- W_Qα (Eq. 4.24) ---
    alpha_max_deg: float = _w(3.0, "deg", "Eq. 4.24: α_max = 3°")
    q_alpha_q_floor_pa: float = _w(0.0, "Pa", "Eq. 4.24 uses Q(ρ); "
                                   "W_Qα = (α_max·max(Q(ρ), this))⁻¹ "
                                   "(0: the thesis' pure α bound)")
    # --- W_β (Eqs. 4.25-4.26) ---
    beta_lf_deg: float = _w(6.5, "deg", "Eq. 4.25: l_u = β_max = 6.5° (Table 3.1)")
    beta_hf_deg: float = _w(0.01, "deg", "Eq. 4.26: h_u = 0.01")
    beta_bandwidth_scale: float = _w(1.0, "1", "Eq. 4.26: ω_u = ω_q1(ρ) (this × ω_q1)")
    notches: bool = _w(True, "-", "Eq. 4.26: two notches at ω_q1(ρ), ω_q2(ρ)")
    notch_numerator_radps: float = _w(0.5, "rad/s", "Eq. 4.26: s² + 0.5 s + ω_qi² (notch depth)")
    notch_denominator_radps: float = _w(70.0, "rad/s", "Eq. 4.26: s² + 70 s + ω_qi² (notch width)")

    def __post_init__(self):
        if self.wind_channel not in WIND_CHANNELS:
            raise ValueError(f"wind_channel must be one of {WIND_CHANNELS}, "
                             f"got {self.wind_channel!r}")
        if self.turbulence_intensity not in ("light", "moderate", "severe"):
            raise ValueError("turbulence_intensity must be 'light', 'moderate' or 'severe', "
                             f"got {self.turbulence_intensity!r}")
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, float) and not (value > 0.0 or (
                    value == 0.0 and f.name == "q_alpha_q_floor_pa")):
                raise ValueError(f"WeightSet.{f.name} must be > 0, got {value!r}")

    def with_changes(self, name: str, description: str, **changes) -> "WeightSet":
        """A copy with some fields changed, renamed (``dataclasses.replace``)."""
        return replace(self, name=name, description=description, **changes)

    def changes_from(self, other: "WeightSet") -> dict[str, tuple]:
        """Fields (other than name/description) that differ: ``{field: (other, self)}``."""
        return {f.name: (getattr(other, f.name), getattr(self, f.name))
                for f in fields(self)
                if f.name not in ("name", "description")
                and getattr(self, f.name) != getattr(other, f.name)}

    @classmethod
    def table(cls) -> list[tuple[str, str, str]]:
        """``(field, unit, source)`` for every weight parameter, in declaration order."""
        return [(f.name, f.metadata["unit"], f.metadata["source"]) for f in fields(cls)
                if f.name not in ("name", "description")]


THESIS = WeightSet()

# One-at-a-time changes to THESIS ranked by the LTI study (label -> field changes).
SINGLE_RELAXATIONS: dict[str, dict] = {
    "θ̇ command 1 → 0.5 °/s": {"command_theta_dot_degps": 0.5},
    "θ command 1 → 0.5 °": {"command_theta_deg": 0.5},
    "z, ż commands 1 → 0.5 m, m/s": {"command_z_m": 0.5, "command_z_dot_mps": 0.5},
    "all commands × 0.5": {"command_theta_deg": 0.5, "command_theta_dot_degps": 0.5,
                           "command_z_m": 0.5, "command_z_dot_mps": 0.5},
    "W_β without notches": {"notches": False},
    "W_β bandwidth × 2": {"beta_bandwidth_scale": 2.0},
    "sensitivity peak 3.16 → 5.62": {"sensitivity_peak": 5.62},
    "α_max 3 → 4 °": {"alpha_max_deg": 4.0},
    "W_Qα with Q floor 40 kPa": {"q_alpha_q_floor_pa": 40.0e3},
    "noise × 2": {"noise_scale": 2.0},
}

SHIPPED = THESIS.with_changes(
    "shipped",
    "thesis weights + profile wind channel, Qα bound floored at 40 kPa, θ̇ command 0.5 °/s "
    "(docs/SYNTHESIS_WEIGHTS.md §4)",
    # tightening: the wind channel covers the steady V_w(h) profile (Eq. 2.54) the nominal
    # scenario flies, plus 3σ of light turbulence — not only the light Dryden turbulence
    wind_channel="profile",
    # the load requirement is a Qα envelope (Table 3.1, Fig. 3.1), not an α bound: α_max = 3°
    # is kept where Q ≥ 40 kPa (t ≈ 26-65 s, transonic to max-Q); at lower Q the Qα bound
    # stays at 3° × 40 kPa = 120 kPa·deg (two thirds of the max-Q bound)
    q_alpha_q_floor_pa=40.0e3,
    # the guidance is open loop in atmospheric flight (thesis §2.2): no attitude-rate
    # commands reach the controller; a 0.5 °/s rate command still covers re-targeting
    command_theta_dot_degps=0.5,
)

WEIGHT_SETS: dict[str, WeightSet] = {w.name: w for w in (THESIS, SHIPPED)}
