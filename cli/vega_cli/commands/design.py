"""``vega design``: tune the robust structured controller over the whole flight and export it.

``vega design --out FILE.npz`` runs :func:`vega_design.structured.design_flight`
(docs/FLIGHT_DESIGN.md): differential evolution at the anchor times (lift-off, every 10 s,
burn-out; in parallel, ``--workers``), parameters carried to a 2 s grid and re-tuned where
they miss a requirement, then the table in the controller-table format (``design:
structured``) and its JSON report (``FILE.json``). The product flies the committed copy,
``vega_gnc/config/tvc_controller.npz``; regenerate it with ``--out
ros2_ws/src/vega_gnc/config/tvc_controller.npz`` (hours on 2 cores: with the 222-plant design
set an anchor takes ≈ 10 min of one core, the 11 anchors ≈ 55 min; every finished tuning task
is written to a journal, ``FILE.journal.jsonl`` next to ``--out`` or ``--journal``, and the
same command started again after an interruption reuses it and gives the uninterrupted run's
table — :mod:`vega_design.task_journal`;
``--anchors-from TABLE`` reuses an earlier table's anchors and re-tunes only the grid;
``--repair-from TABLE`` keeps every grid point of an earlier table that meets the current
requirements and re-tunes the others; ``--tail-from TABLE`` keeps every grid point before the
tail-off and re-tunes only the one tail-off controller, jointly over 86–100 s; ``--drift-from
TABLE`` applies only step 6, the drift-rate gain after max-Q; ``--corner-repair-from TABLE``
only step 7, the single-parameter repairs of the bending criterion at the dispersed corners,
:mod:`vega_design.corner_repair`, which a full run applies last unless
``--no-corner-repair``) and verify it with ``vega margins --dispersed`` and ``vega robust``.
Exit 0, or 2 on bad input.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from vega_core.errors import BadArgument

from vega_cli.commands._paths import npz_out

__all__ = ["register"]


def heartbeat(journal_path: Path, stop, every_s: float = 60.0, out=None) -> None:
    """Until ``stop`` (a :class:`threading.Event`) is set: every ``every_s`` a line with the
    time since the start and the number of tuning tasks finished so far (the journal's
    lines): a search prints only when a task finishes, ≈ 10 min apart for anchors."""
    import sys
    import time

    start = time.monotonic()
    while not stop.wait(every_s):
        try:
            with open(journal_path, "rb") as f:
                finished = max(sum(1 for _ in f) - 1, 0)
        except OSError:
            continue
        print(f"vega design: {(time.monotonic() - start) / 60:.0f} min, {finished} tuning "
              f"tasks finished (journal {journal_path})", file=out or sys.stdout, flush=True)


def _run(args: argparse.Namespace) -> int:
    import os

    # one BLAS thread here too, as in the spawned tuning processes: a task of a resumed run that
    # runs in this process (the last one of a batch) computes what a worker computed (numpy is
    # imported below, after this; an explicit setting of the caller is kept)
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")
    import json
    import time

    import numpy as np
    from vega_model.parameters import default_context

    from vega_design.corner_repair import repair_design
    from vega_loops.margins import json_ready
    from vega_design.structured import (
        DRIFT_GAINS_PATH, PARAMETERS, TAIL_OFF_HOLD_S, design_flight, load_drift_gains,
        rescale_drift, retune_tail, write_structured_table,
    )
    # step 6 refuses a drift-rate scaling that loses vega robust's worst-case bending criterion
    from vega_analysis.robust import worst_case_bending_ok

    out = npz_out(args.out)
    if not 1 <= args.maxiter <= 1000:
        raise BadArgument(f"--maxiter {args.maxiter}: must be within 1..1000")
    if not 0 <= args.workers <= 64:
        raise BadArgument(f"--workers {args.workers}: must be within 0..64")
    anchor_x = None
    given = [o for o, v in (("--anchors-from", args.anchors_from),
                            ("--repair-from", args.repair_from),
                            ("--tail-from", args.tail_from),
                            ("--drift-from", args.drift_from),
                            ("--corner-repair-from", args.corner_repair_from)) if v]
    if len(given) > 1:
        raise BadArgument(f"{' and '.join(given)}: give one of them")
    if args.journal and (args.tail_from or args.drift_from or args.corner_repair_from):
        raise BadArgument(f"--journal with {given[0]}: only the tuning of a full run, "
                          "--anchors-from or --repair-from is journalled")
    if args.journal and Path(args.journal).is_dir():
        raise BadArgument(f"--journal {args.journal}: is a directory")
    tunes = not (args.tail_from or args.drift_from or args.corner_repair_from)
    if args.drift_gains and args.free_drift_gains:
        raise BadArgument("--drift-gains and --free-drift-gains: give one of them")
    if (args.drift_gains or args.free_drift_gains) and not tunes:
        raise BadArgument(f"{'--drift-gains' if args.drift_gains else '--free-drift-gains'} "
                          f"with {given[0]}: only a full run, --anchors-from or --repair-from "
                          "tunes")
    drift_gains, gains_record = None, None
    if tunes and not args.free_drift_gains:
        import hashlib

        gains = Path(args.drift_gains or DRIFT_GAINS_PATH)
        drift_gains = load_drift_gains(gains)                  # BadFile: one line, exit 2
        # what was read, not what the file holds hours later when the run ends
        gains_record = {"file": str(gains),
                        "sha256": hashlib.sha256(gains.read_bytes()).hexdigest()}
    if args.no_corner_repair and (given and not args.anchors_from and not args.repair_from):
        raise BadArgument(f"--no-corner-repair with {given[0]}: that option runs one step "
                          "only, and never the corner repair (or it is the corner repair)")
    source_path = (args.anchors_from or args.repair_from or args.tail_from or args.drift_from
                   or args.corner_repair_from)
    option = given[0] if given else None
    if source_path:
        from vega_gnc.controller_table import load_controller_table

        source = load_controller_table(source_path)     # BadFile: one line, exit 2
        meta = source.metadata
        keys = ("anchors_s", "grid_times_s", "parameters_per_grid_time")
        if source.design != "structured" or any(k not in meta for k in keys):
            raise BadArgument(f"{option} {source_path}: not a structured design "
                              "table (no tuned parameters in its metadata)")
        by_time = dict(zip(meta["grid_times_s"], meta["parameters_per_grid_time"]))
        grid = (args.repair_from or args.tail_from or args.drift_from
                or args.corner_repair_from)
        used = meta["grid_times_s"] if grid else meta["anchors_s"]
        if any(t not in by_time or len(by_time[t]) != len(PARAMETERS) for t in used):
            raise BadArgument(f"{option} {source_path}: its "
                              f"{'grid points' if grid else 'anchors'} have no "
                              f"{len(PARAMETERS)} tuned parameters in its metadata")
        if args.tail_from and TAIL_OFF_HOLD_S not in by_time:
            raise BadArgument(f"--tail-from {source_path}: no grid point at the tail-off "
                              f"hold time {TAIL_OFF_HOLD_S:g} s")
        if args.drift_from and "drift" in meta.get("solver", {}):
            raise BadArgument(f"--drift-from {source_path}: its drift-rate gain was already "
                              f"scaled ({meta['solver']['drift']}); scaling twice compounds")
        anchor_x = {float(t): by_time[t] for t in used}
    start = time.perf_counter()
    context = default_context()
    kwargs = {"anchors_s": sorted(anchor_x)} if args.repair_from else {}
    if args.tail_from or args.drift_from or args.corner_repair_from:
        tuning = {k: v for k, v in meta.get("solver", {}).items()
                  if k not in ("method", "scipy")}
    if args.corner_repair_from:
        from vega_design.structured import StructuredDesign

        times = sorted(anchor_x)
        design = StructuredDesign(
            np.array(times), np.array([context.parameters(t).v_mps for t in times]),
            np.array([anchor_x[t] for t in times], dtype=float), [None] * len(times),
            tuple(meta["anchors_s"]), tuning)
        design = repair_design(context, design, workers=args.workers,
                               worst_case=worst_case_bending_ok,
                               progress=lambda line: print(line, flush=True))
    elif args.drift_from:
        design = rescale_drift(context, sorted(anchor_x),
                               [anchor_x[t] for t in sorted(anchor_x)], meta["anchors_s"],
                               tuning, progress=lambda line: print(line, flush=True),
                               worst_case=worst_case_bending_ok)
    elif args.tail_from:
        design = retune_tail(context, sorted(anchor_x), [anchor_x[t] for t in sorted(anchor_x)],
                             meta["anchors_s"], tuning, seed=args.seed + 4000,
                             progress=lambda line: print(line, flush=True))
    else:
        from vega_design.task_journal import TaskJournal

        journal_path = (Path(args.journal) if args.journal
                        else out.with_suffix(".journal.jsonl"))
        journal = TaskJournal(journal_path)          # BadFile (other code, damaged): exit 2
        print(f"journal {journal_path}: {len(journal)} finished tasks"
              + (" (reused where the same task comes again)" if len(journal) else ""),
              flush=True)
        import threading

        stop = threading.Event()
        threading.Thread(target=heartbeat, args=(journal_path, stop), daemon=True).start()
        try:
            design = design_flight(context, seed=args.seed, maxiter=args.maxiter,
                                   workers=args.workers, anchor_x=anchor_x,
                                   repair=bool(args.repair_from), **kwargs,
                                   drift_worst_case=worst_case_bending_ok, journal=journal,
                                   drift_gains=drift_gains,
                                   progress=lambda line: print(line, flush=True))
        finally:
            stop.set()
        if gains_record is not None:
            design.tuning["drift_gains"] = {**design.tuning["drift_gains"], **gains_record}
        if not args.no_corner_repair:
            design = repair_design(context, design, workers=args.workers,
                                   worst_case=worst_case_bending_ok,
                                   progress=lambda line: print(line, flush=True))
    table = write_structured_table(out, design, context)
    report = {"table": str(out), "run_time_s": time.perf_counter() - start,
              "grid_times_s": design.grid_times_s, "grid_v_mps": design.grid_v_mps,
              "anchors_s": design.anchors_s, "tuning": design.tuning,
              "per_grid_time": design.details}
    out.with_suffix(".json").write_text(json.dumps(json_ready(report), indent=1) + "\n")
    worst_pm = min(d["pm_deg"] for d in design.details)
    missed = [float(t) for t, d in zip(design.grid_times_s, design.details) if d["penalty"] > 0]
    print(f"wrote {out} ({table.grid_v_mps.size} grid points, order {table.n_states}) and "
          f"{out.with_suffix('.json')} in {report['run_time_s']:.0f} s; design-grid worst "
          f"nominal PM {worst_pm:.1f}°; grid times missing a design target: "
          f"{missed if missed else 'none'} (verify: vega margins --table {out} --dispersed)")
    return 0


def register(subparsers) -> None:
    """Add the ``design`` sub-command."""
    p = subparsers.add_parser(
        "design", help="tune and export the robust structured controller (0-100 s)",
        description="Tune the scheduled structured TVC controller against the margin and "
                    "robust-stability requirements (docs/FLIGHT_DESIGN.md) and export it as "
                    "a controller table.")
    p.add_argument("--out", required=True, metavar="FILE.npz", help="output table (.npz)")
    p.add_argument("--seed", type=int, default=1, help="seed of the searches (default 1)")
    p.add_argument("--maxiter", type=int, default=80,
                   help="differential-evolution generations per anchor (default 80)")
    p.add_argument("--repair-from", metavar="TABLE",
                   help="keep every grid point of an earlier structured table that meets every "
                        "requirement of the current design set, re-tune the others from "
                        "scratch, then check between grid points (a repair after a "
                        "requirement was added)")
    p.add_argument("--anchors-from", metavar="TABLE",
                   help="reuse the anchor times' parameters of an earlier structured table "
                        "(skips their from-scratch search and re-tunes only the grid)")
    p.add_argument("--tail-from", metavar="TABLE",
                   help="keep every grid point of an earlier structured table before the "
                        "tail-off hold time (86 s) and re-tune only the one tail-off "
                        "controller, jointly over 86-100 s (≈ 15 min on one core)")
    p.add_argument("--drift-from", metavar="TABLE",
                   help="keep every grid point of an earlier structured table and apply only "
                        "the last design step, the drift-rate gain scaled after max-Q where "
                        "the scaled point still meets every requirement (docs/FLIGHT_DESIGN.md "
                        "section 4, step 6; a few minutes)")
    p.add_argument("--corner-repair-from", metavar="TABLE",
                   help="keep every grid point of an earlier structured table and apply only "
                        "step 7: single-parameter repairs where the flown controller misses "
                        "the bending criterion at a dispersed corner of vega margins "
                        "--dispersed (docs/FLIGHT_DESIGN.md section 4; ~6 min on 2 cores "
                        "plus ~0.5 min per repaired point)")
    p.add_argument("--no-corner-repair", action="store_true",
                   help="a full run (or --anchors-from / --repair-from) without step 7")
    p.add_argument("--journal", metavar="FILE",
                   help="journal of finished tuning tasks (default: the --out file with the "
                        "suffix .journal.jsonl): a run interrupted and started again with the "
                        "same journal reuses them and gives the uninterrupted run's table "
                        "(full runs, --anchors-from, --repair-from)")
    p.add_argument("--workers", type=int, default=2,
                   help="processes for the anchors (default 2; 0 = in this process)")
    p.add_argument("--drift-gains", metavar="FILE.yaml",
                   help="drift-gain schedule the tuning holds k_zdot and k_z at (default: "
                        "offline/vega_design/data/drift_gains.yaml; docs/FLIGHT_DESIGN.md "
                        "section 4, 'The drift gains')")
    p.add_argument("--free-drift-gains", action="store_true",
                   help="tune the drift gains with the other parameters (the tables made "
                        "before 2026-11-27, eighth session)")
    p.set_defaults(func=_run)
