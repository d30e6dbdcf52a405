"""Collection rule of the reference-trajectory tests.

The cross-check against the thesis' full reference files is collected only where they are
present (../shared/reference in development checkouts and CI, or VEGA_THESIS_REFERENCE_DIR;
tests/thesis_reference.py): a clone without them collects nothing from it and reports no skip.
The calibration tests themselves read the committed table tests/data/thesis_reference_points.csv
and always run.
"""

from thesis_reference import reference_dir

collect_ignore = ([] if reference_dir() is not None
                  else ["test_trajectory_reference_crosscheck.py"])
