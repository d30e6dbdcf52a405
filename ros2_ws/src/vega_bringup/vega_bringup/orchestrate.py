"""Orchestration of one SIL run: the node command lines, the parameters file, the supervisor.

``vega sil run`` (:mod:`vega_cli.commands.sil`) is a thin shell over this module:

* pure functions build what a run needs — the participants (:data:`PARTICIPANTS`), the one
  parameters file all nodes share (:func:`params_yaml`), the command of each node
  (:func:`node_command`) and the same as a line to paste into a terminal
  (:func:`shell_line`), the run directory layout (:class:`RunLayout`);
* :class:`Supervisor` starts every node as its own process (setsid: own process group,
  the environment of :func:`vega_bringup.rosenv.ros_environment` with one ROS_DOMAIN_ID for the
  whole run, output to a log file per node), watches the start barrier on ``/vega/ready``
  (:class:`ReadyWatcher`), waits for the flight to end, and stops everything on a failure or
  an interrupt: SIGCONT then SIGTERM to every process group still running, SIGKILL after
  :data:`TERM_GRACE_S`. The recorder closes its bag on SIGTERM, so a stopped run keeps a
  readable bag (SIGCONT first: a stopped node — SIGSTOP from a debugger or job control —
  resumes and handles SIGTERM instead of being killed with its bag open). If a node was
  killed by a signal, the shared-memory files it could not remove are cleaned
  (:func:`clean_shared_memory`).

A node's exit status follows the contract of the node executables: 0 = the run ended
normally (after the scenario's t_end), 1 = run failure (sequence gap, lockstep stall, barrier
timeout), 2 = bad input (parameters, scenario, controller table); a negative status is the
signal that killed it.

Run directory (``DIR/<run-id>/``)::

    params.yaml     the parameters of every node (section ``/**: ros__parameters:``)
    commands.sh     the command of each node, one per line (what ``--dry-run`` prints)
    logs/NODE.log   stdout and stderr of each node
    bag/            the rosbag2 (MCAP) the recorder writes
    report/         the report (JSON, Markdown, plots) written from the bag
"""

from __future__ import annotations

import json
import os
import re
import selectors
import shlex
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

from vega_bus import barrier, parameters, qos, topics
from vega_bus.shell import DUMP_STACKS_SIGNAL, TEARDOWN_WATCHDOG_SIGNAL

__all__ = ["NodeSpec", "PARTICIPANTS", "DEFAULT_BARRIER_TIMEOUT_S", "TERM_GRACE_S",
           "FINISH_GRACE_S", "RunParameters", "RunLayout", "params_yaml", "default_run_id",
           "node_command", "environment_script", "shell_line", "describe_status",
           "clean_shared_memory", "NodeProcess", "RunOutcome", "ReadyWatcher", "Supervisor"]


@dataclass(frozen=True)
class NodeSpec:
    """A node of the graph: ROS 2 package and executable (the node name is the executable)."""

    package: str
    executable: str

    @property
    def name(self) -> str:
        """Node name (= executable name)."""
        return self.executable


_PACKAGES = {"plant": "vega_plant", "ins_sensor": "vega_plant", "tvc_actuator": "vega_plant",
             "tvc_controller": "vega_gnc", "recorder": "vega_bags"}
"""ROS 2 package of each node executable."""

PARTICIPANTS = tuple(NodeSpec(_PACKAGES[name], name) for name in barrier.PARTICIPANTS)
"""Every node of a SIL run (:data:`vega_bus.barrier.PARTICIPANTS`), in start order (any order
works: the start barrier waits)."""

DEFAULT_BARRIER_TIMEOUT_S = 60.0
"""Start-barrier timeout a run writes for its nodes [s] (a node started without it waits
:data:`vega_bus.parameters.BARRIER_TIMEOUT_S`'s shorter default): long enough for five Python
processes to import and set up on a loaded 2-core machine (2–3 s measured, up to 20 s under
heavy load) plus a slow DDS discovery (up to ≈ 3 s, docs/ENVIRONMENT_SETUP.md); a node that is
missing after it fails the run and is named."""

TERM_GRACE_S = 5.0
"""Time a node gets to exit after SIGTERM before it is killed (SIGKILL) [s]."""

FINISH_GRACE_S = 30.0
"""Once one node has ended normally, time the others get to end too [s]: they all end at the
same t_end, so a node still running after this is hung (its own stall check failed)."""

STACK_DUMP_WAIT_S = 0.5
"""Time a hung node gets to write its stacks before it is stopped [s] (faulthandler writes
them from its signal handler at once; this is only the scheduling slack)."""

_BARRIER_MARGIN_S = 5.0
"""The orchestrator's own barrier deadline is the nodes' timeout plus this margin [s], so that
the nodes normally report the timeout first (exit 1) and the orchestrator names the missing."""


# ----------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class RunParameters:
    """The parameters every node of a run reads (one ``/**`` section, see :func:`params_yaml`).

    Every field is a node parameter of :data:`vega_bus.parameters.PARAMETERS`, which holds
    its meaning, unit and domain (the nodes declare them from there, and ``ros2 param
    describe`` shows them); tests/bus/test_parameters.py checks that the two agree.

    Attributes
    ----------
    scenario : str
        Shipped scenario name, or the absolute path of a scenario YAML file.
    seed : int
        Seed overriding the scenario's; -1 keeps the scenario's own.
    realtime : bool
        Pace the flight to the wall clock instead of running as fast as possible.
    controller_table : str
        Absolute path of the controller table (.npz); "" = the installed default.
    bag_path : str
        Output directory of the recorder (must not exist yet).
    participants : tuple of str
        Names of the nodes the start barrier waits for.
    barrier_timeout_s : float
        Start-barrier timeout [s].
    """

    scenario: str
    seed: int
    realtime: bool
    controller_table: str
    bag_path: str
    participants: tuple[str, ...] = tuple(spec.name for spec in PARTICIPANTS)
    barrier_timeout_s: float = DEFAULT_BARRIER_TIMEOUT_S


def _yaml_scalar(value) -> str:
    """One parameter value as a YAML flow scalar whose type the ROS 2 YAML parser keeps.

    Strings are always double-quoted (a JSON string is a valid YAML double-quoted scalar), so
    a scenario called ``yes`` or ``1`` stays a string; floats always carry a decimal point.
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_yaml_scalar(v) for v in value) + "]"
    raise TypeError(f"unsupported parameter value {value!r}")


def params_yaml(params: RunParameters) -> str:
    """The parameters file of a run: one ``/**: ros__parameters:`` section for every node.

    Parameters
    ----------
    params
        The run's parameters.

    Returns
    -------
    str
        YAML text for ``--ros-args --params-file``.
    """
    lines = ["# Parameters of every node of one VEGA TVC SIL run (written by `vega sil run`).",
             "/**:", "  ros__parameters:"]
    for name in RunParameters.__dataclass_fields__:
        value = parameters.spec(name).coerce(getattr(params, name))   # in the node's type
        lines.append(f"    {name}: {_yaml_scalar(value)}")
    return "\n".join(lines) + "\n"


def default_run_id(scenario_name: str, seed: int, now: float | None = None) -> str:
    """Run directory name: ``<UTC time>-<scenario>-seed<N>``
    (e.g. ``20261121T083000Z-nominal-seed1``).

    Parameters
    ----------
    scenario_name
        Scenario name (``Scenario.name``).
    seed
        The seed the run flies with.
    now
        POSIX time (default: now).
    """
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(time.time() if now is None else now))
    return f"{stamp}-{scenario_name}-seed{seed}"


@dataclass(frozen=True)
class RunLayout:
    """The files of one run directory (module docstring)."""

    run_dir: Path

    @property
    def params_file(self) -> Path:
        """The parameters file every node reads."""
        return self.run_dir / "params.yaml"

    @property
    def commands_file(self) -> Path:
        """The node commands, one per line."""
        return self.run_dir / "commands.sh"

    @property
    def log_dir(self) -> Path:
        """One log file per node."""
        return self.run_dir / "logs"

    @property
    def bag_dir(self) -> Path:
        """The run's rosbag2 directory."""
        return self.run_dir / "bag"

    @property
    def report_dir(self) -> Path:
        """The report written from the bag."""
        return self.run_dir / "report"

    def log_file(self, spec: NodeSpec) -> Path:
        """Log file of a node."""
        return self.log_dir / f"{spec.name}.log"


# ----------------------------------------------------------------------------- commands
def node_command(executable_path: str | os.PathLike, params_file: str | os.PathLike,
                 extra_ros_args: Sequence[str] = ()) -> list[str]:
    """The command that starts one node: ``EXE --ros-args --params-file FILE [ARGS...]``.

    Parameters
    ----------
    executable_path
        ``<prefix>/lib/PKG/EXE`` (:func:`vega_bringup.executables.find_executable`).
    params_file
        The run's parameters file.
    extra_ros_args
        More ROS arguments (e.g. ``-r`` remappings), appended after the params file.
    """
    return [str(executable_path), "--ros-args", "--params-file", str(params_file),
            *extra_ros_args]


def environment_script() -> Path | None:
    """The project's ``tools/env.bash`` for this installation, or None if there is none.

    Found next to the virtual environment (``$VIRTUAL_ENV/../tools/env.bash``, what the
    ``vega`` wrapper sources), else above this source file (the workspace is symlinked).
    """
    candidates = []
    if os.environ.get("VIRTUAL_ENV"):
        candidates.append(Path(os.environ["VIRTUAL_ENV"]).parent / "tools" / "env.bash")
    here = Path(__file__).resolve()
    candidates += [parent / "tools" / "env.bash" for parent in here.parents]
    for path in candidates:
        if path.is_file():
            return path
    return None


def shell_line(command: Sequence[str], domain_id: int, env_script: Path | None) -> str:
    """One node command as a line to paste into a fresh bash terminal.

    The line enters the project environment (``source tools/env.bash``: venv, workspace,
    LOCALHOST discovery), exports the run's ROS_DOMAIN_ID so that nodes in separate terminals
    meet, and runs the command. Without an environment script (a full ROS install) it only
    exports the two ROS variables.

    Parameters
    ----------
    command
        :func:`node_command`.
    domain_id
        The run's ROS_DOMAIN_ID.
    env_script
        :func:`environment_script`.
    """
    setup = (f"source {shlex.quote(str(env_script))} && " if env_script is not None else "")
    return (f"{setup}export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID={domain_id}"
            f" && {shlex.join(command)}")


def describe_status(returncode: int) -> str:
    """A node's exit status in words: ``exit status 1`` or ``killed by SIGKILL``."""
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exit status {returncode}"


def _last_line(path: Path, limit: int = 65536) -> str:
    """The last non-empty line of a log file ("" if none or unreadable)."""
    try:
        with open(path, "rb") as handle:
            handle.seek(0, os.SEEK_END)
            size = handle.tell()
            handle.seek(max(0, size - limit))
            tail = handle.read().decode("utf-8", "replace")
    except OSError:
        return ""
    lines = [line.strip() for line in tail.splitlines() if line.strip()]
    return lines[-1] if lines else ""


def clean_shared_memory() -> bool:
    """Remove the Fast DDS shared-memory files no live process holds (``fastdds shm clean``).

    A node that was killed (SIGKILL) cannot remove its ``/dev/shm/fastrtps_*`` files; Fast DDS's
    own tool removes exactly those whose lock nobody holds, so concurrent runs are not
    disturbed. Returns False if the tool is not found or fails (nothing else happens then).
    """
    tool = Path(sys.prefix) / "bin" / "fastdds"
    tool = str(tool) if tool.is_file() else shutil.which("fastdds")
    if tool is None:
        return False
    try:
        done = subprocess.run([tool, "shm", "clean"], stdin=subprocess.DEVNULL,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              timeout=30, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


# ----------------------------------------------------------------------------- processes
@dataclass
class NodeProcess:
    """A started node: its spec, command, log file and process."""

    spec: NodeSpec
    command: list[str]
    log_path: Path
    popen: subprocess.Popen
    pidfd: int | None = None
    cpu_s: float | None = None
    """CPU time (user + system) the node used [s], once it has ended."""
    teardown_hung: bool = False
    """The node finished its run but its middleware teardown hung with the GIL held, and its
    own watchdog ended it (:data:`vega_bus.shell.TEARDOWN_WATCHDOG_SIGNAL`; counted as status
    0, with a warning; its Python stacks are in its log)."""

    @property
    def name(self) -> str:
        """Node name (= executable name)."""
        return self.spec.name

    def reap(self, block: bool = False):
        """Collect the exit status and CPU time (``wait4``) if the node has ended (or, with
        ``block``, once it has)."""
        if self.popen.returncode is not None:
            return
        try:
            pid, status, usage = os.wait4(self.popen.pid, 0 if block else os.WNOHANG)
        except ChildProcessError:  # reaped elsewhere: only the status is left
            self.popen.poll()
            return
        if pid:
            code = os.waitstatus_to_exitcode(status)
            if code == -TEARDOWN_WATCHDOG_SIGNAL:
                self.teardown_hung, code = True, 0
            self.popen.returncode = code
            self.cpu_s = usage.ru_utime + usage.ru_stime

    @property
    def returncode(self) -> int | None:
        """Exit status once it has ended (negative: killed by that signal), else None."""
        self.reap()
        return self.popen.returncode

    def last_log_line(self) -> str:
        """The last non-empty line the node wrote (its one-line error, if it failed)."""
        return _last_line(self.log_path)


_STOPPED = re.compile(r": stopped by SIG[A-Z]+")
"""The line a node writes when a signal stopped it (vega_bus.shell)."""
DISK_FULL_BYTES = 1 << 20
"""Free space below which a failed run is reported as a full disk (1 MiB: less than one
second of bag)."""


def _free_bytes(path: Path) -> int | None:
    """Free bytes on the file system of ``path`` (None if it cannot be asked)."""
    try:
        return shutil.disk_usage(path).free
    except OSError:
        return None


STALL_FOLLOW_S = 20.0
"""How long the supervisor waits for a running node that another one stalled on to report its
own stall (twice the nodes' default stall timeout of 10 s: under load a stall is reported
late)."""
# "lockstep stall: waited 10 s for /vega/ins seq 12" (vega_bus.shell.Shell.wait_until)
_STALL = re.compile(r"lockstep stall: waited \S+ s for (/[\w/]+)")
_PUBLISHERS = {t.name: t.publisher for t in (*topics.ALL_TOPICS, topics.RECORDED, topics.RUN)}


def _process_state(pid: int) -> str | None:
    """The state letter of /proc/PID/stat (R, S, D, T, t, Z, ...), None if unreadable."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text.rpartition(")")[2].split()[0] if ")" in text else None


@dataclass
class RunOutcome:
    """How a run ended.

    ``status``: ``"ok"`` (every node ended with 0), ``"failed"`` (a node failed, died, or
    the barrier timed out), ``"bad_input"`` (a node rejected its input: exit 2) or
    ``"interrupted"``; ``message`` says which node and how (one line, empty if ok);
    ``returncodes`` the exit status of every node, ``cpu_s`` its CPU time (user + system)
    [s]; ``flight_wall_s`` the wall time from the
    barrier to the end (None if the barrier never completed).
    """

    status: str
    message: str = ""
    returncodes: dict[str, int | None] = field(default_factory=dict)
    cpu_s: dict[str, float | None] = field(default_factory=dict)
    flight_wall_s: float | None = None
    barrier_wall_s: float | None = None

    @property
    def ok(self) -> bool:
        """True if the run ended normally."""
        return self.status == "ok"


def _set_parent_death_signal():
    """In the child before exec: get SIGTERM if the orchestrator dies (Linux prctl), so that
    even a killed ``vega sil run`` leaves no nodes behind."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        pass


_RUN_TOPICS = (*topics.ALL_TOPICS, topics.RECORDED, topics.RUN, topics.READY)
_FASTDDS_VENDOR = b"\x01\x0f"   # eProsima's RTPS vendor id, the first bytes of every GUID
_UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"   # rmw's node name of an endpoint not yet attributed
NAME_WAIT_S = 5.0
"""How long the watch waits for the node name of a foreign endpoint the graph knows only by
its GID so far (the name comes on ros_discovery_info, usually within milliseconds) [s]."""
FOREIGN_POLL_S = 0.25
"""Period of the supervisor's watch for foreign publishers on the run's topics [s]."""


def foreign_publisher(endpoints_by_topic, own_pids: Mapping[str, int],
                      participants: Sequence[str]) -> str | None:
    """The first publisher on a run topic that is not one of the run's own nodes, as one line
    naming it (node name and GID), or None.

    Parameters
    ----------
    endpoints_by_topic
        Topic name → its publishers' ``TopicEndpointInfo`` (rclpy's
        ``Node.get_publishers_info_by_topic``).
    own_pids
        Node name → process id of the run's node processes.
    participants
        The run's participants (any of them may publish on ``/vega/ready``).

    A publisher is the run's own if its node name is the topic's publisher
    (:mod:`vega_bus.topics`) and its GID is a Fast DDS GUID whose process-id field (bytes
    4–5, little-endian: the low 16 bits of the pid, as Fast DDS builds its GUID prefix) is
    that node's process. Without DDS-Security the GID is what the sender claims: this finds
    an ordinary ROS 2 process on the bus, not a forger of RTPS packets (docs/SECURITY.md).
    """
    own = {pid & 0xFFFF: name for name, pid in own_pids.items()}
    for topic in _RUN_TOPICS:
        allowed = tuple(participants) if topic.publisher == "*" else (topic.publisher,)
        for info in endpoints_by_topic.get(topic.name, ()):
            gid = bytes(info.endpoint_gid)
            name = info.node_name
            owner = own.get(int.from_bytes(gid[4:6], "little")) \
                if gid[:2] == _FASTDDS_VENDOR else None
            if owner is not None and owner in allowed and name in (owner, _UNKNOWN_NODE):
                # the run's node (its name may not be known yet: the graph learns endpoints
                # before the node names, which come on ros_discovery_info)
                continue
            namespace = info.node_namespace.rstrip("/")
            return (f"foreign publisher on {topic.name}: node '{namespace}/{name}' (GID "
                    f"{gid.hex('.')}) is not one of the run's nodes; nothing but the run may "
                    f"publish on its topics (docs/SECURITY.md)")
    return None


class ReadyWatcher:
    """Subscribes to the start barrier's ``/vega/ready`` and collects the names announced;
    watches the graph for foreign publishers on the run's topics (:meth:`foreign`).

    An own rclpy context, shut down completely by :meth:`close` at the end of the run; it
    subscribes to nothing but ``/vega/ready`` and publishes nothing on the run's topics.
    """

    def __init__(self):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import String

        self.ready: set[str] = set()
        self._rclpy = rclpy
        self._context = rclpy.Context()
        rclpy.init(context=self._context, signal_handler_options=_no_signal_handlers())
        self._node = rclpy.create_node("vega_sil_run", context=self._context)
        self._node.create_subscription(String, topics.READY.name, self._on_ready,
                                       qos.control_qos())
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)

    def _on_ready(self, msg):
        self.ready.add(msg.data)

    def spin_once(self, timeout_s: float):
        """Handle what arrived, waiting at most ``timeout_s``."""
        self._executor.spin_once(timeout_sec=timeout_s)

    def foreign(self, own_pids: Mapping[str, int], participants: Sequence[str]) -> str | None:
        """:func:`foreign_publisher` on the graph as this participant sees it now."""
        if self._node is None:
            return None
        deadline = time.monotonic() + NAME_WAIT_S
        while True:
            found = foreign_publisher(
                {t.name: self._node.get_publishers_info_by_topic(t.name) for t in _RUN_TOPICS},
                own_pids, participants)
            # the graph learns an endpoint before its node's name: give the name time to come
            if found is None or _UNKNOWN_NODE not in found or time.monotonic() > deadline:
                return found
            time.sleep(0.05)

    def close(self):
        """Destroy the node and shut the context down (idempotent)."""
        if self._node is None:
            return
        self._executor.remove_node(self._node)
        self._node.destroy_node()
        self._node = None
        self._executor.shutdown()
        self._rclpy.try_shutdown(context=self._context)


def _no_signal_handlers():
    """rclpy.init option: leave SIGINT/SIGTERM to the supervisor (it stops the nodes)."""
    from rclpy.signals import SignalHandlerOptions

    return SignalHandlerOptions.NO


class _Terminated(Exception):
    """SIGTERM (or SIGHUP) to the orchestrator: stop everything like on Ctrl-C."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class Supervisor:
    """Start, watch and stop the nodes of one run.

    Parameters
    ----------
    nodes
        (spec, command) per node.
    layout
        The run directory (logs go to ``layout.log_file(spec)``).
    env
        The environment of every node (:func:`vega_bringup.rosenv.ros_environment`).
    participants
        Names the start barrier waits for (default: the nodes' names).
    barrier_timeout_s
        The nodes' barrier timeout; the supervisor gives up :data:`_BARRIER_MARGIN_S` later.
    watch_barrier
        Subscribe to ``/vega/ready`` to name the nodes missing at a barrier timeout.
    progress
        Called with one-line status messages (default: nothing).
    on_flight
        Called once, without arguments, when the start barrier is complete and the flight
        begins (e.g. to prepare the report while the nodes fly; default: nothing).

    Use :meth:`run` (start → barrier → flight → stop); it never leaves a process behind.
    """

    def __init__(self, nodes: Iterable[tuple[NodeSpec, Sequence[str]]], layout: RunLayout,
                 env: Mapping[str, str], *, participants: Sequence[str] | None = None,
                 barrier_timeout_s: float = DEFAULT_BARRIER_TIMEOUT_S,
                 watch_barrier: bool = True,
                 progress: Callable[[str], None] | None = None,
                 on_flight: Callable[[], None] | None = None):
        self.nodes = [(spec, list(command)) for spec, command in nodes]
        self.on_flight = on_flight or (lambda: None)
        self.layout = layout
        self.env = dict(env)
        self.participants = tuple(participants if participants is not None
                                  else (spec.name for spec, _ in self.nodes))
        self.barrier_timeout_s = float(barrier_timeout_s)
        self.watch_barrier = watch_barrier
        self.progress = progress or (lambda line: None)
        self.processes: list[NodeProcess] = []

    # -- starting
    def start(self):
        """Start every node (setsid: own process group; log file, the run's environment)."""
        self.layout.log_dir.mkdir(parents=True, exist_ok=True)
        for spec, command in self.nodes:
            log_path = self.layout.log_file(spec)
            with open(log_path, "wb") as log:
                popen = subprocess.Popen(
                    command, env=self.env, cwd=self.layout.run_dir, stdin=subprocess.DEVNULL,
                    stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                    preexec_fn=_set_parent_death_signal)
            process = NodeProcess(spec, command, log_path, popen)
            try:
                process.pidfd = os.pidfd_open(popen.pid)
            except (AttributeError, OSError):  # pragma: no cover - Linux < 5.3
                process.pidfd = None
            self.processes.append(process)

    # -- watching
    def _failed(self) -> NodeProcess | None:
        """The first node (in start order) that ended with a non-zero status, if any."""
        for process in self.processes:
            code = process.returncode
            if code is not None and code != 0:
                return process
        return None

    def _running(self) -> list[NodeProcess]:
        return [p for p in self.processes if p.returncode is None]

    def _wait_any(self, timeout_s: float):
        """Block until a running node ends or ``timeout_s`` passes (pidfd select)."""
        running = self._running()
        fds = [p.pidfd for p in running if p.pidfd is not None]
        if not running:
            return
        if len(fds) < len(running):  # pragma: no cover - no pidfd: poll
            time.sleep(min(timeout_s, 0.05))
            return
        with selectors.DefaultSelector() as selector:
            for fd in fds:
                selector.register(fd, selectors.EVENT_READ)
            selector.select(timeout_s)

    def _failure_message(self, process: NodeProcess, phase: str) -> str:
        code = process.returncode
        line = process.last_log_line()
        text = f"node '{process.name}' failed {phase}: {describe_status(code)}"
        text = f"{text}: {line}" if line and code > 0 else text
        culprit = self._culprit(process)
        text = text if culprit is None else f"{culprit}; then {text}"
        free = _free_bytes(self.layout.run_dir)
        if free is not None and free < DISK_FULL_BYTES:
            text += (f"; the file system of {self.layout.run_dir} is full ({free} bytes free): "
                     f"the nodes could not write their logs or the bag")
        return text

    def _ended_early(self) -> str | None:
        """A node that ended with status 0 because something outside the run stopped it (its
        last line says ``stopped by SIG…``) while the others still fly: the run is not
        complete, whatever the status says (a recorder stopped so closes a partial bag)."""
        if not self._running():
            return None
        for process in self.processes:
            if process.returncode != 0:
                continue
            line = process.last_log_line() or ""
            if _STOPPED.search(line):
                return (f"node '{process.name}' ended (exit status 0) before the run was "
                        f"complete: {line}")
        return None

    def _await_stall_chain(self, failed: NodeProcess) -> None:
        """When ``failed`` stalled waiting for a node that still runs and is not stopped, that
        node is most likely waiting itself: give it up to :data:`STALL_FOLLOW_S` to end with
        its own stall message, so that the chain leads to the node that stopped first."""
        deadline = time.monotonic() + STALL_FOLLOW_S
        while time.monotonic() < deadline:
            culprit = self._stall_chain(failed)
            if culprit is None or not culprit[1]:
                return
            self._wait_any(0.2)

    def _culprit(self, failed: NodeProcess) -> str | None:
        """The text of :meth:`_stall_chain` (None: nobody else to name)."""
        chain = self._stall_chain(failed)
        return None if chain is None else chain[0]

    def _stall_chain(self, failed: NodeProcess) -> tuple[str, bool] | None:
        """Who a lockstep stall really waited for: the producer of the awaited topic, followed
        through further stalls, when it did not fail by itself first — a node that is stopped
        (SIGSTOP, a debugger), hung, or ended early. None when ``failed`` did not stall, or the
        chain ends at a node whose own failure is the cause (then that one is named
        elsewhere). The flag says whether the named node still runs without being stopped
        (it may yet report a stall of its own)."""
        by_name = {p.name: p for p in self.processes}
        node, seen = failed, {failed.name}
        while True:
            match = _STALL.search(node.last_log_line() or "")
            if match is None:
                return None if node is failed else (
                    f"node '{node.name}' failed: {describe_status(node.returncode)}: "
                    f"{node.last_log_line()}", False)
            producer = by_name.get(_PUBLISHERS.get(match.group(1), ""))
            if producer is None or producer.name in seen:
                return None
            seen.add(producer.name)
            code = producer.returncode
            if code is None:
                stopped = _process_state(producer.popen.pid) in ("T", "t")
                how = ("is stopped (SIGSTOP or a debugger)" if stopped
                       else "is running but stopped publishing")
                return (f"node '{producer.name}' stopped making progress: it {how}, and "
                        f"'{node.name}' waited in vain for {match.group(1)}", not stopped)
            if code == 0:
                return (f"node '{producer.name}' ended (exit status 0) before the run was "
                        f"complete, and '{node.name}' waited in vain for {match.group(1)}",
                        False)
            node = producer

    def wait_barrier(self, watcher: ReadyWatcher | None) -> RunOutcome | None:
        """Wait until every participant has announced itself on ``/vega/ready``.

        Returns
        -------
        RunOutcome or None
            None once the barrier is complete; a failed outcome if a node ended first or the
            deadline (the nodes' timeout plus a margin) passed, naming the missing nodes.
        """
        if watcher is None:  # not watched: the flight phase reports every failure
            return None
        deadline = time.monotonic() + self.barrier_timeout_s + _BARRIER_MARGIN_S
        next_poll = time.monotonic()
        while True:
            if time.monotonic() >= next_poll:
                next_poll = time.monotonic() + FOREIGN_POLL_S
                foreign = self._foreign(watcher)
                if foreign is not None:
                    return RunOutcome("failed", foreign)
            failed = self._failed()
            missing = [name for name in self.participants if name not in watcher.ready]
            if failed is not None:
                message = self._failure_message(failed, "before the start barrier completed")
                if missing:
                    message += f" (not ready: {', '.join(missing)})"
                return RunOutcome("bad_input" if failed.returncode == 2 else "failed", message)
            if not missing:
                return None
            if any(p.returncode == 0 for p in self.processes):
                # a node ends normally only after the flight: the barrier was complete even if
                # the announcements left with their publishers before this watcher heard them
                return None
            if time.monotonic() > deadline:
                return RunOutcome(
                    "failed", f"start barrier timed out after {self.barrier_timeout_s:g} s: "
                              f"not ready: {', '.join(missing)}")
            watcher.spin_once(0.05)

    def _foreign(self, watcher: ReadyWatcher | None) -> str | None:
        """A foreign publisher on the run's topics (:func:`foreign_publisher`), or None."""
        if watcher is None:
            return None
        own = {p.name: p.popen.pid for p in self.processes}
        return watcher.foreign(own, self.participants)

    def wait_flight(self, watcher: ReadyWatcher | None = None) -> RunOutcome:
        """Wait until every node has ended; a failure (non-zero status), or a foreign
        publisher on the run's topics (with ``watcher``), ends the wait."""
        first_end = None
        while True:
            foreign = self._foreign(watcher)
            if foreign is not None:
                return RunOutcome("failed", foreign)
            failed = self._failed()
            if failed is not None:
                self._await_stall_chain(failed)
                message = self._failure_message(failed, "during the flight")
                foreign = self._foreign(watcher)
                # a node that refused a foreign message: the watch's own graph may learn the
                # publisher a moment later than the node's subscription matched it
                deadline = time.monotonic() + NAME_WAIT_S
                while (foreign is None and "refused a message on" in message
                       and time.monotonic() < deadline):
                    time.sleep(0.05)
                    foreign = self._foreign(watcher)
                return RunOutcome("bad_input" if failed.returncode == 2 else "failed",
                                  message if foreign is None else f"{foreign}; {message}")
            early = self._ended_early()
            if early is not None:
                return RunOutcome("failed", early)
            running = self._running()
            if not running:
                return RunOutcome("ok")
            now = time.monotonic()
            if len(running) < len(self.processes) and first_end is None:
                first_end = now
            if first_end is not None and now - first_end > FINISH_GRACE_S:
                dumped = self._dump_stacks(running)
                return RunOutcome(
                    "failed", f"node(s) {', '.join(p.name for p in running)} still running "
                              f"{FINISH_GRACE_S:g} s after the others ended"
                              + (" (Python stacks in the node logs)" if dumped else ""))
            self._wait_any(FOREIGN_POLL_S if watcher is not None else 1.0)

    @staticmethod
    def _dump_stacks(processes: Sequence[NodeProcess]) -> bool:
        """Ask hung nodes for their Python stacks (:data:`vega_bus.shell.DUMP_STACKS_SIGNAL`,
        written to their logs); True when at least one was asked."""
        asked = False
        for process in processes:
            try:
                os.kill(process.popen.pid, DUMP_STACKS_SIGNAL)
                asked = True
            except (ProcessLookupError, PermissionError):
                pass
        if asked:
            time.sleep(STACK_DUMP_WAIT_S)
        return asked

    # -- stopping
    def stop(self, grace_s: float | None = None):
        """Stop every node still running: SIGCONT and SIGTERM, then SIGKILL after ``grace_s``
        (default :data:`TERM_GRACE_S`); reap all.

        SIGCONT comes first so that a stopped node (SIGSTOP: a debugger, job control) resumes
        and handles SIGTERM — the recorder then closes its bag — instead of sitting out the
        grace time and being killed; to a running node it does nothing. Signals go to each
        node's process group while its leader is not yet reaped (so the group id cannot have
        been reused).
        """
        grace_s = TERM_GRACE_S if grace_s is None else grace_s
        for sigs, wait_s in (((signal.SIGCONT, signal.SIGTERM), grace_s),
                             ((signal.SIGKILL,), grace_s)):
            running = self._running()
            if not running:
                break
            for process in running:
                for sig in sigs:
                    try:
                        os.killpg(process.popen.pid, sig)
                    except (ProcessLookupError, PermissionError):
                        break
            deadline = time.monotonic() + wait_s
            while self._running() and time.monotonic() < deadline:
                self._wait_any(deadline - time.monotonic())
        for process in self.processes:
            process.reap(block=True)
            if process.pidfd is not None:
                os.close(process.pidfd)
                process.pidfd = None

    # -- the whole run
    def run(self) -> RunOutcome:
        """Start, wait for the barrier, fly, and stop: the run's outcome.

        SIGINT (Ctrl-C) and SIGTERM to the orchestrator stop every node (status
        ``"interrupted"``); nothing is left running whatever happens.
        """
        previous = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGHUP)}

        def _raise(signum, _frame):
            raise _Terminated(signum)

        for sig in previous:
            signal.signal(sig, _raise)
        watcher = None
        outcome = None
        t_start = time.monotonic()
        t_barrier = None
        try:
            self.start()
            self.progress(f"started {len(self.processes)} nodes (logs: {self.layout.log_dir})")
            if self.watch_barrier:
                watcher = ReadyWatcher()
            outcome = self.wait_barrier(watcher)
            if outcome is None:
                t_barrier = time.monotonic()
                self.progress(f"start barrier complete after {t_barrier - t_start:.1f} s: "
                              f"{', '.join(self.participants)}; flying")
                self.on_flight()
                outcome = self.wait_flight(watcher)
        except (KeyboardInterrupt, _Terminated) as exc:
            what = "Ctrl-C" if isinstance(exc, KeyboardInterrupt) else str(exc)
            outcome = RunOutcome("interrupted", f"interrupted ({what}): stopped every node")
        finally:
            # a second Ctrl-C must not cut the clean stop short
            previous.setdefault(signal.SIGINT, signal.signal(signal.SIGINT, signal.SIG_IGN))
            if watcher is not None:
                watcher.close()
            self.stop()
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        t_end = time.monotonic()
        outcome.returncodes = {p.name: p.returncode for p in self.processes}
        outcome.cpu_s = {p.name: p.cpu_s for p in self.processes}
        for process in self.processes:
            if process.teardown_hung:
                self.progress(f"warning: {process.name} finished its run, but its middleware "
                              f"teardown hung and its watchdog ended it (stacks in "
                              f"{process.log_path})")
        if any(code is not None and code < 0 for code in outcome.returncodes.values()) or any(
                p.teardown_hung for p in self.processes):
            clean_shared_memory()
        if t_barrier is not None:
            outcome.barrier_wall_s = t_barrier - t_start
            outcome.flight_wall_s = t_end - t_barrier
        return outcome
