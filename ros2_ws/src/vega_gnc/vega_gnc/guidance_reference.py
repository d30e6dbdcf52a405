"""Wind-biased guidance references: the flight software's trusted copy of the offline guidance.

A launcher does not fight the forecast wind with its attitude loop: the first-stage steering is
biased so that the vehicle flies the expected (design) wind at a small air-relative angle of
attack (docs/GUIDANCE.md). ``vega_reference.guidance`` computes that bias — the reference
deviations from the nominal pitch programme and the nozzle feed-forward that flies them — and
exports one versioned ``.npz`` file; this module loads and validates it before the loop ever
sees it, and interpolates it on board.

File contents (SI units):

* ``format_version`` — 1;
* ``t_s`` (N,) — flight time since lift-off, strictly increasing, uniform or not;
* ``reference`` (N, 4) — the reference of each INS measurement, in the order of
  :data:`vega_gnc.controller_table.MEASUREMENT_NAMES` (θ_INS [rad], θ̇_INS [rad/s],
  z_INS [m], ż_INS [m/s]): deviations from the nominal trajectory, as the INS would measure
  them on the reference flight;
* ``beta_ff_rad`` (N,) — the nozzle angle that flies the reference (feed-forward) [rad];
* ``metadata`` — a JSON object (design wind, weights, constraints, solver, provenance).

On board (:class:`vega_gnc.controller_runtime.ControllerRuntime`): the controller acts on
``measurement − reference(t)`` and adds ``beta_ff(t)`` to its command; ``t`` is the
measurement's sample time; values are linear in time between samples and held beyond the ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from vega_core.errors import BadFile

from vega_gnc.config_files import check_header, installed_config, numeric_arrays, read_npz
from vega_gnc.controller_table import MEASUREMENT_NAMES

__all__ = ["FORMAT_VERSION", "REQUIRED_METADATA", "REFERENCE_BOUNDS", "NO_GUIDANCE",
           "DEFAULT_GUIDANCE",
           "GuidanceReference", "GuidanceReferenceError", "validate_reference_arrays",
           "load_guidance_reference", "default_reference_path", "reference_path",
           "resolve_reference"]

FORMAT_VERSION = 1
REQUIRED_METADATA = ("input_names", "units", "design_wind", "weights", "constraints", "solver",
                     "versions", "git_revision", "created_utc")
NO_GUIDANCE = "none"
"""The value of a ``guidance`` setting or node parameter that flies no reference (zero bias)."""
DEFAULT_GUIDANCE = "default"
"""The value of a ``guidance`` setting that flies the installed reference."""

# Largest reference a file may hold: beyond these it is not a wind bias of the nominal
# programme but another trajectory, which the controller table was not designed around
# (assumption: θ 10° and 10°/s, about four times the shipped bias; z 2 km and ż 50 m/s, four
# and three times the drift budget of thesis Table 3.1; docs/GUIDANCE.md §4).
REFERENCE_BOUNDS = {
    "theta_ins_rad": math.radians(10.0),
    "theta_dot_ins_radps": math.radians(10.0),
    "z_ins_m": 2000.0,
    "z_dot_ins_mps": 50.0,
}
# The feed-forward must leave the actuator range (thesis Table 3.1, ±6.5°) to the feedback:
# at most half of it (assumption).
MAX_FEEDFORWARD_RAD = math.radians(3.25)


class GuidanceReferenceError(BadFile):
    """A guidance reference file that cannot be trusted (message is one line)."""


@dataclass(frozen=True)
class GuidanceReference:
    """A validated guidance reference (arrays read-only, SI units)."""

    path: str
    t_s: np.ndarray
    reference: np.ndarray
    beta_ff_rad: np.ndarray
    metadata: Mapping[str, Any]

    def __post_init__(self):
        # [references..., feed-forward] per sample and the increment to the next sample
        stack = np.column_stack([self.reference, self.beta_ff_rad])
        object.__setattr__(self, "_stack", stack)
        object.__setattr__(self, "_dstack", np.diff(stack, axis=0))
        object.__setattr__(self, "_dt", np.diff(self.t_s))

    def at(self, t_s: float) -> np.ndarray:
        """``[θ_ref, θ̇_ref, z_ref, ż_ref, β_ff]`` at flight time ``t_s`` (linear in time,
        held beyond the ends); a new array."""
        t = self.t_s
        i = int(np.searchsorted(t, t_s, side="right")) - 1
        if i < 0:
            return self._stack[0].copy()
        if i >= t.size - 1:
            return self._stack[-1].copy()
        return self._stack[i] + ((t_s - t[i]) / self._dt[i]) * self._dstack[i]


def _fail(path: str, what: str) -> GuidanceReferenceError:
    return GuidanceReferenceError(f"{path}: {what}")


def validate_reference_arrays(path: str, arrays: Mapping[str, np.ndarray]) -> GuidanceReference:
    """Validate a mapping of named arrays (as stored in the file) into a GuidanceReference."""
    meta = check_header(path, arrays, ("format_version", "t_s", "reference", "beta_ff_rad",
                                       "metadata"),
                        FORMAT_VERSION, REQUIRED_METADATA, GuidanceReferenceError)
    if meta["input_names"] != list(MEASUREMENT_NAMES):
        raise _fail(path, f"metadata 'input_names' must be {list(MEASUREMENT_NAMES)}")
    num = numeric_arrays(path, arrays, ("t_s", "reference", "beta_ff_rad"),
                         GuidanceReferenceError)
    t = num["t_s"]
    if t.ndim != 1 or t.size < 2:
        raise _fail(path, "'t_s' must be a 1-D array of at least 2 times")
    if np.any(np.diff(t) <= 0.0):
        raise _fail(path, "'t_s' must be strictly increasing")
    n = t.size
    if num["reference"].shape != (n, len(MEASUREMENT_NAMES)):
        raise _fail(path, f"'reference' has shape {num['reference'].shape}, "
                          f"expected ({n}, {len(MEASUREMENT_NAMES)})")
    if num["beta_ff_rad"].shape != (n,):
        raise _fail(path, f"'beta_ff_rad' has shape {num['beta_ff_rad'].shape}, expected ({n},)")
    for j, name in enumerate(MEASUREMENT_NAMES):
        col = num["reference"][:, j]
        k = int(np.argmax(np.abs(col)))
        if abs(col[k]) > REFERENCE_BOUNDS[name]:
            raise _fail(path, f"reference {name} = {col[k]:.6g} at t = {t[k]:g} s is beyond "
                              f"±{REFERENCE_BOUNDS[name]:.6g} (not a wind bias)")
    k = int(np.argmax(np.abs(num["beta_ff_rad"])))
    if abs(num["beta_ff_rad"][k]) > MAX_FEEDFORWARD_RAD:
        raise _fail(path, f"feed-forward {math.degrees(num['beta_ff_rad'][k]):.4g} deg at "
                          f"t = {t[k]:g} s is beyond ±{math.degrees(MAX_FEEDFORWARD_RAD):g} deg "
                          f"(half the actuator range)")
    return GuidanceReference(path=path, t_s=t, reference=num["reference"],
                             beta_ff_rad=num["beta_ff_rad"], metadata=meta)


def load_guidance_reference(path: str | Path) -> GuidanceReference:
    """Load and validate a guidance reference file.

    Raises
    ------
    GuidanceReferenceError
        One line naming the file and the problem (unreadable, not an npz, any check above).
    """
    p = str(path)
    arrays = read_npz(p, GuidanceReferenceError, "guidance reference")
    return validate_reference_arrays(p, arrays)


def default_reference_path() -> Path:
    """The installed guidance reference ``share/vega_gnc/config/guidance_reference.npz``.

    Raises
    ------
    BadInput
        If the package ``vega_gnc`` is not in the ament index (workspace not built).
    """
    return installed_config("guidance_reference.npz")


def reference_path(setting: str) -> Path | None:
    """The file a ``guidance`` setting names: ``""`` or :data:`DEFAULT_GUIDANCE` → the
    installed one,
    ``"none"`` → None, anything else → that path (not checked here)."""
    if setting == NO_GUIDANCE:
        return None
    return default_reference_path() if setting in ("", DEFAULT_GUIDANCE) else Path(setting)


def resolve_reference(setting: str) -> GuidanceReference | None:
    """The reference a ``guidance`` setting names: ``""`` or ``"default"`` → the installed
    one, ``"none"`` → None (no bias), anything else → that file.

    Raises
    ------
    BadInput
        A file that does not load (one line).
    """
    path = reference_path(setting)
    return None if path is None else load_guidance_reference(path)
