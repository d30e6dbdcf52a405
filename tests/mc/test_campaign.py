"""Monte Carlo campaigns without a cluster: the statistics against scipy and the order-statistics
figures of NASA/TP-2010-216447, the dispersion file's refusals, and the samples (a function of
the campaign seed and the index only; one distribution change moves no other draw)."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import binomtest

from vega_campaign.campaign import (fly_sample, load_dispersions, parse_dispersions,
                                        sample_scenario)
from vega_campaign.campaign_run import batches, clopper_pearson_lower, runs_needed
from vega_core.errors import BadFile
from vega_model.uncertainty import UNCERTAINTY_NAMES, UncertaintySet
from vega_model.vehicle_data import load_vehicle_data
from vega_sim.scenario import dump_scenario, load_scenario


@pytest.mark.parametrize("k, n", [(852, 852), (851, 852), (90, 100), (1, 10), (5, 5)])
@pytest.mark.parametrize("confidence", [0.90, 0.95])
def test_clopper_pearson_lower_bound_is_scipys_exact_one_sided(k, n, confidence):
    want = binomtest(k, n, alternative="greater").proportion_ci(confidence_level=confidence,
                                                               method="exact").low
    assert clopper_pearson_lower(k, n, confidence) == pytest.approx(want, rel=1e-9)
    assert clopper_pearson_lower(0, n, confidence) == 0.0


@pytest.mark.slow
def test_runs_for_99_73_percent_at_90_percent():
    """Hanson & Beard (NASA/TP-2010-216447): 852 runs without a failure, 1 440 with one."""
    assert runs_needed(0.9973, 0.90, failures=0) == 852
    assert runs_needed(0.9973, 0.90, failures=1) == 1440


GOOD = load_dispersions().text


@pytest.mark.parametrize("old, new, message", [
    ("default: uniform", "default: gaussian", "field 'uncertainty.default': must be one of"),
    ("overrides: {}", "overrides: {thrustt: normal}", "field 'uncertainty.overrides.thrustt': "
                                                      "unknown parameter"),
    ("profile_scale: [0.5, 1.3]", "profile_scale: [1.3, 0.5]",
     "field 'wind.profile_scale': must be finite with low <= high"),
    ("profile_scale: [0.5, 1.3]", "profile_scale: 1.0", "field 'wind.profile_scale': must be"),
    ("profile_reverse_probability: 0.0", "profile_reverse_probability: 1.5",
     "field 'wind.profile_reverse_probability': must lie within [0, 1]"),
    ("turbulence: light", "turbulence: stormy", "field 'wind.turbulence': must be one of"),
    ("probability: 0.5", "probability: .nan", "field 'wind.gust.probability': must be a finite"),
    ("initial_pitch_sigma_deg: 0.1", "initial_pitch_sigma_deg: -1",
     "field 'initial_pitch_sigma_deg': must lie within"),
    ("schema_version: 1", "schema_version: 2", "field 'schema_version': must be 1"),
    ("sensor_noise: true", "sensor_noise: yes please", "field 'sensor_noise': must be true or"),
    ("sensor_noise: true", "sensor_noise: true\nextra: 1", "field 'extra': unknown key"),
])
def test_bad_dispersion_files_are_one_line_naming_the_field(old, new, message):
    assert old in GOOD
    with pytest.raises(BadFile) as info:
        parse_dispersions(GOOD.replace(old, new), "d.yaml")
    text = str(info.value)
    assert text.startswith("d.yaml: ") and message in text and "\n" not in text


BASE = load_scenario("nominal")
DISP = load_dispersions()


def test_a_sample_depends_on_the_seed_and_its_index_only():
    a, va = sample_scenario(BASE, DISP, 7, 3)
    b, vb = sample_scenario(BASE, DISP, 7, 3)
    assert a == b and va == vb
    c, _ = sample_scenario(BASE, DISP, 7, 4)
    d, _ = sample_scenario(BASE, DISP, 8, 3)
    assert c.seed != a.seed and d.seed != a.seed and c.uncertainty != a.uncertainty


@pytest.mark.slow
def test_samples_stay_in_the_set_and_follow_their_distribution():
    uset = UncertaintySet.from_vehicle(load_vehicle_data())
    draws = {name: [] for name in UNCERTAINTY_NAMES}
    scales = []
    for i in range(400):
        sc, values = sample_scenario(BASE, DISP, 1, i)
        for name in UNCERTAINTY_NAMES:
            par = uset[name]
            assert par.lower <= values[name] <= par.upper
            draws[name].append(values[name])
        assert dict(sc.uncertainty) == {k: v for k, v in
                                        ((n, values[n]) for n in UNCERTAINTY_NAMES) if v != 0.0}
        assert 0.5 <= values["profile_scale"] <= 1.3
        assert sc.wind.profile_scale == values["profile_scale"]
        assert (values["gust_amplitude_mps"] == 0.0) == (sc.wind.gust is None)
        scales.append(values["profile_scale"])
        assert values["delay_s"] * 1000 == round(values["delay_s"] * 1000)
    thrust = np.array(draws["thrust"])
    par = uset["thrust"]
    # uniform on [lower, upper]: mean at the centre, variance (b − a)²/12 (400 draws: ±4 σ_mean)
    width = par.upper - par.lower
    assert abs(thrust.mean() - (par.lower + par.upper) / 2) < 4 * width / math.sqrt(12 * 400)
    assert thrust.std() == pytest.approx(width / math.sqrt(12), rel=0.15)
    gusts = sum(1 for i in range(400) if sample_scenario(BASE, DISP, 1, i)[0].wind.gust)
    assert 150 < gusts < 250                          # probability 0.5


def test_one_distribution_change_moves_no_other_draw():
    normal = parse_dispersions(GOOD.replace("overrides: {}", "overrides: {x_cp: normal, "
                                                             "jyy: nominal}"), "d.yaml")
    _, a = sample_scenario(BASE, DISP, 5, 11)
    _, b = sample_scenario(BASE, normal, 5, 11)
    assert b["jyy"] == 0.0 and b["x_cp"] != a["x_cp"]
    uset = UncertaintySet.from_vehicle(load_vehicle_data())
    par = uset["x_cp"]
    assert abs(b["x_cp"]) <= max(abs(par.lower), abs(par.upper))
    same = [k for k in a if k not in ("jyy", "x_cp")]
    assert {k: a[k] for k in same} == {k: b[k] for k in same}


def test_fly_sample_is_the_in_process_flight_of_that_scenario():
    """The row of a sample is the requirement check of run_scenario on its scenario."""
    from vega_gnc.controller_table import default_table_path
    from vega_sim.closed_loop import run_scenario

    short = dataclasses.replace(BASE, t_start_s=40.0, t_end_s=42.0)
    row = fly_sample(dump_scenario(short), str(default_table_path()), GOOD, 3, 2)
    sc, values = sample_scenario(short, DISP, 3, 2)
    res = run_scenario(sc, default_table_path())
    assert row["seed"] == sc.seed and row["sample"] == 2
    assert row["max_abs_z_m"] == float(np.abs(res.z_m).max())
    assert row["max_abs_q_alpha_pa_deg"] == float(np.degrees(np.abs(res.q_alpha_pa_rad).max()))
    assert row["verdict"] == ("pass" if res.metrics().passed and row["stable"] else "fail")
    # the Mach profile: max |Qα| per 0.1-wide Mach bin, its maximum the flight's
    profile = np.array(row["q_alpha_profile_pa_deg"])
    assert np.nanmax(profile) == row["max_abs_q_alpha_pa_deg"]
    k = int(res.mach[0] / 0.1)
    assert np.isfinite(profile[k]) and np.isnan(profile[k + 10])
    assert all(row[k] == v for k, v in values.items() if not (isinstance(v, float) and
                                                                 math.isnan(v)))
    assert row["q_alpha_profile_pa_deg"] is not None


@pytest.mark.parametrize("n, size, workers, sizes", [
    (852, 64, 2, [61] * 12 + [60] * 2),       # 14 batches: 7 per worker
    (130, 64, 2, [33, 33, 32, 32]),           # 3 needed, rounded up to 4 for two workers
    (6, 64, 1, [6]),
    (6, 64, 2, [3, 3]),
    (3, 64, 8, [1, 1, 1]),                    # never an empty batch
    (5, 1, 2, [1] * 5),
    (10, 4, 1, [4, 3, 3]),
])
def test_batches_cover_the_samples_in_order_in_equal_shares(n, size, workers, sizes):
    todo = [i * 3 + 1 for i in range(n)]          # the missing samples of a resumed campaign
    got = batches(todo, size, workers)
    assert [len(b) for b in got] == sizes
    assert [i for b in got for i in b] == todo
    assert batches([], size, workers) == []


@pytest.mark.slow
@pytest.mark.parametrize("change", ["linear_plant", "thesis_dryden"])
def test_samples_the_batched_engine_refuses_are_flown_per_flight(change):
    """A campaign of a scenario fly_batch does not fly (a linear plant; the thesis' constant
    Dryden input on the nonlinear plant): fly_batch_samples flies each sample through
    run_scenario and returns fly_sample's rows (wall time apart)."""
    from vega_campaign.campaign import fly_batch_samples
    from vega_gnc.controller_table import default_table_path
    from vega_sim.batch import batch_refusal

    short = dataclasses.replace(BASE, t_start_s=40.0, t_end_s=41.0)
    if change == "linear_plant":
        short = dataclasses.replace(short, plant="linear")
    else:
        short = dataclasses.replace(short, wind=dataclasses.replace(
            short.wind, thesis_constant_dryden=True))
    assert batch_refusal(short, short) is not None
    text, table = dump_scenario(short), str(default_table_path())
    rows = fly_batch_samples(text, table, GOOD, 3, [5, 2])
    assert [r["sample"] for r in rows] == [5, 2]
    for row in rows:
        want = fly_sample(text, table, GOOD, 3, row["sample"])
        assert row.pop("wall_s") > 0.0 and want.pop("wall_s") > 0.0
        assert repr(row) == repr(want)
