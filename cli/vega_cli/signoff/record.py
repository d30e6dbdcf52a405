"""The sign-off record of a controller table (``verify.json``, written by ``vega verify``) and
the rule a record must meet for ``vega ship`` to install the table it signs off.

A record holds the table's path and SHA-256 (taken when the table was read, so a record signs
off bytes, not a file name), the scope of its checks (which checks, SIL scenarios, frozen times,
flights, Monte Carlo reference and, when one was flown, the held-out reference campaign), per
check its command's exit status, wall time, figures and verdict, and ``signed_off``: every
gated check passed and the table did not change while they ran.

A complete sign-off (:func:`check_record`) is a signed-off record whose scope is the whole
sign-off: every check of :data:`CHECKS`, every scenario of :data:`GATED_SCENARIOS`, the frozen
times :data:`FULL_FLIGHT_AT`, at least :data:`MIN_RUNS` flights and a Monte Carlo reference of
passes no lower than the flown table's own.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from vega_core.errors import BadInput, one_line

__all__ = ["CHECKS", "GATED_SCENARIOS", "REPORTED_SCENARIOS", "FULL_FLIGHT_AT", "MIN_RUNS",
           "sha256_of", "read_record", "check_record", "signed_off_passes"]

CHECKS = ("sil", "margins", "robust", "mc", "flight-day")
"""The checks of a sign-off, in the order they run."""
GATED_SCENARIOS = ("nominal", "thesis", "gust", "wind_change", "dispersed_bending_low",
                   "dispersed_bending_high", "dispersed_mode2", "dispersed_worst")
"""SIL scenarios a table must fly with exit status 0."""
REPORTED_SCENARIOS = ("severe", "nominal_no_bias")
"""SIL scenarios flown and reported, not gated: ``severe`` is declared off-design in its
scenario file; ``nominal_no_bias`` is the guidance's no-bias case, expected to fail its drift
and load requirements."""
FULL_FLIGHT_AT = "0:100:0.5"
"""The frozen times of the sign-off: the whole flight every 0.5 s (``vega verify``'s
default)."""
MIN_RUNS = 852
"""Flights of the sign-off campaign: 852 without failure demonstrate 99.73 % at 90 %
confidence (docs/MONTE_CARLO.md); fewer cannot, so a shorter campaign is no sign-off."""


def sha256_of(path: Path) -> str:
    """The SHA-256 of the file at ``path`` (hex): ties a sign-off record to the table's bytes,
    so that ``vega ship`` can refuse a table changed after it was verified."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def signed_off_passes(record: dict) -> int | None:
    """The campaign passes of a sign-off record (its ``mc`` check), or None without one."""
    for check in record.get("checks", []):
        if str(check.get("check", "")).startswith("mc "):
            return check.get("figures", {}).get("passed")
    return None


def read_record(path: Path) -> dict:
    """The sign-off record at ``path`` (a JSON object), or :class:`BadInput`."""
    path = Path(path)
    try:
        record = json.loads(path.read_text())
    except OSError as exc:
        raise BadInput(f"sign-off record {path}: {one_line(exc)}") from None
    except json.JSONDecodeError as exc:
        raise BadInput(f"sign-off record {path}: not JSON ({exc.msg}, line {exc.lineno})") \
            from None
    if not isinstance(record, dict):
        raise BadInput(f"sign-off record {path}: not a JSON object")
    return record


def check_record(record: dict, where: Path, reference_floor: int | None) -> None:
    """:class:`BadInput` naming ``where`` and what is short unless ``record`` is a complete,
    passed sign-off (module docstring); ``reference_floor``: the passes of the flown table's own
    sign-off, if it has one (a design may not be compared against a lower bar than the one it
    replaces)."""
    missing = [k for k in ("table", "table_sha256", "scope", "checks", "signed_off")
               if k not in record]
    if missing:
        raise BadInput(f"sign-off record {where}: no {', '.join(missing)} (written by an older "
                       "vega verify? verify the table again)")
    failed = [c.get("check") for c in record["checks"] if c.get("gated") and not c.get("passed")]
    if record["signed_off"] is not True or failed:
        raise BadInput(f"sign-off record {where}: not signed off"
                       + (f" (failed: {', '.join(map(str, failed))})" if failed else ""))
    scope = record["scope"]
    short = [c for c in CHECKS if c not in scope.get("checks", [])]
    short += [f"scenario {s}" for s in GATED_SCENARIOS if s not in scope.get("scenarios", [])]
    if scope.get("at") != FULL_FLIGHT_AT:
        short.append(f"frozen times {scope.get('at')!r} (not {FULL_FLIGHT_AT})")
    if not isinstance(scope.get("runs"), int) or scope["runs"] < MIN_RUNS:
        short.append(f"{scope.get('runs')} flights (fewer than {MIN_RUNS})")
    reference = scope.get("mc_reference")
    if reference is None:
        short.append("no Monte Carlo reference")
    elif reference_floor is not None and reference < reference_floor:
        short.append(f"Monte Carlo reference {reference} below the flown table's "
                     f"{reference_floor} passes")
    if short:
        raise BadInput(f"sign-off record {where}: short of the full sign-off: "
                       + "; ".join(short))
