"""Ship a signed-off controller table as the flown default (docs/FLIGHT_DESIGN.md §6.5).

A table replaces ``ros2_ws/src/vega_gnc/config/tvc_controller.npz`` only with a sign-off record
of its own bytes: the ``verify.json`` that ``make verify-design`` (``verify_table.py``) wrote.
This tool refuses — one line naming the file and what is wrong, exit 2, nothing written — a
record that is not signed off, one whose scope is short of the full sign-off (every check,
every gated SIL scenario, the frozen times 0–100 s every 0.5 s, at least 852 flights against a
reference of passes no lower than the flown table's own), and a table whose SHA-256 is not
the recorded one (changed after it was verified). Otherwise it writes, each by a rename of a
complete file:

* ``config/tvc_controller.npz`` — the table;
* ``config/tvc_controller.json`` — its tuning record (the ``.json`` beside the table, as
  ``vega design`` writes it);
* ``config/tvc_controller.signoff.json`` — the sign-off record, with the time it was shipped.

Then ``make test`` (the tests of the shipped design and the SIL verdicts run on it; one of
them checks that the flown table's bytes are the signed-off ones).

Usage: .venv/bin/vega-env python tools/design/ship_table.py VERIFY_DIR [--table FILE]
       [--config DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

from verify_table import CHECKS, GATED_SCENARIOS, sha256_of
from vega_core.errors import BadInput, one_line

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "ros2_ws/src/vega_gnc/config"
NAME = "tvc_controller"
FULL_FLIGHT_AT = "0:100:0.5"
"""The frozen times of the sign-off: the whole flight every 0.5 s (verify_table's default)."""
MIN_RUNS = 852
"""Flights of the sign-off campaign: 852 without failure demonstrate 99.73 % at 90 %
confidence (docs/MONTE_CARLO.md); fewer cannot, so a shorter campaign is no sign-off."""


def signed_off_passes(record: dict) -> int | None:
    """The campaign passes of a sign-off record (its ``mc`` check), or None without one."""
    for check in record.get("checks", []):
        if str(check.get("check", "")).startswith("mc "):
            return check.get("figures", {}).get("passed")
    return None


def read_record(path: Path) -> dict:
    """The sign-off record at ``path`` (a JSON object), or :class:`BadInput`."""
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
    """:class:`BadInput` unless ``record`` is a complete, passed sign-off (module docstring);
    ``reference_floor``: the passes of the flown table's own sign-off, if it has one."""
    missing = [k for k in ("table", "table_sha256", "scope", "checks", "signed_off")
               if k not in record]
    if missing:
        raise BadInput(f"sign-off record {where}: no {', '.join(missing)} (written by an older "
                       "verify_table.py? verify the table again)")
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


def _write(source: Path | None, text: str | None, target: Path) -> None:
    """``target`` replaced by a complete copy of ``source`` (or by ``text``): written beside it
    and renamed, so an interrupted ship leaves the old file or the new one, never half."""
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.")
    os.close(fd)
    try:
        if source is not None:
            shutil.copyfile(source, tmp)
        else:
            Path(tmp).write_text(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def ship(verify_dir: Path, table: Path | None = None, config: Path = CONFIG) -> dict:
    """Check everything, then write the three files; returns the shipped sign-off record.

    Raises
    ------
    BadInput
        Before anything is written, for any of the refusals of the module docstring.
    """
    from vega_gnc.controller_table import load_controller_table

    where = verify_dir / "verify.json"
    record = read_record(where)
    flown = config / f"{NAME}.signoff.json"
    floor = signed_off_passes(read_record(flown)) if flown.exists() else None
    check_record(record, where, floor)
    table = Path(record["table"]) if table is None else table
    report = table.with_suffix(".json")
    for path, what in ((table, "table"), (report, "tuning record")):
        if not path.is_file():
            raise BadInput(f"{what} {path}: not found (give the table with --table)")
    if sha256_of(table) != record["table_sha256"]:
        raise BadInput(f"table {table}: SHA-256 {sha256_of(table)[:12]}… is not the signed-off "
                       f"{str(record['table_sha256'])[:12]}… of {where}: changed since verified")
    try:
        load_controller_table(table)
    except (BadInput, OSError) as exc:
        raise BadInput(f"table {table}: {one_line(exc)}") from None
    if not config.is_dir():
        raise BadInput(f"--config {config}: not a directory")
    shipped = {**record, "shipped_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
               "shipped_from": str(table)}
    _write(table, None, config / f"{NAME}.npz")
    _write(report, None, config / f"{NAME}.json")
    _write(None, json.dumps(shipped, indent=1) + "\n", flown)
    return shipped


def main(argv=None) -> int:
    """Exit 0 shipped, 2 refused (one line, nothing written)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("verify_dir", type=Path, help="the --out directory of verify_table.py")
    p.add_argument("--table", type=Path, default=None,
                   help="the table, if it moved since it was verified (its SHA-256 is checked)")
    p.add_argument("--config", type=Path, default=CONFIG,
                   help=f"the flown table's directory (default {CONFIG.relative_to(ROOT)})")
    args = p.parse_args(argv)
    try:
        shipped = ship(args.verify_dir, args.table, args.config)
    except BadInput as exc:
        print(f"ship_table: {exc}", file=sys.stderr)
        return 2
    print(f"ship_table: {shipped['shipped_from']} (SHA-256 {shipped['table_sha256'][:12]}…, "
          f"{signed_off_passes(shipped)} of {shipped['scope']['runs']} flights) is the flown "
          f"table now: {args.config / NAME}.npz, .json, .signoff.json; run make test")
    return 0


if __name__ == "__main__":
    sys.exit(main())
