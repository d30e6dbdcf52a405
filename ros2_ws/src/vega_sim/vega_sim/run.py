"""One run of a scenario: the scenario, the seed in force and the lockstep description.

Plain Python: every SIL node that needs the run (plant, INS, actuator, recorder) and the run
planner resolve the ``scenario`` and ``seed`` parameters through :func:`load_run`, so they
agree on the span and the timing without one importing the other.
"""

from __future__ import annotations

from vega_bus.schedule import RunInfo

from vega_sim.assembly import loop_timing
from vega_sim.scenario import Scenario, load_scenario

__all__ = ["load_run"]


def load_run(scenario_name: str, seed: int) -> tuple[Scenario, int, RunInfo]:
    """(Scenario, seed in force, RunInfo) of scenario ``scenario_name`` (a name or a YAML path)
    flown with ``seed`` (−1: the scenario's own seed).

    Raises
    ------
    BadInput
        One line on an unknown or invalid scenario (:class:`vega_core.errors.BadInput`).
    """
    scenario = load_scenario(scenario_name)
    seed = scenario.seed if seed == -1 else seed
    info = RunInfo(scenario.name, seed, scenario.t_start_ms, scenario.t_end_ms,
                   loop_timing(scenario), scenario.guidance).check()
    return scenario, seed, info
