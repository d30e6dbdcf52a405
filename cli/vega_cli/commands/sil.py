"""``vega sil run``: fly a scenario through the ROS 2 node graph, record a bag, check it.

Arguments are validated before anything starts (an unknown scenario, a bad seed or table, an
existing run directory, an executable that is not built → one line, exit status 2). Then the
run directory ``OUT/<run-id>/`` gets the parameters file, every node is started as its own
process (:class:`vega_bringup.orchestrate.Supervisor`) with the run's ROS_DOMAIN_ID, the start
barrier is awaited, the flight supervised, and once every node has ended normally the report
is written from the bag and the requirement table printed.

Exit status: 0 every requirement and health check of the report passes; 1 one fails, or the
run failed (a node died or failed, barrier timeout — the message names the node); 2 bad input
(arguments, or a node rejected its input, e.g. a malformed controller table: the node's own
one-line error is shown); 130 interrupted (Ctrl-C) — every node is stopped, the bag closed.

``--dry-run`` writes the parameters file and prints the command of each node, one per line,
ready to paste into separate terminals, without starting anything.
"""

import os
import resource
import signal
import sys
import threading
import time

from vega_core.errors import BadArgument

from vega_bringup import rosenv
from vega_bringup.planning import DEFAULT_OUT, DEFAULT_SCENARIO, plan_run, write_run_files

__all__ = ["register"]

_STATUS_EXIT = {"ok": 0, "failed": 1, "bad_input": 2, "interrupted": 130}


def _say(line):
    """A progress line on stderr (stdout carries the table and the dry-run commands)."""
    print(f"vega sil: {line}", file=sys.stderr, flush=True)


REPORT_PRELOAD_NICE = 10
"""Niceness added to the thread that imports the report's modules during the flight: it takes
the CPU the lockstep leaves idle (the five nodes keep ≈ 1.3 of the 2 cores busy), not the
nodes' (docs/SIL_SPEED.md)."""


class _ReportPreload:
    """Imports what the report needs (numpy, the bag reader and checker, matplotlib with its
    font cache) in a background thread of lower priority while the nodes fly, so that the
    report after the flight starts with them loaded (≈ 0.3–0.5 s of imports, measured:
    docs/SIL_SPEED.md). Nothing is written; an import error is left to the report itself."""

    def __init__(self):
        self._thread = threading.Thread(target=self._run, name="report-preload", daemon=True)
        self._tid = None

    def start(self):
        """Start the imports (from :class:`~vega_bringup.orchestrate.Supervisor`'s
        ``on_flight``)."""
        self._thread.start()

    def _run(self):
        # signals go to the main thread (the supervisor's stop reacts at once)
        signal.pthread_sigmask(signal.SIG_BLOCK, (signal.SIGINT, signal.SIGTERM, signal.SIGHUP))
        self._tid = threading.get_native_id()
        try:
            os.setpriority(os.PRIO_PROCESS, self._tid,
                           os.getpriority(os.PRIO_PROCESS, self._tid) + REPORT_PRELOAD_NICE)
        except OSError:
            pass
        try:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot  # loaded for the report's plots

            import vega_bags.report  # noqa: F401 - loaded for _write_report
        except Exception:  # noqa: BLE001 - the report imports again and reports any error
            pass

    def finish(self):
        """Before the report: the thread back at the process's priority (if allowed) and
        waited for, so that the report never waits on a half-done import at low priority."""
        if not self._thread.is_alive():
            return
        if self._tid is not None:
            try:
                os.setpriority(os.PRIO_PROCESS, self._tid, os.getpriority(os.PRIO_PROCESS, 0))
            except OSError:
                pass
        self._thread.join()


def _write_report(plan):
    """Write the report (:func:`vega_bags.report.write_report`) from the bag; return
    (passed, health checks passed, console table)."""
    from vega_bags.report import write_report

    result = write_report(plan.layout.bag_dir, plan.layout.report_dir)
    return result.passed, all(h.passed for h in result.health), result.table()


def _check_table_loops(plan):
    """Refuse a table whose nominal frozen loops are unstable inside its scheduling range (one
    line, exit 2, before anything starts); report those outside it (velocity clamped)."""
    from vega_loops.margins import check_table_stabilises
    from vega_gnc.controller_table import load_controller_table
    from vega_model.parameters import default_context

    table = load_controller_table(plan.params.controller_table)
    clamped = check_table_stabilises(table, default_context(), plan.scenario.t_start_s,
                                     plan.scenario.t_end_s)
    if clamped:
        _say("warning: the nominal frozen loop is unstable at t = "
             + ", ".join(f"{r['t_s']:g}" for r in clamped)
             + " s, where the velocity is outside the controller table's grid (clamped; "
               "see `vega margins`)")


def _run(args):
    """``vega sil run``."""
    from vega_bringup import orchestrate

    plan = plan_run(scenario=args.scenario, seed=args.seed, out=args.out,
                    realtime=args.realtime, table=args.table, run_id=args.run_id,
                    domain_id=args.ros_domain_id)
    _check_table_loops(plan)
    if not args.dry_run:
        # the run's domain must hold no participant but its own (picked free, or exported)
        rosenv.refuse_busy_domain(plan.domain_id)
    write_run_files(plan)
    if args.dry_run:
        for line in plan.lines:
            print(line)
        _say(f"dry run: nothing started; parameters in {plan.layout.params_file}; paste each "
             f"line into its own terminal (any order)")
        return 0
    span = plan.scenario.t_end_s - plan.scenario.t_start_s
    _say(f"scenario '{plan.scenario.name}' seed {plan.seed}, {plan.scenario.t_start_s:g}-"
         f"{plan.scenario.t_end_s:g} s, ROS_DOMAIN_ID={plan.domain_id}, run directory "
         f"{plan.layout.run_dir}")
    preload = _ReportPreload()
    supervisor = orchestrate.Supervisor(
        plan.nodes, plan.layout, rosenv.ros_environment(domain_id=plan.domain_id),
        participants=plan.params.participants,
        barrier_timeout_s=plan.params.barrier_timeout_s, progress=_say,
        on_flight=preload.start)
    outcome = supervisor.run()
    if not outcome.ok:
        # the preload thread is waited for on this path too: a daemon thread still importing
        # (matplotlib's C extensions) while the interpreter finalizes aborts the process
        # (SIGABRT, "PyThreadState_Get: ... the GIL is released") instead of exiting with the
        # run's status
        preload.finish()
        _say(f"error: {outcome.message}")
        if (plan.layout.bag_dir / "metadata.yaml").is_file():
            _say(f"partial bag: {plan.layout.bag_dir}; node logs: {plan.layout.log_dir}")
        elif plan.layout.bag_dir.exists():
            _say(f"bag not closed: {plan.layout.bag_dir}; `vega bag repair "
                 f"{plan.layout.bag_dir}` recovers what was written; node logs: "
                 f"{plan.layout.log_dir}")
        else:
            _say(f"node logs: {plan.layout.log_dir}")
        return _STATUS_EXIT[outcome.status]
    rtf = span / outcome.flight_wall_s if outcome.flight_wall_s else float("inf")
    _say(f"flew {span:g} s in {outcome.flight_wall_s:.2f} s wall ({rtf:.1f}x real time); "
         f"bag {plan.layout.bag_dir}")
    cpu = outcome.cpu_s
    if all(v is not None for v in cpu.values()):
        own = resource.getrusage(resource.RUSAGE_SELF)
        _say("node CPU time (start-up included): " + ", ".join(
            f"{name} {seconds:.1f} s" for name, seconds in cpu.items())
            + f"; sum {sum(cpu.values()):.1f} s; vega sil run itself "
              f"{own.ru_utime + own.ru_stime:.1f} s")
    t0 = time.monotonic()
    preload.finish()
    passed, healthy, table = _write_report(plan)
    print(table)
    if not passed and healthy and plan.scenario.off_design:
        _say(f"report {plan.layout.report_dir} ({time.monotonic() - t0:.1f} s); verdict FAIL "
             f"on requirements, reported and not gated: scenario '{plan.scenario.name}' is "
             f"declared off-design ({plan.scenario.off_design}) (exit status 0)")
        return _end(0)
    _say(f"report {plan.layout.report_dir} ({time.monotonic() - t0:.1f} s); verdict "
         f"{'PASS' if passed else 'FAIL'} (exit status {0 if passed else 1})")
    return _end(0 if passed else 1)


def _end(status):
    """``status``, or — when this process is the ``vega`` command itself (its ``__main__``
    is ``vega_cli.cli``), after a run whose report is written — the end of the process with
    it, stdout and stderr flushed (:func:`os._exit`): the interpreter's teardown of what the
    run imported (matplotlib, rclpy, numpy, …) took 0.3–0.7 s and holds nothing of the run
    (docs/SIL_SPEED.md). Called in-process (tests), the status is returned."""
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    if spec is None or spec.name != "vega_cli.cli":
        return status
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def _no_action(args):
    raise BadArgument("sil: an ACTION is required: run (see vega sil --help)")


def register(subparsers):
    """Add the ``sil`` sub-command (action ``run``)."""
    parser = subparsers.add_parser(
        "sil", help="software-in-the-loop runs: fly a scenario through the ROS 2 nodes",
        description="Fly a scenario through the ROS 2 node graph (every node its own process), "
                    "record a bag, write a report and check the requirements.")
    parser.set_defaults(func=_no_action)
    actions = parser.add_subparsers(dest="action", metavar="ACTION")
    run = actions.add_parser(
        "run", help="fly one scenario",
        description="Validate the arguments, start every node as its own process, wait for "
                    "the start barrier, fly, record OUT/<run-id>/bag, write the report to "
                    "OUT/<run-id>/report and print the requirement table. Exit status: 0 "
                    "every requirement and health check passes, 1 one fails or the run "
                    "failed, 2 bad input, 130 interrupted.")
    run.add_argument("--scenario", default=DEFAULT_SCENARIO, metavar="NAME|PATH",
                     help=f"shipped scenario name or YAML file (default: {DEFAULT_SCENARIO})")
    run.add_argument("--seed", default=None, metavar="N",
                     help="seed (>= 0) overriding the scenario's")
    run.add_argument("--out", default=DEFAULT_OUT, metavar="DIR",
                     help=f"parent directory of the run directory (default: {DEFAULT_OUT})")
    run.add_argument("--run-id", default=None, metavar="ID",
                     help="name of the run directory (default: UTC time-scenario-seedN); an "
                          "existing one is never overwritten")
    run.add_argument("--table", default=None, metavar="FILE",
                     help="controller table (.npz; default: the installed "
                          "vega_gnc/config/tvc_controller.npz)")
    run.add_argument("--realtime", action="store_true",
                     help="pace the flight to the wall clock (default: as fast as possible)")
    run.add_argument("--dry-run", action="store_true",
                     help="write the parameters and print the command of each node, one per "
                          "line, ready to paste into separate terminals; start nothing")
    run.set_defaults(func=_run)
