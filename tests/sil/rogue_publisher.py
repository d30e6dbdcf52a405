"""A foreign ROS 2 publisher for the security tests: an ordinary rclpy process on the host, in
the caller's ROS_DOMAIN_ID (LOCALHOST discovery, as the environment given says), that is not
one of the run's nodes.

``python rogue_publisher.py NODE TOPIC N [FIELD=VALUE ...]`` publishes N messages of the
topic's type (:mod:`vega_bus.topics`) with the data QoS once a subscriber has matched (or
after 30 s, scaled by the load: tests/load_scaling.py), ``seq`` counting from the ``seq``
given (default 0) and every other FIELD set (floats; ``header.stamp`` from ``stamp_ms``),
prints ``published N`` and then stays on the bus until SIGTERM/SIGINT. N = 0: it only appears
as a publisher.
"""

import signal
import sys
import time
from pathlib import Path


def main(argv):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))    # tests/: load_scaling
    from load_scaling import budget_s

    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from vega_bus import qos, topics
    from vega_bus.timing import ms_to_stamp

    node_name, topic_name, count = argv[0], argv[1], int(argv[2])
    fields = dict(arg.split("=", 1) for arg in argv[3:])
    topic = next(t for t in (*topics.ALL_TOPICS, topics.RECORDED) if t.name == topic_name)
    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.append(1))
    rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    node = rclpy.create_node(node_name)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    cls = topics.message_class(topic.type_name)
    pub = node.create_publisher(cls, topic.name, qos.data_qos())
    deadline = time.monotonic() + budget_s(30.0)
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline and not stop:
        executor.spin_once(timeout_sec=0.05)
    seq = int(fields.pop("seq", 0))
    stamp_ms = int(fields.pop("stamp_ms", 0))
    for k in range(count):
        msg = cls()
        if hasattr(msg, "seq"):
            msg.seq = seq + k
        if hasattr(msg, "header"):
            msg.header.stamp.sec, msg.header.stamp.nanosec = ms_to_stamp(stamp_ms + 10 * k)
        for name, value in fields.items():
            setattr(msg, name, type(getattr(msg, name))(float(value)))
        pub.publish(msg)
        time.sleep(0.01)
    print(f"published {count}", flush=True)
    while not stop:
        executor.spin_once(timeout_sec=0.1)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main(sys.argv[1:])
