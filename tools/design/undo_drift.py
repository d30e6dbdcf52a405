"""Undo step 6 (the drift-rate gain scaled after max-Q) of a structured controller table.

`vega design --drift-from TABLE` refuses a table whose drift-rate gain was scaled already
(scaling twice compounds). To re-apply step 6 with a changed rule (2026-11-27, third session:
`structured.scale_drift` now also checks `vega robust`'s worst-case bending criterion), this
tool writes the table with the recorded factor (``solver.drift.factor``) divided out of k_ż at
every grid point whose tuning record (``solver.how``) says it was scaled, and without the
``drift`` record; every other parameter and record entry is kept. Then:

    python tools/design/undo_drift.py SHIPPED --out UNSCALED.npz
    vega design --drift-from UNSCALED.npz --out NEW.npz

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python tools/design/undo_drift.py TABLE
       --out FILE.npz
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from design_table import write_design

MARK = "; k_zdot x "
"""What :func:`vega_design.structured.scale_drift` appends to a scaled point's record."""


def unscaled(meta: dict) -> tuple[list[float], list[np.ndarray], dict]:
    """Grid times, parameters with the drift step undone, and the tuning record without it.

    Raises SystemExit when the record does not say the step was applied, or says it for no
    grid point."""
    from vega_design import structured as S

    solver = dict(meta.get("solver", {}))
    if "drift" not in solver:
        raise SystemExit("the table's tuning record has no drift step (solver.drift)")
    factor = float(solver.pop("drift")["factor"])
    how = dict(solver.get("how", {}))
    times = [float(t) for t in meta["grid_times_s"]]
    xs = [np.array(x, dtype=float) for x in meta["parameters_per_grid_time"]]
    n = 0
    for t, x in zip(times, xs):
        key = f"{t:g}"
        if MARK in how.get(key, ""):
            x[S.DRIFT_RATE_INDEX] /= factor
            how[key] = how[key].split(MARK)[0]
            n += 1
    if n == 0:
        raise SystemExit(f"the tuning record says no grid point was scaled ({MARK.strip()!r})")
    solver["how"] = how
    return times, xs, {k: v for k, v in solver.items() if k not in ("method", "scipy")}


def main(argv=None) -> int:
    """Read, undo, write (table and JSON report, as `vega design` does)."""
    from vega_model.parameters import default_context
    from vega_model.uncertainty import UncertaintySet

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    meta = json.loads(str(np.load(args.table)["metadata"]))
    if meta.get("design") != "structured":
        raise SystemExit(f"{args.table}: not a structured design table")
    times, xs, tuning = unscaled(meta)
    context = default_context()
    uset = UncertaintySet.from_vehicle(context.vehicle)
    write_design(args.out, context, uset, times, xs, meta["anchors_s"], tuning)
    print(f"wrote {args.out} ({len(times)} grid points, drift step undone) and "
          f"{args.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
