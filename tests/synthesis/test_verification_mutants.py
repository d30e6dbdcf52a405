"""Verification-tool behaviour that mutation testing (``make mutation MODULE=verification``)
found unchecked: the margins' dB conversion for the values that have no finite dB, the
time-of-velocity map's 2–100 s window, and what the frozen-point sweep reports (its times as
floats, the velocity of each time from the flight-condition table, the rate slice).
"""

import math

import numpy as np
import pytest

from vega_lpv.gridded_plant import GriddedPlant
from vega_lpv.interconnection import weighted_plant
from vega_lpv.lpv_synthesis import synthesize
from vega_lpv.verification import LoopMargins, frozen_point_sweep, time_at_velocity
from vega_lpv.weights import SHIPPED
from vega_model.parameters import default_context


def _margins(gm_low, gm_high):
    return LoopMargins(t_s=40.0, gm_low=gm_low, gm_high=gm_high, pm_deg=35.0,
                       crossover_radps=2.0, bending_gain_db=(-12.0, -20.0))


def test_gain_margins_in_db_by_hand():
    """20·log10(2) = 6.0206 dB; 20·log10(0.5) = −6.0206 dB."""
    d = _margins(0.5, 2.0).as_dict()
    assert d["gm_low_db"] == pytest.approx(-6.0206, abs=1e-4)
    assert d["gm_high_db"] == pytest.approx(6.0206, abs=1e-4)
    assert (d["t_s"], d["pm_deg"], d["crossover_radps"]) == (40.0, 35.0, 2.0)
    assert (d["bending1_gain_db"], d["bending2_gain_db"]) == (-12.0, -20.0)


@pytest.mark.parametrize("g", [math.nan, math.inf, 0.0, -1.0])
def test_a_margin_without_a_finite_db_value_is_reported_infinite(g):
    """No crossing (NaN or inf) and the degenerate factors 0 and < 0 are +inf dB, never NaN
    or −inf (the report's requirement checks compare these numbers)."""
    d = _margins(g, g).as_dict()
    assert d["gm_low_db"] == math.inf and d["gm_high_db"] == math.inf


def test_time_at_velocity_stays_within_2_to_100_s():
    """Beyond the velocity at 100 s the map is clamped to 100 s (v(t) flattens in the thrust
    tail-off), below the velocity at 2 s to 2 s; inside, the inverse of the table's v(t)."""
    ctx = default_context()
    t, v = ctx.conditions.t_s, ctx.conditions.column("v_mps")
    v100 = np.interp(100.0, t, v)
    v_after = np.interp(100.5, t, v)
    assert v_after > v100
    assert time_at_velocity(v_after, ctx) == pytest.approx(100.0, abs=1e-9)
    assert time_at_velocity(np.interp(1.0, t, v), ctx) == pytest.approx(2.0, abs=1e-9)
    assert time_at_velocity(np.interp(63.25, t, v), ctx) == pytest.approx(63.25, abs=1e-6)


@pytest.fixture(scope="module")
def frozen_result():
    m = weighted_plant(40.0, SHIPPED, default_context())
    plant = GriddedPlant(np.array([m.rho_mps]), m.A[None], m.B[None], m.C[None], m.D[None],
                         m.n_w, m.n_u, m.n_e, m.n_y)
    return synthesize(plant, rate_bounds=None, basis="constant", backoff=1.0)


def test_frozen_sweep_reports_times_velocities_and_rate(frozen_result):
    ctx = default_context()
    sweep = frozen_point_sweep(frozen_result, SHIPPED, ctx, [40, 41], 20)
    assert sweep.times_s.dtype == np.float64 and sweep.times_s.tolist() == [40.0, 41.0]
    v = np.interp([40.0, 41.0], ctx.conditions.t_s, ctx.conditions.column("v_mps"))
    np.testing.assert_allclose(sweep.rho, v, rtol=1e-15)
    assert sweep.rate_mps2 == 20.0 and isinstance(sweep.rate_mps2, float)
    assert np.all(sweep.max_real_eig < 0) and np.all(np.isfinite(sweep.hinf))


def test_frozen_sweep_uses_the_given_context(frozen_result, tmp_path):
    """A context whose bending data start at 20 s (not 0 s) has other mode frequencies at
    40 s, so its frozen loop, and its H∞ norm, differ from the default context's."""
    from vega_model.parameters import ModelContext
    from vega_model.vehicle_data import default_vehicle_path, load_vehicle_data

    text = default_vehicle_path().read_text()
    path = tmp_path / "vehicle.yaml"
    path.write_text(text.replace("t_start_s: {value: 0.0,", "t_start_s: {value: 20.0,", 1))
    other = ModelContext(vehicle=load_vehicle_data(path))
    assert other.parameters(40.0).f1_hz != default_context().parameters(40.0).f1_hz
    mine = frozen_point_sweep(frozen_result, SHIPPED, other, [40.0], 20.0)
    default = frozen_point_sweep(frozen_result, SHIPPED, default_context(), [40.0], 20.0)
    assert abs(mine.hinf[0] - default.hinf[0]) > 1e-9 * default.hinf[0]
