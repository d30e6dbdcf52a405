"""The INS step never marks a non-finite sample valid (hardening: the controller must be able to
trust ``valid``)."""

import math

import numpy as np
import pytest

from vega_bus.records import TruthOut
from vega_model.parameters import default_context
from vega_sim.assembly import make_ins
from vega_sim.scenario import load_scenario


def _truth(t_ms, **changes):
    fields = dict(stamp_ms=t_ms, seq=0, pitch_rad=0.001, pitch_rate_radps=0.0, drift_m=0.0,
                  drift_rate_mps=0.0, aoa_rad=0.0, q_alpha_pa_rad=0.0,
                  dynamic_pressure_pa=5.0e4, mach=1.5, velocity_mps=500.0, altitude_m=1.0e4,
                  wind_mps=0.0, bending_q=(0.0, 0.0), bending_qdot=(0.0, 0.0))
    fields.update(changes)
    return TruthOut(**fields)


@pytest.fixture(scope="module")
def ins():
    return make_ins(load_scenario("thesis"))


@pytest.mark.parametrize("field", ["pitch_rad", "pitch_rate_radps", "drift_m", "drift_rate_mps",
                                   "velocity_mps"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_truth_gives_an_invalid_sample(ins, field, bad):
    ctx = default_context()
    t_ms = 40_000
    good = ins.sample(_truth(t_ms), ctx.parameters(t_ms / 1000.0))
    assert good.valid and all(math.isfinite(x) for x in good[3:8])
    out = ins.sample(_truth(t_ms + 10, **{field: bad}), ctx.parameters((t_ms + 10) / 1000.0))
    assert not all(np.isfinite(out[3:8]))          # the sample carries the fault …
    assert out.valid is False                       # … and says so
