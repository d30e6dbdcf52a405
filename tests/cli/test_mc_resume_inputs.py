"""``vega mc run|margins --resume DIR`` with a damaged or edited campaign.json: one line naming
the file and the field, exit 2, nothing started (docs/ADVERSARIAL.md): malformed JSON, a
missing field or a JSON list is no internal error with a traceback, and an edited ``runs`` does
not skip the --runs bound."""

import json

import pytest

from vega_campaign.campaign import load_dispersions
from vega_campaign.campaign_run import _inputs
from vega_cli import cli
from vega_cli.commands import mc
from vega_gnc.controller_table import default_table_path
from vega_sim.scenario import load_scenario


@pytest.fixture(scope="module")
def inputs():
    """The campaign.json a real 3-flight campaign of the thesis scenario writes."""
    return _inputs(load_scenario("thesis"), load_dispersions(), 4, 3, default_table_path())


def _campaign_dir(tmp_path, content):
    out = tmp_path / "campaign"
    out.mkdir()
    (out / "campaign.json").write_text(content if isinstance(content, str)
                                       else json.dumps(content))
    return out


def _edited(inputs, **changes):
    edited = dict(inputs)
    for key, value in changes.items():
        if value is KeyError:
            del edited[key]
        else:
            edited[key] = value
    return edited


def test_the_written_inputs_are_accepted(inputs, tmp_path):
    out = _campaign_dir(tmp_path, inputs)
    assert mc._resumed_inputs(out / "campaign.json") == inputs


@pytest.mark.parametrize("change, message", [
    ("{not json", "not a campaign.json (Expecting property name"),
    ("[1, 2]", "not a campaign.json (a JSON object expected)"),
    (dict(scenario_yaml=KeyError), "field 'scenario_yaml': must be a JSON string, got None"),
    (dict(table=7), "field 'table': must be a JSON string, got 7"),
    (dict(runs=10**12), f"field 'runs': must be within 1..{mc.MAX_RUNS}, got 1000000000000"),
    (dict(runs=0), f"field 'runs': must be within 1..{mc.MAX_RUNS}, got 0"),
    (dict(runs=3.5), "field 'runs': must be a JSON integer, got 3.5"),
    (dict(runs=True), "field 'runs': must be a JSON integer, got True"),
    (dict(seed=2**63), "field 'seed': --seed must be <= 9223372036854775807"),
    (dict(seed=-1), "field 'seed': --seed must be an integer >= 0"),
    (dict(times_s="50"), "field 'times_s': must be null or a list of numbers"),
    (dict(kind=3), "field 'kind': must be a JSON string"),
])
@pytest.mark.parametrize("action", ["run", "margins"])
def test_a_damaged_campaign_json_is_one_line_exit_2(inputs, tmp_path, capsys, change, message,
                                                    action):
    out = _campaign_dir(tmp_path, change if isinstance(change, str)
                        else _edited(inputs, **change))
    assert cli.main(["mc", action, "--resume", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vega: error: {out / 'campaign.json'}: {message}"), err
    assert err.count("\n") == 1, err
    assert sorted(p.name for p in out.iterdir()) == ["campaign.json"]


def test_an_oversized_campaign_json_is_refused(inputs, tmp_path, capsys):
    out = _campaign_dir(tmp_path, " " * (1 << 20) + json.dumps(inputs))
    assert cli.main(["mc", "run", "--resume", str(out)]) == 2
    assert "over the 1 MiB" in capsys.readouterr().err


def test_rerun_of_a_damaged_campaign_json_is_one_line_exit_2(inputs, tmp_path, capsys):
    out = _campaign_dir(tmp_path, "{not json")
    assert cli.main(["mc", "rerun", str(out), "--sample", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vega: error: {out / 'campaign.json'}: not a campaign.json (")
    assert err.count("\n") == 1, err


@pytest.mark.parametrize("row, message", [("{oops", "not a campaign sample row (Expecting"),
                                          ("7", "not a campaign sample row (a JSON object")])
def test_rerun_of_a_damaged_sample_row_is_one_line_exit_2(inputs, tmp_path, capsys, row,
                                                          message):
    """A damaged samples/000001.json: refused before anything is flown or written."""
    out = _campaign_dir(tmp_path, inputs)
    (out / "samples").mkdir()
    (out / "samples" / "000001.json").write_text(row)
    assert cli.main(["mc", "rerun", str(out), "--sample", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vega: error: {out / 'samples' / '000001.json'}: {message}"), err
    assert err.count("\n") == 1, err
    assert not (out / "reruns").exists()
