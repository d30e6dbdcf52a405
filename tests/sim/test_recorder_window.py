"""The recorder's back-pressure window against Fast DDS's shared-memory port (vega_bus.schedule):
the messages of the frames the recorder has not reported yet must stay well inside the 512
descriptors of a port, or a descheduled recorder loses samples (seen once in CI with the old
100-frame window: 120 frames × ≈ 4.5 messages ≈ 540)."""

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
