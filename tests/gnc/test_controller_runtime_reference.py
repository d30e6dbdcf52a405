"""The guidance reference and feed-forward in the controller runtime's law.

The law (module docstring of vega_gnc/controller_runtime.py): ``u = Cd x + Dd y + β_ff(t)``,
``y = sign·(meas − ref(t))``, with ``ref(t)`` and ``β_ff(t)`` linear in time between the
reference samples, taken at the measurement's sample stamp (not at the time of use) and held
beyond the last sample. Every expected number is worked out here by hand for the static-gain
table β_cmd = 0.5·θ_INS (tests/fixture_tables.py, measurement sign +1); angles in rad.
"""

import numpy as np
import pytest

from fixture_tables import write_gain_table
from vega_gnc.controller_runtime import STATUS_OK, ControllerRuntime, Measurement
from vega_gnc.controller_table import MEASUREMENT_NAMES
from vega_gnc.guidance_reference import GuidanceReference

NAMES = list(MEASUREMENT_NAMES)


@pytest.fixture(scope="module")
def gain_table(tmp_path_factory):
    """β_cmd = 0.5·θ_INS, grid 0..3000 m/s, measurement sign +1."""
    return write_gain_table(tmp_path_factory.mktemp("gain") / "gain.npz")


@pytest.fixture(scope="module")
def reference():
    """θ_ref 0 → 0.02 rad, θ̇_ref 0.004 rad/s, z_ref 0, ż_ref 0.5 m/s, β_ff 0.001 → 0.003 rad
    over t = 0..1 s (the θ̇, ż columns differ from β_ff so that a wrong column shows)."""
    t = np.array([0.0, 1.0])
    ref = np.array([[0.0, 0.004, 0.0, 0.5], [0.02, 0.004, 0.0, 0.5]])
    ff = np.array([0.001, 0.003])
    return GuidanceReference(path="hand", t_s=t, reference=ref, beta_ff_rad=ff,
                             metadata={"input_names": NAMES})


def _m(stamp, pitch=0.0, v=500.0, valid=True, rate=0.0):
    return Measurement(stamp, pitch, rate, 0.0, 0.0, v, valid)


def test_reference_and_feed_forward_enter_the_law(gain_table, reference):
    """At stamp 0.5 s: θ_ref = 0.01 rad, β_ff = 0.002 rad, so θ = 0.03 rad gives
    u = 0.5·(0.03 − 0.01) + 0.002 = 0.012 rad (used at 0.51 s: the reference is taken at the
    sample's stamp, where 0.51 s would give 0.5·(0.03 − 0.0102) + 0.00202 = 0.01192)."""
    rt = ControllerRuntime(gain_table, reference=reference)
    cmd = rt.step(_m(0.5, 0.03), now_s=0.51)
    assert cmd.status == STATUS_OK
    assert cmd.deflection_cmd_rad == pytest.approx(0.012, abs=1e-15)


def test_without_reference_the_law_is_the_bare_gain(gain_table):
    cmd = ControllerRuntime(gain_table).step(_m(0.5, 0.03))
    assert cmd.deflection_cmd_rad == pytest.approx(0.015, abs=1e-15)


def test_reference_held_beyond_its_last_sample(gain_table, reference):
    """At 3 s (past the last sample at 1 s): θ_ref = 0.02, β_ff = 0.003 → u = 0.5·0.01 + 0.003."""
    cmd = ControllerRuntime(gain_table, reference=reference).step(_m(3.0, 0.03))
    assert cmd.deflection_cmd_rad == pytest.approx(0.008, abs=1e-15)
