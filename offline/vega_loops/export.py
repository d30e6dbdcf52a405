"""Export of the scheduled controller to the flight-software table (``lpv_controller.npz``).

The exporter discretises every grid controller at the controller rate (Tustin / bilinear,
``scipy.signal.cont2discrete``), records provenance and the stability of each discrete
controller, writes the file atomically and re-reads it through the flight software's own
loader (:func:`vega_gnc.controller_table.load_controller_table`) before reporting success:
a file this function writes is a file the flight software accepts.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import subprocess
import tempfile
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from scipy.signal import cont2discrete

from vega_gnc.controller_table import FORMAT_VERSION, ControllerTable, load_controller_table

__all__ = ["discretise", "git_revision", "library_versions", "write_controller_table",
           "write_checked_npz"]


def discretise(A, B, C, D, dt_s: float):
    """Tustin (bilinear) discretisation of one continuous controller (no prewarping)."""
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, D), dt_s, method="bilinear")
    return Ad, Bd, Cd, Dd


def git_revision(repo: str | Path | None = None) -> str:
    """Current git revision of the repository (with ``-dirty``), or ``"unknown"``."""
    cwd = Path(repo) if repo else Path(__file__).resolve().parent
    try:
        rev = subprocess.run(["git", "describe", "--always", "--dirty", "--abbrev=12"],
                             cwd=cwd, capture_output=True, text=True, timeout=10, check=True)
        return rev.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def library_versions() -> dict[str, str]:
    """Versions of the numerical libraries the synthesis used."""
    import importlib.metadata as md

    out = {}
    for name in ("numpy", "scipy", "cvxpy", "clarabel", "control", "slycot"):
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:
            out[name] = "absent"
    return out


def write_controller_table(path: str | Path, grid_v_mps, A, B, C, D, *, dt_s: float,
                           gamma: float, gamma_min: float, rate_bounds_mps2,
                           metadata: Mapping[str, Any],
                           rate_grid_mps2=None) -> ControllerTable:
    """Discretise, write and verify a controller table.

    Parameters
    ----------
    path
        Output ``.npz`` file (replaced atomically).
    grid_v_mps
        Scheduling velocities [m/s], strictly increasing (≥ 2).
    A, B, C, D
        Continuous controllers, leading axis = grid point (then the ρ̇ slice axis if
        ``rate_grid_mps2`` is given); input = the measurements in ``metadata['input_names']``
        order, output = the nozzle deflection command [rad].
    dt_s
        Controller sample time [s].
    gamma, gamma_min, rate_bounds_mps2
        Back-off γ, stage-1 γ and the rate bounds [m/s²] used by the synthesis.
    metadata
        At least input_names, measurement_sign, output_name, units, weights, solver
        (the rest — interpolation, discretisation, versions, git revision, creation time,
        controller stability — is filled in here unless given).
    rate_grid_mps2
        The two ρ̇ values of the slice axis, or None for a ρ̇-independent controller.

    Returns
    -------
    ControllerTable
        The file as the flight software loads it.
    """
    A, B, C, D = (np.asarray(m, dtype=float) for m in (A, B, C, D))
    lead = A.shape[:-2]
    disc = {k: np.empty_like(m) for k, m in (("Ad", A), ("Bd", B), ("Cd", C), ("Dd", D))}
    for idx in np.ndindex(*lead):
        disc["Ad"][idx], disc["Bd"][idx], disc["Cd"][idx], disc["Dd"][idx] = discretise(
            A[idx], B[idx], C[idx], D[idx], dt_s)
    radius = np.abs(np.linalg.eigvals(disc["Ad"])).max(axis=-1)
    meta = {
        "interpolation": "linear_in_velocity",
        "discretisation": {"method": "tustin", "prewarp": None, "dt_s": dt_s},
        "versions": library_versions(),
        "git_revision": git_revision(),
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "controller_stable": (radius < 1.0).tolist(),
        "spectral_radius": radius.tolist(),
    }
    meta.update(metadata)
    arrays = dict(
        format_version=np.array(FORMAT_VERSION), grid_v_mps=np.asarray(grid_v_mps, float),
        A=A, B=B, C=C, D=D, dt_s=np.array(float(dt_s)), gamma=np.array(float(gamma)),
        gamma_min=np.array(float(gamma_min)),
        rate_bounds_mps2=np.asarray(rate_bounds_mps2, float),
        metadata=np.array(json.dumps(meta, sort_keys=True)), **disc)
    if rate_grid_mps2 is not None:
        arrays["rate_grid_mps2"] = np.asarray(rate_grid_mps2, float)
    write_checked_npz(path, arrays, load_controller_table)
    return load_controller_table(path)


def write_checked_npz(path: str | Path, arrays: Mapping[str, np.ndarray], loader) -> None:
    """Write ``arrays`` to the ``.npz`` file ``path`` atomically, after ``loader`` (the flight
    software's own loader) accepted the temporary file: a file that replaces the old one is a
    file the flight software reads."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=out.name, suffix=".npz", dir=out.parent)
    os.close(fd)
    try:
        np.savez_compressed(tmp, **arrays)
        loader(tmp)             # the flight software must accept it before it replaces anything
        os.chmod(tmp, 0o644)    # mkstemp creates 0600; the file is installed and shared
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
