"""The guidance reference on the flight side: the loader's refusals, the interpolation, and
the runtime acting on measurement − reference with the feed-forward added (numbers worked out
by hand from a static-gain table, not from the code under test)."""

import json
import math

import numpy as np
import pytest

from fixture_tables import write_gain_table
from vega_core.errors import BadFile
from vega_gnc.controller_runtime import STATUS_LIMITED, STATUS_OK, ControllerRuntime, Measurement
from vega_gnc.controller_table import MEASUREMENT_NAMES
from vega_gnc.guidance_reference import (FORMAT_VERSION, MAX_FEEDFORWARD_RAD, REQUIRED_METADATA,
                                         load_guidance_reference, resolve_reference)

T = np.array([0.0, 1.0, 3.0])
REF = np.array([[0.00, 0.000, 0.0, 0.0],
                [0.01, 0.002, 10.0, 1.0],
                [0.03, -0.002, 30.0, -1.0]])
FF = np.array([0.0, 0.001, -0.003])


def _arrays(**changes):
    meta = {key: {} for key in REQUIRED_METADATA}
    meta["input_names"] = list(MEASUREMENT_NAMES)
    arrays = dict(format_version=np.array(FORMAT_VERSION), t_s=T, reference=REF,
                  beta_ff_rad=FF, metadata=np.array(json.dumps(meta)))
    arrays.update(changes)
    return {k: v for k, v in arrays.items() if v is not None}


def _write(tmp_path, name="r.npz", **changes):
    path = tmp_path / name
    np.savez(path, **_arrays(**changes))
    return path


def test_good_file_loads_and_interpolates_linearly_held_at_the_ends(tmp_path):
    ref = load_guidance_reference(_write(tmp_path))
    assert ref.at(0.5) == pytest.approx([0.005, 0.001, 5.0, 0.5, 0.0005], abs=1e-15)
    # 2.0 s: halfway between 1 s and 3 s
    assert ref.at(2.0) == pytest.approx([0.02, 0.0, 20.0, 0.0, -0.001], abs=1e-15)
    assert ref.at(-5.0) == pytest.approx([0, 0, 0, 0, 0])
    assert ref.at(99.0) == pytest.approx([0.03, -0.002, 30.0, -1.0, -0.003])
    assert ref.at(1.0) == pytest.approx([0.01, 0.002, 10.0, 1.0, 0.001])


@pytest.mark.parametrize("changes, message", [
    (dict(t_s=None), "missing key 't_s'"),
    (dict(format_version=np.array(2)), "format_version 2 is not supported"),
    (dict(t_s=np.array([0.0, 2.0, 1.0])), "'t_s' must be strictly increasing"),
    (dict(t_s=np.array([0.0])), "at least 2 times"),
    (dict(reference=np.where(REF == 10.0, np.nan, REF)), "'reference' has non-finite values"),
    (dict(reference=REF[:, :3]), "'reference' has shape (3, 3), expected (3, 4)"),
    (dict(beta_ff_rad=FF[:2]), "'beta_ff_rad' has shape (2,), expected (3,)"),
    (dict(reference=REF * [1, 1, 100, 1]), "reference z_ins_m = 3000 at t = 3 s is beyond"),
    (dict(reference=REF * [20, 1, 1, 1]), "reference theta_ins_rad = 0.6 at t = 3 s"),
    (dict(beta_ff_rad=np.array([0.0, 0.0, -(MAX_FEEDFORWARD_RAD + 1e-6)])),
     "feed-forward -3.25 deg at t = 3 s is beyond ±3.25 deg"),
    (dict(metadata=np.array("[1, 2]")), "'metadata' must be a JSON object"),
    (dict(metadata=np.array(json.dumps({"input_names": list(MEASUREMENT_NAMES)}))),
     "metadata lacks 'units'"),
])
def test_bad_files_are_refused_in_one_line_naming_the_file(tmp_path, changes, message):
    path = _write(tmp_path, **changes)
    with pytest.raises(BadFile) as info:
        load_guidance_reference(path)
    text = str(info.value)
    assert message in text and text.startswith(str(path)) and "\n" not in text


def test_wrong_input_order_is_refused(tmp_path):
    meta = {key: {} for key in REQUIRED_METADATA}
    meta["input_names"] = list(reversed(MEASUREMENT_NAMES))
    with pytest.raises(BadFile, match="input_names"):
        load_guidance_reference(_write(tmp_path, metadata=np.array(json.dumps(meta))))


def test_unreadable_and_missing_files(tmp_path):
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(BadFile, match="not a readable guidance reference"):
        load_guidance_reference(junk)
    with pytest.raises(BadFile, match="no such file"):
        load_guidance_reference(tmp_path / "absent.npz")
    assert resolve_reference("none") is None


@pytest.fixture(scope="module")
def gain_table(tmp_path_factory):
    """β_cmd = 0.5·θ_INS (measurement sign +1)."""
    return write_gain_table(tmp_path_factory.mktemp("gain") / "gain.npz")


def test_runtime_acts_on_the_deviation_and_adds_the_feed_forward(tmp_path, gain_table):
    ref = load_guidance_reference(_write(tmp_path))
    with_ref = ControllerRuntime(gain_table, reference=ref)
    without = ControllerRuntime(gain_table)
    # at 2.0 s: θ_ref = 0.02, β_ff = −0.001 → u = 0.5 (θ − 0.02) − 0.001
    m = Measurement(2.0, 0.05, 0.0, 0.0, 0.0, 500.0)
    cmd = with_ref.step(m)
    assert cmd.status == STATUS_OK
    assert cmd.deflection_cmd_rad == pytest.approx(0.5 * (0.05 - 0.02) - 0.001, rel=1e-12)
    assert without.step(m).deflection_cmd_rad == pytest.approx(0.025, rel=1e-12)
    # on the reference the command is the feed-forward alone
    cmd = with_ref.step(Measurement(2.5, 0.025, -0.001, 25.0, -0.5, 500.0))
    assert cmd.deflection_cmd_rad == pytest.approx(-0.002, abs=1e-15)


def test_the_limit_applies_to_feedback_plus_feed_forward(tmp_path, gain_table):
    ff = np.array([0.0, 0.05, 0.05])            # 2.86°, within the file limit
    ref = load_guidance_reference(_write(tmp_path, beta_ff_rad=ff))
    runtime = ControllerRuntime(gain_table, reference=ref)
    # feedback 0.5·(0.2 − 0.02) = 0.09 rad (5.2°) alone is within the 6.5° stop; with the
    # feed-forward 0.14 rad it is not
    cmd = runtime.step(Measurement(2.0, 0.2, 0.0, 0.0, 0.0, 500.0))
    assert cmd.deflection_cmd_rad == math.radians(6.5) and cmd.status == STATUS_LIMITED
