"""Run bags for tests, written from the in-process simulation (no SIL needed).

:func:`short_run` flies the thesis scenario over a short span with the PD fixture table;
:func:`write_bag` writes its messages (``vega_bags.simbag``: the real message types,
serialised by rclpy) into a run bag, after an optional ``mutate(messages)`` that injects a
fault (a NaN, a dropped message, a stalled stamp, …) into the list of
(topic, log time [ns], rclpy message).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable

from fixture_tables import write_pd_table

__all__ = ["ShortRun", "short_run", "write_bag", "messages_on"]

SPAN_S = (10.0, 14.0)
"""Span of the short run [s] (thesis scenario: θ0 = 2°, the thesis' wind and noise)."""


@dataclass(frozen=True)
class ShortRun:
    """An in-process run and the controller table it flew (file and loaded table)."""

    result: Any
    table_path: Path
    table: Any


def short_run(directory: Path, span_s=SPAN_S) -> ShortRun:
    """Fly the thesis scenario over ``span_s`` with the PD table written into ``directory``."""
    from vega_sim.scenario import load_scenario
    from vega_sim.closed_loop import run_scenario

    table_path = Path(directory) / "pd.npz"
    table = write_pd_table(table_path)
    scenario = replace(load_scenario("thesis"), t_start_s=span_s[0], t_end_s=span_s[1])
    return ShortRun(run_scenario(scenario, table), table_path, table)


def write_bag(path: Path, run: ShortRun,
              mutate: Callable[[list], list | None] | None = None) -> Path:
    """Write the run's bag at ``path``, after ``mutate(messages)`` if given (it may change the
    list in place or return a new one)."""
    from vega_bags import bagio, simbag

    messages = simbag.simulation_messages(run.result)
    if mutate is not None:
        changed = mutate(messages)
        messages = messages if changed is None else changed
    meta = bagio.run_metadata(run.result.scenario.name,
                              simbag.scenario_yaml(run.result.scenario), run.result.seed,
                              run.table_path, git_rev="test")
    return simbag.write_messages(path, messages, meta)


def messages_on(messages: list, topic: str) -> list[int]:
    """Indices in ``messages`` of the messages on ``topic``, in order."""
    return [i for i, (name, _, _) in enumerate(messages) if name == topic]
