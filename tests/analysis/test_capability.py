"""The vehicle's wind capability (vega_analysis.capability, ``vega wind capability``): the
bisection against hand thresholds, the wind-change profile, a band change of 0 passing and
one far over failing, a reproducible result, and the command's files and refusals."""

import json
import math

import numpy as np
import pytest

from cli_errors import assert_refused
from vega_analysis.capability import (Bisection, Search, _fly_group, _scenario,
                                      band_window, bisect_largest_passing, calm_profile,
                                      capability, check_amplitudes, jet_window,
                                      month_mean_profile)
from vega_campaign.wind_environment import load_site
from vega_cli import cli
from vega_gnc.controller_table import default_table_path
from vega_model.wind import WindTable


@pytest.mark.parametrize("threshold", [0.0, 0.1, 0.25, 7.3, 23.75, 59.9, 60.0, 75.0])
def test_bisection_finds_a_known_threshold_of_a_monotone_function(threshold):
    calls = []

    def passes(x):
        calls.append(x)
        return x <= threshold

    largest, failing, n = bisect_largest_passing(passes, 60.0, 0.25)
    want = min(math.floor(threshold / 0.25) * 0.25, 60.0)
    assert largest == want
    assert failing == (None if threshold >= 60.0 else want + 0.25)
    assert n == len(calls) <= 9            # the cap, then log2(240) = 8 halvings at most
    assert all(x == round(x / 0.25) * 0.25 for x in calls)


def test_bisection_refuses_a_bad_grid_and_an_update_after_the_end():
    with pytest.raises(ValueError):
        Bisection(1.0, 2.0)
    b = Bisection(1.0, 1.0)
    b.update(True)
    assert b.done and b.largest_passing == 1.0 and b.candidate() is None
    with pytest.raises(RuntimeError):
        b.update(False)


def test_windows_by_hand():
    h = np.array([1000.0, 2000.0, 2500.0, 3000.0, 4000.0, 4100.0])
    assert np.allclose(band_window(h, 2000.0, 4000.0), [0, 0, 0.5, 1, 0, 0], atol=1e-15)
    assert np.allclose(jet_window(h, 3000.0, 1000.0), [0, 0, 0.5, 1, 0, 0], atol=1e-15)


def test_band_change_is_confined_to_its_band_and_peaks_at_its_centre():
    h0 = np.arange(0.0, 30_001.0, 500.0)
    base = WindTable(h0, 5.0 + h0 / 2_000.0, "a ramp")       # m/s; not zero, not on 100 m
    s = Search("wind_change", 10_000.0, 12_000.0, -1, Bisection(60.0, 0.25))
    flown = s.profile(base, 20.0)
    h = np.asarray(flown.altitude_m)
    diff = np.asarray(flown.wind_mps) - np.interp(h, base.altitude_m, base.wind_mps)
    assert np.all(diff[(h <= 10_000.0) | (h >= 12_000.0)] == pytest.approx(0.0, abs=1e-12))
    assert diff[h == 11_000.0] == pytest.approx(-20.0)
    assert diff.min() == pytest.approx(-20.0) and diff.max() <= 1e-12


def test_amplitudes_beyond_the_tabulated_wind_bound_are_refused():
    h = np.array([0.0, 10_000.0, 12_000.0, 30_000.0])
    base = WindTable(h, [0.0, 30.0, 0.0, 0.0], "hand")     # 30 m/s at 10 km, calm above 12
    check_amplitudes(base, ((20, 25),), (16,), 60.0, 100.0)   # calm at 16 ± 3 km
    with pytest.raises(ValueError, match="--upper-cap-mps 100: the measured profile"):
        check_amplitudes(base, (), (12,), 60.0, 100.0)        # 30 m/s at 10 km: 130 > 120
    with pytest.raises(ValueError, match="--cap-mps 91: "):
        check_amplitudes(base, ((9.5, 10.5),), (), 91.0, 100.0)


@pytest.mark.slow
def test_a_band_change_of_zero_passes_and_one_far_over_fails(tmp_path):
    from vega_reference.rebias import rebias_reference, write_rebiased_reference

    base = calm_profile()
    ref = tmp_path / "measured.npz"
    write_rebiased_reference(ref, rebias_reference(base.altitude_m, base.wind_mps),
                             base.altitude_m, base.wind_mps)
    from vega_sim.scenario import load_scenario

    nominal = load_scenario("nominal")
    s = Search("wind_change", 10_000.0, 12_000.0, 1, Bisection(60.0, 0.25))
    flights = [_scenario(nominal, f"c{a}", s.profile(base, a), str(ref)) for a in (0.0, 60.0)]
    (zero, far), _ = _fly_group(flights, str(default_table_path()))
    assert zero.passed and zero.failed == () and zero.max_abs_q_alpha_pa_deg < 1.0
    assert not far.passed and far.failed[0] == "q_alpha_allowable"
    assert far.max_abs_q_alpha_pa_deg > 240_715.2        # docs/REQUIREMENTS.md §6


@pytest.mark.slow
def test_capability_is_reproducible():
    kwargs = dict(bands_km=((10, 12),), jet_centres_km=(), cap_mps=40.0, resolution_mps=10.0)
    one = capability(default_table_path(), **kwargs, workers=1)
    again = capability(default_table_path(), **kwargs, workers=1)
    assert one.rows == again.rows and one.base_flights == again.base_flights
    plus, minus = one.rows
    # calm measured profile: the model is symmetric in z, so both signs give the same answer
    assert plus["max_mps"] == minus["max_mps"] and 0 < plus["max_mps"] < 40.0
    assert plus["fail_at_mps"] == plus["max_mps"] + 10.0
    assert plus["binding"] == "q_alpha_allowable"


@pytest.mark.slow
def test_cli_writes_its_files(tmp_path, capsys):
    out = tmp_path / "cap"
    assert cli.main(["wind", "capability", "--out", str(out), "--workers", "1",
                     "--bands", "10-12", "--jets", "11", "--cap-mps", "40",
                     "--upper-cap-mps", "40", "--resolution-mps", "10"]) == 0
    printed = capsys.readouterr().out
    assert "vega wind: round 1:" in printed and "wind_change 10-12 km +:" in printed
    data = json.loads((out / "capability.json").read_text())
    assert data["base"]["kind"] == "calm" and data["settings"]["cap_mps"] == 40.0
    kinds = [r["kind"] for r in data["rows"]]
    assert kinds == ["wind_change"] * 2 + ["upper_wind_rebiased"] * 2 + [
        "upper_wind_default"] * 2 + ["upper_wind_none"] * 2
    lines = (out / "capability.csv").read_text().splitlines()
    assert lines[0].startswith("kind,lo_km,hi_km,centre_km,sign,max_mps") and len(lines) == 9
    for name in ("capability_wind_change.png", "capability_upper_wind.png"):
        assert (out / name).stat().st_size > 10_000


@pytest.mark.parametrize("args, message", [
    (["--month", "13"], "argument --month: must be within 1..12, got '13'"),
    (["--site", "x.yaml"], "--site FILE needs --month M"),
    (["--workers", "0"], "argument --workers: must be within 1..64, got '0'"),
    (["--bands", "4-2"], "argument --bands: must be LO-HI with 0 <= LO < HI <= 30 km"),
    (["--bands", "a-b"], "argument --bands: not LO-HI in km: 'a-b'"),
    (["--jets", "1"], "argument --jets: must be within 3..27 km, got '1'"),
    (["--cap-mps", "nan"], "argument --cap-mps: must be within (0, 100] m/s"),
    (["--cap-mps", "5", "--resolution-mps", "10"], "--resolution-mps 10 exceeds --cap-mps 5"),
    (["--cap-mps", "100", "--resolution-mps", "0.001"], "--cap-mps / --resolution-mps must"),
    (["--upper-cap-mps", "0.1"], "--resolution-mps 0.25 exceeds --upper-cap-mps 0.1"),
    (["--table", "no/such/table.npz"], "no/such/table.npz"),
])
def test_bad_arguments_are_one_line_exit_2(tmp_path, capsys, args, message):
    out = tmp_path / "cap"
    assert_refused(["wind", "capability", *args, "--out", str(out)], capsys, message)
    assert not out.exists()


def test_a_non_empty_out_and_a_bad_site_file_are_one_line_exit_2(tmp_path, capsys):
    out = tmp_path / "cap"
    out.mkdir()
    (out / "old.csv").write_text("x\n")
    assert_refused(["wind", "capability", "--out", str(out)], capsys,
                   "must not exist or be an empty directory")
    site = tmp_path / "site.yaml"
    site.write_text("schema_version: 1\n")
    assert_refused(["wind", "capability", "--site", str(site), "--month", "1", "--out",
                    str(tmp_path / "other")], capsys, f"{site}")
    assert not (tmp_path / "other").exists()


@pytest.mark.slow
def test_month_mean_profile_is_the_site_tables_mean_speed():
    site = load_site()
    p = month_mean_profile(site, 4)
    rows = site.months[4]
    assert np.array_equal(p.altitude_m, site.fine_altitude_m)
    level = int(np.flatnonzero(site.altitude_m == 12_000.0)[0])
    assert p.wind_mps[120] == rows[level, 6]        # 12 km: the MEAN WS column, unchanged
