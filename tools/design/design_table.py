"""What the table tools of tools/design share: the design-set check of an edited controller
and writing a structured table with its JSON report, as `vega design` writes them.

Imported by graft.py, set_parameter.py and undo_drift.py (run as scripts: this directory is on
their sys.path).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def misses_check(context, uset, worse: list, against: str = "before"):
    """A check ``(label, t_s, K_new, K_old)`` that prints the requirement misses of both
    discrete controllers on the design set of ``t_s`` and appends ``"<label> <t> s"`` to
    ``worse`` where the new one adds a miss."""
    from vega_design import structured as S

    def check(label, t_s, K_new, K_old):
        ds = S.design_set(context, t_s, uset)
        new = S.requirement_misses(S.evaluate_discrete(K_new, ds, detail=True)[1])
        old = S.requirement_misses(S.evaluate_discrete(K_old, ds, detail=True)[1])
        print(f"{label} {t_s:g} s: misses {new} ({against} {old})", flush=True)
        if any(a > b for a, b in zip(new, old)):
            worse.append(f"{label} {t_s:g} s")

    return check


def write_design(out: Path, context, uset, times, xs, anchors_s, tuning):
    """Evaluate every grid point on its design set, write the structured table ``out`` and
    its report ``out.json``; return the :class:`~vega_design.structured.StructuredDesign`."""
    from vega_design import structured as S
    from vega_loops.margins import json_ready

    times = [float(t) for t in times]
    xs = [np.asarray(x, dtype=float) for x in xs]
    details = [S.evaluate(x, S.design_set(context, t, uset), detail=True)[1]
               for t, x in zip(times, xs)]
    design = S.StructuredDesign(np.array(times), np.array(
        [context.parameters(t).v_mps for t in times]), np.array(xs), details,
        tuple(anchors_s), tuning)
    S.write_structured_table(out, design, context)
    report = {"table": str(out), "grid_times_s": design.grid_times_s,
              "grid_v_mps": design.grid_v_mps, "anchors_s": design.anchors_s,
              "tuning": design.tuning, "per_grid_time": design.details}
    out.with_suffix(".json").write_text(json.dumps(json_ready(report), indent=1) + "\n")
    return design


def structured_grid_point(path, time_s: float):
    """(metadata, grid times [s], index of ``time_s``) of a structured design table; exits with
    one line when the file is not one or has no grid point at ``time_s``."""
    meta = json.loads(str(np.load(path)["metadata"]))
    if meta.get("design") != "structured":
        raise SystemExit(f"{path}: not a structured design table")
    times = [float(t) for t in meta["grid_times_s"]]
    if time_s not in times:
        raise SystemExit(f"{path}: no grid point at {time_s:g} s")
    return meta, times, times.index(time_s)
