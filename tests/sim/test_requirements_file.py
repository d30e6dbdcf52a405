"""The requirement file (docs/REQUIREMENTS.md): what the loader reads and what it refuses.

Independent reference: the shipped YAML read here with PyYAML (not through the module) and
edited field by field; unit conversions by hand (deg → rad = π/180, Pa·deg → Pa·rad). Checked:
every field read back (bounds, sources, provenance, envelope definition, thesis Table 5.1
figures and notes; tables read-only); integer Mach breakpoints; an absent provenance or
definition; each malformed field refused with a message naming it; the smallest accepted
tables and definitions; that evaluation without a spec uses the shipped file and that a
definition edited in the file reaches the Qα sensitivity.
"""

import copy
import math

import numpy as np
import pytest
import yaml

from vega_core.errors import BadFile
from vega_sim.requirements import (default_requirements_path, evaluate_requirements,
                                   load_requirements, q_alpha_flip)

D = math.pi / 180.0


@pytest.fixture(scope="module")
def raw():
    with open(default_requirements_path()) as f:
        return yaml.safe_load(f)


def _load(tmp_path, tree, name="r.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path, load_requirements(path)


def _refused(tmp_path, tree, match):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    with pytest.raises(BadFile, match=match):
        load_requirements(path)


def test_loaded_fields_match_the_raw_file(tmp_path, raw):
    path, spec = _load(tmp_path, raw)
    assert spec.path == str(path)
    for key, file_key in (("q_alpha", "q_alpha_envelope"), ("drift", "drift"),
                          ("drift_rate", "drift_rate"), ("deflection", "deflection"),
                          ("deflection_integral", "deflection_integral")):
        assert spec.sources[key] == raw[file_key]["source"].strip()
    assert spec.sources["q_alpha_objective"] == raw["q_alpha_objective"]["source"].strip()
    assert spec.provenance == raw["q_alpha_envelope"]["provenance"]
    assert spec.drift_m == 500.0 and spec.drift_rate_mps == 15.0
    assert spec.deflection_rad == pytest.approx(6.5 * D, rel=1e-15)
    assert spec.deflection_integral_rad_s == pytest.approx(250.0 * D, rel=1e-15)
    np.testing.assert_allclose(spec.objective_mach, raw["q_alpha_objective"]["mach"])
    np.testing.assert_allclose(spec.objective_pa_rad,
                               np.array(raw["q_alpha_objective"]["value"]) * D, rtol=1e-15)
    d = spec.envelope_definition
    assert d.alpha_max_rad == pytest.approx(4.0 * D, rel=1e-15)
    assert d.mach_min == 0.31
    assert d.floor_pa_rad == pytest.approx(25770.9 * D, rel=1e-15)
    for key, deg_value, note in (("q_alpha", -14554.6, True), ("drift", -0.5002, False),
                                 ("deflection", 2.9281, True)):
        fig = spec.thesis[key]
        factor = D if key != "drift" else 1.0
        assert fig.value == pytest.approx(deg_value * factor, rel=1e-15)
        assert (fig.note == raw["thesis_table_5_1"][key]["note"].strip()) if note \
            else fig.note == ""
    # every table is read-only
    for arr in (spec.envelope_mach, spec.envelope_pa_rad, spec.objective_mach,
                spec.objective_pa_rad):
        assert not arr.flags.writeable


def test_integer_mach_breakpoints_give_a_float_table(tmp_path, raw):
    tree = copy.deepcopy(raw)
    tree["q_alpha_envelope"]["mach"] = list(range(len(tree["q_alpha_envelope"]["value"])))
    _, spec = _load(tmp_path, tree)
    assert spec.envelope_mach.dtype == np.float64
    assert spec.envelope(0.5) == pytest.approx(25770.9 * D)


def test_no_provenance_is_an_empty_mapping_and_no_definition_is_none(tmp_path, raw):
    tree = copy.deepcopy(raw)
    del tree["q_alpha_envelope"]["provenance"]
    del tree["q_alpha_envelope"]["definition"]
    _, spec = _load(tmp_path, tree)
    assert spec.provenance == {} and spec.envelope_definition is None
    t = np.array([0.0, 1.0])
    rep = evaluate_requirements(t, [0.0, 0.0], [0.5, 0.6], [0.0, 0.0], [0.0, 0.0], t,
                                [0.0, 0.0], spec=spec)
    assert rep.q_alpha_flip is None


def test_scalar_deg_values_are_converted_by_multiplying(tmp_path, raw):
    tree = copy.deepcopy(raw)
    tree["deflection"]["value"] = 2.0
    _, spec = _load(tmp_path, tree)
    assert spec.deflection_rad == pytest.approx(2.0 * math.pi / 180.0, rel=1e-15)


@pytest.mark.parametrize("edit, match", [
    (lambda t: t.__setitem__("drift", 500.0), r"field 'drift': must be a mapping"),
    (lambda t: t["drift"].__setitem__("mach", [0, 1]), r"field 'drift\.mach': unknown key"),
    (lambda t: t["drift"].pop("source"), r"field 'drift\.source'"),
    (lambda t: t["drift"].__setitem__("source", "   "), r"field 'drift\.source'"),
    (lambda t: t["drift"].__setitem__("value", 0.0), r"field 'drift\.value': must be > 0"),
    (lambda t: t["q_alpha_envelope"].__setitem__("value", "many"),
     r"'q_alpha_envelope\.value': must be a list of numbers"),
    (lambda t: t["q_alpha_envelope"].__setitem__("value", []),
     r"'q_alpha_envelope\.value': must be a list of numbers"),
    (lambda t: t["q_alpha_envelope"]["value"].__setitem__(3, "x"),
     r"'q_alpha_envelope\.value': must be a list of numbers"),
    (lambda t: t["q_alpha_envelope"]["value"].__setitem__(3, True),
     r"'q_alpha_envelope\.value': must be a list of numbers"),
    (lambda t: t["q_alpha_envelope"]["value"].__setitem__(3, -1.0),
     r"'q_alpha_envelope\.value': must be >= 0"),
    (lambda t: t["q_alpha_envelope"].__setitem__("mach", 5),
     r"'q_alpha_envelope\.mach': must be a list of numbers"),
    (lambda t: t["q_alpha_envelope"]["mach"].__setitem__(3, True),
     r"'q_alpha_envelope\.mach': must be a list of numbers"),
    (lambda t: t["q_alpha_envelope"]["mach"].__setitem__(3, t["q_alpha_envelope"]["mach"][2]),
     r"'q_alpha_envelope\.mach': must increase"),
    (lambda t: t["q_alpha_envelope"]["mach"].__setitem__(0, -0.5),
     r"'q_alpha_envelope\.mach': must increase from >= 0"),
    (lambda t: t["q_alpha_objective"].pop("source"), r"'q_alpha_objective\.source'"),
    (lambda t: t["q_alpha_envelope"]["definition"].__setitem__("mach_min", -0.1),
     r"definition\.mach_min"),
    (lambda t: t["q_alpha_envelope"]["definition"].__setitem__("floor_pa_deg", "high"),
     r"definition\.floor_pa_deg"),
    (lambda t: t["q_alpha_envelope"]["definition"].__setitem__("alpha_max_deg", "4"),
     r"definition\.alpha_max_deg"),
])
def test_refusals_name_the_field(tmp_path, raw, edit, match):
    tree = copy.deepcopy(raw)
    edit(tree)
    _refused(tmp_path, tree, match)


def test_mach_table_of_one_point_refused_two_points_accepted(tmp_path, raw):
    tree = copy.deepcopy(raw)
    env = tree["q_alpha_envelope"]
    env["mach"], env["value"] = [0.0], [100.0]
    _refused(tmp_path, tree, r"'q_alpha_envelope\.mach': must be a list of numbers")
    env["mach"], env["value"] = [0.0, 6.0], [100.0, 200.0]
    _, spec = _load(tmp_path, tree, "ok.yaml")
    assert spec.envelope(3.0) == pytest.approx(150.0 * D)


def test_definition_zero_mach_min_and_floor_are_accepted(tmp_path, raw):
    tree = copy.deepcopy(raw)
    tree["q_alpha_envelope"]["definition"].update(mach_min=0, floor_pa_deg=0)
    _, spec = _load(tmp_path, tree)
    assert spec.envelope_definition.mach_min == 0.0
    assert spec.envelope_definition.floor_pa_rad == 0.0


def test_thesis_note_missing_is_empty(tmp_path, raw):
    tree = copy.deepcopy(raw)
    _, spec = _load(tmp_path, tree)
    assert spec.thesis["drift_rate"].note == ""
    assert spec.thesis["drift_rate"].value == pytest.approx(0.1221, rel=1e-15)
    assert spec.thesis["deflection_integral"].value == pytest.approx(0.4985 * D, rel=1e-15)


def _series(n=5, dt=0.01):
    t = dt * np.arange(n)
    return t


def test_default_spec_is_the_shipped_file():
    t = _series()
    args = (t, np.full(5, 1000.0), np.full(5, 1.0), np.zeros(5), np.zeros(5), t,
            np.full(5, 1.0 * D))
    a = evaluate_requirements(*args)
    b = evaluate_requirements(*args, spec=load_requirements())
    assert a.table() == b.table()
    assert a["deflection"].bound == pytest.approx(6.5 * D)


def test_flip_uses_the_given_spec(tmp_path, raw):
    tree = copy.deepcopy(raw)
    tree["q_alpha_envelope"]["definition"]["alpha_max_deg"] = 2.0
    _, spec = _load(tmp_path, tree)
    t = _series(3)
    rep = evaluate_requirements(t, np.full(3, 1000.0), np.full(3, 1.0), np.zeros(3),
                                np.zeros(3), t, np.zeros(3), spec=spec)
    assert rep.q_alpha_flip.alpha_max_rad == pytest.approx(2.0 * D)
    assert q_alpha_flip(t, np.full(3, 1000.0), np.full(3, 1.0),
                        spec=spec).alpha_max_rad == pytest.approx(2.0 * D)
    assert q_alpha_flip(t, np.full(3, 1000.0),
                        np.full(3, 1.0)).alpha_max_rad == pytest.approx(4.0 * D)
