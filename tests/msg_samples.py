"""Sample vega_msgs messages with non-trivial values, conversions to plain data, and a publisher.

:data:`SAMPLES` holds one sample of each message type as plain nested dicts (every field set,
stamps with nanoseconds, extreme integers, arrays of several lengths). :func:`to_ros` builds the
rclpy message from it; :func:`ros_to_plain` and :func:`rosbags_to_plain` turn a received rclpy
or rosbags message back into the same plain form, so a test compares with ``==``.

Run as a script, ``python msg_samples.py TOPIC_PREFIX``, it is a ROS 2 node that publishes each
sample once on ``TOPIC_PREFIX/<type name>`` (reliable, transient local, so a subscriber that
matches later still gets it) and then spins until SIGINT/SIGTERM.
"""

import sys

__all__ = [
    "TYPE_NAMES",
    "SAMPLES",
    "QOS_DEPTH",
    "topic_name",
    "message_class",
    "to_ros",
    "ros_to_plain",
    "rosbags_to_plain",
    "main",
]

TYPE_NAMES = ("InsMeasurement", "TvcCommand", "ActuatorState", "VehicleState", "StepDiagnostics")
"""The vega_msgs message types, as in ``vega_msgs/msg/<name>``."""

QOS_DEPTH = 1
"""History depth of the sample topics (one sample each)."""

_HEADER = {"stamp": {"sec": 1_700_000_123, "nanosec": 987_654_321}, "frame_id": "vega_body"}

SAMPLES = {
    "InsMeasurement": {
        "header": _HEADER,
        "sample_stamp": {"sec": 1_700_000_123, "nanosec": 975_654_321},
        "seq": 4_294_967_295,
        "pitch_rad": -0.012345678901234567,
        "pitch_rate_radps": 3.0e-7,
        "drift_m": -1234.5678,
        "drift_rate_mps": 0.1 + 0.2,
        "velocity_mps": 1717.0000000000002,
        "valid": True,
    },
    "TvcCommand": {
        "header": {"stamp": {"sec": 42, "nanosec": 12_000_000}, "frame_id": "tvc"},
        "sample_stamp": {"sec": 42, "nanosec": 0},
        "seq": 2_500,
        "deflection_cmd_rad": -0.10471975511965977,
        "scheduling_velocity_mps": 350.25,
        "status": 4,
    },
    "StepDiagnostics": {
        "header": {"stamp": {"sec": 42, "nanosec": 12_000_000}, "frame_id": "tvc_controller"},
        "seq": 2_500,
        "compute_time_s": 1.25e-4,
    },
    "ActuatorState": {
        "header": {"stamp": {"sec": 7, "nanosec": 999_999_999}, "frame_id": "nozzle"},
        "seq": 123_456,
        "deflection_rad": 0.0999,
        "rate_radps": -0.5,
        "accel_radps2": 12.75,
        "deflection_samples_rad": [0.09 + 0.001 * i for i in range(10)][:-1] + [0.0999],
        "rate_samples_radps": [-0.05 * i for i in range(10)][:-1] + [-0.5],
        "accel_samples_radps2": [1e-300, -1e300, 2.5e-3, 0.0, 5.0, 6.0, 7.0, 8.0, 9.0, 12.75],
        "sample_period_s": 0.001,
    },
    "VehicleState": {
        "header": _HEADER,
        "seq": 9,
        "pitch_rad": 0.0017453292519943296,
        "pitch_rate_radps": -0.00087,
        "drift_m": 12.5,
        "drift_rate_mps": -0.75,
        "aoa_rad": 0.034906585039886591,
        "q_alpha_pa_rad": 2094.3951023931954,
        "dynamic_pressure_pa": 60000.0,
        "mach": 1.6180339887498949,
        "velocity_mps": 512.0,
        "altitude_m": 11000.5,
        "wind_mps": -23.0,
        "bending_q": [1.5e-3, -2.25e-4],
        "bending_qdot": [-0.125, 0.0625],
    },
}
"""One sample per type, as plain nested dicts of the message fields."""


def topic_name(prefix, type_name):
    """Topic on which the sample of ``type_name`` travels."""
    return f"{prefix}/{type_name}"


def message_class(type_name):
    """The rclpy message class ``vega_msgs.msg.<type_name>``."""
    from vega_msgs import msg

    return getattr(msg, type_name)


def _fill(message, values):
    """Set the fields of ``message`` from the nested dict ``values``."""
    for field, value in values.items():
        if isinstance(value, dict):
            _fill(getattr(message, field), value)
        else:
            setattr(message, field, value)


def to_ros(type_name):
    """The sample of ``type_name`` as an rclpy message."""
    message = message_class(type_name)()
    _fill(message, SAMPLES[type_name])
    return message


def ros_to_plain(message):
    """Nested dict of the fields of an rclpy message (arrays as lists)."""
    plain = {}
    for field in message.get_fields_and_field_types():
        value = getattr(message, field)
        if hasattr(value, "get_fields_and_field_types"):
            plain[field] = ros_to_plain(value)
        elif hasattr(value, "tolist"):
            plain[field] = value.tolist()
        else:
            plain[field] = value
    return plain


def rosbags_to_plain(message):
    """Nested dict of the fields of a rosbags message (a dataclass; arrays as lists)."""
    import dataclasses

    plain = {}
    for field in dataclasses.fields(message):
        if field.name == "__msgtype__" or field.name.isupper():  # type name, constants
            continue
        value = getattr(message, field.name)
        if dataclasses.is_dataclass(value):
            plain[field.name] = rosbags_to_plain(value)
        elif hasattr(value, "tolist"):
            plain[field.name] = value.tolist()
        else:
            plain[field.name] = value
    return plain


def main(argv):
    """Publish each sample once on ``argv[0]/<type name>``; spin until interrupted.

    Returns
    -------
    int
        0 after a clean shutdown (SIGINT or SIGTERM), 2 on a usage error.
    """
    if len(argv) != 1:
        print("usage: msg_samples.py TOPIC_PREFIX", file=sys.stderr)
        return 2
    import signal

    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    qos = QoSProfile(depth=QOS_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    # A stop is a flag the loop polls, not rclpy's handler: rclpy's shuts the context down
    # under a running spin_once, which then raises RCLError "context is not valid" (a race
    # seen under load), as vega_bus.shell does for the nodes.
    stop = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda s, _f: stop.append(s))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("vega_msg_samples")
    try:
        for type_name in TYPE_NAMES:
            publisher = node.create_publisher(
                message_class(type_name), topic_name(argv[0], type_name), qos)
            publisher.publish(to_ros(type_name))
        print("published", flush=True)
        while not stop:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
