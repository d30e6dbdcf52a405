"""Write the drift-gain schedule of `vega design` (offline/vega_design/data/drift_gains.yaml) from a
structured controller table: its drift gains per unit k_θ (g_ż = k_ż/k_θ, g_z = k_z/k_θ: the
attitude the drift loop commands per m/s of drift rate and per m of drift; schema 2, since
2026-12-02) per grid time, with design step 6 (k_ż × factor from its start time, where its
tuning record says it was applied) divided out, up to the tail-off hold time (one controller
from there on). ``--absolute`` writes k_ż and k_z themselves (schema 1, the schedule of
2026-11-27 to 2026-12-02).

Why (docs/FLIGHT_DESIGN.md §4, "The drift gains"): the design cost leaves the drift gains nearly
undetermined, and the Monte Carlo load verdicts follow them — the first from-scratch table
passed 724 of 852 flights, the same table with the shipped table's drift gains 746. Per unit
k_θ: a tuning that softens the attitude loop would otherwise command more attitude per unit
drift than the table the schedule came from (§4).

Usage: .venv/bin/vega-env python tools/design/drift_schedule.py TABLE --out FILE.yaml [--absolute]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
from undo_drift import unscaled


def schedule(table: Path, per_k_theta: bool = True) -> tuple[list[list[float]], dict]:
    """Rows ``[t_s, g_zdot, g_z]`` (per unit k_θ; ``[t_s, k_zdot, k_z]`` without
    ``per_k_theta``), step 6 undone, up to the tail-off hold time, and the provenance."""
    from vega_design import structured as S

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
    rows = [[t, *(float(x[i] / (10.0 ** x[0] if per_k_theta else 1.0)) for i in (k_zdot, k_z))]
            for t, x in zip(times, xs) if t <= S.TAIL_OFF_HOLD_S + 1e-9]
    source = {"table": str(table), "sha256": hashlib.sha256(table.read_bytes()).hexdigest(),
              "created_utc": meta.get("created_utc"), "git_revision": meta.get("git_revision"),
              "step_6_divided_out": drift}
    return rows, source


def main(argv=None) -> int:
    """Read the table, write the schedule (YAML with its provenance)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("table", type=Path)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--absolute", action="store_true",
                   help="k_zdot and k_z themselves (schema 1), not per unit k_theta")
    args = p.parse_args(argv)
    rows, source = schedule(args.table, per_k_theta=not args.absolute)
    if args.absolute:
        what = ["# k_zdot [mrad/(m/s)] and k_z [urad/m] per flight time [s], before design step 6",
                "# (which multiplies k_zdot by its factor from 70 s); linear in time between rows,"]
        head = ["schema_version: 1", f"source: {json.dumps(source)}",
                "columns: [t_s, k_zdot_mrad_per_mps, k_z_urad_per_m]"]
    else:
        what = ["# the drift gains per unit k_theta, g_zdot = k_zdot/k_theta [mrad/(m/s)] and",
                "# g_z = k_z/k_theta [urad/m] (the attitude the drift loop commands per m/s of",
                "# drift rate and per m of drift), per flight time [s], before design step 6",
                "# (which multiplies k_zdot by its factor from 70 s); linear in time between rows,"]
        head = ["schema_version: 2", f"source: {json.dumps(source)}",
                "columns: [t_s, g_zdot_mrad_per_mps_per_k_theta, g_z_urad_per_m_per_k_theta]"]
    lines = [
        "# Drift-gain schedule of `vega design` (vega_design.structured.DRIFT_GAINS_PATH):",
        *what,
        "# the last row held to burn-out (one controller over the tail-off). The tuning holds",
        "# the two drift gains at the schedule and tunes the twelve others",
        "# (docs/FLIGHT_DESIGN.md §4). Written by tools/design/drift_schedule.py from the table",
        "# below; do not edit by hand.",
        *head,
        "rows:",
    ]
    lines += [f"  - [{t!r}, {a!r}, {b!r}]" for t, a, b in rows]
    args.out.write_text("\n".join(lines) + "\n")
    print(f"drift_schedule: {len(rows)} rows to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
