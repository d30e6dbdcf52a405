"""``vega design``: tune the robust structured controller over the whole flight and export it.

``vega design --out FILE.npz`` runs :func:`vega_design.structured.design_flight`
(docs/FLIGHT_DESIGN.md §4): differential evolution at the anchor times (lift-off, every 10 s,
burn-out; in parallel, ``--workers``), parameters carried to a 2 s grid and re-tuned where
they miss a requirement, the tail-off tuned as one controller, the drift-rate gain scaled after
max-Q (step 6), then the single-parameter repairs of the bending criterion at the dispersed
corners (step 7, :mod:`vega_design.corner_repair`; ``--no-corner-repair`` leaves it out), and
writes the table in the controller-table format (``design: structured``) and its JSON report
(``FILE.json``). The product flies the committed copy,
``vega_gnc/config/tvc_controller.npz``; regenerate it with ``--out
ros2_ws/src/vega_gnc/config/tvc_controller.npz`` and verify it with ``vega margins
--dispersed`` and ``vega robust``.

A table is made from its inputs alone (the code, the vehicle data, the drift-gain schedule and
the options), never from an earlier table. A run takes hours on 2 cores (with the 222-plant
design set an anchor takes ≈ 10 min of one core, the 11 anchors ≈ 55 min), so every finished
tuning task (steps 1–5) is written to a journal, ``FILE.journal.jsonl`` next to ``--out`` or
``--journal FILE`` (:mod:`vega_design.task_journal`): the same command started again reuses
it and gives the uninterrupted run's table. Steps 6 and 7 are not journalled: they are
deterministic functions of the tuned grid points and are recomputed (step 6 a few minutes,
step 7 ≈ 6–25 min on 2 cores, against hours for steps 1–5). Exit 0, or 2 on bad input.
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

    from vega_model.parameters import default_context

    from vega_design.corner_repair import repair_design
    from vega_loops.margins import json_ready
    from vega_design.structured import (
        DRIFT_GAINS_PATH, design_flight, load_drift_gains, write_structured_table,
    )
    from vega_design.task_journal import TaskJournal
    # step 6 refuses a drift-rate scaling that loses vega robust's worst-case bending criterion
    from vega_analysis.robust import worst_case_bending_ok

    out = npz_out(args.out)
    if not 1 <= args.maxiter <= 1000:
        raise BadArgument(f"--maxiter {args.maxiter}: must be within 1..1000")
    if not 0 <= args.workers <= 64:
        raise BadArgument(f"--workers {args.workers}: must be within 0..64")
    if args.journal and Path(args.journal).is_dir():
        raise BadArgument(f"--journal {args.journal}: is a directory")
    if args.drift_gains and args.free_drift_gains:
        raise BadArgument("--drift-gains and --free-drift-gains: give one of them")
    drift_gains, gains_record = None, None
    if not args.free_drift_gains:
        import hashlib

        gains = Path(args.drift_gains or DRIFT_GAINS_PATH)
        drift_gains = load_drift_gains(gains)                  # BadFile: one line, exit 2
        # what was read, not what the file holds hours later when the run ends
        gains_record = {"file": str(gains),
                        "sha256": hashlib.sha256(gains.read_bytes()).hexdigest()}
    start = time.perf_counter()
    context = default_context()
    journal_path = Path(args.journal) if args.journal else out.with_suffix(".journal.jsonl")
    journal = TaskJournal(journal_path)              # BadFile (other code, damaged): exit 2
    print(f"journal {journal_path}: {len(journal)} finished tasks"
          + (" (reused where the same task comes again)" if len(journal) else ""),
          flush=True)
    import threading

    stop = threading.Event()
    threading.Thread(target=heartbeat, args=(journal_path, stop), daemon=True).start()
    try:
        design = design_flight(context, seed=args.seed, maxiter=args.maxiter,
                               workers=args.workers, drift_worst_case=worst_case_bending_ok,
                               journal=journal, drift_gains=drift_gains,
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
                    "a controller table, from its inputs alone (hours on 2 cores). The same "
                    "command started again after an interruption resumes from its journal.")
    p.add_argument("--out", required=True, metavar="FILE.npz", help="output table (.npz)")
    p.add_argument("--seed", type=int, default=1, help="seed of the searches (default 1)")
    p.add_argument("--maxiter", type=int, default=80,
                   help="differential-evolution generations per anchor (default 80)")
    p.add_argument("--no-corner-repair", action="store_true",
                   help="leave out step 7, the single-parameter repairs of the bending "
                        "criterion at the dispersed corners of vega margins --dispersed "
                        "(docs/FLIGHT_DESIGN.md section 4): the table of steps 1-6")
    p.add_argument("--journal", metavar="FILE",
                   help="journal of finished tuning tasks (default: the --out file with the "
                        "suffix .journal.jsonl): the same command started again with the same "
                        "journal reuses them and gives the uninterrupted run's table; a "
                        "journal written by other design code is refused")
    p.add_argument("--workers", type=int, default=2,
                   help="processes for the anchors (default 2; 0 = in this process)")
    p.add_argument("--drift-gains", metavar="FILE.yaml",
                   help="drift-gain schedule the tuning holds k_zdot and k_z at (default: "
                        "offline/vega_design/data/drift_gains.yaml; docs/FLIGHT_DESIGN.md "
                        "section 4, 'The drift gains')")
    p.add_argument("--free-drift-gains", action="store_true",
                   help="tune the drift gains with the other parameters instead of holding "
                        "them at a schedule")
    p.set_defaults(func=_run)
