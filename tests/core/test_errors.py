"""The error core (vega_core.errors, vega_core.documents) and how the front ends map errors.

Bad input (:class:`vega_core.errors.BadInput`) and file-system errors are the user's to fix:
one line, exit status 2, from ``vega`` and from every node. Anything else is a defect: the
traceback, exit status 1 — never reported as the user's mistake.
"""

import sys
import types

import numpy as np
import pytest

from vega_cli import cli
from vega_core.documents import load_yaml, parse_yaml, read_text
from vega_core.errors import BadArgument, BadFile, BadInput, one_line


# ----------------------------------------------------------------------------- one_line
@pytest.mark.parametrize("exc, text", [
    (ValueError("a\n  b\tc  "), "a b c"),
    (BadInput("  leading and\r\ntrailing  "), "leading and trailing"),
    (ValueError(""), "ValueError"),
    (ZeroDivisionError("   \n "), "ZeroDivisionError"),
    (KeyError("seed"), "'seed'"),
    (FileNotFoundError(2, "No such file or directory", "x.yaml"),
     "[Errno 2] No such file or directory: 'x.yaml'"),
])
def test_one_line(exc, text):
    assert one_line(exc) == text


# ----------------------------------------------------------------------------- hierarchy
def test_bad_input_is_a_value_error_and_the_loaders_errors_are_bad_input():
    """Old ``except ValueError`` keeps catching; every loader's own error class is bad input;
    a numerical failure of the synthesis is not (it is a defect path: traceback, exit 1)."""
    from vega_lpv.lpv_synthesis import SynthesisError
    from vega_reference.trajectory import TrajectoryError
    from vega_bags.bagio import BagError
    from vega_bringup.rosenv import DomainIdError
    from vega_gnc.controller_table import ControllerTableError
    from vega_model.flight_conditions import FlightConditionsError
    from vega_model.vehicle_data import VehicleDataError

    assert issubclass(BadInput, ValueError)
    assert issubclass(BadFile, BadInput) and issubclass(BadArgument, BadInput)
    for cls in (VehicleDataError, FlightConditionsError, ControllerTableError, BagError):
        assert issubclass(cls, BadFile), cls
    assert issubclass(DomainIdError, BadArgument)
    assert issubclass(TrajectoryError, BadInput)
    assert not issubclass(SynthesisError, BadInput)


def test_library_checks_of_user_input_raise_bad_input(tmp_path):
    from vega_bus.schedule import RunInfo
    from vega_bus.timing import LoopTiming, check_ms, stamp_to_ms
    from vega_sim.scenario import load_scenario

    with pytest.raises(BadArgument, match="unknown scenario 'nope'"):
        load_scenario("nope")
    with pytest.raises(BadFile, match="cannot read scenario"):
        load_scenario(tmp_path / "missing.yaml")
    with pytest.raises(BadInput, match="does not match the loop timing"):
        check_ms(0.01, 20, "controller table dt_s")
    with pytest.raises(BadInput, match="malformed run description"):
        RunInfo.from_json("not json")
    with pytest.raises(BadInput, match="whole 10 ms frames"):
        RunInfo("x", 1, 5, 100, LoopTiming()).check()
    # a stamp off the millisecond grid on the wire is a run failure, not bad input
    with pytest.raises(ValueError) as info:
        stamp_to_ms(1, 5)
    assert not isinstance(info.value, BadInput)


# ----------------------------------------------------------------------------- documents
def test_read_text_names_the_file_and_the_reason(tmp_path):
    missing = tmp_path / "none.yaml"
    with pytest.raises(BadFile) as info:
        read_text(missing, "scenario")
    assert str(info.value) == f"{missing}: cannot read scenario (No such file or directory)"
    assert info.value.__cause__ is None and info.value.__suppress_context__
    with pytest.raises(BadFile, match=r": cannot read requirements \(Is a directory\)$"):
        read_text(tmp_path, "requirements")
    latin = tmp_path / "latin.yaml"
    latin.write_bytes(b"name: caf\xe9\n")
    with pytest.raises(BadFile, match=r"latin.yaml: cannot read vehicle data "
                                      r"\(UnicodeDecodeError\)$"):
        read_text(latin, "vehicle data")

    class OwnError(BadFile):
        pass

    with pytest.raises(OwnError):
        read_text(missing, "table", OwnError)
    good = tmp_path / "good.txt"
    good.write_text("é\n", encoding="utf-8")
    assert read_text(good, "text") == "é\n"


@pytest.mark.parametrize("text, message", [
    ("a: 1\nb: [unclosed\n", "src.yaml: not valid YAML (line 3)"),
    ("a: 1\n  b: 2\n", "src.yaml: not valid YAML (line 2)"),
    ("- a\n- b\n", "src.yaml: top level must be a mapping"),
    ("", "src.yaml: top level must be a mapping"),
    ("just text", "src.yaml: top level must be a mapping"),
])
def test_parse_yaml_messages(text, message):
    with pytest.raises(BadFile) as info:
        parse_yaml(text, "src.yaml")
    assert str(info.value) == message
    # no "During handling of the above exception" chain behind the one line
    assert info.value.__cause__ is None
    assert info.value.__context__ is None or info.value.__suppress_context__


def test_load_yaml(tmp_path):
    path = tmp_path / "doc.yaml"
    path.write_text("name: x\nvalues: [1, 2.5]\n", encoding="utf-8")
    assert load_yaml(path, "document") == {"name": "x", "values": [1, 2.5]}
    path.write_text("name: [x\n", encoding="utf-8")
    with pytest.raises(BadFile, match=rf"^{path}: not valid YAML \(line 2\)$"):
        load_yaml(path, "document")
    with pytest.raises(BadFile, match=r"cannot read document \(No such file or directory\)"):
        load_yaml(tmp_path / "none.yaml", "document")


def test_the_three_yaml_loaders_share_the_messages(tmp_path):
    """Vehicle data, scenarios and requirements report a non-YAML file identically."""
    from vega_model.vehicle_data import VehicleDataError, load_vehicle_data
    from vega_sim.requirements import load_requirements
    from vega_sim.scenario import load_scenario

    bad = tmp_path / "bad.yaml"
    bad.write_text("a: 1\nb: [unclosed\n", encoding="utf-8")
    for load, cls in ((load_vehicle_data, VehicleDataError), (load_scenario, BadFile),
                      (load_requirements, BadFile)):
        with pytest.raises(cls) as info:
            load(bad)
        assert str(info.value) == f"{bad}: not valid YAML (line 3)", load


# ----------------------------------------------------------------------------- vega: bad input
def _vega(argv, capsys):
    status = cli.main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def _one_error_line(err):
    assert err.startswith("vega: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    return err[len("vega: error: "):-1]


def test_malformed_scenario_file_is_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "mine.yaml"
    bad.write_text("name: mine\nwind: {profile: [\n", encoding="utf-8")
    status, out, err = _vega(["sil", "run", "--dry-run", "--scenario", str(bad),
                              "--out", str(tmp_path / "runs")], capsys)
    assert status == 2 and out == ""
    assert _one_error_line(err) == f"{bad}: not valid YAML (line 3)"
    assert not (tmp_path / "runs").exists()


def test_table_with_the_wrong_sample_time_is_one_line_exit_2(tmp_path, capsys):
    """A table that loads but does not fit the loop (10 ms instead of the 20 ms controller
    period): bad input, found by a check deep in the flight side (vega_bus.timing)."""
    from vega_loops.export import write_controller_table

    path = tmp_path / "fast.npz"
    write_controller_table(path, [0.0, 3000.0], np.array([[[-1.0]]] * 2),
                           np.zeros((2, 1, 4)), np.zeros((2, 1, 1)),
                           np.array([[[0.5, 0.0, 0.0, 0.0]]] * 2), dt_s=0.01, gamma=1.0,
                           gamma_min=1.0, rate_bounds_mps2=[5.4, 36.4],
                           metadata={"input_names": ["theta_ins_rad", "theta_dot_ins_radps",
                                                     "z_ins_m", "z_dot_ins_mps"],
                                     "measurement_sign": 1, "output_name": "beta_cmd_rad",
                                     "units": {}, "weights": {}, "solver": {}})
    status, _, err = _vega(["sil", "run", "--dry-run", "--scenario", "thesis", "--table",
                            str(path), "--out", str(tmp_path / "runs")], capsys)
    assert status == 2
    assert _one_error_line(err) == ("controller table dt_s 0.01 s does not match the loop "
                                    "timing (20 ms)")


@pytest.mark.parametrize("argv, message", [
    (["linearize", "--t", "ten"], "--t 'ten': expected SECONDS or START:STOP:STEP (numbers)"),
    (["sil"], "sil: an ACTION is required: run (see vega sil --help)"),
    (["replay", "BAG", "--table", "t.npz"], "--table only applies with --check-controller"),
    (["sil", "run", "--seed", "1.5"], "--seed must be an integer >= 0, got '1.5'"),
    (["check", "BAG", "--requirements", "REQ"], "REQ: not valid YAML (line 2)"),
    (["trajectory", "--out", "NODIR/fc.csv"],
     "NODIR/fc.csv: cannot write flight conditions (no directory NODIR)"),
])
def test_bad_input_from_the_command_line_is_one_line_exit_2(tmp_path, capsys, argv, message):
    req = tmp_path / "requirements.yaml"
    req.write_text("schema_version: [1\n", encoding="utf-8")
    subst = {"REQ": str(req), "NODIR": str(tmp_path / "nodir"), "BAG": str(tmp_path / "bag")}

    def fill(text):
        for key, value in subst.items():
            text = text.replace(key, value)
        return text

    status, _, err = _vega([fill(a) for a in argv], capsys)
    assert status == 2
    assert _one_error_line(err) == fill(message)


def test_bad_domain_id_is_one_line_exit_2(monkeypatch, capsys):
    monkeypatch.setenv("ROS_DOMAIN_ID", "300")
    status, _, err = _vega(["sil", "run"], capsys)
    assert status == 2
    assert _one_error_line(err).startswith("ROS_DOMAIN_ID='300' is not allowed")


# ----------------------------------------------------------------------------- vega: defects
def _command_raising(monkeypatch, error):
    """Install a sub-command ``explode`` whose function raises ``error``."""
    module = types.ModuleType("vega_cli.commands.explode")

    def _fail(args):
        raise error

    module.register = lambda subparsers: subparsers.add_parser("explode").set_defaults(
        func=_fail)
    monkeypatch.setattr(cli, "COMMANDS", ("explode",))
    monkeypatch.setitem(sys.modules, "vega_cli.commands.explode", module)


def _assert_defect(status, err, type_name, message):
    assert status == 1
    assert "vega: error:" not in err
    assert err.startswith("Traceback (most recent call last):\n"), err
    assert f"\n{type_name}: {message}\n" in err                 # the traceback's last line
    assert err.splitlines()[-1].startswith(f"vega: internal error: {type_name}: {message}")


@pytest.mark.parametrize("error", [ValueError("internal"), ZeroDivisionError("division by zero"),
                                   KeyError("q_pa")])
def test_other_exceptions_are_defects_with_a_traceback_exit_1(monkeypatch, capsys, error):
    _command_raising(monkeypatch, error)
    status, _, err = _vega(["explode"], capsys)
    _assert_defect(status, err, type(error).__name__, str(error))


def test_a_numpy_value_error_inside_a_command_is_a_defect(monkeypatch, capsys):
    """A real command whose library fails numerically: the traceback shows where."""
    from vega_cli.commands import linearize

    def broken_record(t, context):
        return np.ones(3) @ np.ones(2)            # ValueError from numpy (matmul shapes)

    monkeypatch.setattr(linearize, "_record", broken_record)
    status, out, err = _vega(["linearize", "--t", "47"], capsys)
    assert out == ""
    assert status == 1 and "vega: error:" not in err
    assert "in broken_record" in err and "\nValueError: matmul" in err
    assert err.splitlines()[-1].startswith("vega: internal error: ValueError: matmul")


def test_interrupt_still_exits_130(monkeypatch, capsys):
    _command_raising(monkeypatch, KeyboardInterrupt())
    assert _vega(["explode"], capsys)[0] == 130


# ----------------------------------------------------------------------------- nodes
class _FakeShell:
    """Stands in for vega_bus.shell.Shell (no rclpy) in run_node."""

    signal_name = None

    def __init__(self, name, argv):
        self.closed = False

    def close(self):
        self.closed = True


@pytest.mark.parametrize("error, code, last_line, traceback", [
    (BadFile("scenario.yaml: not valid\n YAML"), 2, "plant: scenario.yaml: not valid YAML",
     False),
    (PermissionError(13, "Permission denied", "bag"), 2,
     "plant: [Errno 13] Permission denied: 'bag'", False),
    (ValueError("internal"), 1, "plant: ValueError: internal", True),
    (ZeroDivisionError("division by zero"), 1, "plant: ZeroDivisionError: division by zero",
     True),
])
def test_run_node_maps_bad_input_to_2_and_defects_to_a_traceback_and_1(
        monkeypatch, capsys, error, code, last_line, traceback):
    from vega_bus import shell

    def body(_shell):
        raise error

    monkeypatch.setattr(shell, "Shell", _FakeShell)
    assert shell.run_node("plant", body, ["plant"]) == code
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == last_line
    if traceback:
        assert err.startswith("Traceback (most recent call last):\n")
        assert f"\n{type(error).__name__}: {error}\n" in err
    else:
        assert err == last_line + "\n"


@pytest.mark.parametrize("raised, code, text", [
    ("node_exit", 1, "plant: sequence gap on /vega/ins\n"),
    ("stopped", 0, "plant: stopped by SIGINT\n"),
])
def test_run_node_keeps_node_exit_and_stop(monkeypatch, capsys, raised, code, text):
    from vega_bus import shell

    error = {"node_exit": shell.NodeExit(shell.EXIT_RUN_FAILURE, "sequence gap on /vega/ins"),
             "stopped": shell.Stopped()}[raised]

    def body(_shell):
        raise error

    monkeypatch.setattr(shell, "Shell", _FakeShell)
    assert shell.run_node("plant", body, ["plant"]) == code
    assert capsys.readouterr().err == text
