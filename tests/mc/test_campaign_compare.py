"""Two campaigns of the same samples compared flight by flight (vega_campaign.compare,
``vega mc compare A B``; docs/FLIGHT_DESIGN.md §6.5, "A held-out seed").

The counting and the test statistic on results written by hand (the exact McNemar p-value
against its closed form); the loading and the refusals on real campaigns of `vega mc run`
(a short scenario, 40–41 s, on a LocalCluster of one worker), through ``vega mc compare``."""

import json
import shutil

import pyarrow.parquet as pq
import pytest

from sil_flights import write_short_scenario
from vega_campaign import compare as C
from vega_cli import cli

RUNS = 3


def _results(verdicts, ratios):
    return {"sample": list(range(len(verdicts))), "verdict": verdicts,
            "failed": ["" if v == "pass" else "q_alpha" for v in verdicts],
            "q_alpha_margin": ratios}


def test_lost_won_and_the_exact_mcnemar_p():
    # B loses sample 1 and wins samples 2..7 (6 won, 1 lost): p = 2·P(X <= 1), X ~ Bin(7, 1/2)
    a = _results(["pass", "pass"] + ["fail"] * 6 + ["fail", "pass"],
                 [0.5, 0.9] + [1.1] * 6 + [1.3, 0.2])
    b = _results(["pass", "fail"] + ["pass"] * 6 + ["fail", "pass"],
                 [0.5, 1.05] + [0.95] * 6 + [1.2, 0.3])
    r = C.compare(a, b)
    assert (r["passed_a"], r["passed_b"], r["runs"]) == (3, 8, 10)
    assert [f["sample"] for f in r["lost"]] == [1]
    assert [f["sample"] for f in r["won"]] == [2, 3, 4, 5, 6, 7]
    assert r["lost"][0]["q_alpha_ratio_b"] == 1.05 and r["lost"][0]["failed_b"] == "q_alpha"
    assert r["mcnemar_exact_p"] == pytest.approx(2 * (1 + 7) / 2 ** 7)
    # the median of the changes (0, +0.15, six times −0.15, −0.1, +0.1)
    assert r["median_q_alpha_ratio_change"] == pytest.approx(-0.15)


def test_no_discordant_flight_is_p_one():
    a = _results(["pass", "fail"], [0.5, 1.2])
    r = C.compare(a, a)
    assert (r["lost"], r["won"], r["mcnemar_exact_p"]) == ([], [], 1.0)


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """Two real campaigns of the same samples (seed 2) and one of another seed."""
    root = tmp_path_factory.mktemp("cmp")
    scenario = write_short_scenario(root, "nominal", "nominal_cmp_short", 40.0, 41.0)
    out = {}
    for name, seed in (("a", 2), ("b", 2), ("other", 3)):
        out[name] = root / name
        code = cli.main(["mc", "run", "--environment", "thesis-box", "--scenario", str(scenario),
                         "--runs", str(RUNS), "--seed", str(seed), "--workers", "1",
                         "--out", str(out[name])])
        assert code in (0, 1)
    return out


@pytest.mark.slow
def test_real_campaigns_of_the_same_samples(campaigns, tmp_path, capsys):
    report, plot = tmp_path / "cmp.json", tmp_path / "cmp.png"
    assert cli.main(["mc", "compare", str(campaigns["a"]), str(campaigns["b"]),
                     "--out", str(report), "--plot", str(plot)]) == 0
    r = json.loads(report.read_text())
    flown = pq.read_table(campaigns["a"] / "results.parquet").to_pydict()
    passed = sum(v == "pass" for v in flown["verdict"])
    # the same table flies the same samples: nothing lost or won, every ratio the same
    assert (r["runs"], r["passed_a"], r["passed_b"]) == (RUNS, passed, passed)
    assert (r["lost"], r["won"], r["median_q_alpha_ratio_change"]) == ([], [], 0.0)
    text = capsys.readouterr().out
    assert f"{RUNS} flights (seed 2): A passes {passed}, B passes {passed}" in text
    assert plot.stat().st_size > 10_000


def _refused(capsys, *dirs) -> str:
    assert cli.main(["mc", "compare", *[str(d) for d in dirs]]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    return err


@pytest.mark.slow
def test_other_samples_and_incomplete_campaigns_are_refused(campaigns, tmp_path, capsys):
    err = _refused(capsys, campaigns["a"], campaigns["other"])
    assert err == (f"vega: error: {campaigns['other']}: its seed is not that of "
                   f"{campaigns['a']}: the campaigns do not fly the same samples")
    # a campaign whose last flight is missing (as one stopped before the end leaves it)
    part = tmp_path / "part"
    shutil.copytree(campaigns["b"], part)
    table = pq.read_table(part / "results.parquet")
    pq.write_table(table.slice(0, RUNS - 1), part / "results.parquet")
    err = _refused(capsys, campaigns["a"], part)
    assert err == (f"vega: error: {part}: {RUNS - 1} of {RUNS} samples flown; finish it "
                   f"first (vega mc run --resume {part})")
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _refused(capsys, empty, campaigns["a"]) == (
        f"vega: error: {empty}: no campaign.json (not a `vega mc run` campaign)")
