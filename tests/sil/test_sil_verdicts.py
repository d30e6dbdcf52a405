"""The flight-design verdicts in the SIL: `vega sil run` with the shipped controller table and
guidance reference passes `nominal` (the `make sil` default), `thesis`, `gust`, `wind_change`,
the first bending frequency at −20 % and the worst case of `vega robust` (exit 0); the no-bias
case fails its load requirement (exit 1); `severe`, declared off-design, is reported and not
gated (exit 0)."""

import pytest

from sil_flights import run_layout_in, vega_sil_run

pytestmark = pytest.mark.ros


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["nominal", "thesis", "gust", "wind_change",
                                      "dispersed_bending_low", "dispersed_worst"])
def test_design_scenarios_pass(tmp_path, scenario):
    result = vega_sil_run(["--scenario", scenario, "--out", tmp_path])
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "verdict: PASS" in result.stdout
    assert run_layout_in(tmp_path).bag_dir.is_dir()


@pytest.mark.slow
def test_no_bias_fails_the_load_requirement(tmp_path):
    result = vega_sil_run(["--scenario", "nominal_no_bias", "--out", tmp_path])
    assert result.returncode == 1, result.stderr[-2000:]
    verdict = next(line for line in result.stdout.splitlines() if line.startswith("verdict:"))
    assert verdict.startswith("verdict: FAIL: Load performance Qα:"), verdict
    # the structured design's drift gains are weak (tuned for margins): without the wind
    # bias the drift budget goes too (docs/FLIGHT_DESIGN.md §6); actuation stays inside
    assert "Actuation" not in verdict


@pytest.mark.slow
def test_off_design_severe_is_reported_not_gated(tmp_path):
    """`severe` is declared off-design in its scenario file: its requirement verdict is
    printed (it fails) and the command exits 0."""
    result = vega_sil_run(["--scenario", "severe", "--out", tmp_path])
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    verdict = next(line for line in result.stdout.splitlines() if line.startswith("verdict:"))
    assert verdict.startswith("verdict: FAIL:") and "Qα" in verdict, verdict
    assert ("reported and not gated: scenario 'severe' is declared off-design"
            in result.stdout + result.stderr)
