"""The verdict of `vega check` (vega_bags.bagcheck): the console table, the failures, the
controller status counts and the JSON record.

One short in-process flight (thesis scenario, 20.0 … 20.5 s, PD fixture table) is written to a
bag and read back once; faults are injected into the columns of that loaded bag in memory
(tests/bags/check_bag_edits.py), so each piece is exercised on its own.

Independent references: the console text typed out by hand (the health table's columns as
wide as their widest cell, two spaces apart; the title, the status line and the verdict line),
the JSON record's key order and its numbers against the report's own fields (non-finite
numbers as strings, angles in deg in the display fields), the file UTF-8 whatever the locale;
a failed informational requirement line is not a failure.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from check_bag_edits import CMD, DIAG, INS, TRUTH, short_run_bag, _edit, _meta, _take
from vega_bags import bagcheck, bagio


@pytest.fixture(scope="module")
def small():
    """(the in-process run, its bag directory, the loaded bag); flown once per set of inputs
    (tests/bags/cached_bags.py)."""
    return short_run_bag()


def test_verdict_of_the_complete_bag(small):
    run, path, bag = small
    check = bagcheck.check_run_bag(bag)
    assert check.passed and check.exit_code == 0 and check.failures == []
    assert check.status_counts() == {"OK": 25}
    assert check.bag == str(path) and check.metadata == bag.metadata
    assert np.array_equal(check.compute_time_s, np.full(25, 5e-5))
    lines = check.table().splitlines()
    assert lines[0] == (f"bag {path}: scenario thesis, seed {run.result.seed}, git test")
    assert lines[1] == "" and lines[-2] == "" and lines[-1] == "verdict: PASS"
    assert lines[-3] == "controller status: OK 25"
    # the health table: columns as wide as their widest cell (23, 17, 24, 4), two spaces apart
    def row(*cells):
        return "  ".join(c.ljust(w) for c, w in zip(cells, (23, 17, 24, 4, 0))).rstrip()

    head = lines.index(next(x for x in lines if x.startswith("health check")))
    assert lines[head - 1] == ""
    assert lines[head:head + 7] == [
        row("health check", "value", "limit", "pass", "detail"),
        row("metadata", "complete", "run metadata + scenario", "yes", ""),
        row("no NaN/inf", "0", "0", "yes", ""),
        row("no message gaps", "ok", "seq +1", "yes", ""),
        row("no lockstep stalls", "ok", "+10 ms/frame, +20 ms/cmd", "yes", ""),
        row("run complete", "20.000 … 20.500 s", "20.000 … 20.500 s", "yes", ""),
        row("controller compute time", "max 0.05 ms", "≤ 12 ms for ≥ 99 %", "yes",
            "median 50 µs, p99 50 µs, max 50 µs")]
    assert lines[head + 1] == "metadata                 complete           " \
                              "run metadata + scenario   yes"
    assert lines[head + 7] == lines[-3]
    assert check.requirements.table() in check.table()
    assert check.context == bagcheck.run_context(bag) and check.context.t_start_ms == 20000
    again = bagcheck.check_bag(path)
    assert again.to_dict() == check.to_dict()


def test_failures_and_verdict_text(small):
    _, _, bag = small
    drift = bag[TRUTH]["drift_m"].copy()
    drift[20] = -612.5                                     # 20.200 s
    pitch = bag[INS]["pitch_rad"].copy()
    pitch[5] = math.nan
    check = bagcheck.check_run_bag(_edit(_edit(bag, TRUTH, drift_m=drift), INS,
                                         pitch_rad=pitch))
    assert not check.passed and check.exit_code == 1
    assert check.failures == [
        "Lateral control performance z: -612.5 m at 20.200 s exceeds its bound 500 m by "
        "112.5 m",
        "no NaN/inf: /vega/ins pitch_rad not finite at 20.062 s"]
    table = check.table().splitlines()
    assert table[-1] == "verdict: FAIL: " + "; ".join(check.failures)
    row = next(x for x in table if x.startswith("no NaN/inf "))
    assert row.endswith("  NO    /vega/ins pitch_rad not finite at 20.062 s")
    assert next(x for x in table if x.startswith("metadata ")).endswith(" yes")
    d = check.to_dict()
    assert d["passed"] is False and d["exit_code"] == 1 and d["failures"] == check.failures
    # only a health check failed: the requirements still pass
    check = bagcheck.check_run_bag(_edit(bag, INS, pitch_rad=pitch))
    assert check.requirements.passed and not check.passed and check.exit_code == 1
    assert check.failures == ["no NaN/inf: /vega/ins pitch_rad not finite at 20.062 s"]


def test_title_without_run_metadata(small):
    _, path, bag = small
    check = bagcheck.check_run_bag(_meta(bag, META_SCENARIO=None, META_SEED=None,
                                         META_GIT_REVISION=None))
    assert check.table().splitlines()[0] == f"bag {path}: scenario ?, seed ?, git ?"


def test_a_failed_informational_line_is_not_a_failure(small, tmp_path):
    import yaml

    from vega_sim.requirements import default_requirements_path, load_requirements

    _, _, bag = small
    tree = yaml.safe_load(default_requirements_path().read_text())
    tree["q_alpha_objective"]["value"] = [v / 1000.0 for v in tree["q_alpha_objective"]["value"]]
    req = tmp_path / "req.yaml"
    req.write_text(yaml.safe_dump(tree))
    check = bagcheck.check_run_bag(bag, load_requirements(req))
    (info,) = [x for x in check.requirements.informational if x.key == "q_alpha_objective"]
    assert not info.passed and not info.gating
    assert check.passed and check.failures == []


def test_status_counts_by_name(small):
    _, _, bag = small
    status = bag[CMD]["status"].copy()
    status[[1, 2, 3]] = 4                                  # LIMITED
    status[5] = 2                                          # VELOCITY_CLAMPED
    status[6] = 99                                         # not a named status
    check = bagcheck.check_run_bag(_edit(bag, CMD, status=status))
    assert check.status_counts() == {"OK": 20, "VELOCITY_CLAMPED": 1, "LIMITED": 3, "99": 1}
    assert "controller status: OK 20, VELOCITY_CLAMPED 1, LIMITED 3, 99 1" in check.table()
    check = bagcheck.check_run_bag(_take(_take(bag, CMD, 0), DIAG, 0))
    assert check.status_counts() == {}
    assert "controller status: no commands" in check.table()
    assert check.compute_time_s.size == 0
    assert not check.passed and "controller compute time: no /vega/diagnostics messages" in \
        check.failures


def test_to_dict_layout_and_numbers(small, tmp_path):
    _, _, bag = small
    check = bagcheck.check_run_bag(bag)
    d = check.to_dict()
    assert list(d) == ["bag", "passed", "exit_code", "failures", "requirements",
                       "informational", "q_alpha_sensitivity", "thesis_definitions", "health",
                       "controller_status", "metadata"]
    assert d["bag"] == check.bag and d["passed"] is True and d["exit_code"] == 0
    assert d["controller_status"] == {"OK": 25} and d["metadata"] == dict(bag.metadata)
    rep = check.requirements
    for rows, results in ((d["requirements"], rep.results), (d["informational"],
                                                              rep.informational)):
        assert len(rows) == len(results)
        for row, r in zip(rows, results):
            s = r.display_scale
            assert list(row) == [
                "key", "requirement", "metric", "value", "bound", "margin", "unit", "passed",
                "gating", "time_s", "peak_value", "peak_time_s", "peak_bound", "display_unit",
                "value_display", "bound_display", "margin_display", "peak_value_display",
                "thesis_table_5_1_display"]
            assert (row["key"], row["requirement"], row["metric"], row["unit"],
                    row["passed"], row["gating"], row["display_unit"]) == (
                r.key, r.requirement, r.metric, r.unit, r.passed, r.gating, r.display_unit)
            for k, v in (("value", r.value), ("bound", r.bound), ("margin", r.margin),
                         ("time_s", r.time_s), ("peak_value", r.peak_value),
                         ("peak_time_s", r.peak_time_s), ("peak_bound", r.peak_bound),
                         ("value_display", r.value * s), ("bound_display", r.bound * s),
                         ("margin_display", r.margin * s),
                         ("peak_value_display", r.peak_value * s)):
                want = None if v is None else (float(v) if math.isfinite(v) else str(float(v)))
                assert row[k] == want, (r.key, k)
            assert row["thesis_table_5_1_display"] == (
                None if r.thesis is None else float(r.thesis.value * s))
    drift = next(r for r in d["requirements"] if r["key"] == "drift")
    assert drift["unit"] == "m" and drift["bound"] == 500.0 and drift["bound_display"] == 500.0
    qa = next(r for r in d["requirements"] if r["key"] == "q_alpha")
    assert math.isclose(qa["value_display"], math.degrees(qa["value"]), rel_tol=1e-15)
    flip = rep.q_alpha_flip
    sens = d["q_alpha_sensitivity"]
    assert list(sens) == ["alpha_max_deg", "mach_min", "floor_pa_deg", "alpha_flip_deg",
                          "alpha_flip_time_s", "alpha_flip_mach", "floor_flip_pa_deg",
                          "floor_flip_time_s", "alpha_flip_tied_deg", "mach_min_flip",
                          "passed"]
    deg = 180.0 / math.pi
    for k, v in (("alpha_max_deg", flip.alpha_max_rad * deg), ("mach_min", flip.mach_min),
                 ("floor_pa_deg", flip.floor_pa_rad * deg),
                 ("alpha_flip_deg", flip.alpha_flip_rad * deg),
                 ("alpha_flip_time_s", flip.alpha_flip_time_s),
                 ("alpha_flip_mach", flip.alpha_flip_mach),
                 ("floor_flip_pa_deg", flip.floor_flip_pa_rad * deg),
                 ("floor_flip_time_s", flip.floor_flip_time_s),
                 ("alpha_flip_tied_deg", flip.alpha_flip_tied_rad * deg),
                 ("mach_min_flip", flip.mach_min_flip)):
        got = sens[k]
        if isinstance(got, str) or v is None or not math.isfinite(v):
            assert got == (None if v is None else str(float(v))), k
        else:
            assert got == pytest.approx(v, rel=1e-14, abs=0), k
    assert sens["alpha_max_deg"] == pytest.approx(4.0, rel=1e-14) and sens["passed"] is True
    assert d["thesis_definitions"] == {
        "command_peak_rad": float(rep.command_peak_rad),
        "command_signed_integral_rad_s": float(rep.command_signed_integral_rad_s)}
    assert d["health"][0] == {"key": "metadata", "check": "metadata", "value": "complete",
                              "limit": "run metadata + scenario", "passed": True,
                              "detail": "", "margin": None}
    assert d["health"][5]["margin"] == 0.012 - 5e-5
    # the file: indented JSON, non-ASCII kept, one newline at the end
    out = check.write_json(tmp_path / "v.json")
    assert out == tmp_path / "v.json"
    text = out.read_text(encoding="utf-8")
    assert text.endswith("}\n") and not text.endswith("\n\n")
    assert '\n  "bag": ' in text and "≤ 12 ms" in text
    assert json.loads(text) == json.loads(json.dumps(d))
    out = check.write_json(str(tmp_path / "w.json"))
    assert out.read_text(encoding="utf-8") == text


def test_json_file_is_utf8_whatever_the_locale(small, tmp_path):
    """Under the C locale (ASCII) the file is still UTF-8 ("≤" in the limits)."""
    import locale

    _, _, bag = small
    check = bagcheck.check_run_bag(bag)
    old = locale.setlocale(locale.LC_CTYPE)
    try:
        locale.setlocale(locale.LC_CTYPE, "C")
        out = check.write_json(tmp_path / "c.json")
    finally:
        locale.setlocale(locale.LC_CTYPE, old)
    assert "≤ 12 ms".encode() in out.read_bytes()


def test_to_dict_without_a_sensitivity_line(small):
    _, _, bag = small
    check = bagcheck.check_run_bag(bag)
    rep = dataclasses.replace(check.requirements, q_alpha_flip=None)
    assert dataclasses.replace(check, requirements=rep).to_dict()["q_alpha_sensitivity"] is None


def test_num_for_json():
    assert bagcheck._num(None) is None
    assert bagcheck._num(math.nan) == "nan" and bagcheck._num(-math.inf) == "-inf"
    assert bagcheck._num(math.inf) == "inf"
    x = bagcheck._num(np.float32(1.5))
    assert x == 1.5 and type(x) is float
    assert type(bagcheck._num(3)) is float and bagcheck._num(3) == 3.0


def test_check_bag_reads_the_bag(small):
    _, path, bag = small
    a, b = bagcheck.check_bag(path), bagcheck.check_run_bag(bag)
    assert a.health == b.health and a.bag == b.bag == str(path)
    with pytest.raises(bagio.BagError, match="no such file"):
        bagcheck.check_bag(path.parent / "missing")
