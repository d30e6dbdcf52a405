"""Step 6 of the structured design (the drift-rate gain after max-Q) with the worst-case check.

`vega design --drift-from TABLE` applies step 6 with the design-set checks of
`offline_synthesis.structured.scale_drift`; this tool applies it with `vega robust`'s
worst-case bending check as well (`structured_worst_case.worst_case_bending_ok`, passed in:
`offline_synthesis.robust` imports `structured`, so `structured` cannot import it) and writes
the table and its JSON report as `vega design` does. Made the shipped table of 2026-11-27,
third session (docs/FLIGHT_DESIGN.md §4):

    python tools/design/undo_drift.py SHIPPED --out U.npz
    python tools/design/set_parameter.py U.npz 82 notch1_zeta_num 0.040 --out E.npz
    python tools/design/drift_checked.py E.npz --out NEW.npz

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python tools/design/drift_checked.py TABLE
       --out FILE.npz
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def main(argv=None) -> int:
    """Read, scale with the checks, write."""
    from offline_synthesis import structured as S
    from offline_synthesis.margins import json_ready
    from offline_synthesis.structured_worst_case import worst_case_bending_ok
    from vega_model.parameters import default_context

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    meta = json.loads(str(np.load(args.table)["metadata"]))
    if meta.get("design") != "structured":
        raise SystemExit(f"{args.table}: not a structured design table")
    start = time.perf_counter()
    tuning = {k: v for k, v in meta.get("solver", {}).items() if k not in ("method", "scipy")}
    design = S.rescale_drift(default_context(), meta["grid_times_s"],
                             meta["parameters_per_grid_time"], meta["anchors_s"], tuning,
                             progress=lambda line: print(line, flush=True),
                             worst_case=worst_case_bending_ok)
    S.write_structured_table(args.out, design, default_context())
    report = {"table": str(args.out), "run_time_s": time.perf_counter() - start,
              "grid_times_s": design.grid_times_s, "grid_v_mps": design.grid_v_mps,
              "anchors_s": design.anchors_s, "tuning": design.tuning,
              "per_grid_time": design.details}
    args.out.with_suffix(".json").write_text(json.dumps(json_ready(report), indent=1) + "\n")
    print(f"wrote {args.out} and {args.out.with_suffix('.json')} in "
          f"{report['run_time_s']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
