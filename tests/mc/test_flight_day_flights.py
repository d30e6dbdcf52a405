"""The flight-day campaign with real flights: the launch commit criterion on hand-made
measured profiles either side of its limits (the guidance re-biased to each, the predicted
flight flown), and a flight-day sample against the thesis-box sample of the same index."""

import dataclasses

import numpy as np
import pytest

from vega_campaign.campaign import load_dispersions, sample_scenario
from vega_campaign.wind_environment import change_rms_mps, load_site
from vega_gnc.controller_table import default_table_path
from vega_model.wind import WindTable
from vega_reference.rebias import rebias_reference, write_rebiased_reference
from vega_sim.closed_loop import run_scenario
from vega_sim.scenario import dump_scenario, load_scenario
from vega_signoff import lcc
from vega_signoff.flight_day import (environment_settings, flight_day_sample,
                                     parse_environment, reference_path)

pytestmark = pytest.mark.slow

SITE = load_site()
ALT = SITE.fine_altitude_m
SIGMA = change_rms_mps(SITE, 7, 5400.0)
SETTINGS = lcc.load_lcc()


@pytest.fixture(scope="module")
def judge(tmp_path_factory):
    """LCC of a measured profile: re-bias, fly the predicted flight, evaluate (July's σ)."""
    base = load_scenario("nominal")
    dz = lcc.drift_allowance_m(dump_scenario(base), str(default_table_path()), ALT, SIGMA,
                               SITE.change_vertical_correlation_m, SETTINGS)
    directory = tmp_path_factory.mktemp("lcc")

    def run(name, wind):
        measured = WindTable(ALT, wind, name)
        ref = directory / f"{name}.npz"
        write_rebiased_reference(ref, rebias_reference(ALT, wind), ALT, wind)
        predicted = run_scenario(lcc.predicted_scenario(base, measured, str(ref)),
                                 default_table_path())
        return lcc.evaluate_lcc(predicted, measured, ALT, SIGMA, dz, SETTINGS)
    return run


def _jet(peak_mps):
    """A jet at 11 km (the altitude of max-Q, ≈ 47 s), 2 km wide (Gaussian)."""
    return peak_mps * np.exp(-0.5 * ((ALT - 11_000.0) / 2_000.0) ** 2)


def test_calm_day_is_go_with_only_the_allowance(judge):
    v = judge("calm", np.zeros_like(ALT))
    assert v.go, v
    # calm and re-biased to calm: no predicted load, no predicted drift
    assert v.predicted_max_q_alpha_pa_deg < 1.0 and v.predicted_drift_m < 1.0
    assert 0.0 < v.q_alpha_with_allowance_pa_deg < v.allowable_pa_deg
    assert v.drift_with_allowance_m < v.drift_limit_m


def test_strong_jet_at_max_q_either_side_of_the_load_limit(judge):
    """80 m/s at 11 km stays below the allowable with its allowance once re-biased; 95 m/s
    does not (the guidance's drift bounds stop it from taking the whole load away)."""
    below, above = judge("jet80", _jet(80.0)), judge("jet95", _jet(95.0))
    assert "load" not in below.reasons
    assert below.q_alpha_with_allowance_pa_deg <= below.allowable_pa_deg
    assert "load" in above.reasons and not above.go
    assert above.q_alpha_with_allowance_pa_deg > above.allowable_pa_deg
    assert 40.0 <= above.load_time_s <= 55.0          # at max-Q, where the jet is met


def test_surface_wind_either_side_of_the_ground_wind_limit(judge):
    limit = SETTINGS.ground_wind_limit_mps
    calm_above = lambda w: np.where(ALT <= 150.0, w, 0.0)   # noqa: E731
    below = judge("sfc_below", calm_above(limit - 0.3))
    above = judge("sfc_above", calm_above(limit + 0.3))
    assert "ground_wind" not in below.reasons and below.ground_wind_mps == limit - 0.3
    assert "ground_wind" in above.reasons and not above.go


def test_flight_day_sample_keeps_the_thesis_box_draws_but_the_steady_wind(tmp_path):
    """Sample i of a flight day: the plant, gust, turbulence, INS noise and attitude of the
    thesis-box sample i, the flown profile of month i mod 12 + 1 in place of the scaled
    thesis profile, the reference re-biased to the measured profile and written once."""
    base, disp = load_scenario("nominal"), load_dispersions()
    env = parse_environment(environment_settings())
    s = flight_day_sample(base, disp, 3, 13, env, tmp_path)
    box, values = sample_scenario(base, disp, 3, 13)
    assert s.month == 2 and s.values["month"] == 2
    assert s.scenario.uncertainty == box.uncertainty and s.scenario.seed == box.seed
    assert s.scenario.wind.gust == box.wind.gust
    assert s.scenario.initial_state == box.initial_state
    assert s.scenario.wind.profile is s.flown and s.scenario.wind.profile_scale == 1.0
    assert "profile_scale" not in s.values and "profile_shift_m" in values
    ref = reference_path(tmp_path, 13)
    assert s.scenario.guidance == str(ref.resolve()) and ref.is_file()
    stamp = ref.stat().st_mtime_ns
    again = flight_day_sample(base, disp, 3, 13, env, tmp_path)   # reuses the written file
    assert ref.stat().st_mtime_ns == stamp
    assert dump_scenario(again.scenario) == dump_scenario(s.scenario)
    other = flight_day_sample(base, disp, 3, 13, dataclasses.replace(env, month=9),
                              tmp_path / "m9")
    assert other.month == 9 and other.scenario.uncertainty == box.uncertainty


def test_flight_day_task_rows_equal_the_per_flight_path(tmp_path):
    """The task flies its samples' predicted flights and flights as batches, each with its
    own re-biased reference: every row equals what run_scenario gives for the recorded
    scenario and for the predicted flight on the sample's measured profile."""
    from vega_campaign.campaign import default_dispersions_path, flight_metrics
    from vega_sim.requirements import load_requirements
    from vega_sim.scenario import parse_scenario
    from vega_signoff.flight_day import (fly_flight_day_batch, flight_day_metrics,
                                         scenario_path)

    base, disp_text = load_scenario("nominal"), default_dispersions_path().read_text()
    settings = environment_settings()
    table = default_table_path()
    rows = fly_flight_day_batch(dump_scenario(base), str(table), disp_text, 4, settings,
                                str(tmp_path), [2, 7, 9])
    assert [r["sample"] for r in rows] == [2, 7, 9]
    env, spec = parse_environment(settings), load_requirements()
    guidance = set()
    for row in rows:
        i = row["sample"]
        scenario = parse_scenario(scenario_path(tmp_path, i).read_text(), "recorded")
        guidance.add(scenario.guidance)
        flown = run_scenario(scenario, table)
        for key, value in {**flight_metrics(flown), **flight_day_metrics(flown, spec)}.items():
            assert row[key] == value or (value != value and row[key] != row[key]), (i, key)
        s = flight_day_sample(base, load_dispersions(), 4, i, env, tmp_path)
        predicted = run_scenario(lcc.predicted_scenario(base, s.measured, s.scenario.guidance),
                                 table)
        sigma = change_rms_mps(SITE, s.month, env.lag_s)
        dz = lcc.drift_allowance_m(dump_scenario(base), str(table), ALT, sigma,
                                   SITE.change_vertical_correlation_m, env.lcc)
        verdict = lcc.evaluate_lcc(predicted, s.measured, ALT, sigma, dz, env.lcc, spec)
        assert {k: row[k] for k in verdict.row()} == verdict.row(), i
        assert row["flight_day_verdict"] in ("pass", "fail", "scrubbed")
    assert len(guidance) == 3                 # each sample flew its own reference
