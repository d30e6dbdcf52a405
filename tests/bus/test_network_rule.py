"""The network rule inside every node (vega_bus.network): a node started directly — ``ros2 run``
or the executable's path, not through ``vega`` — still discovers on localhost only, whatever
the caller exported, and falls back to the hand-start domain id when none is set."""

import json
import subprocess
import sys
import textwrap

from load_scaling import budget_s

from vega_bus import network
from vega_bringup import rosenv

_HOSTILE = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_LOCALHOST_ONLY": "0",
            "ROS_STATIC_PEERS": "127.0.0.2"}


def test_enforce_on_a_mapping():
    env = dict(_HOSTILE, KEEP="1")
    assert network.enforce(env) is True
    assert env == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": "101",
                   "KEEP": "1"}
    env = dict(_HOSTILE, ROS_DOMAIN_ID="7")
    assert network.enforce(env) is False and env["ROS_DOMAIN_ID"] == "7"
    assert rosenv.HAND_START_DOMAIN_ID == network.HAND_START_DOMAIN_ID


def test_node_shell_applies_the_rule_before_rclpy_init():
    """What the middleware would read at rclpy.init, seen from a node's Shell started with a
    hostile environment. rclpy.init is replaced by a probe that records the environment and
    stops: letting the real init run with these variables could send discovery traffic off the
    machine if the rule were broken — the very thing under test."""
    script = textwrap.dedent("""
        import json, os, sys
        import rclpy
        import vega_bus.shell as shell

        def probe(*args, **kwargs):
            names = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS",
                     "ROS_DOMAIN_ID")
            print(json.dumps({n: os.environ.get(n) for n in names}))
            sys.exit(0)

        rclpy.init = probe
        shell.Shell("plant", ["plant"])
    """)
    env = rosenv.ros_environment()
    env.update(_HOSTILE)
    env.pop("ROS_DOMAIN_ID")
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                            text=True, timeout=budget_s(60.0), check=False)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_LOCALHOST_ONLY": None,
        "ROS_STATIC_PEERS": None, "ROS_DOMAIN_ID": "101"}
    assert result.stderr == ("plant: ROS_DOMAIN_ID was not set; using 101, the default for "
                             "nodes started by hand\n")
