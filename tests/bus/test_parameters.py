"""The node parameters, declared once (vega_bus.parameters).

The nodes declare only parameters of the table (through ``Shell.param``), the run planner
writes only keys of the table, in their types; the defaults and the one-line problems are the
nodes' behaviour; and a running node answers ``ros2 param list/describe`` with the table's
descriptions (what ``ros2 param describe /plant seed`` shows on a full ROS install).
"""

import ast
import subprocess
import time
from pathlib import Path

import pytest
import yaml

from load_scaling import budget_s

from vega_bringup import orchestrate
from vega_bringup.executables import find_executable
from vega_bus import parameters
from vega_bus.barrier import PARTICIPANTS

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "ros2_ws" / "src"
SHELL_PY = SRC / "vega_bus" / "vega_bus" / "shell.py"
PACKAGES = {"plant": "vega_plant", "ins_sensor": "vega_plant", "tvc_actuator": "vega_plant",
            "tvc_controller": "vega_gnc", "recorder": "vega_bags"}
RCLPY_OWN = {"use_sim_time", "start_type_description_service"}


def _sources():
    for path in sorted(SRC.glob("*/*/**/*.py")):
        if "/build/" not in str(path) and "/install/" not in str(path):
            yield path


def _calls(attribute: str):
    """(path, first argument node) of every ``<x>.<attribute>(...)`` call in the packages."""
    for path in _sources():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == attribute):
                yield path, (node.args[0] if node.args else None)


# ----------------------------------------------------------------------------- table use
@pytest.mark.slow
def test_every_parameter_a_node_declares_is_in_the_table():
    names = set()
    for path, arg in _calls("param"):
        assert isinstance(arg, ast.Constant) and isinstance(arg.value, str), (
            f"{path}: Shell.param must be called with a literal parameter name")
        names.add(arg.value)
    assert names, "no Shell.param call found"
    assert names <= set(parameters.PARAMETERS), names - set(parameters.PARAMETERS)
    # ... and only through Shell.param, which takes the default and descriptor from the table
    declaring = {path for path, _ in _calls("declare_parameter")}
    assert declaring == {SHELL_PY}


def test_every_key_the_planner_writes_is_in_the_table_in_its_type():
    assert set(orchestrate.RunParameters.__dataclass_fields__) <= set(parameters.PARAMETERS)
    params = orchestrate.RunParameters(scenario="thesis", seed=3, realtime=False,
                                       controller_table="/t/pd.npz", bag_path="/r/bag",
                                       barrier_timeout_s=12)
    written = yaml.safe_load(orchestrate.params_yaml(params))["/**"]["ros__parameters"]
    types = {"string": str, "integer": int, "double": float, "bool": bool,
             "string_array": list}
    for name, value in written.items():
        spec = parameters.spec(name)
        assert type(value) is types[spec.type_name], (name, value)
        assert spec.problem(value) is None, (name, value)


def test_defaults_and_problems_are_the_nodes_behaviour():
    """Pinned: a node started without a parameter file behaves as before the table."""
    defaults = {name: spec.default for name, spec in parameters.PARAMETERS.items()}
    assert defaults == {"scenario": "nominal", "seed": -1, "realtime": False,
                        "controller_table": "", "guidance_reference": "", "bag_path": "",
                        "participants": list(PARTICIPANTS), "barrier_timeout_s": 30.0,
                        "stall_timeout_s": 10.0}
    problems = [("scenario", " ", "must name a scenario or a YAML file"),
                ("seed", -5, "must be >= 0, or -1"), ("bag_path", "", "must be set"),
                ("participants", [""], "must be a non-empty list of node names"),
                ("participants", None, "must be a non-empty list of node names"),
                ("barrier_timeout_s", 0.0, "must be > 0"),
                ("stall_timeout_s", -1.0, "must be > 0")]
    for name, value, text in problems:
        assert parameters.spec(name).problem(value) == text
    for name, spec in parameters.PARAMETERS.items():
        assert spec.problem(spec.default) is None or name == "bag_path"
        assert spec.description and spec.nodes, name
    # the planner's own, longer barrier timeout (five processes starting at once)
    assert orchestrate.DEFAULT_BARRIER_TIMEOUT_S == 60.0
    with pytest.raises(KeyError, match="not a node parameter"):
        parameters.spec("no_such")


# ----------------------------------------------------------------------------- ROS
def _ask(context, executor, node, service_type, service: str, request, timeout_s=None):
    timeout_s = budget_s(30.0) if timeout_s is None else timeout_s
    client = node.create_client(service_type, service)
    try:
        assert client.wait_for_service(timeout_sec=timeout_s), f"no {service}"
        future = client.call_async(request)
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        assert future.done(), f"{service}: no answer within {timeout_s} s"
        return future.result()
    finally:
        node.destroy_client(client)


@pytest.mark.slow
@pytest.mark.ros
def test_running_nodes_describe_their_parameters(ros_env, tmp_path):
    """Each node, waiting for its peers, lists exactly the table's parameters it uses and
    describes them (description with unit and default, constraints, range, read-only)."""
    import rclpy
    from rcl_interfaces.msg import Parameter, ParameterValue
    from rcl_interfaces.srv import DescribeParameters, ListParameters, SetParameters
    from rclpy.executors import SingleThreadedExecutor

    params = tmp_path / "p.yaml"
    params.write_text("/**:\n  ros__parameters:\n    scenario: \"thesis\"\n"
                      f"    bag_path: \"{tmp_path / 'bag'}\"\n"
                      f"    barrier_timeout_s: {budget_s(60.0)}\n"
                      "    participants: [\"plant\", \"nobody\"]\n")
    procs = {name: subprocess.Popen([find_executable(pkg, name), "--ros-args", "--params-file",
                                     str(params)], env=ros_env, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.PIPE, text=True)
             for name, pkg in PACKAGES.items()}
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node("parameter_asker", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        for name in PACKAGES:
            listed = _ask(context, executor, node, ListParameters, f"/{name}/list_parameters",
                          ListParameters.Request()).result.names
            expected = {p.name for p in parameters.PARAMETERS.values() if name in p.nodes}
            assert set(listed) - RCLPY_OWN == expected, name
            described = _ask(context, executor, node, DescribeParameters,
                             f"/{name}/describe_parameters",
                             DescribeParameters.Request(names=sorted(expected))).descriptors
            for d in described:
                spec = parameters.spec(d.name)
                assert (d.description, d.additional_constraints, d.read_only) == (
                    spec.full_description, spec.constraints, True), (name, d.name)
                ranges = [(r.from_value, r.to_value) for r in d.integer_range]
                assert ranges == ([spec.integer_range] if spec.integer_range else []), d.name
        # read-only: a running node refuses a change
        refused = _ask(context, executor, node, SetParameters, "/plant/set_parameters",
                       SetParameters.Request(parameters=[Parameter(
                           name="seed", value=ParameterValue(type=2, integer_value=5))]))
        assert not refused.results[0].successful
        assert "read-only" in refused.results[0].reason
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
        for proc in procs.values():
            if proc.poll() is None:
                proc.terminate()
        deadline = time.monotonic() + budget_s(15.0)
        for proc in procs.values():
            try:
                proc.communicate(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate()
    for name, proc in procs.items():
        assert proc.returncode == 0, f"{name}: {proc.returncode} {proc.stderr}"
