"""The network rule every VEGA TVC process obeys: DDS discovery never leaves the machine.

One source of truth for the rule (docs/ENVIRONMENT_SETUP.md, "The network rule"):
``ROS_AUTOMATIC_DISCOVERY_RANGE`` is LOCALHOST, and the variables that could add peers beyond
it (``ROS_STATIC_PEERS``) or override it (``ROS_LOCALHOST_ONLY``, deprecated in Jazzy) are
removed. ``vega_bringup.rosenv`` applies it to every process the tools start; every node
applies it to itself before ``rclpy.init`` (:class:`vega_bus.shell.Shell`), so that a node
started directly — ``ros2 run`` on a full ROS install, or the executable's path — obeys it too,
whatever the shell exported.
"""

from __future__ import annotations

import os
from typing import MutableMapping

__all__ = ["DISCOVERY_RANGE", "REMOVED_VARIABLES", "HAND_START_DOMAIN_ID", "enforce"]

DISCOVERY_RANGE = "LOCALHOST"
"""The only ROS_AUTOMATIC_DISCOVERY_RANGE the project runs with."""

REMOVED_VARIABLES = ("ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS")
"""Variables removed from every environment (deprecated override; possibly remote peers)."""

HAND_START_DOMAIN_ID = 101
"""ROS_DOMAIN_ID of nodes started by hand when none is exported: one fixed id, so that nodes
started in separate terminals meet; automated runs never get it (vega_bringup.rosenv)."""


def enforce(environ: MutableMapping[str, str] | None = None) -> bool:
    """Apply the network rule to ``environ`` (default ``os.environ``), in place.

    Sets LOCALHOST discovery, removes :data:`REMOVED_VARIABLES`, and sets ROS_DOMAIN_ID to
    :data:`HAND_START_DOMAIN_ID` if it is missing or empty.

    Returns
    -------
    bool
        True if ROS_DOMAIN_ID was missing and has been set.
    """
    env = os.environ if environ is None else environ
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = DISCOVERY_RANGE
    for name in REMOVED_VARIABLES:
        env.pop(name, None)
    if env.get("ROS_DOMAIN_ID", "").strip():
        return False
    env["ROS_DOMAIN_ID"] = str(HAND_START_DOMAIN_ID)
    return True
