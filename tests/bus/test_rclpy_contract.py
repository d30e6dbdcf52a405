"""Contract test of the private rclpy API that the node shell uses.

:meth:`vega_bus.shell.Shell.spin_once` does not use an executor: it builds an rcl wait set
through rclpy's C extension and drains every ready subscription itself. Those names are not
rclpy's public API and may change in any rclpy release. This module calls exactly what the
shell calls, with the arguments it passes, against the installed rclpy, in a real context (on
this test run's ROS_DOMAIN_ID, discovery on localhost), so that an rclpy update that removes or
changes any of it fails here, naming the API, instead of failing every node at run time.

Used by ``Shell`` (``ros2_ws/src/vega_bus/vega_bus/shell.py``):

* ``rclpy.impl.implementation_singleton.rclpy_implementation`` (the ``_rclpy`` extension);
* ``_rclpy.WaitSet(n_subscriptions, 0, 0, 0, 0, 0, context.handle)`` and its methods
  ``clear_entities()``, ``add_subscription(subscription.handle)``, ``wait(timeout_ns)`` (a
  timeout is no error), ``get_ready_entities("subscription")`` (a list of handle pointers);
* ``Context.handle``, ``Node.subscriptions``; of each subscription ``handle`` (with
  ``pointer`` and ``take_message(msg_type, raw)`` → ``(message, info)`` or ``None`` once
  empty; ``info["publication_sequence_number"]`` numbers a writer's messages 1, 2, 3, …),
  ``msg_type``, ``raw``, ``callback``.

Whether the public API would do as well: bench/bench_rclpy_wait.py.
"""

import ast
import os
import time
from importlib import metadata
from pathlib import Path

import pytest

SHELL_PY = (Path(__file__).resolve().parents[2]
            / "ros2_ws" / "src" / "vega_bus" / "vega_bus" / "shell.py")

# What this module checks, by the names shell.py uses for them (see test_shell_uses_only_...).
CHECKED_IMPORTS = {"rclpy.impl.implementation_singleton": {"rclpy_implementation"}}
CHECKED_RCLPY_ATTRIBUTES = {"WaitSet"}  # self._rclpy.<name>
CHECKED_WAIT_SET_METHODS = {"clear_entities", "add_subscription", "wait", "get_ready_entities"}
CHECKED_HANDLE_ATTRIBUTES = {"pointer", "take_message"}  # sub.handle.<name>
CHECKED_SUBSCRIPTION_ATTRIBUTES = {"handle", "msg_type", "raw", "callback"}  # sub.<name>


def _rclpy_version() -> str:
    for dist in ("ros-rclpy", "ros-jazzy-rclpy", "rclpy"):
        try:
            return f"{dist} {metadata.version(dist)}"
        except metadata.PackageNotFoundError:
            continue
    return "rclpy (version unknown)"


def _broken(api: str, problem: str) -> None:
    pytest.fail(f"{_rclpy_version()}: the private rclpy API `{api}` that "
                f"vega_bus/shell.py (Shell.spin_once) relies on {problem}. Adapt "
                f"Shell.spin_once to this rclpy (or move it to the public executor API, "
                f"see bench/bench_rclpy_wait.py) and this test with it.", pytrace=False)


def _attribute(obj, name: str, api: str):
    if not hasattr(obj, name):
        _broken(api, "no longer exists")
    return getattr(obj, name)


def _call(api: str, function, *args):
    try:
        return function(*args)
    except TypeError as exc:
        error = exc
    _broken(api, f"no longer accepts the arguments the shell passes ({error})")


def _implementation():
    try:
        from rclpy.impl import implementation_singleton
    except ImportError as exc:
        _broken("rclpy.impl.implementation_singleton", f"cannot be imported ({exc})")
    return _attribute(implementation_singleton, "rclpy_implementation",
                      "rclpy.impl.implementation_singleton.rclpy_implementation")


def test_the_private_names_exist():
    """Every private name the shell uses exists in the installed rclpy (no context needed)."""
    _rclpy = _implementation()
    wait_set = _attribute(_rclpy, "WaitSet", "_rclpy.WaitSet")
    for method in sorted(CHECKED_WAIT_SET_METHODS):
        _attribute(wait_set, method, f"_rclpy.WaitSet.{method}")
    handle = _attribute(_rclpy, "Subscription", "_rclpy.Subscription (a subscription's handle)")
    for name in sorted(CHECKED_HANDLE_ATTRIBUTES):
        _attribute(handle, name, f"_rclpy.Subscription.{name} (subscription.handle.{name})")


def _shell_private_use() -> dict:
    """The rclpy names shell.py uses where the checked lists above describe them."""
    tree = ast.parse(SHELL_PY.read_text(encoding="utf-8"))
    found = {"imports": {}, "rclpy": set(), "wait_set": set(), "handle": set(), "sub": set()}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("rclpy."):
            if any(part.startswith("_") or part == "impl" for part in node.module.split(".")):
                found["imports"].setdefault(node.module, set()).update(
                    alias.name for alias in node.names)
        if not isinstance(node, ast.Attribute):
            continue
        base = node.value
        if (isinstance(base, ast.Attribute) and base.attr == "_rclpy"
                and isinstance(base.value, ast.Name) and base.value.id == "self"):
            found["rclpy"].add(node.attr)
        elif isinstance(base, ast.Name) and base.id == "ws":
            found["wait_set"].add(node.attr)
        elif (isinstance(base, ast.Attribute) and base.attr == "handle"
              and isinstance(base.value, ast.Name) and base.value.id == "sub"):
            found["handle"].add(node.attr)
        elif isinstance(base, ast.Name) and base.id == "sub":
            found["sub"].add(node.attr)
    return found


def test_shell_uses_only_what_this_test_checks():
    """shell.py uses no private rclpy name beyond those exercised here (keeps the lists true)."""
    found = _shell_private_use()
    assert found["imports"] == CHECKED_IMPORTS, (
        "shell.py's imports from private rclpy modules changed; update this test")
    assert found["rclpy"] <= CHECKED_RCLPY_ATTRIBUTES, found["rclpy"]
    assert found["wait_set"] <= CHECKED_WAIT_SET_METHODS, found["wait_set"]
    assert found["handle"] <= CHECKED_HANDLE_ATTRIBUTES, found["handle"]
    assert found["sub"] <= CHECKED_SUBSCRIPTION_ATTRIBUTES, found["sub"]
    assert found["wait_set"] and found["handle"], "shell.py no longer drains a wait set?"


@pytest.fixture
def ros_node():
    """A node in a context of its own (this run's domain; no rclpy signal handlers)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f"vega_rclpy_contract_{os.getpid()}", context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.mark.ros
def test_a_published_message_is_taken_through_the_wait_set(ros_node):
    """The shell's wait / ready / drain sequence, call for call, on a real topic."""
    from std_msgs.msg import UInt32

    from vega_bus.qos import data_qos

    node = ros_node
    topic = f"/vega_test/rclpy_contract_{os.getpid()}"
    received = []
    node.create_subscription(UInt32, topic, received.append, data_qos())
    publisher = node.create_publisher(UInt32, topic, data_qos())
    deadline = time.monotonic() + 10.0
    while publisher.get_subscription_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert publisher.get_subscription_count() == 1, "publisher and subscription never matched"

    _rclpy = _implementation()
    subs = tuple(_attribute(node, "subscriptions", "Node.subscriptions"))
    assert len(subs) == 1
    sub = subs[0]
    handle = _attribute(sub, "handle", "Subscription.handle")
    msg_type = _attribute(sub, "msg_type", "Subscription.msg_type")
    raw = _attribute(sub, "raw", "Subscription.raw")
    callback = _attribute(sub, "callback", "Subscription.callback")
    assert msg_type is UInt32 and raw is False
    context_handle = _attribute(node.context, "handle", "Context.handle")

    ws = _call("_rclpy.WaitSet(n_subscriptions, 0, 0, 0, 0, 0, context.handle)",
               _rclpy.WaitSet, len(subs), 0, 0, 0, 0, 0, context_handle)

    def wait(timeout_s: float) -> list:
        _call("WaitSet.clear_entities()", ws.clear_entities)
        _call("WaitSet.add_subscription(subscription.handle)", ws.add_subscription, handle)
        _call("WaitSet.wait(timeout_ns)", ws.wait, int(timeout_s * 1e9))
        ready = _call('WaitSet.get_ready_entities("subscription")', ws.get_ready_entities,
                      "subscription")
        if not isinstance(ready, list):
            _broken('WaitSet.get_ready_entities("subscription")',
                    f"no longer returns a list (got {type(ready).__name__})")
        return ready

    # Nothing published yet: the wait times out without an error and nothing is ready.
    started = time.monotonic()
    assert wait(0.05) == [], "a wait that timed out reported a ready subscription"
    assert time.monotonic() - started >= 0.04, "WaitSet.wait(timeout_ns) did not wait"

    sent = [7, 8, 9]
    for value in sent:
        publisher.publish(UInt32(data=value))
    pointer = _attribute(handle, "pointer", "subscription.handle.pointer")
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        ready = wait(0.5)
        if pointer in ready:
            break
    else:
        _broken('WaitSet.get_ready_entities("subscription")',
                "never listed the subscription's handle.pointer although messages were sent")

    take = _attribute(handle, "take_message", "subscription.handle.take_message")
    deadline = time.monotonic() + 10.0
    while len(received) < len(sent) and time.monotonic() < deadline:
        got = _call("subscription.handle.take_message(msg_type, raw)", take, msg_type, raw)
        if got is None:  # drained; the rest is still on its way
            wait(0.5)
            continue
        if not (isinstance(got, tuple) and len(got) == 2 and isinstance(got[0], UInt32)):
            _broken("subscription.handle.take_message(msg_type, raw)",
                    f"no longer returns (message, info) (got {got!r})")
        # the shell's StreamCheck: the writer's publication sequence number, 1, 2, 3, …
        if got[1].get("publication_sequence_number") != len(received) + 1:
            _broken("subscription.handle.take_message(msg_type, raw)",
                    f"info no longer carries the publication sequence number (got {got[1]!r})")
        callback(got[0])
    assert [m.data for m in received] == sent
    assert _call("subscription.handle.take_message(msg_type, raw)", take, msg_type, raw) is None, (
        "take_message on an empty subscription no longer returns None (the shell's drain stop)")
