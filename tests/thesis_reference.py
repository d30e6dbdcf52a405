"""The thesis' reference trajectory: the committed calibration figures and, where present, the data.

* ``tests/data/thesis_reference_points.csv`` (committed, read by :func:`load_points`): the few
  figures the calibration tests need — the reference values at the 10 s marks and at the sample
  of peak dynamic pressure; its header names the source and every column. Every clone has it.
* The full reference files (``thesis_trajectory_sim.csv``, ``thesis_thrust_pitch_program.csv``,
  converted from the thesis' public repository) are never committed. Development checkouts and
  CI have them in ``../shared/reference`` beside the repository; the environment variable
  ``VEGA_THESIS_REFERENCE_DIR`` names another directory (a path without the files, e.g.
  ``/nonexistent``, hides them, which is how a clone without ``../shared`` is reproduced).
  :func:`reference_dir` says whether they are present; :func:`extract_points` computes the
  committed figures from them, which tests/synthesis/test_trajectory_reference_crosscheck.py
  compares with the table (that module is collected only where the files exist: tests/conftest.py).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

__all__ = ["POINTS_CSV", "COLUMNS", "MARK_TIMES_S", "REFERENCE_DIR_VARIABLE", "TRAJECTORY_FILE",
           "PROGRAM_FILE", "load_points", "reference_dir", "load_reference", "extract_points",
           "format_value"]

POINTS_CSV = Path(__file__).resolve().parent / "data" / "thesis_reference_points.csv"
"""The committed table of reference figures."""

COLUMNS = ("t_s", "v_mps", "mach", "q_pa", "mass_kg", "x_cg_m", "jyy_kgm2", "thrust_n")
"""Numeric columns of the table, in file order (after the ``point`` label)."""

MARK_TIMES_S = tuple(float(t) for t in range(0, 101, 10))
"""Flight times of the ``mark`` rows [s]."""

REFERENCE_DIR_VARIABLE = "VEGA_THESIS_REFERENCE_DIR"
"""Environment variable naming the directory of the full reference files (overrides the default
``../shared/reference`` beside the repository)."""

TRAJECTORY_FILE = "thesis_trajectory_sim.csv"
PROGRAM_FILE = "thesis_thrust_pitch_program.csv"

_DEFAULT_REFERENCE_DIR = Path(__file__).resolve().parents[1].parent / "shared" / "reference"


def format_value(value: float) -> str:
    """A figure as the table writes it: 9 significant digits (the reference files' precision)."""
    return f"{value:.9g}"


def load_points(path: Path = POINTS_CSV) -> dict[str, dict[str, np.ndarray]]:
    """The committed table: ``{point: {column: values}}`` for point ``mark`` and ``max_q``.

    Lines starting with ``#`` are the header comment; the first other line names the columns.
    """
    with open(path, newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(line for line in stream if not line.startswith("#")))
    points: dict[str, dict[str, np.ndarray]] = {}
    for kind in sorted({row["point"] for row in rows}):
        selected = [row for row in rows if row["point"] == kind]
        points[kind] = {c: np.array([float(row[c]) for row in selected]) for c in COLUMNS}
    return points


def reference_dir() -> Path | None:
    """Directory holding both full reference files, or None where they are absent."""
    override = os.environ.get(REFERENCE_DIR_VARIABLE)
    if override == "":
        return None
    directory = Path(override) if override is not None else _DEFAULT_REFERENCE_DIR
    if (directory / TRAJECTORY_FILE).is_file() and (directory / PROGRAM_FILE).is_file():
        return directory
    return None


def load_reference(directory: Path) -> tuple[np.ndarray, np.ndarray]:
    """The full reference files: (trajectory, thrust program) as named record arrays."""
    trajectory = np.genfromtxt(directory / TRAJECTORY_FILE, delimiter=",", names=True)
    program = np.genfromtxt(directory / PROGRAM_FILE, delimiter=",", names=True)
    return trajectory, program


def extract_points(directory: Path) -> list[tuple[str, dict[str, float]]]:
    """The table's rows computed from the full reference files, in table order.

    ``mark`` rows: every column linearly interpolated in time (as the calibration tests did on
    the full files) at t = 0, 10, …, 100 s. ``max_q`` row: the trajectory sample of largest
    dynamic pressure, its own values. ``thrust_n`` always from the thrust program, interpolated.
    """
    trajectory, program = load_reference(directory)
    rows = []
    for t in MARK_TIMES_S:
        row = {"t_s": t}
        for column in COLUMNS[1:-1]:
            row[column] = float(np.interp(t, trajectory["t_s"], trajectory[column]))
        row["thrust_n"] = float(np.interp(t, program["t_s"], program["thrust_n"]))
        rows.append(("mark", row))
    i = int(np.argmax(trajectory["q_pa"]))
    row = {column: float(trajectory[column][i]) for column in COLUMNS[:-1]}
    row["thrust_n"] = float(np.interp(row["t_s"], program["t_s"], program["thrust_n"]))
    rows.append(("max_q", row))
    return rows
