"""The wind site file: the shipped one loads; bad files are refused in one line naming the file
and the field; the source converters (RRA Table I rows, CLIMAT TEMP steadiness)."""

import math

import numpy as np
import pytest

from vega_campaign.wind_environment import default_site_path, load_site, parse_site
from vega_campaign.wind_sources import isotropic_level_from_steadiness, read_rra_wind_table
from vega_core.errors import BadFile

HEAD = default_site_path().read_text().split("\nmonths:")[0]
ROWS = {0: "[0, -7.0, 2.0, 0.1, -3.0, 2.0, 8.0, 2.0]",
        1: "[15000, -5.0, 7.0, -0.3, 2.0, 6.0, 10.0, 5.0]",
        2: "[30000, -4.0, 15.0, -0.1, 2.0, 5.0, 16.0, 5.0]"}


def small_site(rows=ROWS, months=range(1, 13), head=HEAD):
    body = "".join(f"  {m}:\n" + "".join(f"    - {r}\n" for r in rows.values()) for m in months)
    return head + "\nmonths:\n" + body


def edited(old, new):
    """A small site whose head has ``old`` replaced by ``new``."""
    assert old in HEAD
    return small_site(head=HEAD.replace(old, new))


def level_1(row):
    """A small site whose middle level is ``row``."""
    return small_site(rows={**ROWS, 1: row})


def test_the_shipped_site_file_loads():
    site = load_site()
    assert sorted(site.months) == list(range(1, 13))
    assert site.altitude_m[0] == 4.0 and site.altitude_m[-1] == 30000.0
    assert site.altitude_m.size == 61 and site.flight_azimuth_deg == 350.0
    assert site.fine_altitude_m[0] == 0.0 and site.fine_altitude_m[-1] == 30000.0


def test_a_small_site_parses():
    site = parse_site(small_site(), "small.yaml")
    assert list(site.altitude_m) == [0.0, 15000.0, 30000.0]


@pytest.mark.parametrize("text, key, problem", [
    (small_site(months=[m for m in range(1, 13) if m != 7]), "months.7", "missing"),
    (level_1("[15000, -5.0, -7.0, -0.3, 2.0, 6.0, 10.0, 5.0]"),
     "months.1[1][2]", "u_sd_mps must be >= 0"),
    (level_1("[35000, -5.0, 7.0, -0.3, 2.0, 6.0, 10.0, 5.0]"),
     "months.1[2][0]", "altitudes must increase strictly"),
    (level_1("[15000, -5.0, 7.0, 1.3, 2.0, 6.0, 10.0, 5.0]"),
     "months.1[1][3]", "r_uv must lie within [-1, 1]"),
    (level_1("[15000, -5.0, fast, -0.3, 2.0, 6.0, 10.0, 5.0]"),
     "months.1[1][2]", "must be a finite number"),
    (level_1("[15000, -5.0, 7.0]"), "months.1[1]",
     "must be a list of 8 numbers"),
    (small_site(rows={0: ROWS[0], 1: ROWS[1]}), "months.1", "levels must reach"),
    (edited("  value: 4000.0", "  value: 0.0"),
     "vertical_correlation_m.value", "must be > 0"),
    (edited("  value: 4000.0", "  value: -10.0"),
     "vertical_correlation_m.value", "must lie within"),
    (edited("  value: 4000.0", "  value: '4 km'"),
     "vertical_correlation_m.value", "must be a finite number"),
    (edited("  vertical_correlation_m: 1000.0", "  vertical_correlation_m: 0"),
     "wind_change.vertical_correlation_m", "must be > 0"),
    (edited("  lag_exponent: 0.3333", "  lag_exponent: [1]"),
     "wind_change.lag_exponent", "must be a finite number"),
    (edited("schema_version: 1", "schema_version: 2"),
     "schema_version", "must be 1"),
    (edited("  smoothing_window_m: 600.0\n  source: >-",
            "  smoothing_window_m: 600.0\n  note: >-"),
     "sounding.note", "unknown key"),
])
def test_bad_site_files_are_refused_in_one_line_naming_file_and_key(text, key, problem):
    with pytest.raises(BadFile) as info:
        parse_site(text, "bad_site.yaml")
    message = str(info.value)
    assert message.startswith(f"bad_site.yaml: field '{key}'"), message
    assert problem in message and "\n" not in message


def test_a_block_without_its_source_is_refused():
    text = edited("  smoothing_window_m: 600.0\n  source: >-",
                  "  smoothing_window_m: 600.0\n  source: ''\n  comment: >-")
    with pytest.raises(BadFile, match="bad.yaml: field 'sounding"):
        parse_site(text, "bad.yaml")


def test_a_missing_file_is_one_line(tmp_path):
    with pytest.raises(BadFile, match="cannot read wind site file"):
        load_site(tmp_path / "none.yaml")


RRA_HEAD = "      91366       8.73N  167.75E\n"
RRA = """     T A B L E  I -   1.  W I N D  S T A T I S T I C A L  P A R A M E T E R S
{month}
    Z    MEAN U   SD  U  R(U,V)  MEAN V   SD  V MEAN WS  SD  WS SKEW WS    NOBS
  0.000    0.00    0.00  0.0000    0.00    0.00    0.00    0.00    0.00     100
  0.004   -7.17    2.29  0.1000   -3.61    2.29    8.36    2.23   -0.06    1030
  0.500   -8.72    2.59  0.1064   -3.42    2.52    9.78    2.54   -0.31    1030
"""


def test_rra_table_rows_are_read_as_they_are():
    names = ["January", "February", "March", "April", "May", "June", "July", "August",
             "September", "October", "November", "December", "Annual"]
    months = read_rra_wind_table(RRA_HEAD + "".join(RRA.format(month=m) for m in names))
    assert sorted(months) == list(range(1, 13))
    assert months[3] == [[4.0, -7.17, 2.29, 0.1, -3.61, 2.29, 8.36, 2.23],
                         [500.0, -8.72, 2.59, 0.1064, -3.42, 2.52, 9.78, 2.54]]
    with pytest.raises(BadFile, match="no rows for month"):
        read_rra_wind_table(RRA_HEAD + RRA.format(month="January"))


def test_steadiness_gives_the_rice_model():
    """q = 0: Rayleigh, σ = S̄ √(2/π); q = 0.6: a sampled wind has that mean speed and
    steadiness, blowing from the given direction."""
    u, v, s = isotropic_level_from_steadiness(10.0, 0.0, 90.0)
    assert (u, v) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert s == pytest.approx(10.0 * math.sqrt(2 / math.pi), rel=1e-9)
    u, v, s = isotropic_level_from_steadiness(10.0, 0.6, 90.0)     # from the east
    assert u < 0 and abs(v) < 1e-9
    x = np.array([u, v]) + s * np.random.default_rng(0).standard_normal((200_000, 2))
    speed = np.linalg.norm(x, axis=1)
    assert speed.mean() == pytest.approx(10.0, rel=0.005)
    assert np.linalg.norm(x.mean(axis=0)) / speed.mean() == pytest.approx(0.6, abs=0.005)
