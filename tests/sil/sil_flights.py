"""Helpers of the SIL regression tests (tests/sil/test_sil_run_flight.py, test_sil_equivalence.py).

Short scenarios written from the shipped ones, ``vega sil run`` as a real process, process
inspection, and the canonical form of bag payloads for byte comparisons.
"""

import dataclasses
import subprocess
import sys
from pathlib import Path

import yaml

from load_scaling import budget_s
from vega_bus import qos, topics
from vega_sim.scenario import scenario_path
from vega_bags import bagio
from vega_bringup import orchestrate, rosenv

__all__ = ["write_short_scenario", "flight_env", "vega_sil_run", "start_vega_sil_run",
           "run_layout_in", "children_of", "alive", "wait_for_sim_time", "normalised",
           "by_topic", "comparable_payloads"]


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
    return [sys.executable, "-m", "vega_cli.cli", "sil", "run", *map(str, args)]


def vega_sil_run(args):
    """Run ``vega sil run ARGS`` to completion; the CompletedProcess (text)."""
    return subprocess.run(_vega_sil_run_argv(args), env=flight_env(), capture_output=True,
                          text=True, timeout=budget_s(600.0), check=False)


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
    """True if process ``pid`` runs (a zombie, dead but not yet reaped, does not count)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def wait_for_sim_time(t_s, timeout_s=120.0, still_running=lambda: True):
    """Block until the plant's ``/clock`` reaches ``t_s`` (a subscriber in this process, own
    rclpy context); False if ``timeout_s`` (scaled by the load: tests/load_scaling.py) passes
    or ``still_running()`` turns false first."""
    import time

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock

    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    latest = [-1.0]
    try:
        node = rclpy.create_node("sil_test_clock_watch", context=context)
        node.create_subscription(
            Clock, topics.CLOCK.name,
            lambda msg: latest.__setitem__(0, msg.clock.sec + 1e-9 * msg.clock.nanosec),
            qos.clock_qos())
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        deadline = time.monotonic() + budget_s(timeout_s)
        while latest[0] < t_s and time.monotonic() < deadline and still_running():
            executor.spin_once(timeout_sec=0.05)
        executor.remove_node(node)
        node.destroy_node()
        executor.shutdown()
    finally:
        rclpy.try_shutdown(context=context)
    return latest[0] >= t_s


_TYPES = {t.name: t.type_name for t in topics.ALL_TOPICS}


def normalised(topic, data, drop_frame_id=False):
    """The CDR payload of a message in canonical form, for byte comparisons.

    Deserialised and serialised again by the rosbags typestore of the bags
    (:func:`vega_bags.bagio.vega_typestore`), which writes zeros into the alignment padding:
    rclpy's serialiser leaves whatever was in memory there, so two serialisations of one
    message may differ in those bytes while every data byte is the same. If asked,
    ``header.frame_id`` is cleared.
    """
    store = bagio.vega_typestore()
    msg = store.deserialize_cdr(bytes(data), _TYPES[topic])
    if drop_frame_id and hasattr(msg, "header"):
        msg = dataclasses.replace(msg, header=dataclasses.replace(msg.header, frame_id=""))
    return bytes(store.serialize_cdr(msg, _TYPES[topic]))


def by_topic(messages):
    """{topic: [(log time, payload), ...] in order}. (The order across topics is compared
    separately: tests/sil/test_sil_equivalence.py reads the file order.)"""
    out = {}
    for topic, log_time, data in messages:
        out.setdefault(topic, []).append((log_time, data))
    return out


def comparable_payloads(bag_dir, drop_frame_id=False):
    """Every message of a run bag, :func:`by_topic`, payloads :func:`normalised`."""
    return by_topic((topic, log_time, normalised(topic, data, drop_frame_id))
                    for topic, log_time, data in bagio.iter_raw_messages(bag_dir))


def write_node_params(path: Path, **values) -> Path:
    """A node parameters file (``/**: ros__parameters:``) with ``values`` (strings quoted,
    lists of strings, booleans as YAML true/false), for starting a node by hand."""
    lines = ["/**:", "  ros__parameters:"]
    for key, value in values.items():
        if isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, str):
            text = f'"{value}"'
        elif isinstance(value, (list, tuple)):
            text = "[" + ", ".join(f'"{v}"' for v in value) + "]"
        else:
            text = repr(value)
        lines.append(f"    {key}: {text}")
    path.write_text("\n".join(lines) + "\n")
    return path
