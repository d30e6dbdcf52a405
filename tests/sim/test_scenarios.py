"""Scenario files: the shipped scenarios, and the validating loader's one-line errors."""

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from vega_model.flight_conditions import FlightConditions
from vega_model.vehicle_data import load_vehicle_data
from vega_model.wind import WindTable, wind_profile_mps
from vega_sim.scenario import (GustSettings, dump_scenario, load_scenario, parse_scenario,
                               scenario_names, scenario_path)

SRC = Path(__file__).resolve().parents[2] / "ros2_ws" / "src"

GOOD = """\
name: demo
description: a test scenario
t_start_s: 10.0
t_end_s: 12.5
plant: nonlinear
initial_state:
  theta_rad: 0.01
  beta_rad: 0.001
wind:
  profile: true
  turbulence: moderate
  gust: {start_s: 11.0}
sensor_noise: false
seed: 7
uncertainty: {thrust: 0.05, delay_s: 0.01}
"""


def test_shipped_scenarios():
    assert scenario_names() == ("dispersed_bending_high", "dispersed_bending_low",
                                "dispersed_mode2", "dispersed_worst", "gust", "nominal",
                                "nominal_no_bias", "severe", "thesis", "wind_change")
    data = load_vehicle_data()
    thesis = load_scenario("thesis")
    assert (thesis.t_start_s, thesis.t_end_s, thesis.plant) == (10.0, 90.0, "linear")
    assert thesis.initial_state.theta_rad == pytest.approx(math.radians(2.0), rel=1e-15)
    assert thesis.initial_state.plant_state()[1:] == (0.0,) * 7
    assert thesis.wind.thesis_constant_dryden and thesis.wind.turbulence == "light"
    assert not thesis.wind.profile and thesis.wind.gust is None and thesis.sensor_noise
    nominal = load_scenario("nominal")
    assert (nominal.t_start_s, nominal.t_end_s, nominal.plant) == (0.0, 100.0, "nonlinear")
    assert nominal.wind.profile and nominal.wind.turbulence == "light"
    assert not nominal.wind.thesis_constant_dryden and nominal.sensor_noise
    gust = load_scenario("gust")
    assert replace(gust, name="nominal", description=nominal.description, wind=nominal.wind) \
        == nominal
    g = gust.wind.gust
    assert (g.amplitude_mps, g.duration_s) == (data["wind.gust.amplitude_mps"],
                                               data["wind.gust.duration_s"])
    fc = FlightConditions.load()
    t_max_q = fc.t_s[np.argmax(fc.column("q_pa"))]
    assert abs(g.start_s + g.duration_s / 2 - t_max_q) <= 0.1     # peak at max-Q
    severe = load_scenario("severe")
    assert severe.wind.turbulence == "severe" and severe.wind.profile
    assert severe.off_design.startswith("severe Dryden turbulence")
    assert "\n" not in severe.off_design
    assert [n for n in scenario_names() if load_scenario(n).off_design] == ["severe"]
    for name in scenario_names():
        assert load_scenario(scenario_path(name)) == load_scenario(name)


def test_full_file(tmp_path):
    path = tmp_path / "demo.yaml"
    path.write_text(GOOD)
    s = load_scenario(path)
    assert (s.t_start_ms, s.t_end_ms) == (10_000, 12_500)
    assert s.wind.gust == GustSettings(11.0, 9.0, 2.0)        # vehicle.yaml defaults
    assert s.deviations == {"delay_s": 0.01, "thrust": 0.05}
    assert s.initial_state.beta_rad == 0.001 and s.seed == 7


def test_setup_cfg_installs_the_yaml_files():
    import configparser

    cfg = configparser.ConfigParser()
    cfg.read(SRC / "vega_sim" / "setup.cfg")
    globs = [g.strip() for g in cfg["options.package_data"]["vega_sim"].split(",")]
    assert "scenarios/*.yaml" in globs and "config/*.yaml" in globs


def _error(tmp_path, text, name="demo"):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        load_scenario(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path))
    return message


@pytest.mark.parametrize("old, new, field", [
    ("seed: 7", "seed: 7\nextra: 1", "extra"),
    ("  profile: true", "  profile: true\n  profil: true", "wind.profil"),
    ("  theta_rad: 0.01", "  theta: 0.01", "initial_state.theta"),
    ("gust: {start_s: 11.0}", "gust: {start_s: 11.0, peak: 3}", "wind.gust.peak"),
    ("seed: 7", "", "seed"),
    ("gust: {start_s: 11.0}", "gust: {duration_s: 2}", "wind.gust.start_s"),
    ("t_end_s: 12.5", "t_end_s: '12.5'", "t_end_s"),
    ("seed: 7", "seed: 7.0", "seed"),
    ("seed: 7", "seed: true", "seed"),
    ("seed: 7", "seed: -1", "seed"),
    ("  profile: true", "  profile: 1", "wind.profile"),
    ("sensor_noise: false", "sensor_noise: off2", "sensor_noise"),
    ("plant: nonlinear", "plant: quadratic", "plant"),
    ("  turbulence: moderate", "  turbulence: stormy", "wind.turbulence"),
    ("t_end_s: 12.5", "t_end_s: 12.505", "t_end_s"),
    ("t_end_s: 12.5", "t_end_s: 10.0", "t_end_s"),
    ("t_start_s: 10.0", "t_start_s: -0.01", "t_start_s"),
    ("t_end_s: 12.5", "t_end_s: 110.0", "t_end_s"),
    ("t_end_s: 12.5", "t_end_s: 1000.0", "t_end_s"),
    ("t_start_s: 10.0", "t_start_s: .nan", "t_start_s"),
    ("  beta_rad: 0.001", "  beta_rad: 0.2", "initial_state.beta_rad"),
    ("gust: {start_s: 11.0}", "gust: {start_s: 11.0, duration_s: 0}", "wind.gust.duration_s"),
    ("gust: {start_s: 11.0}", "gust: {start_s: 11.0, duration_s: 100.01}",
     "wind.gust.duration_s"),
    ("gust: {start_s: 11.0}", "gust: {start_s: 11.0, amplitude_mps: -45.01}",
     "wind.gust.amplitude_mps"),
    ("gust: {start_s: 11.0}", "gust: {start_s: 11.0, amplitude_mps: 1.0e+300}",
     "wind.gust.amplitude_mps"),
    ("  theta_rad: 0.01", "  theta_rad: 1.0e+300", "initial_state.theta_rad"),
    ("  theta_rad: 0.01", "  theta_rad: -0.3501", "initial_state.theta_rad"),
    ("  theta_rad: 0.01", "  theta_rad: 0.01\n  theta_dot_radps: 0.36",
     "initial_state.theta_dot_radps"),
    ("  theta_rad: 0.01", "  theta_rad: 0.01\n  z_m: 1000.5", "initial_state.z_m"),
    ("  theta_rad: 0.01", "  theta_rad: 0.01\n  z_dot_mps: -50.5", "initial_state.z_dot_mps"),
    ("  theta_rad: 0.01", "  theta_rad: 0.01\n  q1: 10.5", "initial_state.q1"),
    ("  theta_rad: 0.01", "  theta_rad: 0.01\n  q2_dot: -1000.5", "initial_state.q2_dot"),
    ("uncertainty: {thrust: 0.05, delay_s: 0.01}", "uncertainty: {thrusts: 0.05}",
     "uncertainty.thrusts"),
    ("uncertainty: {thrust: 0.05, delay_s: 0.01}", "uncertainty: {thrust: 0.5}",
     "uncertainty.thrust"),
    ("uncertainty: {thrust: 0.05, delay_s: 0.01}", "uncertainty: {delay_s: 0.0005}",
     "uncertainty.delay_s"),
    ("seed: 7", "seed: 7\noff_design: ''", "off_design"),
    ("seed: 7", "seed: 7\noff_design: 3", "off_design"),
    ("seed: 7", "seed: 7\noff_design: \"a\\nb\"", "off_design"),
])
def test_loader_names_the_field(tmp_path, old, new, field):
    assert old in GOOD
    message = _error(tmp_path, GOOD.replace(old, new, 1))
    assert f"field '{field}'" in message, message


def test_loader_other_errors(tmp_path):
    assert "differs from the file name" in _error(tmp_path, GOOD, name="other")
    assert "not valid YAML" in _error(tmp_path, "name: [unclosed")
    assert "top level must be a mapping" in _error(tmp_path, "- a\n- b\n")
    no_wind_mapping = GOOD[:GOOD.index("wind:")] + "wind: 3\nsensor_noise: false\nseed: 7\n"
    assert "field 'wind': must be a mapping" in _error(tmp_path, no_wind_mapping)
    with pytest.raises(ValueError, match=re.escape(
            "unknown scenario 'nope' (shipped: dispersed_bending_high, dispersed_bending_low, "
            "dispersed_mode2, dispersed_worst, gust, nominal, nominal_no_bias, severe, thesis, "
            "wind_change)")):
        load_scenario("nope")
    with pytest.raises(ValueError, match="cannot read scenario"):
        load_scenario(tmp_path / "missing.yaml")


def test_constructor_validates():
    thesis = load_scenario("thesis")
    with pytest.raises(ValueError, match=r"^scenario 'thesis': field 'plant': must be one of"):
        replace(thesis, plant="quadratic")
    with pytest.raises(ValueError, match=r"^scenario 'thesis': field 't_end_s'"):
        replace(thesis, t_end_s=5.0)
    assert parse_scenario(GOOD, "x.yaml").name == "demo"


def test_span_beyond_the_flight_condition_table_is_refused_on_loading(tmp_path):
    """t_end must leave the plant one frame of flight-condition data past it (the rule of
    vega_sim.plant_step.ParameterTrack, applied when the scenario is loaded, so that
    ``vega sil run`` refuses it before any node starts)."""
    end_s = float(FlightConditions.load().t_s[-1])
    last = round(end_s - 0.01, 2)
    assert parse_scenario(GOOD.replace("t_end_s: 12.5", f"t_end_s: {last}"),
                          "demo.yaml").t_end_s == last
    message = _error(tmp_path, GOOD.replace("t_end_s: 12.5", f"t_end_s: {end_s}"))
    assert message.endswith(f"field 't_end_s': must be <= {last:g} s (the flight-condition "
                            f"table ends at {end_s:g} s and the plant needs one 10 ms frame "
                            f"past t_end), got {end_s!r}"), message
    with pytest.raises(ValueError, match=r"^scenario 'thesis': field 't_end_s': must be <="):
        replace(load_scenario("thesis"), t_end_s=500.0)


def test_plausibility_bounds_are_inclusive(tmp_path):
    """The edges of the plausible ranges load (the bound itself is allowed)."""
    text = GOOD.replace("  theta_rad: 0.01", "  theta_rad: -0.35\n  z_m: 1000.0\n  q1: 10.0", 1)
    text = text.replace("gust: {start_s: 11.0}",
                        "gust: {start_s: 11.0, amplitude_mps: 45.0, duration_s: 100.0}", 1)
    path = tmp_path / "demo.yaml"
    path.write_text(text)
    s = load_scenario(path)
    assert s.initial_state.theta_rad == -0.35 and s.initial_state.q1 == 10.0
    assert s.wind.gust.amplitude_mps == 45.0


# ----------------------------------------------------------------------------- wind tables
TABLE = WindTable([0.0, 1500.0, 11_000.0, 30_000.0], [1.25, 9.5, 31.0, 4.0])
INLINE = ("  profile:\n    altitude_m: [0.0, 1500.0, 11000.0, 30000.0]\n"
          "    wind_mps: [1.25, 9.5, 31.0, 4.0]\n")


def _with_profile(text_block):
    return GOOD.replace("  profile: true\n", text_block, 1)


def test_inline_table_loads_and_dumps_inline(tmp_path):
    path = tmp_path / "demo.yaml"
    path.write_text(_with_profile(INLINE))
    s = load_scenario(path)
    assert s.wind.profile == TABLE
    assert parse_scenario(dump_scenario(s)) == s


def test_table_dump_round_trips_every_float():
    """A sampled profile (301 rows of arbitrary floats, a source) dumped and parsed again: the
    same numbers bit for bit (YAML writes floats with repr)."""
    alt = np.linspace(0.0, 30_000.0, 301)
    wind = np.sin(alt / 1777.0) * 23.456789 + np.pi
    base = load_scenario("nominal")
    s = replace(base, wind=replace(base.wind, profile=WindTable(alt, wind, "sample 7 flown")))
    again = parse_scenario(dump_scenario(s))
    assert again == s and again.wind.profile.wind_mps == tuple(wind.tolist())


@pytest.mark.parametrize("block, field, problem", [
    ("  profile:\n    altitude_m: [0, 10, 10]\n    wind_mps: [1, 2, 3]\n",
     "wind.profile.altitude_m[2]", "must be strictly increasing, got 10.0 after 10.0"),
    ("  profile:\n    altitude_m: [0, 20, 10]\n    wind_mps: [1, 2, 3]\n",
     "wind.profile.altitude_m[2]", "must be strictly increasing"),
    ("  profile:\n    altitude_m: [0, 10, 20]\n    wind_mps: [1, .nan, 3]\n",
     "wind.profile.wind_mps[1]", "must be finite, got nan"),
    ("  profile:\n    altitude_m: [0, 10, 20]\n    wind_mps: [1, 2]\n",
     "wind.profile.wind_mps", "2 values for 3 altitudes"),
    ("  profile:\n    altitude_m: [0]\n    wind_mps: [1]\n",
     "wind.profile.altitude_m", "needs at least 2 rows, got 1"),
    ("  profile:\n    altitude_m: [0, 10]\n    wind_mps: [1, 121]\n",
     "wind.profile.wind_mps[1]", "within ±120 m/s"),
    ("  profile:\n    altitude_m: [0, 10]\n", "wind.profile.wind_mps", "missing"),
    ("  profile:\n    altitude_m: [0, 10]\n    wind_mps: [1, 2]\n    sha: x\n",
     "wind.profile.sha", "unknown key"),
    ("  profile: yes please\n", "wind.profile", "must be true, false or a table"),
    ("  profile: {file: t.csv}\n", "wind.profile.file", "unknown key"),
    ("  profile:\n    altitude_m: [0, 10]\n    wind_mps: [1, 2]\n    source: [a]\n",
     "wind.profile.source", "must be a string"),
])
def test_bad_tables_refused_naming_file_and_field(tmp_path, block, field, problem):
    message = _error(tmp_path, _with_profile(block))
    assert f"field '{field}': " in message and problem in message, message


def test_constructor_refuses_a_profile_that_is_no_table():
    nominal = load_scenario("nominal")
    with pytest.raises(ValueError, match=r"field 'wind.profile': must be true, false or a "):
        replace(nominal, wind=replace(nominal.wind, profile=[(0.0, 1.0), (1.0, 2.0)]))


@pytest.mark.slow
def test_a_table_of_eq_2_54_flies_eq_2_54_in_the_closed_loop():
    """The nominal flight's first 12 s with Eq. 2.54 tabulated every 100 m in place of the
    formula (same seed: the same turbulence): the flown wind differs by at most the
    interpolation bound of tests/model/test_wind_table.py (0.37 m/s below 100 m, 0.106 m/s at
    100–200 m, less above) — the plant flies the table."""
    from vega_gnc.controller_table import default_table_path
    from vega_sim.closed_loop import run_scenario

    alt = np.arange(0.0, 30_001.0, 100.0)
    nominal = replace(load_scenario("nominal"), t_end_s=12.0)
    tabled = replace(nominal, wind=replace(nominal.wind, profile=WindTable(
        alt, wind_profile_mps(alt, load_vehicle_data()))))
    a, b = (run_scenario(s, default_table_path()) for s in (nominal, tabled))
    diff = np.abs(a.wind_mps - b.wind_mps)
    assert np.all(diff[a.h_m < 100.0] <= 0.366) and np.all(diff[a.h_m >= 200.0] <= 0.05)
    assert 0.0 < diff.max()                            # the table, not the formula, flew
    # and the loads agree to ≈ the wind's share: ΔQα ≈ Q·Δv_w/V (2 % of the peak measured)
    assert np.abs(a.q_alpha_pa_rad - b.q_alpha_pa_rad).max() < 0.03 * np.abs(
        a.q_alpha_pa_rad).max()
