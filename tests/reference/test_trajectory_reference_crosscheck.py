"""Cross-check against the thesis' full reference files (development checkouts and CI only).

Collected only where the converted files are present — ``../shared/reference`` beside the
repository, or the directory named by ``VEGA_THESIS_REFERENCE_DIR`` (tests/reference/conftest.py,
tests/thesis_reference.py): a clone without them collects nothing from this module and reports
no skip. The files are never committed.

1. The committed table ``tests/data/thesis_reference_points.csv``, which
   tests/reference/test_trajectory_calibration.py runs on in every clone, equals the figures
   computed from the files (same rows, values to the table's 9 significant digits).
2. The calibration criteria between the 10 s marks: mass, Mach, x_CG and J_yy every 0.5 s, the
   coarse thrust table against the thrust program at its own samples from 1 s to 90 s (the
   criteria and tolerances of the calibration tests; docs/TRAJECTORY.md §6).
"""

import numpy as np
import pytest

from thesis_reference import (COLUMNS, POINTS_CSV, extract_points, format_value, load_reference,
                              reference_dir)
from vega_model.flight_conditions import FlightConditions


@pytest.fixture(scope="module")
def directory():
    """The directory of the full reference files (this module is run only where it exists)."""
    found = reference_dir()
    if found is None:
        pytest.fail("the thesis' reference files are not present (../shared/reference or "
                    "VEGA_THESIS_REFERENCE_DIR); this cross-check needs them", pytrace=False)
    return found


@pytest.fixture(scope="module")
def reference(directory):
    """(trajectory, thrust program) from the full files."""
    return load_reference(directory)


@pytest.fixture(scope="module")
def ref(reference):
    return reference[0]


@pytest.fixture(scope="module")
def fc():
    return FlightConditions.load()


def _relative_error(fc, ref, column, times):
    ours = np.interp(times, fc.t_s, fc.column(column))
    theirs = np.interp(times, ref["t_s"], ref[column])
    return ours / theirs - 1.0


def test_committed_table_equals_the_reference_files(directory):
    with open(POINTS_CSV, encoding="utf-8") as stream:
        committed = [line.rstrip("\n") for line in stream if not line.startswith("#")]
    expected = [",".join(("point",) + COLUMNS)]
    expected += [",".join([kind] + [format_value(row[c]) for c in COLUMNS])
                 for kind, row in extract_points(directory)]
    assert committed == expected


def test_mass_within_1_percent_every_half_second(fc, ref):
    times = np.arange(0.0, 100.01, 0.5)
    err = _relative_error(fc, ref, "mass_kg", times)
    assert np.max(np.abs(err)) < 0.01


def test_mach_within_3_percent_every_half_second(fc, ref):
    times = np.arange(10.0, 100.01, 0.5)
    err = _relative_error(fc, ref, "mach", times)
    assert np.max(np.abs(err)) < 0.03


def test_mass_properties_within_1_percent_every_half_second(fc, ref):
    times = np.arange(0.0, 100.01, 0.5)
    for column in ("x_cg_m", "jyy_kgm2"):
        err = _relative_error(fc, ref, column, times)
        assert np.max(np.abs(err)) < 0.01, column


def test_thrust_breakpoints_follow_the_program_at_its_samples(fc, reference):
    """The coarse thrust table stays within 2 % of the thrust program from 1 s to 90 s."""
    program = reference[1]
    times = program["t_s"][(program["t_s"] >= 1.0) & (program["t_s"] <= 90.0)]
    ours = np.interp(times, fc.t_s, fc.column("thrust_n"))
    assert np.max(np.abs(ours / np.interp(times, program["t_s"], program["thrust_n"]) - 1)) < 0.02
