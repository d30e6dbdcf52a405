"""Scheduled LPV controller tables: the flight software's trusted copy of the synthesis.

One versioned ``.npz`` file (written by ``vega_loops.export``) holds, per scheduling
grid point (velocity, increasing): the continuous controller ``A B C D`` and its discretised
form ``Ad Bd Cd Dd`` at the controller rate, plus γ, the rate bounds and a JSON metadata
string. :func:`load_controller_table` validates everything before the loop ever sees it —
version, keys, shapes, finiteness, grid monotonicity, metadata, and that the discrete
controller's stability at each grid point is what the synthesis recorded — and reports any
problem as one line (:class:`ControllerTableError`, a :class:`vega_core.errors.BadFile`).

Matrix layout: leading axis = grid point; if the controller depends on ρ̇ an extra axis
right after it holds the ρ̇ slices listed in ``rate_grid_mps2``.

Interpolation (thesis §4.3.2, "affine interpolation"): element-wise linear in the
scheduling velocity between neighbouring grid points, clamped at the ends; linear in ρ̇
between the two rate slices, clamped.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from vega_core.errors import BadFile

from vega_gnc.config_files import check_header, installed_config, numeric_arrays, read_npz

__all__ = [
    "default_table_path",
    "FORMAT_VERSION", "MEASUREMENT_NAMES", "REQUIRED_METADATA", "ControllerTable",
    "ControllerTableError", "load_controller_table", "validate_arrays", "DESIGNS",
]

FORMAT_VERSION = 1
# Names of the INS measurements the controller may take (vega_plant's linear-model outputs).
MEASUREMENT_NAMES = ("theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps")
REQUIRED_METADATA = ("input_names", "measurement_sign", "output_name", "interpolation",
                     "units", "weights", "solver", "versions", "git_revision", "created_utc",
                     "discretisation", "controller_stable")
_MATRICES = ("A", "B", "C", "D", "Ad", "Bd", "Cd", "Dd")
DESIGNS = ("lpv", "structured")
"""``metadata['design']``: ``lpv`` (vega_lpv.pipeline, γ and the rate bounds are its
certificate's figures; the default when the key is absent) or ``structured``
(vega_design.structured: a fixed-structure controller tuned per grid point, which has
no γ and no rate bounds — the file stores NaN for them, and any other value is refused)."""
_LPV_ONLY = ("gamma", "gamma_min", "rate_bounds_mps2")
_REQUIRED_KEYS = ("format_version", "grid_v_mps", "dt_s", "gamma", "gamma_min",
                  "rate_bounds_mps2", "metadata") + _MATRICES


class ControllerTableError(BadFile):
    """A controller table that cannot be trusted (message is one line)."""


@dataclass(frozen=True)
class ControllerTable:
    """A validated controller table (arrays read-only, SI units)."""

    path: str
    grid_v_mps: np.ndarray
    rate_grid_mps2: np.ndarray | None
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    Cd: np.ndarray
    Dd: np.ndarray
    dt_s: float
    gamma: float
    gamma_min: float
    rate_bounds_mps2: tuple[float, float]
    metadata: Mapping[str, Any]

    @property
    def n_states(self) -> int:
        """Controller order."""
        return self.Ad.shape[-1]

    @property
    def design(self) -> str:
        """``lpv`` or ``structured`` (:data:`DESIGNS`)."""
        return str(self.metadata.get("design", "lpv"))

    @property
    def input_names(self) -> tuple[str, ...]:
        """Measurement names in the controller's input order."""
        return tuple(self.metadata["input_names"])

    @property
    def measurement_sign(self) -> int:
        """−1: the controller input is reference − measurement; +1: the measurement."""
        return int(self.metadata["measurement_sign"])

    def weights(self, v_mps: float, rate_mps2: float | None = None):
        """Interpolation weights: ``(i, w, j, s)`` with the matrix at v = (1−w)M[i] + wM[i+1]
        (and (1−s) slice j + s slice j+1 in ρ̇), clamped to the grid."""
        g = self.grid_v_mps
        if v_mps <= g[0]:
            i, w = 0, 0.0
        elif v_mps >= g[-1]:
            i, w = len(g) - 2, 1.0
        else:
            i = int(np.searchsorted(g, v_mps, side="right")) - 1
            w = (v_mps - g[i]) / (g[i + 1] - g[i])
        if self.rate_grid_mps2 is None:
            return i, w, 0, 0.0
        if rate_mps2 is None:  # default: the upper rate slice (the thesis simulated ρ̇ = 36.4)
            return i, w, 0, 1.0
        r = self.rate_grid_mps2
        s = min(max((rate_mps2 - r[0]) / (r[1] - r[0]), 0.0), 1.0)
        return i, w, 0, s

    def interpolate(self, v_mps: float, rate_mps2: float | None = None, discrete: bool = True):
        """Controller matrices at velocity ``v_mps`` (and ρ̇; default: the upper rate slice).

        Returns (Ad, Bd, Cd, Dd) if ``discrete`` else (A, B, C, D).
        """
        i, w, j, s = self.weights(v_mps, rate_mps2)
        names = ("Ad", "Bd", "Cd", "Dd") if discrete else ("A", "B", "C", "D")
        out = []
        for name in names:
            m = getattr(self, name)
            lo, hi = m[i], m[i + 1]
            if self.rate_grid_mps2 is not None:
                lo = (1.0 - s) * lo[j] + s * lo[j + 1]
                hi = (1.0 - s) * hi[j] + s * hi[j + 1]
            out.append((1.0 - w) * lo + w * hi)
        return tuple(out)


def _fail(path: str, what: str) -> ControllerTableError:
    return ControllerTableError(f"{path}: {what}")


def validate_arrays(path: str, arrays: Mapping[str, np.ndarray]) -> ControllerTable:
    """Validate a mapping of named arrays (as stored in the file) into a ControllerTable."""
    meta = check_header(path, arrays, _REQUIRED_KEYS, FORMAT_VERSION, REQUIRED_METADATA,
                        ControllerTableError)
    design = meta.get("design", "lpv")
    if design not in DESIGNS:
        raise _fail(path, f"metadata 'design' {design!r} is not one of {DESIGNS}")
    skip = _LPV_ONLY if design == "structured" else ()
    num = numeric_arrays(path, arrays, (k for k in _REQUIRED_KEYS
                                        if k != "metadata" and k not in skip),
                         ControllerTableError)
    for key in skip:
        arr = np.asarray(arrays[key])
        if arr.dtype.kind != "f" or not np.all(np.isnan(arr)):
            raise _fail(path, f"'{key}' must be NaN in a structured design (it has no {key})")
        num[key] = arr.astype(float)
        num[key].setflags(write=False)
    grid = num["grid_v_mps"]
    if grid.ndim != 1 or grid.size < 2:
        raise _fail(path, "'grid_v_mps' must be a 1-D array of at least 2 velocities")
    if np.any(np.diff(grid) <= 0):
        raise _fail(path, "'grid_v_mps' must be strictly increasing")
    rate_grid = None
    if "rate_grid_mps2" in arrays:
        rate_grid = np.asarray(arrays["rate_grid_mps2"], dtype=float)
        if (rate_grid.shape != (2,) or not np.all(np.isfinite(rate_grid))
                or rate_grid[1] <= rate_grid[0]):
            raise _fail(path, "'rate_grid_mps2' must be 2 increasing finite values")
    lead = (grid.size,) + ((2,) if rate_grid is not None else ())
    A = num["A"]
    if A.ndim != len(lead) + 2 or A.shape[:len(lead)] != lead or A.shape[-1] != A.shape[-2]:
        raise _fail(path, f"'A' has shape {A.shape}, expected {lead} + (n, n)")
    n = A.shape[-1]
    names = meta["input_names"]
    if (not isinstance(names, list) or not names
            or any(name not in MEASUREMENT_NAMES for name in names)
            or len(set(names)) != len(names)):
        raise _fail(path, f"metadata 'input_names' must be distinct names from {MEASUREMENT_NAMES}")
    ny, nu = len(names), 1
    expected = {"B": (n, ny), "C": (nu, n), "D": (nu, ny)}
    for cont, disc in (("A", "Ad"), ("B", "Bd"), ("C", "Cd"), ("D", "Dd")):
        shape = lead + (expected.get(cont, (n, n)))
        for key in (cont, disc):
            if num[key].shape != shape:
                raise _fail(path, f"'{key}' has shape {num[key].shape}, expected {shape}")
    if meta["measurement_sign"] not in (-1, 1):
        raise _fail(path, "metadata 'measurement_sign' must be -1 or +1")
    if meta["interpolation"] != "linear_in_velocity":
        raise _fail(path, f"metadata 'interpolation' {meta['interpolation']!r} is not supported")
    dt = float(num["dt_s"].item()) if num["dt_s"].size == 1 else float("nan")
    if not dt > 0.0:
        raise _fail(path, "'dt_s' must be one positive number")
    rb = num["rate_bounds_mps2"]
    if rb.shape != (2,) or (design == "lpv" and rb[1] < rb[0]):
        raise _fail(path, "'rate_bounds_mps2' must be [lower, upper]")
    stable = np.asarray(meta["controller_stable"], dtype=bool)
    if stable.shape != lead:
        raise _fail(path, f"metadata 'controller_stable' must have shape {lead}")
    radius = np.abs(np.linalg.eigvals(num["Ad"])).max(axis=-1)
    mismatch = np.argwhere((radius < 1.0) != stable)
    if mismatch.size:
        where = tuple(int(k) for k in mismatch[0])
        raise _fail(path, f"discrete controller at grid index {where} has spectral radius "
                          f"{radius[where]:.6f}, contradicting the recorded stability")
    return ControllerTable(
        path=path, grid_v_mps=grid, rate_grid_mps2=rate_grid,
        A=num["A"], B=num["B"], C=num["C"], D=num["D"],
        Ad=num["Ad"], Bd=num["Bd"], Cd=num["Cd"], Dd=num["Dd"],
        dt_s=dt, gamma=float(num["gamma"].item()), gamma_min=float(num["gamma_min"].item()),
        rate_bounds_mps2=(float(rb[0]), float(rb[1])), metadata=meta,
    )


def load_controller_table(path: str | Path) -> ControllerTable:
    """Load and validate a controller table file.

    Raises
    ------
    ControllerTableError
        One line naming the file and the problem (unreadable, not an npz, any check above).
    """
    p = str(path)
    arrays = read_npz(p, ControllerTableError, "controller table")
    return validate_arrays(p, arrays)


def default_table_path() -> Path:
    """The installed controller table the product flies by default,
    ``share/vega_gnc/config/tvc_controller.npz`` (the robust structured design,
    docs/FLIGHT_DESIGN.md; the LPV table of ``vega synth`` is installed beside it as
    ``lpv_controller.npz``).

    Raises
    ------
    BadInput
        If the package ``vega_gnc`` is not in the ament index (workspace not built).
    """
    return installed_config("tvc_controller.npz")
