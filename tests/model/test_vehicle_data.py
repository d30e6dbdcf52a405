"""The vehicle data file: every field present with unit and source; bad files get one line."""

import math

import pytest
import yaml

from vega_model.vehicle_data import (FIELDS, VehicleDataError, default_vehicle_path,
                                     load_vehicle_data)


def test_shipped_file_loads_in_si():
    data = load_vehicle_data()
    assert data["actuator.position_limit_rad"] == pytest.approx(math.radians(6.5))
    assert data["delays.actuator_s"] == pytest.approx(0.015)
    assert data["wind.dryden.altitude_m"][-1] == 20000.0
    assert data["propulsion.propellant_mass_kg"] == 88000.0
    assert list(data["uncertainty.delay_s"]) == pytest.approx([-0.010, 0.010])
    for key in FIELDS:
        assert data.source(key), f"{key} has no source"


def _tree():
    return yaml.safe_load(default_vehicle_path().read_text(encoding="utf-8"))


def _write(tmp_path, tree):
    path = tmp_path / "vehicle.yaml"
    path.write_text(yaml.safe_dump(tree), encoding="utf-8")
    return path


@pytest.mark.slow
@pytest.mark.parametrize("edit, message", [
    (lambda t: t["geometry"].pop("x_ins_m"), "field 'geometry.x_ins_m' is missing"),
    (lambda t: t["nozzle"]["mass_kg"].pop("source"), "field 'nozzle.mass_kg': missing 'source'"),
    (lambda t: t["nozzle"]["mass_kg"].update(unit="lb"),
     "field 'nozzle.mass_kg': unit 'lb' is not convertible to 'kg'"),
    (lambda t: t["geometry"]["s_ref_m2"].update(value="big"),
     "field 'geometry.s_ref_m2': value must be a number"),
    (lambda t: t["bending"]["mode1"]["frequency_hz"].update(value=[4.7]),
     "field 'bending.mode1.frequency_hz': value must be a list of 2 numbers"),
    (lambda t: t["ins"]["noise_drift_m"].update(value=float("nan")),
     "field 'ins.noise_drift_m': value must be finite"),
    (lambda t: t["wind"]["dryden"]["length_scale_m"].update(value=[1.0, 2.0]),
     "have different lengths"),
    (lambda t: t["wind"]["dryden"]["altitude_m"]["value"].reverse(), "must be strictly increasing"),
    (lambda t: t["geometry"].update(x_pvp_m=0.96), "expected a mapping with value, unit, source"),
])
def test_malformed_field_is_one_line_naming_field_and_file(tmp_path, edit, message):
    tree = _tree()
    edit(tree)
    path = _write(tmp_path, tree)
    with pytest.raises(VehicleDataError) as err:
        load_vehicle_data(path)
    text = str(err.value)
    assert text.startswith(str(path)) and message in text and "\n" not in text


def test_unreadable_and_invalid_yaml(tmp_path):
    with pytest.raises(VehicleDataError, match="cannot read vehicle data"):
        load_vehicle_data(tmp_path / "absent.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("geometry: [unclosed\n", encoding="utf-8")
    with pytest.raises(VehicleDataError, match=r"not valid YAML \(line \d+\)"):
        load_vehicle_data(bad)


def test_unit_conversion(tmp_path):
    tree = _tree()
    tree["nozzle"]["mass_kg"].update(value=1.616, unit="t")
    data = load_vehicle_data(_write(tmp_path, tree))
    assert data["nozzle.mass_kg"] == pytest.approx(1616.0)
    assert data.unit("nozzle.mass_kg") == "t"
