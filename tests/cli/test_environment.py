"""The project's ROS environment: localhost discovery and a ROS_DOMAIN_ID per run, everywhere.

Checked (a) in this test process, (b) in children started through the real entry points
(``.venv/bin/vega``, ``vega node`` and ``.venv/bin/vega-env``, called by absolute path from
another directory with a bare environment: no venv activated, nothing ROS set, or hostile
values set), and (c) across invocations: each gets its own domain id unless the caller set one.
Also the rules of :mod:`vega_bringup.rosenv` themselves.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from vega_bringup import rosenv

VENV_BIN = Path(sys.prefix) / "bin"
VEGA = VENV_BIN / "vega"
VEGA_ENV = VENV_BIN / "vega-env"

_HOSTILE = {
    "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
    "ROS_LOCALHOST_ONLY": "0",
    "ROS_STATIC_PEERS": "192.0.2.1",
}
"""Caller settings the project must override (192.0.2.1 is TEST-NET-1; no DDS starts with it)."""

_PROBE = """#!{python}
import json, os, sys
report = {{name: os.environ.get(name) for name in (
    "ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS")}}
report["argv"] = sys.argv[1:]
if report["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and not report["ROS_STATIC_PEERS"]:
    import rclpy
    from rclpy.context import Context
    context = Context()
    rclpy.init(args=sys.argv, context=context)
    node = rclpy.create_node("vega_envprobe", context=context)
    report["context_domain_id"] = context.get_domain_id()
    report["node_name"] = node.get_name()
    node.destroy_node()
    rclpy.shutdown(context=context)
print(json.dumps(report))
"""
"""A ROS 2 executable that reports the environment and the domain its rclpy context uses."""


def _bare_env(**extra):
    """A minimal environment, as from a fresh login shell without the venv activated."""
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root"),
           "LANG": "C.UTF-8"}
    env.update(extra)
    return env


def _run(command, env, cwd, timeout=120):
    """Run ``command``; return the completed process (text output)."""
    return subprocess.run([str(part) for part in command], env=env, cwd=cwd, timeout=timeout,
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, check=False)


def _printed_env(stdout):
    """Parse ``vega --print-env`` output into {name: value or None}."""
    printed = {}
    for line in stdout.splitlines():
        if line.startswith("unset "):
            printed[line.split()[1]] = None
        else:
            name, _, value = line.partition("=")
            printed[name] = value
    return printed


@pytest.fixture
def probe_prefix(tmp_path):
    """An ament prefix holding package ``vega_envprobe`` with executable ``probe``."""
    prefix = tmp_path / "probe_prefix"
    marker = prefix / "share" / "ament_index" / "resource_index" / "packages" / "vega_envprobe"
    marker.parent.mkdir(parents=True)
    marker.write_text("")
    executable = prefix / "lib" / "vega_envprobe" / "probe"
    executable.parent.mkdir(parents=True)
    executable.write_text(_PROBE.format(python=sys.executable))
    executable.chmod(0o755)
    return prefix


# (a) this test process ------------------------------------------------------------------------

def test_test_process_has_localhost_discovery_and_run_domain(ros_domain_id):
    """conftest applied the rules before any test module was imported."""
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "ROS_LOCALHOST_ONLY" not in os.environ
    assert "ROS_STATIC_PEERS" not in os.environ
    assert os.environ["ROS_DOMAIN_ID"] == str(ros_domain_id)
    assert rosenv.DOMAIN_ID_MIN <= ros_domain_id <= rosenv.DOMAIN_ID_MAX


@pytest.mark.ros
def test_rclpy_in_test_process_uses_run_domain(ros_domain_id):
    """An rclpy context created here joins the run's domain."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        assert context.get_domain_id() == ros_domain_id
    finally:
        rclpy.shutdown(context=context)


def test_ros_env_fixture_keeps_the_run_domain(ros_env, ros_domain_id):
    """Children of tests get the run's domain and the full environment, not a stripped one."""
    assert ros_env["ROS_DOMAIN_ID"] == str(ros_domain_id)
    assert ros_env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert ros_env["PATH"] == os.environ["PATH"]
    assert ros_env.get("LD_LIBRARY_PATH") == os.environ.get("LD_LIBRARY_PATH")


# (b) children started through the real entry points --------------------------------------------

@pytest.mark.slow
def test_vega_sets_environment_from_bare_shell(tmp_path):
    """``.venv/bin/vega`` by absolute path, no venv active, hostile ROS settings: fixed."""
    result = _run([VEGA, "--print-env"], _bare_env(**_HOSTILE), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    printed = _printed_env(result.stdout)
    assert printed["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert printed["ROS_LOCALHOST_ONLY"] is None
    assert printed["ROS_STATIC_PEERS"] is None
    assert rosenv.DOMAIN_ID_MIN <= int(printed["ROS_DOMAIN_ID"]) <= rosenv.DOMAIN_ID_MAX
    assert printed["VIRTUAL_ENV"] == str(Path(sys.prefix))
    prefixes = printed["AMENT_PREFIX_PATH"].split(os.pathsep)
    assert str(Path(sys.prefix)) in prefixes
    assert any(Path(prefix).name == "vega_msgs" for prefix in prefixes)


@pytest.mark.slow
@pytest.mark.ros
def test_vega_node_runs_executable_in_project_environment(tmp_path, probe_prefix):
    """``vega node PKG EXE ARGS`` finds EXE through the ament index, passes ARGS through, and
    the node's rclpy context runs with LOCALHOST discovery on the hand-start domain 101 (the
    same for every terminal, so that hand-started nodes meet; never a round-robin id)."""
    env = _bare_env(AMENT_PREFIX_PATH=str(probe_prefix), ROS_LOCALHOST_ONLY="1", ROS_DOMAIN_ID="")
    arguments = ["--ros-args", "-r", "__node:=renamed_probe", "--log-level", "warn"]
    result = _run([VEGA, "node", "vega_envprobe", "probe", *arguments], env, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["argv"] == arguments
    assert report["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert report["ROS_LOCALHOST_ONLY"] is None
    assert report["context_domain_id"] == int(report["ROS_DOMAIN_ID"])
    assert report["context_domain_id"] == rosenv.HAND_START_DOMAIN_ID == 101
    assert report["node_name"] == "renamed_probe"
    assert "ROS_DOMAIN_ID=101 (the default for nodes started by hand" in result.stderr


@pytest.mark.slow
@pytest.mark.ros
def test_vega_node_keeps_caller_domain(tmp_path, probe_prefix):
    """A caller's ROS_DOMAIN_ID is what the node uses, and no note is printed."""
    env = _bare_env(AMENT_PREFIX_PATH=str(probe_prefix), ROS_DOMAIN_ID="57")
    result = _run([VEGA, "node", "vega_envprobe", "probe"], env, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["context_domain_id"] == 57
    assert "ROS_DOMAIN_ID" not in result.stderr


@pytest.mark.slow
def test_vega_env_runs_command_in_project_environment(tmp_path):
    """``vega-env CMD``: the project environment, the workspace on the path, LOCALHOST."""
    code = ("import json, os, vega_msgs.msg; print(json.dumps({n: os.environ.get(n) for n in "
            "('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_LOCALHOST_ONLY', "
            "'ROS_STATIC_PEERS')}))")
    result = _run([VEGA_ENV, "python", "-c", code], _bare_env(**_HOSTILE), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert report["ROS_LOCALHOST_ONLY"] is None and report["ROS_STATIC_PEERS"] is None
    assert rosenv.DOMAIN_ID_MIN <= int(report["ROS_DOMAIN_ID"]) <= rosenv.DOMAIN_ID_MAX


# (c) one domain id per invocation ---------------------------------------------------------------

@pytest.mark.slow
def test_invocations_get_different_domain_ids(tmp_path):
    """Invocations without a caller's ROS_DOMAIN_ID get different ids (vega and vega-env)."""
    ids = []
    for _ in range(2):
        result = _run([VEGA, "--print-env"], _bare_env(), cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        ids.append(int(_printed_env(result.stdout)["ROS_DOMAIN_ID"]))
    result = _run([VEGA_ENV, "printenv", "ROS_DOMAIN_ID"], _bare_env(), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    ids.append(int(result.stdout))
    assert len(set(ids)) == len(ids), ids


@pytest.mark.slow
def test_caller_domain_id_is_kept(tmp_path):
    """With ROS_DOMAIN_ID set by the caller, every invocation uses it."""
    for command in ([VEGA, "--print-env"], [VEGA, "--print-env"]):
        result = _run(command, _bare_env(ROS_DOMAIN_ID="42"), cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert _printed_env(result.stdout)["ROS_DOMAIN_ID"] == "42"


@pytest.mark.slow
@pytest.mark.parametrize("value", ["0", "102", "seven", "-1"])
def test_bad_caller_domain_id_is_rejected(tmp_path, value):
    """A caller's ROS_DOMAIN_ID outside 1..101 is an error of one line, exit status 2."""
    for command, program in (([VEGA, "--print-env"], "vega"), ([VEGA_ENV, "true"], "vega-env")):
        result = _run(command, _bare_env(ROS_DOMAIN_ID=value), cwd=tmp_path)
        assert result.returncode == 2
        assert result.stderr.startswith(f"{program}: error: ROS_DOMAIN_ID=")
        assert result.stderr.count("\n") == 1


# vega_bringup.rosenv ---------------------------------------------------------------------

def test_pick_domain_id_hands_out_free_ids_in_turn(tmp_path):
    """From the counter on, in turn over 1..100: consecutive picks differ, every pick is free
    (no DDS participant on it: rosenv.domain_in_use; busy ids are skipped,
    tests/sil/test_sil_security.py), and the hand-start id 101 is never handed out."""
    state = tmp_path / "counter"
    picks = [rosenv.pick_domain_id(state) for _ in range(20)]
    assert all(rosenv.DOMAIN_ID_MIN <= p < rosenv.HAND_START_DOMAIN_ID for p in picks)
    assert len(set(picks)) == 20
    assert rosenv.HAND_START_DOMAIN_ID == 101
    assert state.read_text().strip() == str(picks[-1])


def test_pick_domain_id_without_counter_file(tmp_path):
    """An unusable counter file: the search starts from an id derived from the process id."""
    domain_id = rosenv.pick_domain_id(tmp_path / "missing" / "counter")
    start = rosenv.DOMAIN_ID_MIN + (os.getpid() + 1 - rosenv.DOMAIN_ID_MIN) % 100
    assert domain_id == start or rosenv.domain_in_use(start) is not None


def test_ros_environment_overrides_and_keeps():
    """Hostile settings are replaced, other variables kept, the base left untouched."""
    base = dict(_HOSTILE, ROS_DOMAIN_ID=" 9 ", KEEP_ME="yes")
    env = rosenv.ros_environment(base)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "ROS_LOCALHOST_ONLY" not in env and "ROS_STATIC_PEERS" not in env
    assert env["ROS_DOMAIN_ID"] == "9" and env["KEEP_ME"] == "yes"
    assert base["ROS_LOCALHOST_ONLY"] == "0"
    assert rosenv.ros_environment(base, domain_id=77)["ROS_DOMAIN_ID"] == "77"
    with pytest.raises(rosenv.DomainIdError):
        rosenv.ros_environment(base, domain_id=0)


def test_ros_environment_repairs_library_path_for_guarded_child():
    """A base with the wheels' bootstrap guard but no LD_LIBRARY_PATH (the stripped-env
    pitfall) gets the library directories back, and rclpy imports in the child."""
    base = {name: value for name, value in os.environ.items() if name != "LD_LIBRARY_PATH"}
    base["_ROS_WHEELS_BOOTSTRAP_COMPLETE"] = "1"
    env = rosenv.ros_environment(base)
    assert any(part.endswith("ros_rclpy.libs") for part in env["LD_LIBRARY_PATH"].split(":"))
    result = subprocess.run([sys.executable, "-c", "import rclpy.impl.implementation_singleton"],
                            env=env, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
