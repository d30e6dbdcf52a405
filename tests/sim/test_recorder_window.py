"""The recorder's back-pressure window against Fast DDS's shared-memory port (vega_bus.schedule):
the messages of the frames the recorder has not reported yet must stay well inside the 512
descriptors of a port, or a descheduled recorder loses samples (a 100-frame window lets
120 frames × ≈ 4.5 messages ≈ 540 wait, more than a port holds); and the report itself
(vega_bags.recorder.FramesRecorded) counts the frames held on every topic, so that one
writer's deliveries held up stop the plant within the window (a report counting the truth
alone does not: the other writers' samples, e.g. /vega/ins, are then lost)."""

import pytest

from vega_bus.schedule import RECORDER_REPORT_FRAMES, RECORDER_WINDOW_FRAMES
from vega_sim.run import load_run

SHM_PORT_DESCRIPTORS = 512
"""Fast DDS's default shared-memory port queue capacity (port_queue_capacity) [messages]."""


def test_unreported_messages_stay_inside_a_shared_memory_port():
    _, _, info = load_run("nominal", 1)
    counts = info.expected_counts()
    per_frame = sum(counts.values()) / info.n_frames          # every topic the recorder takes
    assert 4.0 < per_frame < 5.0    # truth, ins, actuator, ½ cmd, ½ diag, clock
    in_flight = (RECORDER_WINDOW_FRAMES + RECORDER_REPORT_FRAMES) * per_frame
    assert in_flight <= 0.75 * SHM_PORT_DESCRIPTORS, in_flight


def _feed_in_frame_order(info, held, upto_frame, skip=()):
    """The messages of frames 0 … upto_frame of the schedule, in stamp order (topic names
    in ``skip`` left out); returns the truth count fed."""
    from vega_bus import topics
    from vega_bus.timing import NS_PER_MS

    t0, f = info.t_start_ms, info.timing.frame_ms
    latency = info.timing.sensor_latency_ms
    stamps = {topics.TRUTH.name: [t0 + k * f for k in range(info.n_frames + 1)],
              topics.INS.name: [t0 + k * f + latency for k in range(info.n_frames)],
              topics.ACTUATOR.name: [t0 + (k + 1) * f for k in range(info.n_frames)],
              topics.CLOCK.name: [t0 + k * f for k in info.clock_frames()]}
    fed = 0
    events = sorted((t, name) for name, ts in stamps.items() for t in ts
                    if t < t0 + (upto_frame + 1) * f and name not in skip)
    for t, name in events:
        held.add(name, t * NS_PER_MS)
        fed += name == topics.TRUTH.name
    return fed


def test_the_report_is_the_frames_held_on_every_topic_and_stops_with_a_silent_writer():
    """FramesRecorded on the nominal run's schedule (truth, INS, actuator and /clock fed in
    stamp order; commands and diagnostics of a run are left out, so they are given as done):
    the report follows the truth within the /clock period; an INS writer whose messages stop
    arriving holds it at the INS's last frame whatever the truth does — the plant then stops
    within the window, while the INS samples are still in its writer's history."""
    from vega_bags.recorder import FramesRecorded
    from vega_bus import topics
    from vega_bus.timing import NS_PER_MS

    _, _, info = load_run("nominal", 1)
    expected = {name: n for name, n in info.expected_counts().items()
                if name not in (topics.TVC_CMD.name, topics.DIAGNOSTICS.name)}
    held = FramesRecorded(expected, info.t_start_ms * NS_PER_MS,
                          info.timing.frame_ms * NS_PER_MS)
    assert held.frames() == 0
    truth = _feed_in_frame_order(info, held, 500)
    assert truth == 501
    assert truth - 10 <= held.frames() <= truth          # /clock: every 10 frames
    more = FramesRecorded(expected, info.t_start_ms * NS_PER_MS,
                          info.timing.frame_ms * NS_PER_MS)
    _feed_in_frame_order(info, more, 300)
    at_300 = more.frames()
    assert 291 <= at_300 <= 301
    # frames 301 … 900 without INS: truth runs 600 frames ahead, the report does not move
    t0, f = info.t_start_ms, info.timing.frame_ms
    for k in range(301, 901):
        more.add(topics.TRUTH.name, (t0 + k * f) * NS_PER_MS)
        more.add(topics.ACTUATOR.name, (t0 + (k + 1) * f) * NS_PER_MS)
        if k % 10 == 0:
            more.add(topics.CLOCK.name, (t0 + k * f) * NS_PER_MS)
    assert more.frames() == 301           # the INS's last frame (300) + 1: held there
    truth_alone = FramesRecorded({topics.TRUTH.name: expected[topics.TRUTH.name]}, 0, 1)
    for k in range(901):
        truth_alone.add(topics.TRUTH.name, k)
    assert truth_alone.frames() == 901    # a report counting the truth alone


def test_a_finished_topic_no_longer_holds_the_report_and_all_done_is_the_truth_count():
    from vega_bags.recorder import FramesRecorded

    held = FramesRecorded({"/a": 3, "/b": 1}, 0, 10)
    held.add("/b", 5)                                    # /b done after frame 0
    for k in range(3):
        held.add("/a", 10 * k)
        assert held.frames() == k + 1
    assert held.frames() == 3                            # every topic done: the largest count
    final = FramesRecorded({"/t": 45}, 0, 1)
    reports = [r for r in (final.add("/t", k) for k in range(45)) if r is not None]
    assert reports == [20, 40]           # never 45: the truth count is the final report's
    early = FramesRecorded({"/a": 5, "/b": 5}, 100, 10)
    early.add("/a", 100 + 40)                            # frame 4
    assert early.frames() == 0                           # /b has sent nothing yet
    early.add("/b", 100 + 25)                            # frame 2
    assert early.frames() == 3


@pytest.mark.slow
def test_the_window_protocol_over_a_whole_flight_never_stalls_and_holds_the_plant():
    """The plant / recorder protocol simulated over the nominal run's schedule: the plant
    publishes frame k only while k − report < RECORDER_WINDOW_FRAMES; the other nodes' messages
    of a frame follow it; the recorder takes its queues in batches of B frames' worth, topic
    by topic, the truth first (the worst order for a report triggered by the truth); reports
    are FramesRecorded's. For several batch sizes: the whole run completes (no stall), the
    plant is never more than window + report interval frames beyond what the recorder holds
    on every topic, and with the INS queue held back for 300 frames the plant stops."""
    from vega_bags.recorder import FramesRecorded
    from vega_bus import topics
    from vega_bus.timing import NS_PER_MS

    _, _, info = load_run("nominal", 1)
    n, f, t0 = info.n_frames, info.timing.frame_ms, info.t_start_ms
    expected = info.expected_counts()
    commands = info.command_samples()
    per_frame = {k: [] for k in range(n + 1)}
    for k in range(n + 1):
        per_frame[k].append((topics.TRUTH.name, t0 + k * f))
    for k in info.clock_frames():
        per_frame[k].append((topics.CLOCK.name, t0 + k * f))
    for k in range(n):
        per_frame[k].append((topics.INS.name, t0 + k * f + info.timing.sensor_latency_ms))
        per_frame[k].append((topics.ACTUATOR.name, t0 + (k + 1) * f))
    latency = info.timing.sensor_latency_ms + info.timing.computing_latency_ms
    for sample in commands:
        k = min(n, (sample - t0) // f)
        for name in (topics.TVC_CMD.name, topics.DIAGNOSTICS.name):
            per_frame[k].append((name, sample + latency))
    assert sum(len(v) for v in per_frame.values()) == sum(expected.values())

    for batch, hold_ins in ((3, None), (40, None), (40, 2000)):
        held = FramesRecorded(expected, t0 * NS_PER_MS, f * NS_PER_MS)
        queues = {name: [] for name in expected}
        report, k, taken, worst_ahead, steps = 0, 0, 0, 0, 0
        held_steps, k_while_held = 0, None
        while taken < sum(expected.values()):
            steps += 1
            assert steps < 50 * n, f"batch {batch}: stalled at frame {k}, report {report}"
            if hold_ins and k >= hold_ins and held_steps < 100:
                held_steps += 1                # INS deliveries held up for 100 steps
                k_while_held = k
            for _ in range(batch):                         # the plant and the nodes run
                if k > n or k - report >= RECORDER_WINDOW_FRAMES:
                    break
                for name, stamp in per_frame[k]:
                    queues[name].append(stamp)
                k += 1
            for name in [topics.TRUTH.name] + [x for x in queues if x != topics.TRUTH.name]:
                if name == topics.INS.name and hold_ins and k >= hold_ins and held_steps < 100:
                    continue
                for stamp in queues[name]:
                    got = held.add(name, stamp * NS_PER_MS)
                    report = got if got is not None else report
                    taken += 1
                queues[name].clear()
            worst_ahead = max(worst_ahead, k - held.frames())
        assert k == n + 1 and held.frames() == n + 1
        assert report <= n        # the truth count n + 1 is the final report's alone
        if hold_ins:                           # the plant stopped within the window
            assert held_steps == 100
            assert k_while_held <= hold_ins + RECORDER_WINDOW_FRAMES + batch, k_while_held
        assert worst_ahead <= RECORDER_WINDOW_FRAMES + RECORDER_REPORT_FRAMES + batch, \
            (batch, worst_ahead)
