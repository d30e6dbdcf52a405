"""QoS profiles of the VEGA TVC topics (:mod:`vega_bus.topics` names the topics).

Apart from :mod:`vega_bus.topics` because these build rclpy objects: the topic table itself is
plain Python, imported by the simulation and the offline tools, which never import rclpy.
rclpy is imported when a profile is built, so that tools reading bags (``vega check``) start
without loading it.
"""

from __future__ import annotations

from vega_bus.topics import CONTROL_QUEUE_DEPTH, DATA_QUEUE_DEPTH

__all__ = ["data_qos", "clock_qos", "control_qos"]


def data_qos():
    """QoS profile of the data topics (RELIABLE, VOLATILE, KEEP_LAST DATA_QUEUE_DEPTH)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=DATA_QUEUE_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def clock_qos():
    """QoS profile of /clock (RELIABLE, VOLATILE, KEEP_LAST DATA_QUEUE_DEPTH)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=DATA_QUEUE_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def control_qos():
    """QoS profile of /vega/ready and /vega/run (RELIABLE, TRANSIENT_LOCAL, KEEP_LAST
    CONTROL_QUEUE_DEPTH)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=CONTROL_QUEUE_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
