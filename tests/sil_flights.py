"""Helpers of the SIL regression tests (tests/test_sil_run_flight.py, test_sil_equivalence.py).

Short scenarios written from the shipped ones, ``vega sil run`` as a real process, process
inspection, and the canonical form of bag payloads for byte comparisons.
"""

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import yaml

from vega_bus import topics
from vega_plant.scenario import scenario_path
from vega_sil import bagio, orchestrate, rosenv

__all__ = ["write_short_scenario", "flight_env", "vega_sil_run", "start_vega_sil_run",
           "run_layout_in", "children_of", "alive", "normalised", "by_topic",
           "comparable_payloads"]


def write_short_scenario(directory, base, name, t_start_s, t_end_s):
    """A shipped scenario cut to [t_start_s, t_end_s], as ``directory/NAME.yaml`` (the file
    name is the scenario name); everything else is the shipped scenario's."""
    tree = yaml.safe_load(scenario_path(base).read_text())
    tree.update(name=name, t_start_s=float(t_start_s), t_end_s=float(t_end_s),
                description=f"{base} cut to {t_start_s:g}-{t_end_s:g} s: {tree['description']}")
    path = Path(directory) / f"{name}.yaml"
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path


def flight_env():
    """Environment of a flight: this test run's ROS_DOMAIN_ID, LOCALHOST discovery."""
    return rosenv.ros_environment()


def _vega_sil_run_argv(args):
    return [sys.executable, "-m", "vega_sil.cli", "sil", "run", *map(str, args)]


def vega_sil_run(args):
    """Run ``vega sil run ARGS`` to completion; the CompletedProcess (text)."""
    return subprocess.run(_vega_sil_run_argv(args), env=flight_env(), capture_output=True,
                          text=True, timeout=600, check=False)


def start_vega_sil_run(args):
    """Start ``vega sil run ARGS`` (stdout and stderr piped, line-buffered text)."""
    return subprocess.Popen(_vega_sil_run_argv(args), env=flight_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, bufsize=1)


def run_layout_in(out):
    """The layout of the one run directory under ``out``."""
    (run_dir,) = list(Path(out).iterdir())
    return orchestrate.RunLayout(run_dir)


def children_of(pid):
    """{pid: argv} of the live child processes of ``pid`` (from /proc)."""
    found = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[1]) == pid:
                argv = (stat.parent / "cmdline").read_bytes().split(b"\0")
                found[int(stat.parent.name)] = [a.decode() for a in argv if a]
        except (OSError, IndexError, ValueError):
            continue
    return found


def alive(pid):
    """True if process ``pid`` exists (a zombie counts until reaped)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


_TYPES = {t.name: t.type_name for t in topics.ALL_TOPICS}


def normalised(topic, data, drop_frame_id=False):
    """The CDR payload of a message in canonical form, for byte comparisons.

    Deserialised and serialised again by the rosbags typestore of the bags
    (:func:`vega_sil.bagio.vega_typestore`), which writes zeros into the alignment padding:
    rclpy's serialiser leaves whatever was in memory there, so two serialisations of one
    message may differ in those bytes while every data byte is the same. The controller's
    wall-clock ``compute_time_s`` (the one field that may differ between runs) is set to 0
    and, if asked, ``header.frame_id`` cleared.
    """
    store = bagio.vega_typestore()
    msg = store.deserialize_cdr(bytes(data), _TYPES[topic])
    if topic == topics.TVC_CMD.name:
        msg = dataclasses.replace(msg, compute_time_s=0.0)
    if drop_frame_id and hasattr(msg, "header"):
        msg = dataclasses.replace(msg, header=dataclasses.replace(msg.header, frame_id=""))
    return bytes(store.serialize_cdr(msg, _TYPES[topic]))


def by_topic(messages):
    """{topic: [(log time, payload), ...] in order}. The order of messages of different
    topics with the same log time is the order they reached the recorder, which is not part
    of the run; within a topic the order is."""
    out = {}
    for topic, log_time, data in messages:
        out.setdefault(topic, []).append((log_time, data))
    return out


def comparable_payloads(bag_dir, drop_frame_id=False):
    """Every message of a run bag, :func:`by_topic`, payloads :func:`normalised`."""
    return by_topic((topic, log_time, normalised(topic, data, drop_frame_id))
                    for topic, log_time, data in bagio.iter_raw_messages(bag_dir))
