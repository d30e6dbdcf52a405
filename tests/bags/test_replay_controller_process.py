"""The controller child process of ``vega replay --check-controller``
(``vega_bags.replay._ControllerProcess``).

It starts a tiny shell script found through a real ament index prefix (the real
``find_executable``), and once the installed ``tvc_controller`` itself. Independent
references: what the script itself records (argv, working directory, environment, the
parameters file read with PyYAML against hand-typed values), the exit status and the log line
it was told to print; the installed controller's own message when nobody publishes the run
description within the barrier timeout of its parameters file [s].
"""

from __future__ import annotations

import os
import signal
import stat
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml

from vega_bags import replay

FAKE_NODE = """#!/bin/sh
rec="$VEGA_FAKE_RECORD"
printf '%s\\n' "$0" "$@" > "$rec/argv"
pwd > "$rec/cwd"
cp "$3" "$rec/params.yaml"
printf '%s\\n' "${VEGA_FAKE_MARK-unset}" "${VEGA_ONLY_IN_PARENT-unset}" > "$rec/env"
if [ -n "$VEGA_FAKE_SAY" ]; then printf 'first line\\n%s\\n\\n' "$VEGA_FAKE_SAY"; fi
if [ -n "$VEGA_FAKE_SLEEP" ]; then exec sleep "$VEGA_FAKE_SLEEP"; fi
exit "${VEGA_FAKE_EXIT-0}"
"""


@pytest.fixture
def fake_controller(tmp_path, monkeypatch):
    """An ament prefix whose vega_gnc has a ``tvc_controller`` script (:data:`FAKE_NODE`),
    searched first; returns (the script's path, its record directory, env maker)."""
    from vega_bringup import rosenv

    prefix = tmp_path / "prefix"
    index = prefix / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True)
    (index / "vega_gnc").write_text("")
    exe = prefix / "lib" / "vega_gnc" / "tvc_controller"
    exe.parent.mkdir(parents=True)
    exe.write_text(FAKE_NODE)
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("AMENT_PREFIX_PATH",
                       os.pathsep.join([str(prefix), os.environ.get("AMENT_PREFIX_PATH", "")]))
    monkeypatch.setenv("VEGA_ONLY_IN_PARENT", "yes")
    record = tmp_path / "record"
    record.mkdir()

    def env(**extra):
        out = rosenv.ros_environment()
        out.pop("VEGA_ONLY_IN_PARENT", None)
        out.update(VEGA_FAKE_RECORD=str(record), VEGA_FAKE_MARK="passed", **extra)
        return out

    return exe, record, env


def _params(barrier_timeout_s=7.5, table="/x/t.npz"):
    from vega_bringup import orchestrate

    return orchestrate.RunParameters(
        scenario="thesis", seed=42, realtime=False, controller_table=table, bag_path="",
        participants=("tvc_controller", "recorder"), barrier_timeout_s=barrier_timeout_s)


@contextmanager
def _started(params, workdir, env):
    controller = replay._ControllerProcess(params, workdir, env)
    try:
        yield controller
    finally:
        controller.stop()


def test_controller_command_line_directory_environment(fake_controller, tmp_path):
    """A fresh nested work directory: the executable of vega_gnc/tvc_controller from the
    ament index, ``--ros-args --params-file WORKDIR/params.yaml`` holding the run's
    parameters, started in WORKDIR with exactly the given environment, its output in
    WORKDIR/logs/tvc_controller.log."""
    exe, record, env = fake_controller
    workdir = tmp_path / "new" / "work"
    with _started(_params(), workdir, env(VEGA_FAKE_SAY="said")) as controller:
        assert controller.wait(10.0) == 0
        assert controller.returncode == 0
        sup = controller.supervisor
        assert sup.participants == ("tvc_controller", "recorder")
        assert sup.barrier_timeout_s == 7.5
        assert not sup.watch_barrier          # the checker watches the barrier, not this
        assert controller.process is sup.processes[0] and len(sup.processes) == 1
    params_file = workdir / "params.yaml"
    assert (record / "argv").read_text().splitlines() == [
        str(exe), "--ros-args", "--params-file", str(params_file)]
    assert Path((record / "cwd").read_text().strip()).resolve() == workdir.resolve()
    assert (record / "env").read_text().splitlines() == ["passed", "unset"]
    assert yaml.safe_load((record / "params.yaml").read_text()) == {"/**": {"ros__parameters": {
        "scenario": "thesis", "seed": 42, "realtime": False, "controller_table": "/x/t.npz",
        "bag_path": "", "participants": ["tvc_controller", "recorder"],
        "barrier_timeout_s": 7.5}}}
    assert (workdir / "logs" / "tvc_controller.log").read_text() == "first line\nsaid\n\n"


def test_controller_in_an_existing_directory(fake_controller, tmp_path):
    """check_controller hands it a directory mkdtemp made already."""
    _, record, env = fake_controller
    workdir = tmp_path / "exists"
    workdir.mkdir()
    with _started(_params(), workdir, env()) as controller:
        assert controller.wait(10.0) == 0
    assert (record / "argv").read_text().splitlines()[-1] == str(workdir / "params.yaml")


@pytest.mark.parametrize("status, say, text", [
    (2, "tvc_controller: bad input", "tvc_controller ended with exit status 2: "
                                     "tvc_controller: bad input"),
    (1, "", "tvc_controller ended with exit status 1"),
])
def test_controller_failure_names_status_and_last_line(fake_controller, tmp_path, status,
                                                       say, text):
    _, _, env = fake_controller
    with _started(_params(), tmp_path / "w", env(VEGA_FAKE_EXIT=str(status),
                                                 VEGA_FAKE_SAY=say)) as controller:
        assert controller.wait(10.0) == status
        assert controller.returncode == status
        assert controller.failure() == text


def test_controller_wait_gives_up_and_stop_ends_it(fake_controller, tmp_path):
    """A node that keeps running: wait(0.2) returns None after about 0.2 s; stop() ends it
    (SIGTERM), and the failure says so."""
    _, _, env = fake_controller
    with _started(_params(), tmp_path / "w", env(VEGA_FAKE_SLEEP="60")) as controller:
        out = []
        waiter = threading.Thread(target=lambda: out.append(controller.wait(0.2)), daemon=True)
        t = time.monotonic()
        waiter.start()
        waiter.join(5.0)
        assert out == [None] and time.monotonic() - t >= 0.2
        assert controller.returncode is None
        controller.stop()
        assert controller.returncode == -signal.SIGTERM
        assert controller.failure() == "tvc_controller ended with killed by SIGTERM"


@pytest.mark.slow
@pytest.mark.ros
def test_installed_controller_reads_its_parameters(tmp_path):
    """The real tvc_controller, nobody publishing /vega/run: it gives up after the barrier
    timeout of the parameters file (0.5 s) and exits 1 saying so (its installed table)."""
    from vega_bringup import rosenv

    with _started(_params(barrier_timeout_s=0.5, table=""), tmp_path / "w",
                  rosenv.ros_environment()) as controller:
        assert controller.wait(30.0) == 1
        text = controller.failure()
    assert text.startswith("tvc_controller ended with exit status 1: tvc_controller: ")
    assert "waited 0.5 s for the run description on /vega/run" in text
