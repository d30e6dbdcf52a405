"""Verification tools of the synthesis, exercised with a frozen-point (single-grid-point)
controller at t = 40 s, and the scheduling-rate bounds computed the thesis' way.

Also by hand: the margins' dB conversion (and the values that have no finite dB), the
time-of-velocity map's 2–100 s window, and what the frozen-point sweep reports (its times as
floats, the velocity of each time from the flight-condition table, the rate slice, the
context it is given)."""

import math

import numpy as np
import pytest

from vega_lpv.gridded_plant import GriddedPlant
from vega_lpv.interconnection import weighted_plant
from vega_lpv.lpv_synthesis import synthesize
from vega_lpv.pipeline import grid_times, rate_bounds_from_trajectory, rate_box
from vega_lpv.verification import (LoopMargins, frozen_point_sweep, loop_margins,
                                   time_at_velocity)
from vega_lpv.weights import SHIPPED
from vega_model.parameters import default_context


@pytest.fixture(scope="module")
def frozen_result():
    m = weighted_plant(40.0, SHIPPED, default_context())
    plant = GriddedPlant(np.array([m.rho_mps]), m.A[None], m.B[None], m.C[None], m.D[None],
                         m.n_w, m.n_u, m.n_e, m.n_y)
    return synthesize(plant, rate_bounds=None, basis="constant", backoff=1.0)


def test_rate_bounds_like_the_thesis():
    """Min/max over 1–100 s of a 6 s moving mean of dv/dt (thesis §4.3.2: [5.4, 36.4] m/s²
    on its own trajectory); ours differ at the low end (thrust tail-off at 100 s)."""
    lo, hi = rate_bounds_from_trajectory(default_context())
    assert lo == pytest.approx(3.36, abs=0.05)
    assert hi == pytest.approx(35.83, abs=0.05)
    assert hi == pytest.approx(36.4, rel=0.03)


def test_rate_box():
    """Default box adds ρ̇ = 0 (frozen operation) to the trajectory's all-positive bounds."""
    assert rate_box((3.36, 35.83)) == (0.0, 35.83)
    assert rate_box((3.36, 35.83), "thesis") == (3.36, 35.83)
    assert rate_box((-2.0, 35.83)) == (-2.0, 35.83)
    with pytest.raises(ValueError, match="--rate-box 'x': expected one of with_frozen, thesis"):
        rate_box((3.36, 35.83), "x")


def test_grids_and_time_map():
    ctx = default_context()
    assert list(grid_times("thesis", ctx)) == [10, 20, 30, 40, 50, 60, 70, 80, 90]
    full = grid_times("full", ctx)
    assert full[0] == pytest.approx(2.0, abs=1e-6) and full[-1] == pytest.approx(100.0, abs=1e-6)
    v = np.interp(full, ctx.conditions.t_s, ctx.conditions.column("v_mps"))
    assert np.allclose(np.diff(v), np.diff(v)[0], rtol=1e-3)        # evenly spaced in velocity
    assert time_at_velocity(np.interp(47.0, ctx.conditions.t_s, ctx.conditions.column("v_mps")),
                            ctx) == pytest.approx(47.0, abs=1e-6)
    refined = grid_times("refined", ctx)
    assert set(grid_times("thesis", ctx)) <= set(refined) and np.all(np.diff(refined) > 0)
    assert {72.0, 74.0, 82.0} <= set(refined) and refined[0] == 10 and refined[-1] == 90
    with pytest.raises(ValueError, match="expected one of thesis, refined, full"):
        grid_times("dense", ctx)


@pytest.mark.slow
def test_frozen_sweep_at_the_design_point(frozen_result):
    sweep = frozen_point_sweep(frozen_result, SHIPPED, default_context(), [40.0, 41.0], 20.0)
    assert sweep.all_stable
    assert sweep.hinf[0] <= 1.01 * frozen_result.gamma
    assert sweep.hinf[1] > 0 and math.isfinite(sweep.hinf[1])


@pytest.mark.slow
def test_loop_margins_of_a_stabilising_controller(frozen_result):
    m = loop_margins(frozen_result, default_context(), 40.0, 20.0)
    assert 0 < m.gm_low < 1.0          # conditionally stable: the rigid body diverges open loop
    assert m.gm_high > 1.0
    assert 0 < m.pm_deg < 180 and m.crossover_radps > 0
    assert all(math.isfinite(g) for g in m.bending_gain_db)
    d = m.as_dict()
    assert d["gm_low_db"] < 0 < d["gm_high_db"]


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


@pytest.mark.slow
def test_frozen_sweep_reports_times_velocities_and_rate(frozen_result):
    ctx = default_context()
    sweep = frozen_point_sweep(frozen_result, SHIPPED, ctx, [40, 41], 20)
    assert sweep.times_s.dtype == np.float64 and sweep.times_s.tolist() == [40.0, 41.0]
    v = np.interp([40.0, 41.0], ctx.conditions.t_s, ctx.conditions.column("v_mps"))
    np.testing.assert_allclose(sweep.rho, v, rtol=1e-15)
    assert sweep.rate_mps2 == 20.0 and isinstance(sweep.rate_mps2, float)
    assert np.all(sweep.max_real_eig < 0) and np.all(np.isfinite(sweep.hinf))


@pytest.mark.slow
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
