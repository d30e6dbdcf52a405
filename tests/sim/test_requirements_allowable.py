"""The constant Qα allowable of the flight-day sign-off (docs/REQUIREMENTS.md §6).

The file's number is 4° × the largest dynamic pressure of the nominal trajectory (recomputed
here from flight_conditions.csv, not from the code under test); it is evaluated as an
informational line beside the envelope, ``≤`` at the bound; ``passed_with_allowable`` puts it in
the envelope's place and keeps every other requirement; a file without it gives no line and
None; a bad block is refused in one line naming the field.
"""

import copy
import csv
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from vega_core.errors import BadFile
from vega_sim.requirements import (default_requirements_path, evaluate_requirements,
                                   load_requirements)

D = math.pi / 180.0
SPEC = load_requirements()
A = SPEC.allowable_pa_rad


def _eval(qa, mach, z=None, spec=SPEC):
    t = np.arange(len(qa), dtype=float)
    zero = np.zeros(len(qa))
    return evaluate_requirements(t, np.asarray(qa, float), np.asarray(mach, float),
                                 zero if z is None else np.asarray(z, float), zero, t, zero,
                                 spec=spec)


def test_the_allowable_is_four_degrees_times_the_largest_nominal_dynamic_pressure():
    import vega_model
    path = Path(vega_model.__file__).parent / "data" / "flight_conditions.csv"
    with open(path) as f:
        rows = csv.DictReader(line for line in f if not line.startswith("#"))
        q_max = max(float(r["q_pa"]) for r in rows if float(r["t_s"]) <= 100.0)
    assert q_max == pytest.approx(60178.8, abs=0.1)                    # TRAJECTORY.md
    assert A / D == pytest.approx(4.0 * q_max, abs=0.2)                # 240 715.2 Pa*deg
    assert A / D == pytest.approx(float(np.max(SPEC.envelope_pa_rad)) / D, rel=5e-4)


def test_a_low_speed_load_the_envelope_refuses_is_within_the_allowable():
    """30 kPa·deg at M 0.2: over the envelope's floor (25 770.9), far inside the allowable."""
    r = _eval([0.0, 30000.0 * D, 0.0], [0.1, 0.2, 0.3])
    line = next(x for x in r.informational if x.key == "q_alpha_allowable")
    assert not r["q_alpha"].passed and not r.passed
    assert line.passed and not line.gating and line.time_s == 1.0
    assert line.margin == pytest.approx(A - 30000.0 * D, rel=1e-12)
    assert r.passed_with_allowable is True


def test_at_the_allowable_it_passes_and_just_over_it_fails_at_any_mach():
    at = _eval([0.0, -A, 0.0], [1.5, 1.9, 2.5])
    line = next(x for x in at.informational if x.key == "q_alpha_allowable")
    assert line.margin == 0.0 and line.passed and at.passed_with_allowable is True
    over = _eval([0.0, 0.0, A + 1.0 * D], [0.2, 0.3, 4.0])
    line = next(x for x in over.informational if x.key == "q_alpha_allowable")
    assert not line.passed and line.time_s == 2.0
    assert line.margin == pytest.approx(-1.0 * D, rel=1e-9)
    assert over.passed_with_allowable is False


def test_another_failing_requirement_still_fails_the_allowable_verdict():
    r = _eval([0.0, 1000.0 * D, 0.0], [0.5, 0.6, 0.7], z=[0.0, 600.0, 0.0])
    assert not r["drift"].passed and r.passed_with_allowable is False
    ok = _eval([0.0, 1000.0 * D, 0.0], [0.5, 0.6, 0.7])
    assert ok.passed and ok.passed_with_allowable is True


@pytest.fixture(scope="module")
def raw():
    return yaml.safe_load(default_requirements_path().read_text())


def test_a_file_without_the_allowable_gives_no_line_and_no_verdict(tmp_path, raw):
    tree = copy.deepcopy(raw)
    del tree["q_alpha_allowable"]
    p = tmp_path / "r.yaml"
    p.write_text(yaml.safe_dump(tree))
    spec = load_requirements(p)
    assert spec.allowable_pa_rad is None
    r = _eval([0.0, 1000.0 * D, 0.0], [0.5, 0.6, 0.7], spec=spec)
    assert [x.key for x in r.informational] == ["q_alpha_objective"]
    assert r.passed_with_allowable is None


@pytest.mark.parametrize("edit, match", [
    (lambda t: t["q_alpha_allowable"].__setitem__("value", 0.0),
     r"field 'q_alpha_allowable\.value': must be > 0"),
    (lambda t: t["q_alpha_allowable"].__setitem__("value", -5.0),
     r"field 'q_alpha_allowable\.value': must be > 0"),
    (lambda t: t["q_alpha_allowable"].pop("source"), r"field 'q_alpha_allowable\.source'"),
    (lambda t: t["q_alpha_allowable"].__setitem__("source", "  "),
     r"field 'q_alpha_allowable\.source'"),
    (lambda t: t["q_alpha_allowable"].__setitem__("unit", "m"),
     r"field 'q_alpha_allowable\.unit'"),
    (lambda t: t["q_alpha_allowable"].__setitem__("mach", [0, 1]),
     r"field 'q_alpha_allowable\.mach': unknown key"),
    (lambda t: t.__setitem__("q_alpha_allowable", 240715.2),
     r"field 'q_alpha_allowable': must be a mapping"),
])
def test_a_bad_allowable_is_refused_naming_the_field(tmp_path, raw, edit, match):
    tree = copy.deepcopy(raw)
    edit(tree)
    p = tmp_path / "r.yaml"
    p.write_text(yaml.safe_dump(tree))
    with pytest.raises(BadFile, match=match) as err:
        load_requirements(p)
    assert "\n" not in str(err.value) and str(p) in str(err.value)


def test_the_unit_is_converted(tmp_path, raw):
    tree = copy.deepcopy(raw)
    tree["q_alpha_allowable"].update(value=1000.0, unit="Pa*rad")
    p = tmp_path / "r.yaml"
    p.write_text(yaml.safe_dump(tree))
    assert load_requirements(p).allowable_pa_rad == 1000.0
