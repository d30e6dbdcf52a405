"""Every parameter of the uncertainty set, applied, against a hand-computed perturbed vehicle.

The set (thesis Table 2.3, §2.12.3, §2.12.4; vega_model.uncertainty): eleven model-parameter
deviations applied by :meth:`ModelParameters.perturbed` (relative: x = x⁰(1 + δ)), the TVC
bandwidth (``ActuatorParams.from_vehicle(bandwidth_scale = 1 + δ)``) and the delay (seconds
added to the actuator latency, ``LoopTiming.from_vehicle``).

Expectations are written from the nominal parameters by hand, with the consequences each
deviation must carry (docstring of ``perturbed``): a velocity deviation changes v, Mach
(M = v/a, a unchanged), Q = ½ρv² (× (1 + δ)²) and every Mach-dependent coefficient (C_Nα, x_CP,
axial force Q·S·C_A); a density deviation changes ρ and Q (× (1 + δ)) and the axial force, not
Mach; a position deviation moves the position measured from the base, so the lever arms
x_CP − x_CG, x_CG − x_PVP, x_INS − x_CG follow. Every other field must stay bit-identical.
Both signs of every deviation (the set's own bounds) are checked, and the rows of the linear
model (docs/MODEL.md §3) are recomputed by hand from the expected parameters.

The shipped normal-force tables are flat in Mach, so a run with a linear-in-Mach aerodynamic
model (hand formulas) checks that C_Nα and x_CP really follow the perturbed Mach.
"""

import dataclasses
import math

import numpy as np
import pytest

from vega_model.dynamics import linear_model
from vega_model.parameters import ModelParameters, default_context
from vega_model.uncertainty import UncertaintySet

T_S = 40.0                    # Mach 1.51: on a sloping segment of the C_A(M) table
MODEL_NAMES = ("thrust", "velocity", "density", "x_cp", "x_cg", "mass", "jyy",
               "bending_frequency_1", "bending_frequency_2", "psi_mode_1", "psi_mode_2")
PSI = ("psi_t_pvp", "psi_r_pvp", "psi_t_ins", "psi_r_ins")
FIELDS = tuple(f.name for f in dataclasses.fields(ModelParameters) if f.name != "aero")


class LinearAero:
    """C_Nα = 1.8 + 0.25 M, x_CP = 17 + 0.9 M, C_A = 0.15 + 0.07 M (hand-checkable)."""

    def cn_alpha(self, m):
        return 1.8 + 0.25 * m

    def x_cp(self, m):
        return 17.0 + 0.9 * m

    def c_a(self, m):
        return 0.15 + 0.07 * m


@pytest.fixture(scope="module")
def uset():
    return UncertaintySet.from_vehicle(default_context().vehicle)


@pytest.fixture(scope="module")
def nominal():
    return default_context().parameters(T_S)


@pytest.fixture(scope="module")
def nominal_linear_aero(nominal):
    aero = LinearAero()
    m = nominal.mach
    return dataclasses.replace(
        nominal, aero=aero, cn_alpha_per_rad=aero.cn_alpha(m), x_cp_m=aero.x_cp(m),
        axial_force_n=nominal.q_pa * nominal.s_ref_m2 * aero.c_a(m))


def _c_a_table(mach):
    """The shipped C_A(M) (vehicle.yaml aerodynamics.axial), interpolated here."""
    v = default_context().vehicle
    return float(np.interp(mach, v["aerodynamics.axial.mach"], v["aerodynamics.axial.c_a"]))


def _expected(p0, dev, c_a, cn_alpha=None, x_cp=None):
    """Hand expectation: dict field -> value, from the nominal p0 and the deviations."""
    e = {name: getattr(p0, name) for name in FIELDS}
    d = {n: dev.get(n, 0.0) for n in MODEL_NAMES}
    kv, kr = 1.0 + d["velocity"], 1.0 + d["density"]
    e["v_mps"] = p0.v_mps * kv
    e["mach"] = p0.mach * kv                                   # a (altitude) unchanged
    e["rho_kgpm3"] = p0.rho_kgpm3 * kr
    e["q_pa"] = p0.q_pa * kr * kv ** 2                         # Q = ½ρv²
    e["axial_force_n"] = e["q_pa"] * p0.s_ref_m2 * c_a(e["mach"])
    if cn_alpha is not None:                                   # Mach-dependent normal force
        e["cn_alpha_per_rad"] = cn_alpha(e["mach"])
    base_x_cp = x_cp(e["mach"]) if x_cp is not None else p0.x_cp_m
    e["x_cp_m"] = base_x_cp * (1.0 + d["x_cp"])
    e["x_cg_m"] = p0.x_cg_m * (1.0 + d["x_cg"])
    e["thrust_n"] = p0.thrust_n * (1.0 + d["thrust"])
    e["mass_kg"] = p0.mass_kg * (1.0 + d["mass"])
    e["jyy_kgm2"] = p0.jyy_kgm2 * (1.0 + d["jyy"])
    e["f1_hz"] = p0.f1_hz * (1.0 + d["bending_frequency_1"])
    e["f2_hz"] = p0.f2_hz * (1.0 + d["bending_frequency_2"])
    for name in PSI:
        a, b = getattr(p0, name)
        e[name] = (a * (1.0 + d["psi_mode_1"]), b * (1.0 + d["psi_mode_2"]))
    return e


def _assert_fields(p, expected, what):
    for name in FIELDS:
        got, want = getattr(p, name), expected[name]
        if isinstance(want, tuple):
            assert got == pytest.approx(want, rel=1e-12, abs=0.0), f"{what}: {name}"
        elif want == 0.0:
            assert got == 0.0, f"{what}: {name}"
        else:
            assert got == pytest.approx(want, rel=1e-12), f"{what}: {name}"


def _cases(uset_bounds):
    return [(name, value) for name in MODEL_NAMES for value in uset_bounds[name]]


# the set's bounds (thesis Table 2.3); test_uncertainty.py checks them against vehicle.yaml
BOUNDS = {"thrust": (-0.10, 0.10), "velocity": (-0.10, 0.10), "density": (-0.10, 0.10),
          "x_cp": (-0.10, 0.10), "x_cg": (-0.02, 0.02), "mass": (-0.02, 0.02),
          "jyy": (-0.02, 0.02), "bending_frequency_1": (-0.20, 0.15),
          "bending_frequency_2": (-0.25, 0.20), "psi_mode_1": (-0.40, 0.30),
          "psi_mode_2": (-0.50, 0.50)}


def test_the_model_deviations_are_those_of_the_set(uset):
    """Every relative deviation of the set is a model-parameter one or the actuator's; the
    absolute one is the delay: nothing in the set is applied nowhere."""
    assert set(uset.names) == set(MODEL_NAMES) | {"actuator", "delay_s"}
    for name in MODEL_NAMES:
        assert (uset[name].lower, uset[name].upper) == pytest.approx(BOUNDS[name], abs=1e-15)


@pytest.mark.parametrize("name, value", _cases(BOUNDS))
def test_each_deviation_alone(nominal, name, value):
    """One deviation at one bound of the set: every field of the perturbed parameters equals
    the hand expectation (the rest unchanged), shipped aerodynamics."""
    p = nominal.perturbed({name: value})
    _assert_fields(p, _expected(nominal, {name: value}, _c_a_table), f"{name}={value}")


@pytest.mark.parametrize("name, value", _cases(BOUNDS))
def test_each_deviation_alone_mach_dependent_aero(nominal_linear_aero, name, value):
    """Same with C_Nα(M), x_CP(M), C_A(M) linear in Mach: a velocity deviation must move all
    three (hand formulas at M⁰(1 + δ)); x_CP's own deviation multiplies x_CP(M)."""
    p0 = nominal_linear_aero
    aero = LinearAero()
    p = p0.perturbed({name: value})
    _assert_fields(p, _expected(p0, {name: value}, aero.c_a, aero.cn_alpha, aero.x_cp),
                   f"{name}={value}")


def test_hand_numbers_for_velocity_and_density(nominal):
    """The two deviations whose consequences are easiest to get wrong, in plain numbers:
    +10 % velocity → Q × 1.21 and Mach × 1.1; −10 % density → Q × 0.9, Mach unchanged."""
    fast = nominal.perturbed({"velocity": 0.10})
    assert fast.q_pa == pytest.approx(1.21 * nominal.q_pa, rel=1e-12)
    assert fast.q_pa == pytest.approx(0.5 * nominal.rho_kgpm3 * (1.1 * nominal.v_mps) ** 2,
                                      rel=1e-12)
    assert fast.mach == pytest.approx(1.1 * nominal.v_mps / nominal.sound_speed_mps, rel=1e-12)
    assert fast.axial_force_n == pytest.approx(
        1.21 * nominal.q_pa * 7.14 * _c_a_table(1.1 * nominal.mach), rel=1e-12)
    assert fast.axial_force_n > 1.21 * nominal.axial_force_n * 0.9       # C_A(M) moved
    thin = nominal.perturbed({"density": -0.10})
    assert thin.q_pa == pytest.approx(0.9 * nominal.q_pa, rel=1e-12)
    assert thin.mach == nominal.mach
    assert thin.axial_force_n == pytest.approx(0.9 * nominal.axial_force_n, rel=1e-12)
    assert thin.normal_force_slope_n == pytest.approx(0.9 * nominal.normal_force_slope_n,
                                                      rel=1e-12)


@pytest.mark.parametrize("sign", [-1.0, 1.0])
def test_lever_arms_follow_the_positions(nominal, sign):
    """x_CG × (1 + δ) moves the CG forward for δ > 0 (positions from the base): the CP arm
    shrinks, the pivot arm and the INS arm change by the same amount (hand numbers)."""
    dx = sign * 0.02 * nominal.x_cg_m
    p = nominal.perturbed({"x_cg": sign * 0.02})
    assert p.x_cg_m == pytest.approx(nominal.x_cg_m + dx, rel=1e-12)
    assert p.l_cp_m == pytest.approx(nominal.x_cp_m - nominal.x_cg_m - dx, rel=1e-12)
    assert p.l_cg_pvp_m == pytest.approx(nominal.x_cg_m - nominal.x_pvp_m + dx, rel=1e-12)
    assert p.l_ins_m == pytest.approx(nominal.x_ins_m - nominal.x_cg_m - dx, rel=1e-12)
    assert (p.l_cp_m - nominal.l_cp_m) * sign < 0
    dcp = sign * 0.10 * nominal.x_cp_m
    q = nominal.perturbed({"x_cp": sign * 0.10})
    assert q.l_cp_m == pytest.approx(nominal.l_cp_m + dcp, rel=1e-12)
    assert q.l_cg_pvp_m == nominal.l_cg_pvp_m and q.l_ins_m == nominal.l_ins_m


@pytest.mark.parametrize("corner", ["lower", "upper", "mixed"])
def test_all_deviations_at_once(nominal, nominal_linear_aero, uset, corner):
    """A corner of the set (every deviation at once): the hand expectation composes
    (Q = Q⁰(1 + δρ)(1 + δv)², x_CP = x_CP(M)(1 + δ_xcp), ...); the actuator and delay
    deviations are for other models and change nothing here."""
    if corner == "mixed":
        dev = {n: (uset[n].lower if i % 2 else uset[n].upper) for i, n in enumerate(uset.names)}
    else:
        dev = {n: getattr(uset[n], corner) for n in uset.names}
    p = nominal.perturbed(dev)
    _assert_fields(p, _expected(nominal, dev, _c_a_table), corner)
    aero = LinearAero()
    q = nominal_linear_aero.perturbed(dev)
    _assert_fields(q, _expected(nominal_linear_aero, dev, aero.c_a, aero.cn_alpha, aero.x_cp),
                   corner)


def test_nominal_and_other_models_deviations_change_nothing(nominal):
    for dev in ({}, {n: 0.0 for n in MODEL_NAMES}, {"actuator": 0.1, "delay_s": -0.01}):
        p = nominal.perturbed(dev)
        _assert_fields(p, {n: getattr(nominal, n) for n in FIELDS}, str(dev))


def _hand_rows(e):
    """Entries of the linear model (docs/MODEL.md §3) from expected parameters ``e``."""
    T, m, J = e["thrust_n"], e["mass_kg"], e["jyy_kgm2"]
    n_a = e["q_pa"] * e["s_ref_m2"] * e["cn_alpha_per_rad"]
    n_v = n_a / e["v_mps"]
    d = e["x_cp_m"] - e["x_cg_m"]
    lc = e["x_cg_m"] - e["x_pvp_m"]
    li = e["x_ins_m"] - e["x_cg_m"]
    tp, rp = e["psi_t_pvp"], e["psi_r_pvp"]
    w1, w2 = 2 * math.pi * e["f1_hz"], 2 * math.pi * e["f2_hz"]
    return {
        ("A", 1, 0): n_a * d / J,                      # aerodynamic (de)stabilising moment
        ("A", 1, 1): -n_v * d * d / J,                 # aerodynamic pitch damping
        ("A", 1, 4): T * (tp[0] + lc * rp[0]) / J,
        ("A", 1, 5): T * (tp[1] + lc * rp[1]) / J,
        ("B", 1, 0): -T * lc / J,                      # TVC moment
        ("A", 3, 0): -n_a / m - (T - e["axial_force_n"]) / m,
        ("B", 3, 0): -T / m,
        ("A", 6, 4): -w1 * w1,
        ("A", 7, 5): -w2 * w2,
        ("A", 6, 6): -2 * e["zeta"] * w1,
        ("B", 6, 0): -T * tp[0],
        ("B", 7, 0): -T * tp[1],
        ("C", 0, 0): e["q_pa"],
        ("C", 1, 4): -e["psi_r_ins"][0],
        ("C", 3, 0): -li,
        ("C", 3, 5): e["psi_t_ins"][1],
    }


@pytest.mark.parametrize("name, value", _cases(BOUNDS))
def test_linear_model_of_the_perturbed_vehicle(nominal, name, value):
    """The linear model built from the perturbed parameters has the entries the hand
    formulas give for the hand-expected vehicle (the deviation reaches the dynamics)."""
    A, B, C, _ = linear_model(nominal.perturbed({name: value}))
    mats = {"A": A, "B": B, "C": C}
    rows = _hand_rows(_expected(nominal, {name: value}, _c_a_table))
    nominal_rows = _hand_rows(_expected(nominal, {}, _c_a_table))
    changed = 0
    for (m, i, j), want in rows.items():
        assert mats[m][i, j] == pytest.approx(want, rel=1e-11), f"{name}={value}: {m}[{i},{j}]"
        changed += not math.isclose(want, nominal_rows[(m, i, j)], rel_tol=1e-9)
    assert changed >= 1, f"{name} changes no entry checked here"


# ----------------------------------------------------------------------------- simulation wiring
@pytest.mark.parametrize("dev", [{"x_cg": -0.02}, {"velocity": 0.1, "density": -0.1},
                                 {"psi_mode_2": 0.5}])
def test_truth_side_parameters_use_the_deviations(nominal, dev):
    """vega_sim.plant_step.parameters_at (the plant, wind and INS evaluation) applies them."""
    from vega_sim.plant_step import parameters_at

    p = parameters_at(default_context(), int(T_S * 1000), dev)
    _assert_fields(p, _expected(nominal, dev, _c_a_table), str(dev))
    same = parameters_at(default_context(), int(T_S * 1000), {"actuator": 0.0})
    _assert_fields(same, {n: getattr(nominal, n) for n in FIELDS}, "zero")


@pytest.mark.parametrize("delta", [-0.10, -0.05, 0.05, 0.10])
def test_actuator_bandwidth_deviation(delta):
    """TVC ±10 % (thesis §2.12.3): ω_n × (1 + δ); ζ and the limits unchanged. The linear
    actuator's poles have modulus ω_n (hand: |λ|² = ω_n² for ζ < 1)."""
    from vega_model.actuator import ActuatorParams, linear_actuator_ss

    vehicle = default_context().vehicle
    nominal = ActuatorParams.from_vehicle(vehicle)
    p = ActuatorParams.from_vehicle(vehicle, bandwidth_scale=1.0 + delta)
    assert nominal.wn_radps == 100.0 and nominal.zeta == 0.5
    assert p.wn_radps == pytest.approx(100.0 * (1.0 + delta), rel=1e-15)
    assert (p.zeta, p.position_limit_rad, p.rate_limit_radps, p.dt_s) == (
        nominal.zeta, nominal.position_limit_rad, nominal.rate_limit_radps, nominal.dt_s)
    A, *_ = linear_actuator_ss(p)
    lam = np.linalg.eigvals(A)
    assert np.abs(lam) == pytest.approx([100.0 * (1.0 + delta)] * 2, rel=1e-12)
    assert -lam.real == pytest.approx([0.5 * 100.0 * (1.0 + delta)] * 2, rel=1e-12)


@pytest.mark.parametrize("delta_s, actuator_ms", [(-0.010, 5), (-0.003, 12), (0.0, 15),
                                                  (0.004, 19), (0.010, 25)])
def test_delay_deviation(delta_s, actuator_ms):
    """Total delay 39 ms ± 10 ms (thesis §2.12.4), the deviation added to the actuator
    latency (12 + 12 + 15 ms nominal)."""
    from vega_bus.timing import LoopTiming

    t = LoopTiming.from_vehicle(default_context().vehicle, delta_s)
    assert t.actuator_latency_ms == actuator_ms
    assert (t.sensor_latency_ms, t.computing_latency_ms) == (12, 12)
    assert t.total_latency_ms == 39 + round(delta_s * 1000)


@pytest.mark.parametrize("actuator, delay_s", [(-0.1, 0.01), (0.1, -0.01)])
def test_scenario_wiring_of_actuator_and_delay(monkeypatch, actuator, delay_s):
    """A dispersed scenario's actuator node gets ω_n × (1 + δ) and the loop timing with the
    delay deviation (what make_actuator hands to the actuator step, recorded)."""
    from vega_sim import assembly
    from vega_sim.scenario import load_scenario

    scenario = dataclasses.replace(load_scenario("thesis"),
                                   uncertainty=(("actuator", actuator), ("delay_s", delay_s)))
    assert assembly.loop_timing(scenario).actuator_latency_ms == 15 + round(delay_s * 1000)
    seen = []
    monkeypatch.setattr(assembly, "ActuatorStep", lambda params, timing, *a: seen.append(
        (params, timing)))
    assembly.make_actuator(scenario)
    (params, timing), = seen
    assert params.wn_radps == pytest.approx(100.0 * (1.0 + actuator), rel=1e-15)
    assert params.zeta == 0.5
    assert timing.actuator_latency_ms == 15 + round(delay_s * 1000)
