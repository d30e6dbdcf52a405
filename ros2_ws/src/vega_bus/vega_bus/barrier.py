"""The start barrier of the lockstep: nobody flies before every participant can hear everybody.

Protocol (topic ``/vega/ready``, std_msgs/String, RELIABLE, TRANSIENT_LOCAL; see
:mod:`vega_bus.topics`):

1. Each participant creates its publishers and subscriptions, then polls
   :meth:`StartBarrier.poll`. Once every one of its publishers has matched the subscribers
   expected from the participants list (:data:`SUBSCRIBERS`: which participant subscribes to
   which topic; the expected node names must appear among the topic's subscriptions and the
   publisher's matched count must reach their number) *and* every one of its subscriptions
   has matched the expected publisher (:data:`PUBLISHERS`), it publishes its own node name on
   ``/vega/ready``, once. Both directions are checked because discovery is not symmetric in
   time: a writer that has matched a reader sends to it, but a reader that has not yet matched
   that writer ignores the data, which the reliable protocol repairs only at the writer's next
   heartbeat (Fast DDS: every 3 s). (The 3 s seen at the end of early runs was something
   else: waiting for DDS acknowledgements, see :meth:`vega_bus.shell.Shell.finish`.)
2. Every participant also reads ``/vega/ready``; the run may begin when it holds the names of
   all participants (:attr:`StartBarrier.complete`). The plant, time master, publishes the
   first frame only then; the others start then too (the actuator, which needs no input for its
   first frames, would otherwise publish before the plant listens).
3. On timeout the caller reports :meth:`StartBarrier.missing` (one line) and exits 1.

Anyone (the orchestrator, a test) may subscribe to ``/vega/ready`` to see who is ready; a
replay tool reuses the class with its own participants and subscriber table.
"""

from __future__ import annotations

import time
from typing import Callable, Iterable, Mapping

from vega_bus.qos import control_qos
from vega_bus.topics import (ACTUATOR, CLOCK, DIAGNOSTICS, INS, READY, RECORDED, RUN, TRUTH,
                             TVC_CMD)

__all__ = ["PARTICIPANTS", "SUBSCRIBERS", "PUBLISHERS", "StartBarrier"]

# Node names of a full SIL run (= executable names), the default ``participants`` parameter.
PARTICIPANTS = ("plant", "ins_sensor", "tvc_controller", "tvc_actuator", "recorder")

# Which participants subscribe to each topic (the recorder records every data topic, /clock and
# the diagnostics).
SUBSCRIBERS: Mapping[str, tuple[str, ...]] = {
    TRUTH.name: ("ins_sensor", "recorder"),
    INS.name: ("tvc_controller", "recorder"),
    TVC_CMD.name: ("tvc_actuator", "recorder"),
    ACTUATOR.name: ("plant", "recorder"),
    CLOCK.name: ("recorder",),
    DIAGNOSTICS.name: ("recorder",),
    RECORDED.name: ("plant", "ins_sensor", "tvc_controller", "tvc_actuator"),
}

# The participant publishing each topic a participant subscribes to. /vega/recorded is not
# required: a tool taking the recorder's seat (vega replay --check-controller) publishes no
# progress, and the nodes fall back to DDS acknowledgements then (vega_bus.shell.Shell.finish).
PUBLISHERS: Mapping[str, str] = {
    **{t.name: t.publisher for t in (TRUTH, INS, TVC_CMD, ACTUATOR, CLOCK, DIAGNOSTICS)},
    RUN.name: RUN.publisher,
}


REANNOUNCE_S = 0.1
"""Period of the repeated announcement while the barrier is incomplete [s]. Discovery is not
symmetric in time: an announcement written when this participant's /vega/ready writer had
matched a peer's reader, but that reader not yet the writer, is dropped by the peer and
repaired only at the writer's next heartbeat (Fast DDS: up to 3 s): the start barrier took
either ≈ 2 s or ≈ 4.3 s on the loaded machine, never between (docs/SIL_SPEED.md). Announcing
again costs one small message per participant per period."""


class StartBarrier:
    """One participant's side of the start barrier (module docstring).

    Parameters
    ----------
    node
        The participant's rclpy node; its name is what it announces.
    participants
        Node names of every participant of the run.
    publishers
        The participant's publishers whose subscribers must have matched.
    subscriptions
        The participant's subscriptions whose publishers must have matched.
    subscribers
        Topic name → participants subscribing to it (default :data:`SUBSCRIBERS`); topics
        absent from it need no subscriber.
    publishers_of
        Topic name → participant publishing it (default :data:`PUBLISHERS`); topics absent
        from it need no publisher.
    """

    def __init__(self, node, participants: Iterable[str], publishers: Iterable = (),
                 subscriptions: Iterable = (),
                 subscribers: Mapping[str, Iterable[str]] = SUBSCRIBERS,
                 publishers_of: Mapping[str, str] = PUBLISHERS):
        from std_msgs.msg import String

        self._node = node
        self.name = node.get_name()
        self.participants = tuple(dict.fromkeys(participants))
        chosen = set(self.participants)
        self._expect = []
        for pub in publishers:
            topic = node.resolve_topic_name(pub.topic_name)
            names = tuple(n for n in subscribers.get(topic, ()) if n in chosen)
            if names:
                self._expect.append((pub, topic, names))
        self._expect_pub = []
        for sub in subscriptions:
            topic = node.resolve_topic_name(sub.topic_name)
            name = publishers_of.get(topic)
            if name in chosen:
                self._expect_pub.append((sub, topic, name))
        self.ready: set[str] = set()
        self.announced = False
        self._next_announce = 0.0
        self._String = String
        self._pub = node.create_publisher(String, READY.name, control_qos())
        self._sub = node.create_subscription(String, READY.name, self._on_ready, control_qos())

    def _on_ready(self, msg) -> None:
        self.ready.add(msg.data)

    def matched(self) -> bool:
        """True once every publisher has matched its expected subscribers."""
        for pub, topic, names in self._expect:
            if pub.get_subscription_count() < len(names):
                return False
            present = {i.node_name for i in self._node.get_subscriptions_info_by_topic(topic)}
            if not present.issuperset(names):
                return False
        for sub, topic, name in self._expect_pub:
            if sub.get_publisher_count() < 1 or name not in {
                    i.node_name for i in self._node.get_publishers_info_by_topic(topic)}:
                return False
        return True

    def poll(self) -> bool:
        """Announce readiness once matched, and again every :data:`REANNOUNCE_S` until the
        barrier is complete; return :attr:`complete`."""
        if not self.announced:
            if self.matched():
                self._announce()
                self.announced = True
        elif not self.complete and time.monotonic() >= self._next_announce:
            self._announce()
        return self.complete

    def _announce(self) -> None:
        self._pub.publish(self._String(data=self.name))
        self._next_announce = time.monotonic() + REANNOUNCE_S

    @property
    def complete(self) -> bool:
        """True when every participant (this one included) has announced itself."""
        return self.announced and self.ready.issuperset(self.participants)

    def missing(self) -> list[str]:
        """Participants not ready yet, in participants order (this one if not matched)."""
        missing = [n for n in self.participants if n not in self.ready]
        if not self.announced and self.name not in missing and self.name in self.participants:
            missing.append(self.name)
        return missing

    def unmatched(self) -> list[str]:
        """``topic->node`` (subscriber) and ``node->topic`` (publisher) links this participant
        has not matched yet."""
        out = []
        for _pub, topic, names in self._expect:
            present = {i.node_name for i in self._node.get_subscriptions_info_by_topic(topic)}
            out += [f"{topic}->{n}" for n in names if n not in present]
        for sub, topic, name in self._expect_pub:
            if sub.get_publisher_count() < 1:
                out.append(f"{name}->{topic}")
        return out

    def wait(self, spin_once: Callable[[float], None], timeout_s: float,
             stop: Callable[[], bool] = lambda: False) -> bool:
        """Spin until the barrier is complete, ``timeout_s`` passes or ``stop()`` is true.

        Parameters
        ----------
        spin_once
            Processes pending messages, waiting at most the given time [s]
            (:meth:`vega_bus.shell.Shell.spin_once`).
        timeout_s
            Wall-clock limit [s].
        stop
            Polled between spins (e.g. a signal flag).

        Returns
        -------
        bool
            True if complete.
        """
        deadline = time.monotonic() + timeout_s
        while not self.poll():
            if stop() or time.monotonic() >= deadline:
                return False
            spin_once(0.02)
        return True

    def describe_missing(self) -> str:
        """One line naming the participants not ready (and what this one has not matched)."""
        text = "start barrier timed out; not ready: " + (", ".join(self.missing()) or "none")
        unmatched = self.unmatched() if not self.announced else []
        if unmatched:
            text += f" (this node has not matched {', '.join(unmatched)})"
        return text
