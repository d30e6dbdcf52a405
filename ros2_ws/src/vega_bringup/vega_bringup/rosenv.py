"""Process environment of every ROS 2 process the project starts.

One source of truth for the environment rules of ``docs/ENVIRONMENT_SETUP.md``:

* discovery never leaves the machine: ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, with
  ``ROS_LOCALHOST_ONLY`` (deprecated in Jazzy) and ``ROS_STATIC_PEERS`` (extra peers, possibly
  remote) removed;
* every run gets its own ``ROS_DOMAIN_ID`` in 1..100 unless the caller chose one: the first
  id, from a per-user counter on, on which no DDS participant of any user lives on this host
  (:func:`domain_in_use` probes the RTPS ports); 101 is reserved for nodes started by hand
  (``vega node``), which must all meet on one id;
* the library path of the ROS 2 wheels stays consistent with the wheels' bootstrap guard, and
  the ament index of the virtual environment stays on ``AMENT_PREFIX_PATH``.

The ``vega`` command, ``vega-env``, the test fixtures and every launcher of child processes use
:func:`ros_environment`; :func:`configure_current_process` applies it to the running
interpreter before anything imports rclpy.

Run as ``python -m vega_bringup.rosenv CMD [ARGS...]`` it executes ``CMD`` in that environment
(this is what ``.venv/bin/vega-env`` does).
"""

import errno
import fcntl
import os
import socket
import sys
import tempfile
from pathlib import Path

from vega_core.errors import BadArgument

from vega_bus import network

__all__ = [
    "DOMAIN_ID_MIN",
    "DOMAIN_ID_MAX",
    "HAND_START_DOMAIN_ID",
    "DomainIdError",
    "PROBED_PARTICIPANTS",
    "domain_in_use",
    "pick_domain_id",
    "refuse_busy_domain",
    "ros_environment",
    "configure_current_process",
]

DOMAIN_ID_MIN = 1
"""Smallest ROS_DOMAIN_ID the project uses (0, the ROS default, is left to everyone else)."""

DOMAIN_ID_MAX = 101
"""Largest ROS_DOMAIN_ID whose Fast DDS ports are safe on Linux."""

HAND_START_DOMAIN_ID = network.HAND_START_DOMAIN_ID
"""ROS_DOMAIN_ID of nodes started by hand with ``vega node`` when the caller exported none:
one fixed id, so that nodes started in separate terminals meet; :func:`pick_domain_id` never
hands it out, so automated runs (tests, ``vega sil run``) never meet hand-started nodes."""
assert HAND_START_DOMAIN_ID == DOMAIN_ID_MAX

_BOOTSTRAP_GUARD = "_ROS_WHEELS_BOOTSTRAP_COMPLETE"
_REMOVED_VARIABLES = network.REMOVED_VARIABLES


class DomainIdError(BadArgument):
    """A ROS_DOMAIN_ID given by the caller is not an integer in 1..101."""


# RTPS 2.x well-known ports (OMG DDSI-RTPS 2.5, 9.6.1.1; every DDS vendor, Fast DDS included):
# the unicast metatraffic (discovery) port of participant i on domain d is
# PB + DG·d + d1 + PG·i.
_RTPS_PB, _RTPS_DG, _RTPS_PG, _RTPS_D1 = 7400, 250, 2, 10
PROBED_PARTICIPANTS = 120
"""Participant indices probed per domain (Fast DDS gives a process the lowest free index;
120 keeps every probed port of domains 1..100 below Linux's ephemeral range, 32768)."""


def domain_in_use(domain_id):
    """The RTPS participant index of a DDS participant alive on ``domain_id`` on this host, or
    None if there is none.

    Every RTPS participant binds the unicast discovery port of its index (the RTPS port
    mapping, whatever its vendor, user or discovery range); this tries to bind each of those
    ports of the first :data:`PROBED_PARTICIPANTS` indices on 127.0.0.1 (nothing is sent; a
    participant bound to 0.0.0.0 or 127.0.0.1 makes the bind fail with EADDRINUSE). Takes
    about a millisecond.
    """
    base = _RTPS_PB + _RTPS_DG * int(domain_id) + _RTPS_D1
    for index in range(PROBED_PARTICIPANTS):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            try:
                probe.bind(("127.0.0.1", base + _RTPS_PG * index))
            except OSError as exc:
                if exc.errno == errno.EADDRINUSE:
                    return index
                raise
    return None


def pick_domain_id(state_file=None):
    """Pick a free ROS_DOMAIN_ID for a new run.

    From a per-user counter file (advanced under an exclusive lock, so two runs started one
    after the other, or concurrently, start from different ids), the ids 1..100 are tried in
    turn (101 is :data:`HAND_START_DOMAIN_ID`) and the first on which no DDS participant of
    any user lives on this host (:func:`domain_in_use`) is taken.

    Parameters
    ----------
    state_file : str or os.PathLike, optional
        Counter file. Default: ``vega-ros-domain-id.<uid>`` in the temporary directory.

    Returns
    -------
    int
        A domain id in ``DOMAIN_ID_MIN..HAND_START_DOMAIN_ID - 1``.

    Raises
    ------
    DomainIdError
        If every id 1..100 has a participant on it.

    Notes
    -----
    If the counter file cannot be used (read-only or missing directory, no locking), the
    search starts from the process id instead: ``1 + pid % 100``.
    """
    if state_file is None:
        state_file = Path(tempfile.gettempdir()) / f"vega-ros-domain-id.{os.getuid()}"
    span = HAND_START_DOMAIN_ID - DOMAIN_ID_MIN

    def first_free(previous):
        for step in range(1, span + 1):
            candidate = DOMAIN_ID_MIN + (previous + step - DOMAIN_ID_MIN) % span
            if domain_in_use(candidate) is None:
                return candidate
        raise DomainIdError(f"no free ROS_DOMAIN_ID: every id in {DOMAIN_ID_MIN}.."
                            f"{HAND_START_DOMAIN_ID - 1} has a DDS participant on this host")

    try:
        with os.fdopen(os.open(state_file, os.O_RDWR | os.O_CREAT, 0o600), "r+") as counter:
            fcntl.flock(counter, fcntl.LOCK_EX)
            text = counter.read().strip()
            domain_id = first_free(int(text) if text.isdigit() else os.getpid())
            counter.seek(0)
            counter.truncate()
            counter.write(f"{domain_id}\n")
    except OSError:
        return first_free(os.getpid())
    return domain_id


def refuse_busy_domain(domain_id):
    """Raise :class:`DomainIdError` (one line) if a DDS participant lives on ``domain_id``:
    a run must not share its domain (its nodes would take a foreign participant's messages,
    and two runs on one id mix and destroy each other; docs/SECURITY.md)."""
    index = domain_in_use(domain_id)
    if index is not None:
        port = _RTPS_PB + _RTPS_DG * int(domain_id) + _RTPS_D1 + _RTPS_PG * index
        raise DomainIdError(
            f"ROS_DOMAIN_ID={domain_id} is in use: a DDS participant on this host holds its "
            f"RTPS port {port}; a run needs a domain of its own: unset ROS_DOMAIN_ID to get a "
            f"free one, or export a free id")


def _checked_domain_id(value):
    """Return ``value`` as a domain id, or raise DomainIdError naming the bad value."""
    text = str(value).strip()
    if not text.isdigit() or not DOMAIN_ID_MIN <= int(text) <= DOMAIN_ID_MAX:
        raise DomainIdError(
            f"ROS_DOMAIN_ID={text!r} is not allowed: use an integer in "
            f"{DOMAIN_ID_MIN}..{DOMAIN_ID_MAX}, or unset it to get a fresh one per run")
    return int(text)


def _ros_library_dirs():
    """Library directories the ROS 2 wheels' bootstrapper adds for this interpreter."""
    prefix = Path(sys.prefix)
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    site_packages = prefix / "lib" / f"python{version}" / "site-packages"
    return [str(prefix / "lib")] + sorted(
        str(path.resolve()) for path in site_packages.glob("ros_*.libs") if path.is_dir())


def _prepend_missing(path_list, entries):
    """Put the entries of ``entries`` missing from ``path_list`` (os.pathsep-separated) first."""
    present = [part for part in path_list.split(os.pathsep) if part]
    missing = [entry for entry in entries if entry not in present]
    return os.pathsep.join(missing + present)


def ros_environment(base=None, domain_id=None):
    """Return the environment for a child process that may use ROS 2.

    Parameters
    ----------
    base : Mapping[str, str], optional
        Environment to start from (copied, never modified). Default: ``os.environ``.
    domain_id : int, optional
        ROS_DOMAIN_ID to set. Default: keep the one in ``base`` if it has one, else pick a
        fresh one with :func:`pick_domain_id`.

    Returns
    -------
    dict[str, str]
        ``base`` plus the project's ROS settings: LOCALHOST discovery, no
        ``ROS_LOCALHOST_ONLY``/``ROS_STATIC_PEERS``, a domain id in 1..101, the venv prefix on
        ``AMENT_PREFIX_PATH`` and, if the wheels' bootstrap guard is set, their library
        directories on ``LD_LIBRARY_PATH``.

    Raises
    ------
    DomainIdError
        If ``domain_id`` or the ROS_DOMAIN_ID in ``base`` is not an integer in 1..101.
    """
    env = dict(os.environ if base is None else base)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = network.DISCOVERY_RANGE
    for name in _REMOVED_VARIABLES:
        env.pop(name, None)
    if domain_id is None:
        inherited = env.get("ROS_DOMAIN_ID", "").strip()
        domain_id = _checked_domain_id(inherited) if inherited else pick_domain_id()
    env["ROS_DOMAIN_ID"] = str(_checked_domain_id(domain_id))
    if (Path(sys.prefix) / "share" / "ament_index").is_dir():
        prefixes = [part for part in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if part]
        if sys.prefix not in prefixes:
            prefixes.append(sys.prefix)
        env["AMENT_PREFIX_PATH"] = os.pathsep.join(prefixes)
    if env.get(_BOOTSTRAP_GUARD):
        # A child inheriting the guard skips the bootstrap re-exec, so it must inherit the
        # library directories too (otherwise: ImportError: librcl_action.so).
        env["LD_LIBRARY_PATH"] = _prepend_missing(
            env.get("LD_LIBRARY_PATH", ""), _ros_library_dirs())
    return env


def configure_current_process():
    """Apply :func:`ros_environment` to ``os.environ`` of the running process.

    Call it before anything imports rclpy (the middleware reads the variables when a context
    is initialised).

    Returns
    -------
    int
        The ROS_DOMAIN_ID now in force.
    """
    env = ros_environment()
    for name in _REMOVED_VARIABLES:
        os.environ.pop(name, None)
    os.environ.update(env)
    return int(env["ROS_DOMAIN_ID"])


def _main(argv):
    """Execute ``argv`` in :func:`ros_environment` (``python -m vega_bringup.rosenv CMD ...``)."""
    if not argv or argv[0] in ("-h", "--help"):
        print("usage: vega-env CMD [ARGS...]  (run CMD in the project ROS 2 environment)",
              file=sys.stderr)
        return 2
    try:
        env = ros_environment()
    except DomainIdError as exc:
        print(f"vega-env: error: {exc}", file=sys.stderr)
        return 2
    try:
        os.execvpe(argv[0], argv, env)
    except OSError as exc:
        print(f"vega-env: error: cannot run {argv[0]}: {exc.strerror}", file=sys.stderr)
        return 127


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
