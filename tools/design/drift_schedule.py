"""Write the drift-gain schedule of `vega design` (offline_synthesis/data/drift_gains.yaml) from a
structured controller table: its k_ż and k_z per grid time, with design step 6 (k_ż × factor from
its start time, where its tuning record says it was applied) divided out, up to the tail-off
hold time (one controller from there on).

Why (docs/FLIGHT_DESIGN.md §4, "The drift gains"): the design cost leaves the drift gains nearly
undetermined, and the Monte Carlo load verdicts follow them — the first from-scratch table
passed 724 of 852 flights, the same table with the shipped table's drift gains 746.

Usage: .venv/bin/vega-env python tools/design/drift_schedule.py TABLE --out FILE.yaml
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
from undo_drift import unscaled


def schedule(table: Path) -> tuple[list[list[float]], dict]:
    """Rows ``[t_s, k_zdot_mrad_per_mps, k_z_urad_per_m]`` (step 6 undone) up to the tail-off
    hold time, and the provenance."""
    from offline_synthesis import structured as S

    meta = json.loads(str(np.load(table)["metadata"]))
    if meta.get("design") != "structured":
        raise SystemExit(f"{table}: not a structured design table")
    drift = meta["solver"].get("drift", {})
    if drift:            # step 6 divided out as undo_drift.py does it (one rule, one place)
        times, xs, _ = unscaled(meta)
    else:
        times = [float(t) for t in meta["grid_times_s"]]
        xs = [np.array(x, dtype=float) for x in meta["parameters_per_grid_time"]]
    k_zdot, k_z = S.PINNED_INDICES
    rows = [[t, float(x[k_zdot]), float(x[k_z])] for t, x in zip(times, xs)
            if t <= S.TAIL_OFF_HOLD_S + 1e-9]
    source = {"table": str(table), "sha256": hashlib.sha256(table.read_bytes()).hexdigest(),
              "created_utc": meta.get("created_utc"), "git_revision": meta.get("git_revision"),
              "step_6_divided_out": drift}
    return rows, source


def main(argv=None) -> int:
    """Read the table, write the schedule (YAML with its provenance)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("table", type=Path)
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    rows, source = schedule(args.table)
    lines = [
        "# Drift-gain schedule of `vega design` (offline_synthesis.structured.DRIFT_GAINS):",
        "# k_zdot [mrad/(m/s)] and k_z [urad/m] per flight time [s], before design step 6 (which",
        "# multiplies k_zdot by its factor from 70 s); linear in time between rows, the last row",
        "# held to burn-out (one controller over the tail-off). The tuning holds these two",
        "# parameters at the schedule and tunes the twelve others (docs/FLIGHT_DESIGN.md §4).",
        "# Written by tools/design/drift_schedule.py from the table below; do not edit by hand.",
        "schema_version: 1",
        f"source: {json.dumps(source)}",
        "columns: [t_s, k_zdot_mrad_per_mps, k_z_urad_per_m]",
        "rows:",
    ]
    lines += [f"  - [{t!r}, {a!r}, {b!r}]" for t, a, b in rows]
    args.out.write_text("\n".join(lines) + "\n")
    print(f"drift_schedule: {len(rows)} rows to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
