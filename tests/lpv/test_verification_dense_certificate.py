"""verification.bending_rate_term (the plant's rate term N(ρ) from the bending-frequency ramp)
and verification.dense_certificate (the certificate between the synthesis grid points).

Independent references:

* bending_rate_term: N(ρ) = diag((dω_i/dt)/(dv/dt)/ω_i) on the η states, from the data
  directly: ω_i(t) = 2π(f_i,start + s(f_i,end − f_i,start)), s = (t − t_start)/(t_end − t_start)
  clamped to [0, 1] (vehicle data bending.*, the linear ramp of parameters.ModelContext), so
  dω_i/dt = 2π(f_i,end − f_i,start)/(t_end − t_start) inside the ramp and 0 outside; dv/dt the
  flight-condition table's own central difference (v[k+1] − v[k−1])/(t[k+1] − t[k−1]) at a
  row k. v(t) is linear between rows (0.1 s apart), so at a row any central step up to 0.1 s
  gives exactly that difference, and a 1 s step a different one.
* dense_certificate: the dense flight times by hand (the synthesis grid times with factor − 1
  evenly spaced points between each pair), ρ = v(t) from the table clipped to the grid, and
  certificate.certificate_check called directly with a plant assembled here at those times.

The LPV result is a real synthesis: the quadratic variant (constant X, Y: valid for every ρ̇)
on the 3-point grid ρ = 400, 500, 600 m/s of the shipped weights, by the IPM path (≈ 1 s). The
same result stated for the rate box [0, 35.83] m/s² (the trajectory's bounds, test_verification
test_rate_bounds_like_the_thesis) stands in for a rate-bounded one: a constant-X certificate
holds at any rate, and dense_certificate only reads the box's vertices.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from vega_lpv.certificate import certificate_check
from vega_lpv.gridded_plant import GriddedPlant
from vega_lpv.interconnection import weighted_plant
from vega_lpv.lpv_synthesis import synthesize
from vega_lpv.verification import bending_rate_term, dense_certificate, time_at_velocity
from vega_lpv.weights import SHIPPED, THESIS
from vega_model.parameters import ModelContext, default_context
from vega_model.vehicle_data import default_vehicle_path, load_vehicle_data

# every test here shares a module fixture that takes seconds (a solve or a flight)
pytestmark = pytest.mark.slow

GRID_RHO_MPS = (400.0, 500.0, 600.0)
RATE_BOX_MPS2 = (0.0, 35.83)


@pytest.fixture(scope="module")
def ctx():
    return default_context()


@pytest.fixture(scope="module")
def late_bending_ctx(tmp_path_factory):
    """The shipped data with the bending-frequency ramp starting at 20 s instead of 0 s."""
    text = default_vehicle_path().read_text()
    changed = text.replace("t_start_s: {value: 0.0,", "t_start_s: {value: 20.0,", 1)
    assert changed != text
    path = tmp_path_factory.mktemp("vehicle") / "vehicle.yaml"
    path.write_text(changed)
    return ModelContext(vehicle=load_vehicle_data(path))


# --------------------------------------------------------------------------- bending_rate_term

def _reference_N_diagonal(context, t_s, mode):
    """(dω/dt)/(dv/dt)/ω of bending mode ``mode`` (0, 1) at table row time ``t_s``."""
    veh = context.vehicle
    t0, t1 = veh["bending.t_start_s"], veh["bending.t_end_s"]
    f_start, f_end = veh[f"bending.mode{mode + 1}.frequency_hz"]
    s = min(max((t_s - t0) / (t1 - t0), 0.0), 1.0)
    omega = 2.0 * math.pi * (f_start + s * (f_end - f_start))
    domega_dt = 2.0 * math.pi * (f_end - f_start) / (t1 - t0) if t0 < t_s < t1 else 0.0
    t, v = context.conditions.t_s, context.conditions.column("v_mps")
    k = int(np.flatnonzero(np.isclose(t, t_s, rtol=0.0, atol=1e-9))[0])
    dv_dt = (v[k + 1] - v[k - 1]) / (t[k + 1] - t[k - 1])
    return domega_dt / dv_dt / omega


ROW_TIMES_S = (10.0, 33.3, 60.0, 85.0)


@pytest.mark.parametrize("weights", [SHIPPED, THESIS], ids=lambda w: w.name)
def test_bending_rate_term_by_hand(ctx, weights):
    names = weighted_plant(40.0, weights, ctx).state_names
    eta = [names.index("eta1"), names.index("eta2")]
    rate_term = bending_rate_term(ctx, weights)
    v = ctx.conditions.column("v_mps")
    for t_s in ROW_TIMES_S:
        rho = float(np.interp(t_s, ctx.conditions.t_s, v))
        N = rate_term(rho)
        assert N.shape == (len(names), len(names))
        expected = [_reference_N_diagonal(ctx, t_s, mode) for mode in (0, 1)]
        assert expected[0] > 0 and expected[1] > 0
        np.testing.assert_allclose([N[eta[0], eta[0]], N[eta[1], eta[1]]], expected,
                                   rtol=1e-9, atol=0.0, err_msg=f"t = {t_s} s")
        rest = N.copy()
        rest[eta, eta] = 0.0
        assert not rest.any(), f"non-zero entries off the eta diagonal at t = {t_s} s"


def test_bending_rate_term_steps_and_modes_are_distinct(ctx):
    """The tolerance above separates what a wrong step or a mode mix-up would give: at 33.3 s a
    1.05 s central step differs by ≈ 0.6 %, and the two modes' N differ by ≈ 4 %."""
    t, v = ctx.conditions.t_s, ctx.conditions.column("v_mps")
    k = int(np.flatnonzero(np.isclose(t, 33.3, atol=1e-9))[0])
    one_row = (v[k + 1] - v[k - 1]) / (t[k + 1] - t[k - 1])
    wide = (np.interp(t[k] + 1.05, t, v) - np.interp(t[k] - 1.05, t, v)) / 2.1
    assert abs(wide / one_row - 1.0) > 1e-3
    n1, n2 = (_reference_N_diagonal(ctx, 33.3, mode) for mode in (0, 1))
    assert abs(n2 / n1 - 1.0) > 1e-2


def test_bending_rate_term_follows_the_context(late_bending_ctx):
    """Bending ramp from 20 s: no frequency change (N = 0) before it, the 80 s ramp after."""
    context = late_bending_ctx
    names = weighted_plant(40.0, SHIPPED, context).state_names
    eta = [names.index("eta1"), names.index("eta2")]
    rate_term = bending_rate_term(context, SHIPPED)
    v = context.conditions.column("v_mps")
    assert not rate_term(float(np.interp(10.0, context.conditions.t_s, v))).any()
    for t_s in (33.3, 60.0):
        N = rate_term(float(np.interp(t_s, context.conditions.t_s, v)))
        expected = [_reference_N_diagonal(context, t_s, mode) for mode in (0, 1)]
        np.testing.assert_allclose([N[eta[0], eta[0]], N[eta[1], eta[1]]], expected,
                                   rtol=1e-9, atol=0.0)


# --------------------------------------------------------------------------- dense_certificate

@pytest.fixture(scope="module")
def grid_times(ctx):
    return time_at_velocity(np.array(GRID_RHO_MPS), ctx)


@pytest.fixture(scope="module")
def quadratic_result(ctx, grid_times):
    """The quadratic variant on the 3-point grid: constant X, Y; no rate vertices."""
    ms = [weighted_plant(float(t), SHIPPED, ctx) for t in grid_times]
    m = ms[0]
    plant = GriddedPlant(np.array(GRID_RHO_MPS), np.stack([p.A for p in ms]),
                         np.stack([p.B for p in ms]), np.stack([p.C for p in ms]),
                         np.stack([p.D for p in ms]), m.n_w, m.n_u, m.n_e, m.n_y)
    result = synthesize(plant, rate_bounds=None, backoff=1.0, solver="IPM")
    assert result.rate_vertices == () and result.certificate_max_eig < 0
    return result


@pytest.fixture(scope="module")
def box_result(quadratic_result):
    return replace(quadratic_result, rate_vertices=RATE_BOX_MPS2)


def _dense_times(t_grid, factor):
    """The grid times with factor − 1 evenly spaced times between each pair, by hand."""
    out = []
    for a, b in zip(t_grid[:-1], t_grid[1:]):
        out += [a + k * (b - a) / factor for k in range(factor)]
    return np.array(out + [t_grid[-1]])


def _reference(result, context, times, weights=SHIPPED, **kw):
    """certificate_check on a plant assembled here at the given times."""
    t_tab, v_tab = context.conditions.t_s, context.conditions.column("v_mps")
    rho = np.clip(np.interp(times, t_tab, v_tab), result.rho[0], result.rho[-1])
    points = [weighted_plant(float(t), weights, context).as_point() for t in times]

    def plant_at(r):
        return points[int(np.argmin(np.abs(rho - r)))]
    vertices = result.rate_vertices or (0.0,)
    return certificate_check(plant_at, result, rho, vertices, **kw)


def test_dense_times_by_hand(ctx, box_result, grid_times):
    t0, t1, t2 = grid_times
    assert 30.0 < t0 < t1 < t2 < 60.0
    times2, _, worst2 = dense_certificate(box_result, SHIPPED, ctx, factor=2)
    np.testing.assert_allclose(times2, [t0, (t0 + t1) / 2, t1, (t1 + t2) / 2, t2],
                               rtol=0.0, atol=1e-9)
    assert worst2.shape == (5, 2)
    times4, _, _ = dense_certificate(box_result, SHIPPED, ctx, factor=4)
    d1, d2 = (t1 - t0) / 4, (t2 - t1) / 4
    np.testing.assert_allclose(
        times4, [t0, t0 + d1, t0 + 2 * d1, t0 + 3 * d1, t1, t1 + d2, t1 + 2 * d2, t1 + 3 * d2,
                 t2], rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(times4, _dense_times(grid_times, 4), rtol=0.0, atol=1e-9)
    default_times, _, _ = dense_certificate(box_result, SHIPPED, ctx)
    np.testing.assert_array_equal(default_times, times4)     # factor 4 by default


def test_dense_rho_is_the_trajectory_velocity_clipped_to_the_grid(ctx, box_result, grid_times):
    t_tab, v_tab = ctx.conditions.t_s, ctx.conditions.column("v_mps")
    # why the clip matters here: v(t(ρ)) comes back an ulp outside at both grid ends
    assert np.interp(grid_times[0], t_tab, v_tab) < GRID_RHO_MPS[0], "precondition: data"
    assert np.interp(grid_times[-1], t_tab, v_tab) > GRID_RHO_MPS[-1], "precondition: data"
    times, rho, _ = dense_certificate(box_result, SHIPPED, ctx, factor=4)
    assert rho[0] == GRID_RHO_MPS[0] and rho[-1] == GRID_RHO_MPS[-1]
    assert rho[4] == pytest.approx(GRID_RHO_MPS[1], rel=1e-12)
    np.testing.assert_allclose(rho[1:-1], np.interp(times[1:-1], t_tab, v_tab),
                               rtol=1e-15, atol=0.0)
    assert np.all(np.diff(rho) > 0)


def test_dense_certificate_equals_a_direct_certificate_check(ctx, box_result, grid_times):
    """Defaults: the exact controller, no rate term; every rate vertex."""
    times, _, worst = dense_certificate(box_result, SHIPPED, ctx)
    assert worst.shape == (9, 2)
    expected = _reference(box_result, ctx, _dense_times(grid_times, 4), controller="exact")
    np.testing.assert_allclose(worst, expected, rtol=1e-9, atol=1e-13)
    # the constant-X certificate and no rate term: both vertices give the same eigenvalues
    np.testing.assert_allclose(worst[:, 0], worst[:, 1], rtol=1e-9, atol=1e-13)


def test_physical_rates_add_the_bending_rate_term(ctx, box_result, grid_times):
    _, _, plain = dense_certificate(box_result, SHIPPED, ctx, physical_rates=False)
    _, _, physical = dense_certificate(box_result, SHIPPED, ctx, physical_rates=True)
    expected = _reference(box_result, ctx, _dense_times(grid_times, 4),
                          rate_term=bending_rate_term(ctx, SHIPPED))
    np.testing.assert_allclose(physical, expected, rtol=1e-9, atol=1e-13)
    np.testing.assert_array_equal(physical[:, 0], plain[:, 0])     # ρ̇ = 0: no term
    assert np.all(np.abs(physical[:, 1] - plain[:, 1]) > 1e-6 * np.abs(plain[:, 1]))


def test_interpolated_controller_is_passed_through(ctx, box_result, grid_times):
    _, _, exact = dense_certificate(box_result, SHIPPED, ctx, controller="exact")
    _, _, interpolated = dense_certificate(box_result, SHIPPED, ctx, controller="interpolated")
    expected = _reference(box_result, ctx, _dense_times(grid_times, 4),
                          controller="interpolated")
    np.testing.assert_allclose(interpolated, expected, rtol=1e-9, atol=1e-13)
    between = [1, 2, 3, 5, 6, 7]
    assert np.all(np.abs(interpolated[between] - exact[between])
                  > 1e-6 * np.abs(exact[between]))
    with pytest.raises(ValueError, match="controller must be 'exact' or 'interpolated'"):
        dense_certificate(box_result, SHIPPED, ctx, controller="other")


def test_without_rate_vertices_the_frozen_rate_is_checked(ctx, quadratic_result, grid_times):
    """The quadratic variant has no rate vertices: ρ̇ = 0 only (one column); with the rate
    term a ρ̇ ≠ 0 would change the numbers."""
    _, _, worst = dense_certificate(quadratic_result, SHIPPED, ctx, factor=2,
                                    physical_rates=True)
    assert worst.shape == (5, 1)
    term = bending_rate_term(ctx, SHIPPED)
    times = _dense_times(grid_times, 2)
    expected = _reference(quadratic_result, ctx, times, rate_term=term)
    np.testing.assert_allclose(worst, expected, rtol=1e-9, atol=1e-13)
    # certified at the grid points, as the synthesis reports (between them this stage-1 design
    # without the robustness margin need not be: lpv_synthesis.synthesize, ``robustness``)
    assert np.all(worst[[0, 2, 4]] < 0)


def test_the_plant_comes_from_the_given_context(ctx, late_bending_ctx, box_result, grid_times):
    """Other bending data (ramp from 20 s): other plants at the same times, other numbers."""
    times, _, mine = dense_certificate(box_result, SHIPPED, late_bending_ctx, factor=2,
                                       physical_rates=True)
    expected = _reference(box_result, late_bending_ctx, _dense_times(grid_times, 2),
                          rate_term=bending_rate_term(late_bending_ctx, SHIPPED))
    np.testing.assert_allclose(mine, expected, rtol=1e-9, atol=1e-13)
    _, _, default = dense_certificate(box_result, SHIPPED, ctx, factor=2, physical_rates=True)
    assert np.all(np.abs(mine - default) > 1e-6 * np.abs(default))
