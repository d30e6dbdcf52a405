"""The lockstep schedule of one run: which message exists when, and what each node waits for.

Plain Python (no ROS). Every node of the graph knows the run's span and the loop timing
(:class:`RunInfo`), hence every producer's schedule; a consumer therefore knows exactly which
messages it needs before it may advance, and the recorder and the bag checker know exactly how
many messages a complete run holds. Time is carried by the stamps, not by timers.

Frames k = 0 … n−1 start at t_k = t_start + k·frame (n = (t_end − t_start)/frame):

* plant: truth at every t_k and at t_end (n + 1 messages, seq 0 … n); it integrates frame k
  when it holds the actuator's frame k; /clock at every :data:`CLOCK_EVERY_FRAMES`-th frame
  start and at t_end (:meth:`RunInfo.clock_frames`), right after the truth of that time;
* INS: one measurement per frame start t_k (n messages), stamped t_k + sensor latency;
* controller: one command per INS sample on the controller period (sample ≡ 0 mod period,
  absolute time), stamped sample + sensor + computing latency (:meth:`RunInfo.command_samples`);
* actuator: frame k = the physics steps starting at t_k … t_k + frame − dt (n messages, stamped
  t_k + frame). A command applies from its stamp + actuator latency, so frame k needs every
  command whose sample is ≤ t_k + frame − dt − total latency (:meth:`RunInfo.commands_needed`).
  With the default timing that is ≤ t_k − 30 ms: the actuator runs up to three frames ahead of
  the plant, and the loop cannot deadlock as long as total latency ≥ one frame
  (:meth:`RunInfo.check`).

:class:`RunInfo` travels on the bus as JSON (``/vega/run``, published by the plant, TRANSIENT_LOCAL)
so that the flight side (the controller), which does not read scenarios, learns the span and
the timing from the time master.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields

from vega_core.errors import BadInput

from vega_bus.timing import LoopTiming

__all__ = ["RunInfo", "RECORDER_REPORT_FRAMES", "RECORDER_WINDOW_FRAMES", "CLOCK_EVERY_FRAMES",
           "clock_frames"]

# Back-pressure from the recorder, the one participant no data dependency holds in step: it
# reports every RECORDER_REPORT_FRAMES truth messages the frames it holds on every topic
# (/vega/recorded, vega_bags.recorder.FramesRecorded: every topic, not the truth alone — with
# the truth alone a soak lost 848 /vega/ins samples while truth kept arriving), and the plant
# does not publish frame k while k − reported ≥ RECORDER_WINDOW_FRAMES. The window keeps the
# messages in flight towards the recorder (≈ 4.5 per frame) well inside the publishers'
# KEEP_LAST history (DATA_QUEUE_DEPTH = 1000 per topic; beyond it a writer drops samples the
# recorder has not acknowledged) and inside the 512 descriptors of a Fast DDS shared-memory
# port, whatever the load of the machine: at most (window + report interval) frames are not
# yet reported, (60 + 20) × 4.5 ≈ 360 messages. A window of 100 frames, (100 + 20) × 4.5 ≈ 540,
# is over the 512: with nodes as fast as vega_bus.cdr makes them, a CI run with it lost
# /vega/ins samples 443–864 towards a descheduled recorder, which refused the gap
# (StreamCheck: "publication sequence number 865, expected 443").
RECORDER_REPORT_FRAMES = 20
RECORDER_WINDOW_FRAMES = 60

# /clock is for tools (sim time for plots, rqt, replays), not for the lockstep, which runs on
# the stamps: a tick every 10 frames (100 ms at the default 10 ms frame, 10 Hz) and one at
# t_end. Every delivered message costs ≈ 0.15 ms of CPU across publisher and recorder; a tick
# per frame was ≈ 10 % of the SIL's CPU.
CLOCK_EVERY_FRAMES = 10


def clock_frames(n_frames: int) -> list[int]:
    """Frames k (0 … n_frames) whose start t_k gets a /clock tick: every
    :data:`CLOCK_EVERY_FRAMES`-th from the first, and the last (t_end)."""
    frames = list(range(0, n_frames + 1, CLOCK_EVERY_FRAMES))
    if frames[-1] != n_frames:
        frames.append(n_frames)
    return frames


@dataclass(frozen=True)
class RunInfo:
    """Span, timing and identity of one run.

    Attributes
    ----------
    scenario
        Scenario name.
    seed
        Scenario seed in force (after any override).
    t_start_ms, t_end_ms
        Span [ms], whole frames.
    timing
        Loop timing of the run (the scenario's delay deviation included).
    guidance
        The guidance reference the scenario names (``default``: the installed one, ``none``,
        or a file path): the controller flies it (vega_gnc.guidance_reference).
    """

    scenario: str
    seed: int
    t_start_ms: int
    t_end_ms: int
    timing: LoopTiming
    guidance: str = "default"

    def check(self) -> "RunInfo":
        """Validate the span against the timing; return self.

        Raises
        ------
        BadInput
            One line: span not in whole frames, empty, or a total latency shorter than one
            frame (the data-driven lockstep would deadlock).
        """
        f = self.timing.frame_ms
        if self.t_start_ms < 0 or self.t_start_ms % f or self.t_end_ms % f \
                or self.t_end_ms <= self.t_start_ms:
            raise BadInput(f"run span [{self.t_start_ms}, {self.t_end_ms}] ms must be whole "
                           f"{f} ms frames with 0 <= t_start < t_end")
        if self.timing.total_latency_ms < f:
            raise BadInput(f"total loop latency {self.timing.total_latency_ms} ms is shorter "
                           f"than one frame ({f} ms): the lockstep needs at least one frame")
        return self

    @property
    def n_frames(self) -> int:
        """Frames in [t_start, t_end)."""
        return (self.t_end_ms - self.t_start_ms) // self.timing.frame_ms

    def frame_start(self, k: int) -> int:
        """t_k [ms]."""
        return self.t_start_ms + k * self.timing.frame_ms

    def clock_frames(self) -> list[int]:
        """Frames k (0 … n) whose start t_k gets a /clock tick (:func:`clock_frames`)."""
        return clock_frames(self.n_frames)

    def command_samples(self) -> range:
        """INS sample times [ms] the controller turns into commands, in order."""
        p = self.timing.controller_period_ms
        first = -(-self.t_start_ms // p) * p
        last_sample = self.t_end_ms - self.timing.frame_ms
        return range(first, last_sample + 1, p)

    def commands_needed(self, k: int) -> int:
        """Number of commands (seq 0 … N−1) the actuator must hold to integrate frame k."""
        t = self.timing
        limit = self.frame_start(k) + t.frame_ms - t.physics_dt_ms - t.total_latency_ms
        samples = self.command_samples()
        if limit < samples.start:
            return 0
        return min(len(samples), (limit - samples.start) // samples.step + 1)

    def expected_counts(self) -> dict[str, int]:
        """Messages of a complete run by topic (:mod:`vega_bus.topics` names)."""
        from vega_bus.topics import ACTUATOR, CLOCK, DIAGNOSTICS, INS, TRUTH, TVC_CMD

        n = self.n_frames
        commands = len(self.command_samples())
        return {TRUTH.name: n + 1, CLOCK.name: len(self.clock_frames()), INS.name: n,
                TVC_CMD.name: commands, ACTUATOR.name: n, DIAGNOSTICS.name: commands}

    def to_json(self) -> str:
        """One-line JSON (keys sorted)."""
        d = asdict(self)
        return json.dumps(d, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "RunInfo":
        """Parse :meth:`to_json` output.

        Raises
        ------
        BadInput
            One line if the text is not a valid run description.
        """
        try:
            d = json.loads(text)
            timing = LoopTiming(**{f.name: int(d["timing"][f.name])
                                   for f in fields(LoopTiming)})
            info = cls(str(d["scenario"]), int(d["seed"]), int(d["t_start_ms"]),
                       int(d["t_end_ms"]), timing, str(d["guidance"]))
        except (ValueError, TypeError, KeyError) as exc:
            raise BadInput(f"malformed run description: {exc}") from None
        return info.check()
