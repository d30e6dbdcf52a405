"""Model parameters from their data sources (``ModelContext.parameters``): the constants taken
from the vehicle data, the bending data interpolated linearly in time between
``bending.t_start_s`` and ``bending.t_end_s`` and held outside (thesis §2.8), the axial force
``Q·S·C_A(M)``, injected data sources used instead of the shipped ones, and the import-time
check that every parameter field has a unit.

Expected values are read from the raw vehicle YAML (yaml.safe_load, not VehicleData) and
interpolated by hand. A fresh :class:`ModelContext` is built in every test (the cached
default context would hide a construction bug from a test run that built it earlier).
"""

import math

import pytest
import yaml

from vega_model import parameters as params_mod
from vega_model.aero import Aerodynamics
from vega_model.flight_conditions import FlightConditions
from vega_model.parameters import ModelContext
from vega_model.vehicle_data import load_vehicle_data

DATA = params_mod.__file__.rsplit("/", 1)[0] + "/data/vehicle.yaml"
KEYS = {"frequency_hz": "f", "psi_t_pvp": "psi_t_pvp", "psi_r_pvp": "psi_r_pvp",
        "psi_t_ins": "psi_t_ins", "psi_r_ins": "psi_r_ins"}


def _raw():
    with open(DATA) as f:
        return yaml.safe_load(f)


@pytest.fixture(scope="module")
def shifted_vehicle(tmp_path_factory):
    """The shipped vehicle data with the bending interval moved to 20..60 s."""
    text = open(DATA).read()
    text = text.replace("t_start_s: {value: 0.0,", "t_start_s: {value: 20.0,", 1)
    text = text.replace("t_end_s: {value: 100.0,", "t_end_s: {value: 60.0,", 1)
    path = tmp_path_factory.mktemp("veh") / "vehicle.yaml"
    path.write_text(text)
    return load_vehicle_data(path)


def _bending(p, mode, key):
    if key == "frequency_hz":
        return getattr(p, f"f{mode}_hz")
    return getattr(p, key)[mode - 1]


@pytest.mark.parametrize("t, s", [(10.0, 0.0), (20.0, 0.0), (30.0, 0.25), (40.0, 0.5),
                                  (60.0, 1.0), (80.0, 1.0)])
def test_bending_data_linear_in_time_between_start_and_end(shifted_vehicle, t, s):
    raw = _raw()["bending"]
    p = ModelContext(vehicle=shifted_vehicle).parameters(t)
    for mode in (1, 2):
        for key in KEYS:
            lo, hi = raw[f"mode{mode}"][key]["value"]
            assert _bending(p, mode, key) == pytest.approx(lo + s * (hi - lo), rel=1e-12,
                                                           abs=1e-15), (mode, key)


def test_shipped_bending_interval_midpoint():
    """Shipped data: 0..100 s, so at 50 s f1 = (4.71 + 5.89)/2 = 5.30 Hz and
    f2 = (10.66 + 13.46)/2 = 12.06 Hz."""
    p = ModelContext().parameters(50.0)
    assert p.f1_hz == pytest.approx(5.30, rel=1e-12)
    assert p.f2_hz == pytest.approx(12.06, rel=1e-12)


def test_constants_come_from_the_vehicle_data():
    raw = _raw()
    p = ModelContext().parameters(40.0)
    assert p.s_ref_m2 == raw["geometry"]["s_ref_m2"]["value"] == 7.14
    assert p.x_pvp_m == raw["geometry"]["x_pvp_m"]["value"]
    assert p.x_ins_m == raw["geometry"]["x_ins_m"]["value"]
    assert p.zeta == raw["bending"]["damping_ratio"]["value"]
    assert p.nozzle_mass_kg == raw["nozzle"]["mass_kg"]["value"]
    assert p.nozzle_inertia_kgm2 == raw["nozzle"]["inertia_about_pivot_kgm2"]["value"]
    assert p.nozzle_lever_m == raw["nozzle"]["cg_behind_pivot_m"]["value"]


@pytest.mark.parametrize("t", [5.0, 40.0, 75.0])
def test_axial_force_is_q_s_ca(t):
    ctx = ModelContext()
    p = ctx.parameters(t)
    assert p.q_pa == pytest.approx(0.5 * p.rho_kgpm3 * p.v_mps ** 2, rel=1e-14)
    assert p.axial_force_n == pytest.approx(p.q_pa * 7.14 * ctx.aero.c_a(p.mach), rel=1e-14)
    assert p.axial_force_n > 0.0


def test_injected_sources_are_used_and_defaults_loaded(shifted_vehicle):
    conditions = FlightConditions.load()
    aero = Aerodynamics(shifted_vehicle)
    ctx = ModelContext(vehicle=shifted_vehicle, conditions=conditions, aero=aero)
    assert ctx.vehicle is shifted_vehicle and ctx.conditions is conditions and ctx.aero is aero
    assert ctx.parameters(40.0).aero is aero
    default = ModelContext()
    assert default.vehicle["bending.t_start_s"] == 0.0
    assert default.vehicle["bending.t_end_s"] == 100.0
    assert isinstance(default.conditions, FlightConditions)
    assert isinstance(default.aero, Aerodynamics)
    # aero built from the given vehicle when not injected
    assert ModelContext(vehicle=shifted_vehicle).aero is not None
    assert math.isfinite(ModelContext(vehicle=shifted_vehicle).parameters(40.0).cn_alpha_per_rad)


def test_field_check_accepts_the_shipped_units_and_refuses_an_unknown_name(monkeypatch):
    params_mod._check_fields_cover_units()
    monkeypatch.setitem(params_mod.PARAMETER_UNITS, "no_such_field", "m")
    with pytest.raises(AssertionError, match="no_such_field"):
        params_mod._check_fields_cover_units()


def test_injected_flight_conditions_are_the_ones_used(tmp_path):
    """A table cut after its first 101 data rows ends earlier than the shipped one: a context
    given it reports that end time, and clamps to it (the shipped table ends later)."""
    lines = open(params_mod.__file__.rsplit("/", 1)[0] + "/data/flight_conditions.csv").readlines()
    header = [ln for ln in lines if ln.startswith("#")]
    data = [ln for ln in lines if not ln.startswith("#")]
    cut = tmp_path / "fc.csv"
    cut.write_text("".join(header + data[:102]))      # column names + 101 rows
    short = FlightConditions.load(cut)
    t_end = float(data[101].split(",", 1)[0])
    ctx = ModelContext(conditions=short)
    assert ctx.conditions is short
    assert ctx.time_range_s[1] == t_end < ModelContext().time_range_s[1]
    assert ctx.parameters(t_end + 10.0).v_mps == ctx.parameters(t_end).v_mps
