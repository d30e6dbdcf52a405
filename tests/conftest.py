"""Session set-up shared by the whole test suite.

Before any test module is imported (and so before anything imports rclpy), the test process
gets the project's ROS environment from :mod:`vega_bringup.rosenv`: discovery on localhost only,
``ROS_LOCALHOST_ONLY`` unset and a ROS_DOMAIN_ID of its own for this test run (kept if the
caller, e.g. ``make test`` through ``vega-env``, already chose one; a pytest-xdist worker
always picks its own). Child processes get the
same environment from the ``ros_env`` fixture, never a stripped one.

Markers (docs/TESTING.md, "Test tiers"): ``slow`` marks tests that take over 2 s (measured
with ``--durations``, a module-scoped fixture's set-up counted to every test that needs it);
``make check`` runs the fast tier, ``-m "not slow"``. ``ros`` marks tests that start real ROS 2
(rclpy, Fast DDS) participants; deselect them with ``-m "not ros"``.
"""

import fcntl
import os
import signal
import sys
from pathlib import Path

import pytest

_REPO_ROOT = Path(__file__).resolve().parent.parent

try:
    from vega_bringup import rosenv
except ImportError:  # pytest started outside the project environment (no workspace on the path)
    sys.path.insert(0, str(_REPO_ROOT / "ros2_ws" / "src" / "vega_bringup"))
    from vega_bringup import rosenv

__all__ = ["ros_domain_id", "ros_env"]

_DOMAIN_KEY = pytest.StashKey[int]()
_SHM = Path("/dev/shm")


def pytest_configure(config):
    """Register the markers, silence a third-party warning, apply the ROS environment."""
    config.addinivalue_line(
        "markers", "ros: starts real ROS 2 participants (rclpy, Fast DDS on localhost)")
    config.addinivalue_line(
        "markers", "slow: takes over 2 s (--durations); left out of the fast tier, make check")
    # lark-parser 0.12, pinned by the ROS 2 Jazzy wheels (rosidl_parser), imports these.
    for module in ("sre_parse", "sre_constants"):
        config.addinivalue_line(
            "filterwarnings", f"ignore:module '{module}' is deprecated:DeprecationWarning")
    if os.environ.get("PYTEST_XDIST_WORKER"):
        # a pytest-xdist worker inherits the ROS_DOMAIN_ID of the process that started the
        # workers; two workers in one domain see each other's participants (a run refuses a
        # busy domain, a node refuses a foreign stream), so each takes a domain of its own
        os.environ["ROS_DOMAIN_ID"] = str(rosenv.pick_domain_id())
    domain_id = rosenv.configure_current_process()
    config.stash[_DOMAIN_KEY] = domain_id
    # Tests send SIGINT to the processes they start (Ctrl-C on `vega sil run`, on the
    # supervisor). A child inherits an *ignored* SIGINT, and a background job of a
    # non-interactive shell (`pytest ... &` in a script) has SIGINT ignored (POSIX): those
    # tests then hung or saw exit 0 instead of 130. The children get the default disposition.
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_report_header(config):
    """Show the run's ROS settings in the header of the test report."""
    return (f"ROS 2: ROS_DOMAIN_ID={config.stash[_DOMAIN_KEY]} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']}")


@pytest.fixture(scope="session")
def ros_domain_id(pytestconfig):
    """The ROS_DOMAIN_ID of this test run."""
    return pytestconfig.stash[_DOMAIN_KEY]


@pytest.fixture
def ros_env():
    """Environment for a child process of a test: the test process's one plus the ROS rules.

    Returns
    -------
    dict[str, str]
        A fresh copy from :func:`vega_bringup.rosenv.ros_environment` (same ROS_DOMAIN_ID as the
        test run); tests may modify it.
    """
    return rosenv.ros_environment()


def _fastdds_files():
    """Names of the Fast DDS shared-memory files present now."""
    return {path.name for path in _SHM.glob("fastrtps_*")}


def _remove_unused_fastdds_files(names):
    """Remove the Fast DDS segments and ports among ``names`` that no process holds.

    Each segment or port ``fastrtps_X`` has a lock file ``fastrtps_X_el`` (or ``_sl``) that its
    users hold with ``flock``; when nobody does, ``fastrtps_X``, the lock file and the port's
    semaphore ``sem.fastrtps_X_mutex`` are garbage (the rule of ``fastdds shm clean``).
    """
    for name in sorted(names):
        if not name.endswith(("_el", "_sl")):
            continue
        lock = _SHM / name
        try:
            with open(lock, "ab") as handle:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue  # in use, or already gone
        base = name[:-3]
        for path in (_SHM / base, lock, _SHM / f"sem.{base}_mutex"):
            path.unlink(missing_ok=True)


@pytest.fixture(scope="session", autouse=True)
def _no_leaked_fastdds_files():
    """After the run, remove the Fast DDS shared-memory files it created and left unused.

    Participants that shut down cleanly remove their files; one killed on a failure path does
    not. Files that existed before the run, or that a live process still holds, are kept, so
    concurrent runs are not disturbed.
    """
    before = _fastdds_files()
    yield
    _remove_unused_fastdds_files(_fastdds_files() - before)
