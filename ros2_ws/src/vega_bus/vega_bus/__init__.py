"""The contract of the VEGA TVC node graph, shared by the truth-side nodes (vega_plant), the flight
side (vega_gnc), the simulation (vega_sim), the bags (vega_bags) and the bring-up (vega_bringup).

Modules: :mod:`~vega_bus.topics` (names, types, QoS), :mod:`~vega_bus.timing` (loop timing,
ms stamps, the time units ``NS_PER_MS``/``NS_PER_S``), :mod:`~vega_bus.records` (one plain
record per data message: ``TruthOut``, ``InsOut``, ``CommandOut``, ``ActuatorOut``),
:mod:`~vega_bus.wire` (records ↔ messages by field name; the ``TvcCommand`` status names from
the message), :mod:`~vega_bus.parameters` (the node parameters: type, default, unit, meaning,
domain), :mod:`~vega_bus.schedule` (the lockstep schedule, :class:`RunInfo`, expected message
counts), :mod:`~vega_bus.barrier` (start barrier), :mod:`~vega_bus.shell` (the ROS shell
every node shares: parameters, waiting, exit codes, signals).

SIL node contract (as implemented)
----------------------------------
Executables (``ros2 run`` layout): ``vega_plant plant``, ``vega_plant ins_sensor``,
``vega_plant tvc_actuator``, ``vega_gnc tvc_controller``, ``vega_bags recorder``; node name =
executable name; started as ``<prefix>/lib/PKG/EXE --ros-args --params-file FILE``.

Parameters (one YAML, ``/**: ros__parameters:``; each node declares only what it uses and
ignores the rest; a bad value → one line, exit 2), declared once in
:data:`vega_bus.parameters.PARAMETERS` (the nodes declare them from there as read-only with
descriptors, answered by ``ros2 param describe`` until the start barrier is complete; the run
planner writes the file from the same names): ``scenario`` (string, default "nominal"),
``seed`` (int, −1 = the scenario's), ``realtime`` (bool, plant), ``controller_table``
(string, "" = installed ``share/vega_gnc/config/tvc_controller.npz``; controller and recorder),
``bag_path`` (string, recorder, must not exist), ``participants`` (string array, default
:data:`vega_bus.barrier.PARTICIPANTS`), ``barrier_timeout_s`` (float, 30 s; ``vega sil run``
writes :data:`vega_bringup.orchestrate.DEFAULT_BARRIER_TIMEOUT_S`), ``stall_timeout_s``
(float, 10 s: the longest wait for an expected input once flying).

Messages: every node moves its step's record to and from the message with
:mod:`vega_bus.wire` (by field name, never by position); the ``TvcCommand`` status values are
the message's own constants.

Additions to the contract first agreed (other helpers: read this):

* ``/vega/run`` (std_msgs/String, RELIABLE, TRANSIENT_LOCAL): the plant publishes the run
  description (:class:`vega_bus.schedule.RunInfo` as JSON: scenario, seed, span, loop timing)
  at start-up, before the barrier. The controller, which reads no scenario (the flight side
  does not import vega_plant), waits for it (up to ``barrier_timeout_s``) before joining the
  barrier. Not recorded.
* ``/vega/recorded`` (std_msgs/UInt32, data QoS): the recorder's progress (truth messages
  written, every :data:`vega_bus.schedule.RECORDER_REPORT_FRAMES`, and a final report);
  when "recorder" is a participant the plant stays at most
  :data:`vega_bus.schedule.RECORDER_WINDOW_FRAMES` frames ahead of it (back-pressure: the
  recorder is the one node no data dependency holds in step), and every node ends its run on
  the final report (below). Subscribed by plant, ins_sensor, tvc_controller, tvc_actuator;
  the recorder's barrier requires those matches, the others' barriers do not require the
  recorder's publisher (a tool in the recorder's seat, such as ``vega replay
  --check-controller``, publishes no progress: then nobody is paced and every node ends on
  DDS acknowledgements).
* ``stall_timeout_s`` parameter (above).
* ``/clock`` is published RELIABLE with depth :data:`vega_bus.topics.DATA_QUEUE_DEPTH` (not 1),
  so that a lagging recorder loses no tick, at 10 Hz, not at every frame: a tick at every
  :data:`vega_bus.schedule.CLOCK_EVERY_FRAMES`-th frame start and at t_end
  (:meth:`RunInfo.clock_frames`, also the recorder's expected count); tools need sim time,
  the lockstep runs on the stamps, and a tick per frame cost ≈ 8 % of the SIL's CPU.
* Every participant, not only the plant, waits until it holds ``/vega/ready`` from all
  participants before its first data message (the actuator needs no input for its first
  frames and would otherwise publish before the plant listens). Nodes that time out exit 1
  with one line naming the missing participants.
* Exit codes (:mod:`vega_bus.shell`): 0 = run finished or SIGINT/SIGTERM (one line
  ``<node>: stopped by SIGTERM`` on stderr; the recorder closes the bag first); 1 = run
  failure (barrier timeout, sequence gap, stamp out of schedule, stall); 2 = bad input.
  A signal that arrives while the interpreter is still importing (before the handlers are
  installed, ≈ 0.5 s) kills the process with the default action (exit −15/143).
* Run end: plant after truth and /clock at t_end; INS after its sample t_end − frame;
  controller after the measurement of sample t_end − frame; actuator after its frame
  (t_end − frame, t_end]. Then, with a recorder among the participants, each of them waits
  for the recorder's final report on ``/vega/recorded`` (= the run's truth count, n + 1) and
  exits 0; the recorder, once it has every expected message
  (:meth:`RunInfo.expected_counts`), closes the bag, publishes that final report and waits
  (≤ stall_timeout_s) until the others have left. Without a recorder, each publisher waits
  (≤ stall_timeout_s) for its subscribers' DDS acknowledgements instead (≈ 2.3 s: Fast DDS
  acknowledges on its heartbeat).
* Start barrier: a participant is ready when its publishers have matched their expected
  subscribers *and* its subscriptions their expected publishers (a reader that has not yet
  matched a writer ignores its data until the writer's next heartbeat, 3 s).
"""
