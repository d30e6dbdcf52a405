"""Graft the grid points of one structured controller table into another, inside a time window.

Used on 2026-11-27 to make the shipped table (docs/FLIGHT_DESIGN.md §4, "Two changes on
2026-11-27"): grid points of the repair run of 2026-11-26 (`vega design --repair-from`, which
met the exact bending criterion on the 222-plant design set at many times but was not
shippable as a whole) replace those of the table flown before, in three windows (18–28 s,
56–64 s, 32–36 s); `vega design --drift-from` applied step 6. Every grid point of the window
and the flown (interpolated) controller midway across both window edges are evaluated on their
design sets and printed with their requirement misses
(vega_design.structured.requirement_misses); nothing is written when a grafted point or
an edge midpoint adds a miss to what the base table had there. The tuning record lists the
grafts (``solver.grafts``: window and the source table's SHA-256).

Usage: OPENBLAS_NUM_THREADS=1 .venv/bin/vega-env python tools/design/graft.py BASE OTHER
       START STOP --out FILE.npz
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
from design_table import misses_check, write_design


def _design(path: Path):
    meta = json.loads(str(np.load(path)["metadata"]))
    if meta.get("design") != "structured":
        raise SystemExit(f"{path}: not a structured design table")
    return meta, dict(zip(meta["grid_times_s"], meta["parameters_per_grid_time"]))


def main(argv=None) -> int:
    """Graft, check, write."""
    from vega_design import structured as S
    from vega_model.parameters import default_context
    from vega_model.uncertainty import UncertaintySet

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", type=Path)
    parser.add_argument("other", type=Path)
    parser.add_argument("start", type=float)
    parser.add_argument("stop", type=float)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    if not args.start < args.stop:
        parser.error(f"window {args.start:g}..{args.stop:g} s: start must be before stop")
    context = default_context()
    uset = UncertaintySet.from_vehicle(context.vehicle)
    base_meta, base = _design(args.base)
    _, other = _design(args.other)
    inside = lambda t: args.start - 1e-9 <= t <= args.stop + 1e-9  # noqa: E731
    merged = {t: x for t, x in base.items() if not inside(t)}
    merged.update({t: x for t, x in other.items() if inside(t)})
    times = sorted(merged)
    worse = []
    check = misses_check(context, uset, worse, against="base")

    def discrete(t, x):
        return S.discretise(*S.controller_ss(x, context.parameters(float(t)).omega_radps),
                            1.0 / float(context.vehicle["controller.rate_hz"]))

    base_times = sorted(base)
    for t in [t for t in times if inside(t)]:
        # the base's flown controller at t: its grid point, or interpolated between its points
        left = max(b for b in base_times if b <= t)
        right = min(b for b in base_times if b >= t)
        K_old = discrete(t, base[t]) if t in base else S.flown_between(
            context, (left, base[left]), (right, base[right]), t)
        check("grafted", t, discrete(t, merged[t]), K_old)
    edges = [(max(t for t in times if t < args.start), min(t for t in times if inside(t))),
             (max(t for t in times if inside(t)), min(t for t in times if t > args.stop))]
    for a, b in edges:
        mid = 0.5 * (a + b)
        left = max(t for t in base_times if t <= mid)
        right = min(t for t in base_times if t >= mid)
        check("edge midpoint", mid,
              S.flown_between(context, (a, merged[a]), (b, merged[b]), mid),
              S.flown_between(context, (left, base[left]), (right, base[right]), mid))
    if worse:
        print(f"not written: the graft adds a requirement miss at {', '.join(worse)}",
              file=sys.stderr)
        return 1
    tuning = dict(base_meta.get("solver", {}))
    tuning = {k: v for k, v in tuning.items() if k not in ("method", "scipy")}
    grafts = list(tuning.pop("grafts", []))
    if "graft" in tuning:                       # the record of the first graft (one window)
        grafts.append(tuning.pop("graft"))
    grafts.append({"window_s": [args.start, args.stop],
                   "from_sha256": hashlib.sha256(args.other.read_bytes()).hexdigest()})
    tuning["grafts"] = grafts
    write_design(args.out, context, uset, times, [merged[t] for t in times],
                 base_meta["anchors_s"], tuning)
    print(f"wrote {args.out} ({len(times)} grid points) and {args.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
