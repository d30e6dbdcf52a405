"""``vega wind sample``: the documented columns in Parquet and CSV with the plot beside them,
and bad arguments or site files refused in one line (exit 2) before anything is written."""

import numpy as np
import pyarrow.csv as pcsv
import pyarrow.parquet as pq
import pytest

from cli_errors import assert_refused
from vega_campaign.wind_environment import COLUMNS, load_site, sample_profiles
from vega_cli import cli


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_sample_writes_the_documented_columns_and_a_plot(tmp_path, suffix):
    out = tmp_path / "sub" / f"winds{suffix}"
    assert cli.main(["wind", "sample", "--month", "2", "--n", "3", "--seed", "4",
                     "--out", str(out), "--lag-s", "1800", "--mode", "in_plane"]) == 0
    table = pq.read_table(out) if suffix == ".parquet" else pcsv.read_csv(out)
    assert tuple(table.column_names) == COLUMNS
    want = sample_profiles(load_site(), 2, n=3, seed=4, lag_s=1800.0, mode="in_plane")
    k = want.altitude_m.size
    assert table.num_rows == 3 * k
    assert np.array_equal(table["sample"].to_numpy(), np.repeat([0, 1, 2], k))
    assert np.array_equal(table["altitude_m"].to_numpy(), np.tile(want.altitude_m, 3))
    assert np.allclose(table["flown_wind_mps"].to_numpy(), want.flown_wind_mps.ravel())
    assert np.allclose(table["measured_wind_mps"].to_numpy(), want.measured_wind_mps.ravel())
    assert out.with_suffix(".png").stat().st_size > 10_000


@pytest.mark.parametrize("args, message", [
    (["--month", "0", "--n", "3"], "argument --month: must be within 1..12, got '0'"),
    (["--month", "1", "--n", "0"], "argument --n: must be within 1..10000, got '0'"),
    (["--month", "1", "--n", "3", "--lag-s", "-5"], "argument --lag-s: must be within"),
    (["--month", "1", "--n", "3", "--mode", "sideways"], "argument --mode: invalid choice"),
    (["--month", "1", "--n", "3", "--seed", "-1"], "--seed must be an integer >= 0"),
])
def test_bad_arguments_are_one_line_exit_2(tmp_path, capsys, args, message):
    out = tmp_path / "w.parquet"
    assert_refused(["wind", "sample", *args, "--out", str(out)], capsys, message)
    assert not out.exists()


def test_bad_output_suffix_and_bad_site_file_are_one_line_exit_2(tmp_path, capsys):
    assert_refused(["wind", "sample", "--month", "1", "--n", "2", "--out",
                    str(tmp_path / "w.txt")], capsys, "must end in .parquet or .csv")
    site = tmp_path / "site.yaml"
    site.write_text(load_site().text.replace("  7:   # July", "  13:   # no such month"))
    out = tmp_path / "w.csv"
    assert_refused(["wind", "sample", "--site", str(site), "--month", "1", "--n", "2",
                    "--out", str(out)], capsys, f"{site}: field 'months.13': unknown key")
    assert not out.exists() and not out.with_suffix(".png").exists()
