"""Planning one SIL run: validate its arguments, lay out its run directory, write its files.

Nothing here starts a process: :func:`plan_run` checks the scenario, seed, controller table,
output and node executables and returns a :class:`RunPlan`; :func:`write_run_files` writes the
parameters file every node reads and the paste-ready node commands. ``vega sil run`` then hands
the plan to :class:`vega_bringup.orchestrate.Supervisor`.
"""

import os
from pathlib import Path

from vega_core.errors import BadArgument, BadInput

from vega_bus import parameters

__all__ = ["DEFAULT_SCENARIO", "DEFAULT_OUT", "RunPlan", "plan_run", "write_run_files"]

DEFAULT_SCENARIO = parameters.SCENARIO.default
"""Scenario flown when none is given (the whole 0–100 s flight; the nodes' own default,
:data:`vega_bus.parameters.SCENARIO`)."""

DEFAULT_OUT = "bags"
"""Parent directory of the run directories (relative to the working directory)."""

class RunPlan:
    """Everything a run needs, validated (built by :func:`plan_run`).

    Attributes: ``scenario`` (the loaded :class:`~vega_sim.scenario.Scenario`), ``seed``
    (effective), ``params`` (:class:`~vega_bringup.orchestrate.RunParameters`), ``layout``
    (:class:`~vega_bringup.orchestrate.RunLayout`), ``nodes`` ((spec, command) per node),
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
    """The seed as an int in [0, the ``seed`` parameter's maximum] (None stays None);
    BadArgument naming ``--seed`` otherwise.

    The upper bound is the one of the node parameter the seed travels in
    (:data:`vega_bus.parameters.SEED`, a ROS int64): a larger value would end every node at
    start-up, so it is refused here, before anything starts.
    """
    if seed is None:
        return None
    text = str(seed).strip()
    if isinstance(seed, bool) or not text.isascii() or not text.isdigit():
        raise BadArgument(f"--seed must be an integer >= 0, got {seed!r}")
    value = int(text)
    highest = parameters.SEED.integer_range[1]
    if value > highest:
        raise BadArgument(f"--seed must be <= {highest} (the int64 range of the node "
                          f"parameter 'seed'), got {text}")
    return value


def _checked_run_id(run_id):
    """``run_id`` if it is a plain directory name; BadArgument naming ``--run-id`` otherwise.

    Refused: empty, ``.``/``..``, a ``/``, and any non-printable character (a newline or other
    control character, which would break the one-line messages and paste-ready commands that
    name the run directory).
    """
    if (not run_id or "/" in run_id or run_id in (".", "..")
            or not run_id.isprintable()):
        raise BadArgument(f"--run-id {run_id!r}: must be a plain directory name (no '/', no "
                          f"control or other non-printable characters)")
    return run_id


def _resolve_scenario(text):
    """(scenario, parameter value): a shipped name stays a name, a file becomes absolute."""
    from vega_sim.scenario import load_scenario

    scenario = load_scenario(text)
    is_path = text.endswith((".yaml", ".yml")) or "/" in text
    return scenario, (str(Path(text).resolve()) if is_path else text)


def _resolve_table(path, scenario):
    """Absolute path of a controller table that loads and fits the scenario's timing."""
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_sim.closed_loop import make_controller

    if path is None:
        table_path = default_table_path()
        if not table_path.is_file():
            raise BadInput(f"no controller table: {table_path} is not installed (the LPV "
                           f"synthesis has not exported it); pass --table FILE")
    else:
        table_path = Path(path).resolve()
    table = load_controller_table(table_path)
    make_controller(scenario, table)  # the table's sample time must be the controller period
    return table_path


def _check_guidance(scenario) -> None:
    """Load and validate the guidance reference the scenario names (the nodes take it from the
    run description), so that a bad one is refused before anything starts."""
    from vega_gnc.guidance_reference import (DEFAULT_GUIDANCE, load_guidance_reference,
                                             reference_path)

    path = reference_path(scenario.guidance)
    if path is None:
        return
    if scenario.guidance == DEFAULT_GUIDANCE and not path.is_file():
        raise BadInput(f"no guidance reference: {path} is not installed; run `vega "
                       f"guidance --out` or fly a scenario with 'guidance: none'")
    load_guidance_reference(path.resolve())


BAG_BYTES_PER_S = 100_000
"""Bag size per simulated second, with a margin (measured: 77 kB/s, the 100 s nominal bag
7.74 MB; assumption: +30 %)."""
RUN_RESERVE_BYTES = 2_000_000
"""Room for the node logs, the report and its plots (measured ≈ 0.3 MB; assumption: ×6)."""


def _check_free_space(out: Path, span_s: float) -> None:
    """Refuse a run whose output file system cannot hold its bag, logs and report: a full
    disk during the flight would cut the bag and lose the logs that say why."""
    import shutil

    existing = out
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    free = shutil.disk_usage(existing).free
    need = int(span_s * BAG_BYTES_PER_S) + RUN_RESERVE_BYTES
    if free < need:
        raise BadArgument(f"--out {out}: {free / 1e6:.1f} MB free on its file system; a "
                          f"{span_s:g} s run needs about {need / 1e6:.1f} MB (bag "
                          f"{BAG_BYTES_PER_S / 1e3:g} kB per simulated second + "
                          f"{RUN_RESERVE_BYTES / 1e6:g} MB for logs and the report)")


def plan_run(scenario=DEFAULT_SCENARIO, seed=None, out=DEFAULT_OUT, realtime=False, table=None,
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
        Run directory name (default: :func:`vega_bringup.orchestrate.default_run_id`).
    domain_id : int, optional
        The run's ROS_DOMAIN_ID (default: this process's).
    barrier_timeout_s : float, optional
        Start-barrier timeout
        (default: :data:`~vega_bringup.orchestrate.DEFAULT_BARRIER_TIMEOUT_S`).

    Raises
    ------
    BadInput
        One line naming the bad argument (scenario, its guidance reference, seed, table,
        output, executable).
    """
    from vega_bringup import orchestrate
    from vega_bringup.executables import find_executable

    seed = _checked_seed(seed)
    loaded, scenario_param = _resolve_scenario(str(scenario))
    effective_seed = loaded.seed if seed is None else seed
    table_path = _resolve_table(table, loaded)
    _check_guidance(loaded)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise BadArgument(f"--out {out}: exists and is not a directory")
    _check_free_space(out, loaded.t_end_s - loaded.t_start_s)
    run_id = run_id if run_id is not None else orchestrate.default_run_id(loaded.name,
                                                                          effective_seed)
    run_id = _checked_run_id(run_id)
    layout = orchestrate.RunLayout((out / run_id).resolve())
    if layout.run_dir.exists():
        raise BadArgument(f"output {layout.run_dir} already exists (runs never overwrite one; "
                          f"choose another --out or --run-id)")
    params = orchestrate.RunParameters(
        scenario=scenario_param, seed=parameters.SEED_FROM_SCENARIO if seed is None else seed,
        realtime=bool(realtime),
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
    from vega_bringup import orchestrate

    plan.layout.run_dir.parent.mkdir(parents=True, exist_ok=True)
    try:
        plan.layout.run_dir.mkdir()
    except FileExistsError:
        raise BadArgument(f"output {plan.layout.run_dir} already exists") from None
    plan.layout.params_file.write_text(orchestrate.params_yaml(plan.params), encoding="utf-8")
    plan.layout.commands_file.write_text(
        "# The nodes of this run, one per terminal (written by `vega sil run`).\n"
        + "\n".join(plan.lines) + "\n", encoding="utf-8")


