"""The node parameters of the graph, declared once: name, type, default, unit, meaning, domain.

Every node declares the parameters it reads through :meth:`vega_bus.shell.Shell.param`, which
takes the default and the check from :data:`PARAMETERS` and hands rclpy a
``ParameterDescriptor`` built from the same entry (description with the unit, additional
constraints, an integer range where the domain is one, read-only: a node reads its parameters
once, at start-up), so that ``ros2 param describe /plant seed`` tells a user what a value
means. The run planner (:class:`vega_bringup.orchestrate.RunParameters`,
:func:`vega_bringup.orchestrate.params_yaml`) writes the one parameters file of a run from
the same names and types (tests/bus/test_parameters.py checks both sides against this table).

A node ignores the keys of the shared file it does not use; a value of the wrong type or
outside its domain ends the node before the start barrier with one line,
``parameter '<name>': <problem> (got <value>)``, exit 2.

Plain Python (no rclpy): :mod:`vega_bus.shell` turns an entry into a descriptor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from vega_bus.barrier import PARTICIPANTS

__all__ = ["ParameterSpec", "PARAMETERS", "SEED_FROM_SCENARIO", "INT64_MAX", "spec",
           "SCENARIO", "SEED", "REALTIME", "CONTROLLER_TABLE", "GUIDANCE_REFERENCE",
           "BAG_PATH",
           "PARTICIPANTS_PARAM", "BARRIER_TIMEOUT_S", "STALL_TIMEOUT_S"]

SEED_FROM_SCENARIO = -1
"""``seed`` value that keeps the scenario's own seed."""

INT64_MAX = 2**63 - 1
"""Largest ROS integer parameter value."""


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter.

    Attributes
    ----------
    name
        Parameter name (the key in the run's ``/**: ros__parameters:`` section).
    default
        A node's default when the parameter is not given; its Python type is the parameter's
        ROS type (str → string, int → integer, float → double, bool → bool, list of str →
        string array).
    description
        What the value means (one or two sentences).
    unit
        Unit of a number ("" if none).
    constraints
        The domain in words (``additional_constraints`` of the descriptor).
    check
        ``check(value)`` → a problem text (the one-line error), or None if the value is fine.
    integer_range
        (from, to) of an integer parameter (the descriptor's ``IntegerRange``, step 1).
    nodes
        The nodes that declare it.
    """

    name: str
    default: Any
    description: str
    unit: str = ""
    constraints: str = ""
    check: Callable[[Any], str | None] | None = None
    integer_range: tuple[int, int] | None = None
    nodes: tuple[str, ...] = ()

    @property
    def type_name(self) -> str:
        """ROS parameter type name (``string``, ``integer``, ``double``, ``bool``,
        ``string_array``)."""
        if isinstance(self.default, bool):
            return "bool"
        if isinstance(self.default, (list, tuple)):
            return "string_array"
        return {str: "string", int: "integer", float: "double"}[type(self.default)]

    def coerce(self, value) -> Any:
        """``value`` in the parameter's type, as written to a parameters file (an int for a
        double becomes a float, a tuple of names a list)."""
        if self.type_name == "double":
            return float(value)
        if self.type_name == "string_array":
            return list(value)
        return value

    def problem(self, value) -> str | None:
        """The one-line problem of ``value`` (:attr:`check`), or None."""
        return self.check(value) if self.check is not None else None

    @property
    def full_description(self) -> str:
        """The description with the unit and the default, as ``ros2 param describe`` shows it."""
        unit = f" [{self.unit}]" if self.unit else ""
        default = list(self.default) if isinstance(self.default, tuple) else self.default
        return f"{self.description}{unit} Default: {default!r}."


def _names_check(v) -> str | None:
    return None if v and all(isinstance(x, str) and x for x in v) \
        else "must be a non-empty list of node names"


_RUN_NODES = ("plant", "ins_sensor", "tvc_actuator", "recorder")
_ALL_NODES = ("plant", "ins_sensor", "tvc_controller", "tvc_actuator", "recorder")

SCENARIO = ParameterSpec(
    "scenario", "nominal",
    "Scenario to fly: a shipped scenario name (nominal, thesis, gust, severe, ...) or the path "
    "of a scenario YAML file. Every node of one run must be given the same.",
    constraints="non-blank; an unknown name or a bad file is rejected at start-up",
    check=lambda v: None if v.strip() else "must name a scenario or a YAML file",
    nodes=_RUN_NODES)
SEED = ParameterSpec(
    "seed", SEED_FROM_SCENARIO,
    "Seed of the run's random draws (sensor noise, turbulence), overriding the scenario's; "
    "-1 keeps the scenario's own seed.",
    constraints=">= 0, or -1 for the scenario's seed",
    check=lambda v: None if v >= SEED_FROM_SCENARIO else "must be >= 0, or -1",
    integer_range=(SEED_FROM_SCENARIO, INT64_MAX), nodes=_RUN_NODES)
REALTIME = ParameterSpec(
    "realtime", False,
    "Pace the flight to the wall clock (one frame per frame period) instead of running as fast "
    "as the lockstep allows.", nodes=("plant",))
CONTROLLER_TABLE = ParameterSpec(
    "controller_table", "",
    "Controller table (.npz) the controller flies and the recorder names in the bag's "
    "metadata; empty: the installed share/vega_gnc/config/tvc_controller.npz.",
    constraints="a readable controller table whose sample time is the controller period",
    nodes=("tvc_controller", "recorder"))
GUIDANCE_REFERENCE = ParameterSpec(
    "guidance_reference", "",
    "Wind-biased guidance reference the controller tracks. Empty: the one the run's scenario "
    "names (its 'guidance', sent on /vega/run). Otherwise 'none' or a file, which must be "
    "the run's own (a check for a hand-started controller).",
    constraints="'', 'none' or a readable guidance reference file that is the run's",
    nodes=("tvc_controller",))
BAG_PATH = ParameterSpec(
    "bag_path", "",
    "Directory of the rosbag2 (MCAP) the recorder writes.",
    constraints="must be set, and must not exist yet (a run never overwrites a bag)",
    check=lambda v: None if v else "must be set", nodes=("recorder",))
PARTICIPANTS_PARAM = ParameterSpec(
    "participants", list(PARTICIPANTS),
    "Node names the start barrier waits for (each announces itself on /vega/ready once its "
    "topics are matched); a node outside the list is not waited for.",
    constraints="a non-empty list of non-empty node names", check=_names_check,
    nodes=_ALL_NODES)
BARRIER_TIMEOUT_S = ParameterSpec(
    "barrier_timeout_s", 30.0,
    "Longest wait for the start barrier (and, for the controller, for the run description on "
    "/vega/run); the node then exits 1 naming who is missing. `vega sil run` writes its own, "
    "longer value.", unit="s",
    constraints="> 0", check=lambda v: None if v > 0 else "must be > 0", nodes=_ALL_NODES)
STALL_TIMEOUT_S = ParameterSpec(
    "stall_timeout_s", 10.0,
    "Longest wait for an expected input once flying (lockstep stall: exit 1), and for the "
    "recorder's final report or the subscribers' acknowledgements at the end of the run.",
    unit="s", constraints="> 0", check=lambda v: None if v > 0 else "must be > 0",
    nodes=_ALL_NODES)

PARAMETERS: dict[str, ParameterSpec] = {p.name: p for p in (
    SCENARIO, SEED, REALTIME, CONTROLLER_TABLE, GUIDANCE_REFERENCE, BAG_PATH,
    PARTICIPANTS_PARAM, BARRIER_TIMEOUT_S, STALL_TIMEOUT_S)}
"""Every node parameter of the graph, by name."""


def spec(name: str) -> ParameterSpec:
    """The entry of parameter ``name``.

    Raises
    ------
    KeyError
        If ``name`` is not a parameter of the graph (a programming error: declare it here).
    """
    try:
        return PARAMETERS[name]
    except KeyError:
        raise KeyError(f"{name!r} is not a node parameter of the graph "
                       f"(vega_bus.parameters.PARAMETERS: {', '.join(PARAMETERS)})") from None
