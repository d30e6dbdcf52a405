"""Small controller tables for the table-loader tests, and their arrays edited key by key.

Two 2-state tables on the velocity grid 100 / 400 / 900 m/s, written through
:func:`vega_loops.export.write_controller_table` (stable at every point): one with two ρ̇
slices (0 and 36 m/s²), one without. :func:`table_arrays` reads a table's arrays back as the
loader reads them (:func:`vega_gnc.config_files.read_npz`) with some keys or metadata fields
replaced, for :func:`vega_gnc.controller_table.validate_arrays`.
"""

import json

import numpy as np

from vega_loops.export import write_controller_table
from vega_gnc.config_files import read_npz
from vega_gnc.controller_table import ControllerTableError

NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]
GRID = [100.0, 400.0, 900.0]


def table_meta(**extra):
    """The metadata of the tables here (measurement sign −1), with ``extra`` fields."""
    meta = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
            "units": {}, "weights": {}, "solver": {}}
    meta.update(extra)
    return meta


def write_rate_table(path):
    """A 2-state table on 3 velocities × 2 ρ̇ slices (0 and 36 m/s²), stable everywhere; its
    path as a string."""
    rng = np.random.default_rng(5)
    lead = (3, 2)
    A = -3.0 * np.eye(2) + 0.3 * rng.standard_normal(lead + (2, 2))
    B = rng.standard_normal(lead + (2, 4))
    C = rng.standard_normal(lead + (1, 2))
    D = rng.standard_normal(lead + (1, 4))
    write_controller_table(path, GRID, A, B, C, D, dt_s=0.02, gamma=1.0, gamma_min=0.9,
                           rate_bounds_mps2=[0.0, 36.0], metadata=table_meta(),
                           rate_grid_mps2=[0.0, 36.0])
    return str(path)


def write_plain_table(path):
    """A 2-state table on 3 velocities without rate slices (rate bounds 5 … 36 m/s²); its
    path as a string."""
    rng = np.random.default_rng(6)
    A = -3.0 * np.eye(2) + 0.3 * rng.standard_normal((3, 2, 2))
    B = rng.standard_normal((3, 2, 4))
    C = rng.standard_normal((3, 1, 2))
    D = rng.standard_normal((3, 1, 4))
    write_controller_table(path, GRID, A, B, C, D, dt_s=0.02, gamma=1.0, gamma_min=0.9,
                           rate_bounds_mps2=[5.0, 36.0], metadata=table_meta())
    return str(path)


def table_arrays(path, **changes):
    """The arrays of the table at ``path``, with ``changes`` (key → array) applied; ``meta``:
    fields replaced in the JSON metadata."""
    arrays = dict(read_npz(path, ControllerTableError, "controller table"))
    meta_changes = changes.pop("meta", None)
    if meta_changes is not None:
        meta = json.loads(str(np.asarray(arrays["metadata"]).item()))
        meta.update(meta_changes)
        arrays["metadata"] = np.array(json.dumps(meta))
    arrays.update(changes)
    return arrays
