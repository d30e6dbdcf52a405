"""``vega check``: requirements and run health from a bag alone (vega_bags.bagcheck).

Bags are written from the in-process simulation (tests/fixture_bags.py: real message types,
serialised by rclpy); faults are injected into the messages before they are written.
"""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from fixture_bags import messages_on, short_run, write_bag
from vega_bus import topics
from vega_bags import bagcheck, bagio
from vega_cli import cli
from vega_sim.requirements import REQUIREMENT_KEYS, default_requirements_path, load_requirements

MS = 1_000_000  # ns


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return short_run(tmp_path_factory.mktemp("run"))


@pytest.fixture(scope="module")
def good_bag(run, tmp_path_factory):
    return write_bag(tmp_path_factory.mktemp("good") / "bag", run)


def _vega(argv, capsys):
    status = cli.main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def _check(tmp_path, run, mutate):
    return bagcheck.check_bag(write_bag(tmp_path / "bag", run, mutate))


def _failed(check):
    return {r.key for r in check.requirements.results if not r.passed} | \
        {h.key for h in check.health if not h.passed}


# ----------------------------------------------------------------------------- good run
@pytest.mark.slow
def test_good_run_passes(good_bag, capsys):
    status, out, err = _vega(["check", str(good_bag)], capsys)
    assert status == 0, out + err
    assert "verdict: PASS" in out
    for metric in ("Qα", "z", "ż", "β", "∫|β|dt"):
        assert f" {metric} " in out
    assert "margin" in out and "controller status: OK 200" in out


@pytest.mark.slow
def test_bag_metrics_equal_the_in_process_run(good_bag, run):
    """The same Table 3.1 figures, bit for bit, from the bag as from the simulation arrays."""
    check = bagcheck.check_bag(good_bag)
    ref = run.result.metrics()
    for got, want in zip(check.requirements.results, ref.results):
        assert (got.key, got.value, got.bound, got.time_s) == \
            (want.key, want.value, want.bound, want.time_s)
    assert check.requirements.command_peak_rad == ref.command_peak_rad
    assert check.requirements.command_signed_integral_rad_s == \
        ref.command_signed_integral_rad_s

def test_bag_holds_the_in_process_run(good_bag, run):
    """The run rebuilt from the bag equals the simulation's result, array for array."""
    got = bagcheck.check_bag(good_bag).result
    assert got.scenario == run.result.scenario and got.seed == run.result.seed
    want = run.result.arrays()
    have = got.arrays()
    assert have.keys() == want.keys()
    for name, value in want.items():
        assert have[name].dtype.kind == value.dtype.kind, name
        assert np.array_equal(have[name], value), name


def test_json_holds_the_same_verdict(good_bag, tmp_path, capsys):
    out_json = tmp_path / "v.json"
    status, out, _ = _vega(["check", str(good_bag), "--json", str(out_json)], capsys)
    verdict = json.loads(out_json.read_text())
    assert status == verdict["exit_code"] == 0 and verdict["passed"] is True
    assert [r["key"] for r in verdict["requirements"]] == list(REQUIREMENT_KEYS)
    drift = next(r for r in verdict["requirements"] if r["key"] == "drift")
    assert drift["bound"] == 500.0 and math.isclose(drift["margin"], 500.0 - abs(drift["value"]))
    assert f"{drift['value']:.6g} m" in out
    assert verdict["metadata"][bagio.META_SCENARIO] == "thesis"
    # the Qα row: the worst-margin sample and, beside it, the largest |Qα|
    check = bagcheck.check_bag(good_bag)
    qa = check.result.q_alpha_pa_rad
    row = next(r for r in verdict["requirements"] if r["key"] == "q_alpha")
    k = int(np.argmax(np.abs(qa)))
    assert (row["peak_value"], row["peak_time_s"]) == (qa[k], check.result.t_s[k])
    assert row["gating"] is True and row["peak_value_display"] == math.degrees(qa[k])
    line = next(x for x in out.splitlines() if x.startswith("Load performance"))
    assert f"{abs(math.degrees(qa[k])):.6g} Pa*deg at {check.result.t_s[k]:.3f} s" in line
    # the informational 3°·Q line: printed, in the JSON, never gating
    (info,) = [x for x in verdict["informational"] if x["key"] == "q_alpha_objective"]
    assert info["key"] == "q_alpha_objective" and info["gating"] is False
    assert any(x.startswith("Load objective") and "info: " in x for x in out.splitlines())
    # the constant allowable of the flight-day sign-off (REQUIREMENTS.md §6): printed, never gating
    (allow,) = [x for x in verdict["informational"] if x["key"] == "q_alpha_allowable"]
    assert allow["gating"] is False
    assert any(x.startswith("Load allowable") and "info: " in x for x in out.splitlines())
    sensitivity = verdict["q_alpha_sensitivity"]
    assert sensitivity["alpha_max_deg"] == 4.0 and sensitivity["passed"] is True
    assert sensitivity["alpha_flip_deg"] <= 4.0 and "Qα sensitivity" in out


# ----------------------------------------------------------------------------- requirement failures
def _set_truth(field, value, at_ms):
    def mutate(messages):
        for i in messages_on(messages, topics.TRUTH.name):
            if messages[i][1] == at_ms * MS:
                setattr(messages[i][2], field, value)
    return mutate


def test_drift_violation_fails_naming_the_requirement(run, tmp_path, capsys):
    bag = write_bag(tmp_path / "bag", run, _set_truth("drift_m", -612.5, 12_000))
    out_json = tmp_path / "v.json"
    status, out, _ = _vega(["check", str(bag), "--json", str(out_json)], capsys)
    assert status == 1
    assert "Lateral control performance z: -612.5 m at 12.000 s exceeds its bound 500 m " \
           "by 112.5 m" in out
    verdict = json.loads(out_json.read_text())
    assert verdict["exit_code"] == 1 and verdict["passed"] is False
    assert [r["key"] for r in verdict["requirements"] if not r["passed"]] == ["drift"]


@pytest.mark.slow
def test_actuator_angle_not_command_is_checked(run, tmp_path):
    """A 7° excursion of the actuator samples fails β; the commands are unchanged."""
    def mutate(messages):
        i = messages_on(messages, topics.ACTUATOR.name)[100]
        samples = list(messages[i][2].deflection_samples_rad)
        samples[3] = math.radians(7.0)
        messages[i][2].deflection_samples_rad = samples
    check = _check(tmp_path, run, mutate)
    assert _failed(check) == {"deflection"}
    assert math.isclose(check.requirements["deflection"].value, math.radians(7.0))


def test_strict_bound_reached_names_no_minus_zero(run, tmp_path, capsys):
    """An actuator sample exactly at the 6.5° stop fails the strict bound and says so, without
    an excess of "-0"."""
    stop = load_requirements().deflection_rad

    def mutate(messages):
        i = messages_on(messages, topics.ACTUATOR.name)[100]
        samples = list(messages[i][2].deflection_samples_rad)
        samples[3] = stop
        messages[i][2].deflection_samples_rad = samples
    check = _check(tmp_path, run, mutate)
    assert _failed(check) == {"deflection"}
    (line,) = check.failures
    assert line.endswith("reaches its bound 6.5 deg (the bound is strict)"), line
    assert "-0" not in line


def test_informational_line_does_not_change_the_verdict(run, tmp_path, capsys):
    """An objective table far below the run's Qα: the line says "info: no", the verdict stays
    PASS and the exit status 0."""
    import yaml

    tree = yaml.safe_load(default_requirements_path().read_text())
    tree["q_alpha_objective"]["value"] = [v / 100.0 for v in tree["q_alpha_objective"]["value"]]
    req = tmp_path / "req.yaml"
    req.write_text(yaml.safe_dump(tree))
    bag = write_bag(tmp_path / "bag", run)
    status, out, _ = _vega(["check", str(bag), "--requirements", str(req)], capsys)
    assert status == 0 and "verdict: PASS" in out
    line = next(x for x in out.splitlines() if x.startswith("Load objective"))
    assert "info: no" in line


def test_q_alpha_envelope_over_mach(run, tmp_path, capsys):
    """A tighter envelope (a requirement file) makes Qα fail where it binds."""
    import yaml

    tree = yaml.safe_load(default_requirements_path().read_text())
    tree["q_alpha_envelope"]["value"] = [v / 100.0 for v in tree["q_alpha_envelope"]["value"]]
    req = tmp_path / "req.yaml"
    req.write_text(yaml.safe_dump(tree))
    bag = write_bag(tmp_path / "bag", run)
    status, out, _ = _vega(["check", str(bag), "--requirements", str(req)], capsys)
    assert status == 1 and "Load performance Qα:" in out


# ----------------------------------------------------------------------------- health failures
def test_nan_is_detected(run, tmp_path):
    def mutate(messages):
        messages[messages_on(messages, topics.INS.name)[50]][2].pitch_rate_radps = math.nan
    check = _check(tmp_path, run, mutate)
    assert _failed(check) == {"finite"}
    detail = next(h.detail for h in check.health if h.key == "finite")
    assert detail == "/vega/ins pitch_rate_radps not finite at 10.512 s"


def test_nan_in_truth_fails_the_requirement_too(run, tmp_path):
    check = _check(tmp_path, run, _set_truth("drift_rate_mps", math.nan, 11_000))
    assert _failed(check) == {"finite", "drift_rate"}


@pytest.mark.slow
def test_sequence_gap_is_detected(run, tmp_path):
    def mutate(messages):
        del messages[messages_on(messages, topics.TVC_CMD.name)[40]]
    check = _check(tmp_path, run, mutate)
    assert {"sequence", "lockstep"} <= _failed(check)
    detail = next(h.detail for h in check.health if h.key == "sequence")
    assert detail.startswith("/vega/tvc_cmd seq 39 → 41 (gap)")


def test_lockstep_stall_is_detected(run, tmp_path):
    """The truth stamp repeats once (sequence intact): a stall."""
    def mutate(messages):
        idx = messages_on(messages, topics.TRUTH.name)
        i, prev = idx[30], idx[29]
        t_prev = messages[prev][1]
        messages[i][2].header.stamp = messages[prev][2].header.stamp
        messages[i] = (messages[i][0], t_prev, messages[i][2])
    check = _check(tmp_path, run, mutate)
    assert "lockstep" in _failed(check) and "sequence" not in _failed(check)
    detail = next(h.detail for h in check.health if h.key == "lockstep")
    assert "/vega/truth stamp stalled at 10.290 s" in detail


@pytest.mark.slow
def test_compute_time_over_budget(run, tmp_path):
    """More than 1 % of the steps over the 12 ms budget fails the run; an isolated overrun (a
    descheduled step on a shared machine) is reported, not failed."""
    def isolated(messages):
        messages[messages_on(messages, topics.DIAGNOSTICS.name)[7]][2].compute_time_s = 0.0125

    check = _check(tmp_path, run, isolated)
    h = next(h for h in check.health if h.key == "compute_time")
    assert h.passed and h.value == "max 12.5 ms" and "1 of " in h.detail
    n_cmd = None

    def systematic(messages):
        nonlocal n_cmd
        cmds = messages_on(messages, topics.DIAGNOSTICS.name)
        n_cmd = len(cmds)
        for i in cmds[::50] + cmds[1::50]:  # 4 % of the steps
            messages[i][2].compute_time_s = 0.0125

    (tmp_path / "b").mkdir()
    check = _check(tmp_path / "b", run, systematic)
    assert _failed(check) == {"compute_time"}
    h = next(h for h in check.health if h.key == "compute_time")
    assert h.value == "max 12.5 ms" and math.isclose(h.margin, -0.0005)
    assert f"of {n_cmd} command(s) over budget" in h.detail


def test_truncated_run_fails_coverage(run, tmp_path):
    """A run that stopped at 12 s (a node died) is not a complete run."""
    check = _check(tmp_path, run, lambda m: [x for x in m if x[1] <= 12_000 * MS])
    assert _failed(check) == {"coverage"}


def test_missing_clock_tick_fails_coverage(run, tmp_path):
    """/clock is checked against its schedule (every 10 frames and t_end), tick by tick."""
    def mutate(messages):
        del messages[messages_on(messages, topics.CLOCK.name)[3]]
    check = _check(tmp_path, run, mutate)
    assert _failed(check) == {"coverage"}
    detail = next(h.detail for h in check.health if h.key == "coverage")
    assert "/clock:" in detail


# ----------------------------------------------------------------------------- bad input
def test_bad_bags_are_one_line_exit_2(good_bag, tmp_path, capsys):
    import shutil

    status, out, err = _vega(["check", str(tmp_path / "missing")], capsys)
    assert status == 2 and out == "" and err.count("\n") == 1
    assert "no such file or directory" in err
    corrupt = tmp_path / "corrupt"
    shutil.copytree(good_bag, corrupt)
    (mcap,) = corrupt.glob("*.mcap")
    mcap.write_bytes(mcap.read_bytes()[:mcap.stat().st_size // 3])
    status, out, err = _vega(["check", str(corrupt)], capsys)
    assert status == 2 and out == "" and err.count("\n") == 1 and str(corrupt) in err


@pytest.mark.slow
def test_foreign_bag_from_the_command_line(tmp_path, ros_env):
    """A bag with only std_msgs: one line on stderr, exit status 2 (a real `vega` process)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(tmp_path / "chatter", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
        msg = store.types["std_msgs/msg/String"](data="hello")
        writer.write(conn, 1, store.serialize_cdr(msg, "std_msgs/msg/String"))
    proc = subprocess.run([sys.executable, "-m", "vega_cli.cli", "check",
                           str(tmp_path / "chatter")], env=ros_env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.startswith("vega: error: bag ") and proc.stderr.count("\n") == 1
    assert "foreign bag: none of the vega topics" in proc.stderr


def test_metadata_missing_fails(run, tmp_path):
    """A bag without the run metadata cannot say what it ran: metadata and coverage fail."""
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer

    from vega_bags import simbag

    store = bagio.vega_typestore()
    with Writer(tmp_path / "bare", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {t.name: writer.add_connection(t.name, t.type_name, typestore=store)
                 for t in topics.ALL_TOPICS}
        for topic, t_ns, message in simbag.simulation_messages(run.result):
            writer.write(conns[topic], t_ns, serialize_message(message))
    check = bagcheck.check_bag(tmp_path / "bare")
    assert _failed(check) == {"metadata", "coverage"}
    assert check.exit_code == 1


def test_bag_without_truth_is_bad_input(run, tmp_path, capsys):
    """A bag of the graph with no truth at all cannot be checked: one line, exit status 2."""
    bag = write_bag(tmp_path / "bag", run,
                    lambda m: [x for x in m if x[0] != topics.TRUTH.name])
    status, out, err = _vega(["check", str(bag)], capsys)
    assert status == 2 and out == ""
    assert err.strip() == f"vega: error: bag {bag}: no messages on /vega/truth: not a " \
                          f"complete run bag (or the run died before its first frame)"
