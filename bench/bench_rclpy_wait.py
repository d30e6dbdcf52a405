"""Benchmark: the node shell's private wait-set path against rclpy's public executors.

Usage: .venv/bin/vega-env python bench/bench_rclpy_wait.py [--round-trips N] [--burst M]
       [--repeat R] [--methods private,executor,events]

:meth:`vega_bus.shell.Shell.spin_once` waits on an rcl wait set of its own and drains every
ready subscription through rclpy's private API (``rclpy.impl.implementation_singleton``,
tests/bus/test_rclpy_contract.py). This script measures whether a public replacement would be as
fast for the shell's use, with two processes (a measuring node and an echo node, both
:class:`~vega_bus.shell.Shell` over Fast DDS on localhost, both using the same method):

* lockstep: N ping-pong round trips (``std_msgs/UInt32``), one message per wake-up, as in
  the SIL lockstep; reports the wall time per round trip and the CPU time per round trip of
  both processes;
* burst: the echo node publishes M messages at once and the measuring node takes them all,
  as the recorder does; reports the wall and CPU time per message of the measuring node
  (bursts of about 900 messages and more overflow Fast DDS on localhost: the loss is repaired
  at the writer's heartbeat, ≈ 6 s later, with every method).

Methods: ``private`` = ``Shell.spin_once`` as shipped; ``executor`` = the public
``rclpy.executors.SingleThreadedExecutor.spin_once`` (one callback per call);
``events`` = ``rclpy.experimental.EventsExecutor.spin_once`` (experimental API).
"""

import argparse
import json
import os
import subprocess
import sys
import time

from std_msgs.msg import UInt32

from vega_bus.shell import Shell, Stopped
from vega_bus.qos import data_qos

PING, PONG, BURST = "/vega_bench/ping", "/vega_bench/pong", "/vega_bench/burst"
START_BURST = 0xFFFFFFFF
MATCH_TIMEOUT_S = 30.0


def _shell(method: str, name: str) -> Shell:
    """A :class:`Shell` whose ``spin_once`` uses ``method``."""
    shell = Shell(name, [name])
    if method == "private":
        return shell
    if method == "executor":
        from rclpy.executors import SingleThreadedExecutor
        executor = SingleThreadedExecutor(context=shell.node.context)
    elif method == "events":
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor(context=shell.node.context)
    else:
        raise SystemExit(f"unknown method {method!r}")
    executor.add_node(shell.node)

    def spin_once(timeout_s: float) -> None:
        executor.spin_once(timeout_sec=timeout_s)
        if shell.failure is not None:
            raise shell.failure
        if shell.signal_name is not None:
            raise Stopped()

    shell.spin_once = spin_once
    shell.executor = executor
    return shell


def _matched(shell: Shell, pubs, subs) -> None:
    """Wait until every publisher and subscription has matched its peer, then settle."""
    shell.wait_until(lambda: all(p.get_subscription_count() > 0 for p in pubs)
                     and all(s.get_publisher_count() > 0 for s in subs),
                     "the peer process", timeout_s=MATCH_TIMEOUT_S, failure="no match")
    deadline = time.monotonic() + 0.5
    while time.monotonic() < deadline:
        shell.spin_once(0.05)


def echo(method: str, burst: int) -> None:
    """Echo node: answer ping k with pong k; on START_BURST publish ``burst`` messages."""
    shell = _shell(method, "bench_echo")
    node = shell.node
    pong = node.create_publisher(UInt32, PONG, data_qos())
    burst_pub = node.create_publisher(UInt32, BURST, data_qos())
    state = {"done": False}
    out = UInt32()

    def on_ping(msg):
        if msg.data == START_BURST:
            for k in range(burst):
                out.data = k
                burst_pub.publish(out)
            state["done"] = True
        else:
            out.data = msg.data
            pong.publish(out)

    ping = node.create_subscription(UInt32, PING, shell.guard(on_ping), data_qos())
    _matched(shell, [pong, burst_pub], [ping])
    cpu0 = time.process_time()
    shell.wait_until(lambda: state["done"], "the burst request", timeout_s=600)
    cpu = time.process_time() - cpu0
    shell.flush([pong, burst_pub], timeout_s=30)
    print(json.dumps({"echo_cpu_s": cpu}), flush=True)
    shell.close()


def measure(method: str, round_trips: int, burst: int) -> dict:
    """One run of both phases with ``method`` (starts the echo process)."""
    child = subprocess.Popen([sys.executable, __file__, "--echo", method, "--burst", str(burst)],
                             stdout=subprocess.PIPE, text=True)
    shell = _shell(method, "bench_measure")
    node = shell.node
    ping = node.create_publisher(UInt32, PING, data_qos())
    got = {"pong": -1, "burst": 0}

    def on_pong(msg):
        got["pong"] = msg.data

    def on_burst(_msg):
        got["burst"] += 1

    pong_sub = node.create_subscription(UInt32, PONG, shell.guard(on_pong), data_qos())
    burst_sub = node.create_subscription(UInt32, BURST, shell.guard(on_burst), data_qos())
    _matched(shell, [ping], [pong_sub, burst_sub])
    msg = UInt32()
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for k in range(round_trips):
        msg.data = k
        ping.publish(msg)
        shell.wait_until(lambda: got["pong"] == k, "the pong")
    wall1, cpu1 = time.perf_counter(), time.process_time()
    msg.data = START_BURST
    ping.publish(msg)
    shell.wait_until(lambda: got["burst"] >= burst, "the burst", timeout_s=600)
    wall2, cpu2 = time.perf_counter(), time.process_time()
    shell.close()
    out, _ = child.communicate(timeout=60)
    echo_cpu = json.loads(out.strip().splitlines()[-1])["echo_cpu_s"]
    return {"method": method,
            "rt_wall_us": (wall1 - wall0) / round_trips * 1e6,
            "rt_cpu_us": (cpu1 - cpu0) / round_trips * 1e6,
            "echo_cpu_us_per_rt": echo_cpu / round_trips * 1e6,
            "burst_wall_us": (wall2 - wall1) / burst * 1e6,
            "burst_cpu_us": (cpu2 - cpu1) / burst * 1e6}


def main():
    """Run every method ``--repeat`` times, interleaved, and print the medians."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--round-trips", type=int, default=3000)
    parser.add_argument("--burst", type=int, default=300,
                        help="messages of the burst (default 300; from about 900 on, Fast DDS "
                             "loses part of it and repairs it seconds later, whatever the method)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--methods", default="private,executor,events")
    parser.add_argument("--echo", metavar="METHOD", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo:
        echo(args.echo, args.burst)
        return
    methods = args.methods.split(",")
    runs = {m: [] for m in methods}
    for _ in range(args.repeat):
        for method in methods:
            runs[method].append(measure(method, args.round_trips, args.burst))
    print(f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')}; {args.round_trips} round trips, "
          f"burst of {args.burst}; median of {args.repeat} interleaved runs")
    keys = ["rt_wall_us", "rt_cpu_us", "echo_cpu_us_per_rt", "burst_wall_us", "burst_cpu_us"]
    print(f"{'method':10s}" + "".join(f"{k:>20s}" for k in keys))
    for method in methods:
        values = [sorted(r[k] for r in runs[method])[len(runs[method]) // 2] for k in keys]
        print(f"{method:10s}" + "".join(f"{v:20.1f}" for v in values))


if __name__ == "__main__":
    main()
