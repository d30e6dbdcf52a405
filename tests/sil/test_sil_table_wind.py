"""A flight-day sample through the ROS 2 nodes: a tabulated flown wind (inline in the scenario)
and the guidance re-biased to the sample's measured profile (a reference file beside the
scenario), flown by ``vega sil run`` and by the in-process simulation — the same bag, byte for
byte, and a bag ``vega check`` reads on its own.

Scenario: the nominal flight cut to 40–44 s (max-Q, where the sampled upper winds load the
vehicle), nonlinear plant, light Dryden turbulence, INS noise; wind: sample 3 of July (seed
11) of the shipped Kourou site file — flown profile as the table, measured profile for the
guidance. Table: the PD fixture (the comparison does not depend on the controller's quality).
"""

import hashlib
import json

import numpy as np
import pytest
import yaml

from fixture_tables import write_pd_table
from sil_flights import (by_topic, comparable_payloads, normalised, run_layout_in,
                         vega_sil_run, write_short_scenario)
from vega_bags import bagio
from vega_bus import topics
from vega_sim.closed_loop import run_scenario
from vega_sim.scenario import load_scenario

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.fixture(scope="module")
def flight_day(tmp_path_factory):
    """(scenario path, flown table, reference file) of one sampled flight day."""
    from vega_campaign.wind_environment import load_site, sample_profiles, sample_table
    from vega_reference.rebias import rebias_reference, write_rebiased_reference

    folder = tmp_path_factory.mktemp("flight_day")
    samples = sample_profiles(load_site(), month=7, indices=[3], seed=11)
    flown, measured = (sample_table(samples, 3, p) for p in ("flown", "measured"))
    design = rebias_reference(measured.altitude_m, measured.wind_mps, source=measured.source)
    write_rebiased_reference(folder / "guidance.npz", design, measured.altitude_m,
                             measured.wind_mps, source=measured.source)
    path = write_short_scenario(folder, "nominal", "flight_day", 40.0, 44.0)
    tree = yaml.safe_load(path.read_text())
    tree["wind"]["profile"] = {"altitude_m": list(flown.altitude_m),
                               "wind_mps": list(flown.wind_mps), "source": flown.source}
    tree["guidance"] = "guidance.npz"
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path, flown, folder / "guidance.npz"


@pytest.fixture(scope="module")
def pd_table(tmp_path_factory):
    return write_pd_table(tmp_path_factory.mktemp("pd") / "pd.npz").path


@pytest.fixture(scope="module")
def bag(tmp_path_factory, flight_day, pd_table):
    out = tmp_path_factory.mktemp("flight")
    result = vega_sil_run(["--scenario", flight_day[0], "--table", pd_table, "--out", out])
    assert result.returncode in (0, 1), result.stderr  # 1: the PD may fail a requirement
    return run_layout_in(out).bag_dir


def test_the_scenario_names_the_table_and_the_rebiased_reference(flight_day):
    """The loaded scenario holds the sample's flown profile, bit for bit; the reference was
    solved on the measured profile, which differs from the flown one (the change since the
    sounding and the unresolved shear)."""
    path, flown, reference = flight_day
    scenario = load_scenario(path)
    table = scenario.wind.profile
    assert table == flown
    assert scenario.guidance == str(reference)
    with np.load(reference) as npz:
        design = json.loads(str(npz["metadata"]))["design_wind"]
    measured = np.array(design["table"]["wind_mps"])
    assert design["table"]["altitude_m"] == list(table.altitude_m)
    assert np.abs(measured - np.array(table.wind_mps)).max() > 0.5


def test_sil_bag_is_the_in_process_flight(bag, flight_day, pd_table):
    """Every message of every topic identical (log times, data bytes) between the SIL bag and
    :func:`run_scenario` of the same scenario — as in tests/sil/test_sil_equivalence.py, with
    the table wind and the re-biased reference; the bag records the table inline (its source
    naming the sample) and the reference file's SHA-256, and ``vega check`` finds the run
    complete."""
    from rclpy.serialization import serialize_message
    from vega_bags.simbag import simulation_messages

    path, _, reference = flight_day
    sil = comparable_payloads(bag, drop_frame_id=True)
    result = run_scenario(path, pd_table)
    assert np.abs(result.wind_mps).max() > 1.0
    messages = simulation_messages(result)
    want = by_topic((topic, t_ns, normalised(topic, serialize_message(msg), drop_frame_id=True))
                    for topic, t_ns, msg in messages)
    assert sorted(sil) == sorted(want) == sorted(t.name for t in topics.ALL_TOPICS)
    del sil[topics.DIAGNOSTICS.name], want[topics.DIAGNOSTICS.name]
    counts = {t: (len(sil[t]), len(w)) for t, w in want.items() if len(sil[t]) != len(w)}
    assert not counts, f"message counts (SIL, in process) differ: {counts}"
    first_bad = {t: next(i for i, (g, x) in enumerate(zip(sil[t], w)) if g != x)
                 for t, w in want.items() if sil[t] != w}
    assert not first_bad, f"first differing message per topic: {first_bad}"
    meta = bagio.read_run_bag(bag).metadata
    recorded = yaml.safe_load(meta[bagio.META_SCENARIO_YAML])["wind"]["profile"]
    table = load_scenario(path).wind.profile
    assert recorded["altitude_m"] == list(table.altitude_m)
    assert recorded["wind_mps"] == list(table.wind_mps)
    assert recorded["source"] == table.source
    assert meta[bagio.META_GUIDANCE_REFERENCE_SHA256] == hashlib.sha256(
        reference.read_bytes()).hexdigest()
    from vega_bags.bagcheck import check_bag

    health = {c.key: c for c in check_bag(bag).health}
    assert health["metadata"].passed and health["coverage"].passed, health
