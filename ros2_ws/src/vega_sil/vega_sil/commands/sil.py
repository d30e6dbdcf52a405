"""``vega sil run``: fly a scenario through the ROS 2 node graph, record a bag, check it.

Arguments are validated before anything starts (an unknown scenario, a bad seed or table, an
existing run directory, an executable that is not built → one line, exit status 2). Then the
run directory ``OUT/<run-id>/`` gets the parameters file, every node is started as its own
process (:class:`vega_sil.orchestrate.Supervisor`) with the run's ROS_DOMAIN_ID, the start
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
import sys
import time
from pathlib import Path

from vega_sil import rosenv

__all__ = ["register", "DEFAULT_SCENARIO", "DEFAULT_OUT", "RunPlan", "plan_run"]

DEFAULT_SCENARIO = "nominal"
"""Scenario flown when none is given (the whole 0–100 s flight)."""

DEFAULT_OUT = "bags"
"""Parent directory of the run directories (relative to the working directory)."""

_STATUS_EXIT = {"ok": 0, "failed": 1, "bad_input": 2, "interrupted": 130}


def _say(line):
    """A progress line on stderr (stdout carries the table and the dry-run commands)."""
    print(f"vega sil: {line}", file=sys.stderr, flush=True)


def default_table_path():
    """The installed controller table ``share/vega_gnc/config/lpv_controller.npz``."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    try:
        return Path(get_package_share_directory("vega_gnc")) / "config" / "lpv_controller.npz"
    except PackageNotFoundError:
        raise ValueError("package 'vega_gnc' not found in the ament index; did 'make setup' "
                         "build it?") from None


class RunPlan:
    """Everything a run needs, validated (built by :func:`plan_run`).

    Attributes: ``scenario`` (the loaded :class:`~vega_plant.scenario.Scenario`), ``seed``
    (effective), ``params`` (:class:`~vega_sil.orchestrate.RunParameters`), ``layout``
    (:class:`~vega_sil.orchestrate.RunLayout`), ``nodes`` ((spec, command) per node),
    ``domain_id``, ``lines`` (the paste-ready command lines).
    """

    def __init__(self, scenario, seed, params, layout, nodes, domain_id, lines):
        self.scenario = scenario
        self.seed = seed
        self.params = params
        self.layout = layout
        self.nodes = nodes
        self.domain_id = domain_id
        self.lines = lines


def _checked_seed(seed):
    """The seed as an int >= 0 (None stays None); ValueError naming ``--seed`` otherwise."""
    if seed is None:
        return None
    text = str(seed).strip()
    if isinstance(seed, bool) or not text.isdigit():
        raise ValueError(f"--seed must be an integer >= 0, got {seed!r}")
    return int(text)


def _resolve_scenario(text):
    """(scenario, parameter value): a shipped name stays a name, a file becomes absolute."""
    from vega_plant.scenario import load_scenario

    scenario = load_scenario(text)
    is_path = text.endswith((".yaml", ".yml")) or "/" in text
    return scenario, (str(Path(text).resolve()) if is_path else text)


def _resolve_table(path, scenario):
    """Absolute path of a controller table that loads and fits the scenario's timing."""
    from vega_gnc.controller_table import load_controller_table
    from vega_sil.closed_loop import make_controller

    if path is None:
        table_path = default_table_path()
        if not table_path.is_file():
            raise ValueError(f"no controller table: {table_path} is not installed (the LPV "
                             f"synthesis has not exported it); pass --table FILE")
    else:
        table_path = Path(path).resolve()
    table = load_controller_table(table_path)
    make_controller(scenario, table)  # the table's sample time must be the controller period
    return table_path


def plan_run(scenario="nominal", seed=None, out=DEFAULT_OUT, realtime=False, table=None,
             run_id=None, domain_id=None, barrier_timeout_s=None):
    """Validate the arguments of a run and build its plan; nothing is written or started.

    Parameters
    ----------
    scenario : str
        Shipped scenario name or YAML path.
    seed : int, optional
        Seed (>= 0) overriding the scenario's.
    out : str or Path
        Parent directory of the run directory.
    realtime : bool
        Pace to the wall clock.
    table : str or Path, optional
        Controller table (default: the installed one).
    run_id : str, optional
        Run directory name (default: :func:`vega_sil.orchestrate.default_run_id`).
    domain_id : int, optional
        The run's ROS_DOMAIN_ID (default: this process's).
    barrier_timeout_s : float, optional
        Start-barrier timeout (default: :data:`~vega_sil.orchestrate.DEFAULT_BARRIER_TIMEOUT_S`).

    Raises
    ------
    ValueError
        One line naming the bad argument (scenario, seed, table, output, executable).
    """
    from vega_sil import orchestrate
    from vega_sil.commands.node import find_executable

    seed = _checked_seed(seed)
    loaded, scenario_param = _resolve_scenario(str(scenario))
    effective_seed = loaded.seed if seed is None else seed
    table_path = _resolve_table(table, loaded)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a directory")
    run_id = run_id if run_id is not None else orchestrate.default_run_id(loaded.name,
                                                                          effective_seed)
    if not run_id or "/" in run_id or run_id in (".", ".."):
        raise ValueError(f"--run-id {run_id!r}: must be a plain directory name")
    layout = orchestrate.RunLayout((out / run_id).resolve())
    if layout.run_dir.exists():
        raise ValueError(f"output {layout.run_dir} already exists (runs never overwrite one; "
                         f"choose another --out or --run-id)")
    params = orchestrate.RunParameters(
        scenario=scenario_param, seed=-1 if seed is None else seed, realtime=bool(realtime),
        controller_table=str(table_path), bag_path=str(layout.bag_dir),
        barrier_timeout_s=(orchestrate.DEFAULT_BARRIER_TIMEOUT_S if barrier_timeout_s is None
                           else float(barrier_timeout_s)))
    nodes = [(spec, orchestrate.node_command(find_executable(spec.package, spec.executable),
                                             layout.params_file))
             for spec in orchestrate.PARTICIPANTS]
    domain_id = int(os.environ["ROS_DOMAIN_ID"]) if domain_id is None else int(domain_id)
    env_script = orchestrate.environment_script()
    lines = [orchestrate.shell_line(command, domain_id, env_script) for _, command in nodes]
    return RunPlan(loaded, effective_seed, params, layout, nodes, domain_id, lines)


def write_run_files(plan):
    """Create the run directory with the parameters file and the node commands."""
    from vega_sil import orchestrate

    plan.layout.run_dir.parent.mkdir(parents=True, exist_ok=True)
    try:
        plan.layout.run_dir.mkdir()
    except FileExistsError:
        raise ValueError(f"output {plan.layout.run_dir} already exists") from None
    plan.layout.params_file.write_text(orchestrate.params_yaml(plan.params), encoding="utf-8")
    plan.layout.commands_file.write_text(
        "# The nodes of this run, one per terminal (written by `vega sil run`).\n"
        + "\n".join(plan.lines) + "\n", encoding="utf-8")


def _write_report(plan):
    """Write the report (:func:`vega_sil.report.write_report`) from the bag; return
    (passed, console table)."""
    from vega_sil.report import write_report

    result = write_report(plan.layout.bag_dir, plan.layout.report_dir)
    return result.passed, result.table()


def _run(args):
    """``vega sil run``."""
    from vega_sil import orchestrate

    plan = plan_run(scenario=args.scenario, seed=args.seed, out=args.out,
                    realtime=args.realtime, table=args.table, run_id=args.run_id,
                    domain_id=args.ros_domain_id)
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
    supervisor = orchestrate.Supervisor(
        plan.nodes, plan.layout, rosenv.ros_environment(domain_id=plan.domain_id),
        participants=plan.params.participants,
        barrier_timeout_s=plan.params.barrier_timeout_s, progress=_say)
    outcome = supervisor.run()
    if not outcome.ok:
        _say(f"error: {outcome.message}")
        if plan.layout.bag_dir.exists():
            _say(f"partial bag: {plan.layout.bag_dir}; node logs: {plan.layout.log_dir}")
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
    passed, table = _write_report(plan)
    print(table)
    _say(f"report {plan.layout.report_dir} ({time.monotonic() - t0:.1f} s); verdict "
         f"{'PASS' if passed else 'FAIL'} (exit status {0 if passed else 1})")
    return 0 if passed else 1


def _no_action(args):
    raise ValueError("sil: an ACTION is required: run (see vega sil --help)")


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
                          "vega_gnc/config/lpv_controller.npz)")
    run.add_argument("--realtime", action="store_true",
                     help="pace the flight to the wall clock (default: as fast as possible)")
    run.add_argument("--dry-run", action="store_true",
                     help="write the parameters and print the command of each node, one per "
                          "line, ready to paste into separate terminals; start nothing")
    run.set_defaults(func=_run)
