"""Ship a signed-off controller table as the flown default (``vega ship``;
docs/FLIGHT_DESIGN.md §6.5).

A table replaces ``ros2_ws/src/vega_gnc/config/tvc_controller.npz`` only with a sign-off record
of its own bytes: the ``verify.json`` that ``vega verify`` (``make verify-design``) wrote.
:func:`ship` refuses — :class:`~vega_core.errors.BadInput`, one line naming the file and what is
wrong, nothing written — a record that is not a complete, passed sign-off
(:func:`~.record.check_record`, against the passes of the flown table's own sign-off), and a
table whose SHA-256 is not the recorded one (changed after it was verified). Otherwise it
writes, each by a rename of a complete file:

* ``config/tvc_controller.npz`` — the table;
* ``config/tvc_controller.json`` — its tuning record (the ``.json`` beside the table, as
  ``vega design`` writes it);
* ``config/tvc_controller.signoff.json`` — the sign-off record, with the time it was shipped.

Then ``make test`` (the tests of the shipped design and the SIL verdicts run on it; one of them
holds the flown table's bytes to the installed record).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from datetime import datetime, timezone
from pathlib import Path

from vega_core.errors import BadInput, one_line

from vega_cli.signoff.record import check_record, read_record, sha256_of, signed_off_passes

__all__ = ["ROOT", "CONFIG", "NAME", "ship"]

ROOT = Path(__file__).resolve().parents[3]
"""The repository (vega_cli is installed in editable mode from ROOT/cli)."""
CONFIG = ROOT / "ros2_ws/src/vega_gnc/config"
"""The flown table's directory in the source tree (installed by the workspace build)."""
NAME = "tvc_controller"
"""The flown table's file name without suffix."""


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


def ship(verify_dir: Path, table: Path | None = None, config: Path = CONFIG,
         write: bool = True) -> dict:
    """Check everything, then (with ``write``) write the three files; returns the sign-off
    record as shipped (with ``shipped_utc`` and ``shipped_from``).

    Parameters
    ----------
    verify_dir : Path
        The ``--out`` directory of ``vega verify`` (holds verify.json).
    table : Path, optional
        The table, if it moved since it was verified (default: the record's path); its
        SHA-256 must be the recorded one, and its tuning record is the ``.json`` beside it.
    config : Path
        The flown table's directory (default :data:`CONFIG`).
    write : bool
        False: check everything and write nothing.

    Raises
    ------
    BadInput
        Before anything is written, for any of the refusals of the module docstring.
    """
    from vega_gnc.controller_table import load_controller_table

    verify_dir, config = Path(verify_dir), Path(config)
    where = verify_dir / "verify.json"
    record = read_record(where)
    flown = config / f"{NAME}.signoff.json"
    floor = signed_off_passes(read_record(flown)) if flown.exists() else None
    check_record(record, where, floor)
    table = Path(record["table"]) if table is None else Path(table)
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
    if write:
        _write(table, None, config / f"{NAME}.npz")
        _write(report, None, config / f"{NAME}.json")
        _write(None, json.dumps(shipped, indent=1) + "\n", flown)
    return shipped
