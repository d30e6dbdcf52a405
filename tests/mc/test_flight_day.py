"""The flight-day campaign's parts that need no flight: the launch commit criterion's
allowance and limits on hand-made predicted flights, the LCC file's validation, the month of a
sample, the summary's counts, and the command line's refusals."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from vega_cli import cli
from vega_core.errors import BadFile
from vega_signoff import lcc
from vega_signoff.flight_day import sample_month, summarise_flight_day
from vega_sim.requirements import load_requirements

SPEC = load_requirements()
A = SPEC.allowable_pa_rad                       # 240 715.2 Pa·deg in Pa·rad
SETTINGS = lcc.load_lcc()


def test_shipped_lcc_numbers():
    assert SETTINGS.k_sigma == 3.0
    assert SETTINGS.ground_wind_limit_mps == pytest.approx(20 * 1852 / 3600, abs=0.005)
    assert SETTINGS.ground_wind_top_m == 150.0
    assert math.degrees(A) == pytest.approx(240_715.2, abs=0.1)


def test_allowance_hand_case():
    """k σ(h) Q/V: σ linear between 1 m/s at 0 m and 3 m/s at 1 000 m, held beyond."""
    got = lcc.change_allowance_pa_rad(3.0, [0.0, 1000.0], [1.0, 3.0],
                                      h_m=[500.0, 2000.0, 0.0], q_pa=[50_000.0, 10_000.0, 0.0],
                                      v_mps=[500.0, 100.0, 0.0])
    # 3·2·50 000/500 = 600; 3·3·10 000/100 = 900; Q = 0 at rest gives 0 (V floored, no NaN)
    np.testing.assert_allclose(got, [600.0, 900.0, 0.0], rtol=0, atol=1e-9)


def test_ground_wind_reads_the_profile_up_to_the_top():
    alt = [0.0, 100.0, 200.0, 300.0]
    assert lcc.ground_wind_mps(alt, [3.0, -9.0, 1.0, 20.0], 150.0) == 9.0
    # between rows the profile is linear: at 150 m it is the mean of −9 and 21
    assert lcc.ground_wind_mps(alt, [3.0, -9.0, 21.0, 0.0], 150.0) == 6.0 + 3.0


def _predicted(qa_pa_rad=0.0, z_m=0.0, *, n=5, mach=None, q_pa=1000.0, v_mps=100.0):
    """A predicted flight of n frames, constant except where given."""
    full = lambda x: np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy()  # noqa: E731
    return SimpleNamespace(t_ms=np.arange(n) * 1000, q_alpha_pa_rad=full(qa_pa_rad),
                           q_pa=full(q_pa), v_mps=full(v_mps), h_m=full(1000.0),
                           mach=full(2.0 if mach is None else mach), z_m=full(z_m))


CALM = SimpleNamespace(altitude_m=np.array([0.0, 30_000.0]), wind_mps=np.zeros(2))
SIGMA_ALT, SIGMA = np.array([0.0, 30_000.0]), np.array([2.0, 2.0])


def _judge(predicted, measured=CALM, dz=0.0):
    return lcc.evaluate_lcc(predicted, measured, SIGMA_ALT, SIGMA, dz, SETTINGS, SPEC)


def test_load_limit_either_side_includes_the_allowance():
    allowance = 3.0 * 2.0 * 1000.0 / 100.0            # 60 Pa·rad
    below = _judge(_predicted(A - allowance - 1e-6))
    above = _judge(_predicted(A - allowance + 1e-3))
    assert below.go and "load" not in below.reasons
    assert not above.go and above.reasons == ("load",)
    assert above.allowance_pa_deg == pytest.approx(math.degrees(allowance))
    assert above.q_alpha_with_allowance_pa_deg > above.allowable_pa_deg


def test_drift_limit_either_side_includes_its_allowance():
    assert _judge(_predicted(z_m=-299.0), dz=200.0).go
    v = _judge(_predicted(z_m=-300.0), dz=200.0)    # 500 m is not < 500 m
    assert v.reasons == ("drift",) and v.drift_with_allowance_m == 500.0
    assert v.predicted_drift_m == 300.0


def test_low_speed_alpha_judges_the_predicted_flight_without_the_allowance():
    """Below Mach 0.31 the predicted |Qα| itself against §2's floor (the change allowance,
    60 Pa·rad here, is not added: docs/MONTE_CARLO.md §9.2 (b))."""
    floor = SPEC.envelope_definition.floor_pa_rad
    ok = _judge(_predicted(floor, mach=0.2))
    bad = _judge(_predicted(floor * (1 + 1e-9) + 1e-6, mach=0.2))
    assert ok.go and ok.low_speed_ratio == pytest.approx(1.0, abs=1e-12)
    assert bad.reasons == ("low_speed_alpha",) and bad.low_speed_ratio > 1.0
    # the same load above Mach 0.31 is judged by the allowable only
    assert _judge(_predicted(2 * floor, mach=0.5)).go


def test_ground_wind_either_side_of_the_limit():
    limit = SETTINGS.ground_wind_limit_mps
    alt = np.array([0.0, 150.0, 151.0, 30_000.0])
    assert _judge(_predicted(), SimpleNamespace(altitude_m=alt,
                                                wind_mps=np.array([limit, -limit, 50, 50]))).go
    v = _judge(_predicted(), SimpleNamespace(altitude_m=alt,
                                             wind_mps=np.array([0.0, -limit - 0.01, 0, 0])))
    assert v.reasons == ("ground_wind",)


@pytest.mark.parametrize("edit, field", [
    (("value: 3.0", "value: -1"), "wind_change_k_sigma.value"),
    (("unit: m/s", "unit: kt"), "ground_wind.limit_mps.unit"),
    (("method: linear_gaussian", "method: fixed"), "drift_allowance.method"),
    (("value: 500.0", "value: 0.5"), "drift_allowance.node_spacing_m.value"),
    (("value: 30000.0\n    unit: m\n", "value: 30000.0\n    unit: km\n"),
     "drift_allowance.top_m.unit"),
    (("schema_version: 1", "schema_version: 2"), "schema_version"),
    (("  top_m:", "  height_m:"), "ground_wind.height_m"),
])
def test_bad_lcc_file_refused_in_one_line(edit, field):
    text = SETTINGS.text.replace(*edit, 1)
    assert text != SETTINGS.text
    with pytest.raises(BadFile) as exc:
        lcc.parse_lcc(text, "lcc.yaml")
    message = str(exc.value)
    assert message.startswith(f"lcc.yaml: field '{field}'") and "\n" not in message


def test_months_cycle_or_stay():
    assert [sample_month(i, None) for i in (0, 1, 11, 12, 25)] == [1, 2, 12, 1, 2]
    assert {sample_month(i, 7) for i in range(30)} == {7}


def _row(sample, month, go, allowable, envelope=True, stable=True, rate=0.0, failed="",
         reasons="load"):
    return {"sample": sample, "month": month, "lcc_go": go,
            "lcc_reasons": "" if go else reasons, "passed_allowable": allowable,
            "passed_envelope": envelope, "stable": stable, "rate_limited_s": rate,
            "failed_allowable": failed, "max_abs_q_alpha_pa_deg": 1.0,
            "flight_day_verdict": ("scrubbed" if not go else
                                   "pass" if allowable and stable else "fail")}


@pytest.mark.slow
def test_summary_counts_go_samples_scrubs_and_availability():
    rows = [_row(0, 1, True, True), _row(1, 2, True, False, failed="q_alpha_allowable"),
            _row(2, 1, False, False), _row(3, 2, True, True, stable=False, rate=0.7,
                                           failed="stability"),
            _row(4, 1, True, True, envelope=False), _row(5, 2, False, True,
                                                         reasons="drift,ground_wind"),
            _row(6, 2, False, True, reasons="ground_wind")]
    s = summarise_flight_day(rows)
    f = s["flight_day"]
    assert (f["n"], f["passed"], f["failed"], f["scrubbed"]) == (4, 2, 2, 3)
    assert (f["unstable"], f["rate_limited"]) == (1, 1)
    assert f["failed_by_requirement"] == {"q_alpha_allowable": 1, "stability": 1}
    assert f["scrub_reasons"] == {"load": 1, "drift": 1, "ground_wind": 2}
    assert s["availability"] == {"1": pytest.approx(2 / 3), "2": 0.5}
    assert s["availability_design"] == {"1": pytest.approx(2 / 3), "2": 0.75}   # 6 only
    assert s["scrub_reasons_by_month"] == {"1": {"load": 1},
                                           "2": {"drift": 1, "ground_wind": 2}}
    # waiving ground wind frees sample 6 (its only reason), not 5 (drift too)
    assert s["availability_without"] == {"drift": {"1": pytest.approx(2 / 3), "2": 0.5},
                                         "ground_wind": {"1": pytest.approx(2 / 3),
                                                         "2": 0.75},
                                         "load": {"1": 1.0, "2": 0.5}}
    # Clopper–Pearson 2 of 4 at 90 %: Beta⁻¹(0.1; 2, 3) (scipy's binomtest agrees)
    from scipy.stats import binomtest

    assert f["lower_bound_90"] == pytest.approx(
        binomtest(2, 4).proportion_ci(0.8, "exact").low, abs=1e-12)
    d = s["definitions"]
    assert d["envelope_section_2"]["go"]["passed"] == 2            # samples 0 and 3 (unstable) …
    assert d["allowable_section_6"]["all_flown"]["passed"] == 4    # 0, 4, 5 and 6
    assert d["allowable_section_6"]["scrubbed"]["n"] == 3
    assert d["allowable_section_6"]["scrubbed"]["passed"] == 2     # 5 and 6


@pytest.mark.slow
@pytest.mark.parametrize("args, message", [
    (["--runs", "2", "--environment", "thesis-box", "--month", "3"],
     "--month needs --environment flight-day"),
    (["--runs", "2", "--environment", "flight-day", "--lag-s", "-1"],
     "--lag-s -1.0: must be within 0..86400 s"),
])
def test_cli_refuses_flight_day_options_in_one_line(tmp_path, capsys, args, message):
    out = tmp_path / "c"
    assert cli.main(["mc", "run", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert not out.exists()


@pytest.mark.slow
def test_cli_refuses_a_bad_lcc_file_before_anything_starts(tmp_path, capsys):
    bad = tmp_path / "lcc.yaml"
    bad.write_text(SETTINGS.text.replace("value: 10.29", "value: fast"))
    out = tmp_path / "c"
    assert cli.main(["mc", "run", "--runs", "2", "--environment", "flight-day", "--lcc",
                     str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: field 'ground_wind.limit_mps.value'" in err and err.count("\n") == 1, err
    assert not out.exists()
