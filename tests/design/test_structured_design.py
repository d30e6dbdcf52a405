"""The structured controller design (vega_design.structured) against hand references.

* the controller realisation: DC gains per input, the notch's zero at its frequency, the
  low-pass corner, the order — from transfer-function formulas, not from the code's own
  pieces;
* the design plants: the set named in the docstring (sizes, the bending frequencies span
  exactly the uncertainty bounds, the Table 2.3 J plant);
* the cost: its closed-loop radius is the exact sampled-data verdict of vega_loops.margins
  (an independent assembly), a destabilising controller is penalised as unstable, a bending
  mode left unattenuated is flagged;
* the export: the table loads through the flight loader, NaN where an LPV table has γ, its
  grid covers the pad and the dispersed burn-out, the parameters reproduce the matrices;
* the short design run end to end (two anchors, few generations).
"""

import math

import numpy as np
import pytest

from vega_design import structured as S
from vega_loops.export import discretise
from vega_loops.margins import plant_loop_ss, sampled_data_model, sampled_data_stability
from fixture_tables import STRUCTURED_2026_11_27


@pytest.fixture(scope="module")
def context():
    from vega_model.parameters import default_context

    return default_context()


@pytest.fixture(scope="module")
def uset(context):
    from vega_model.uncertainty import UncertaintySet

    return UncertaintySet.from_vehicle(context.vehicle)


def _x(**over):
    x = np.array(S.START_X, dtype=float)
    names = [p[0] for p in S.PARAMETERS]
    for k, v in over.items():
        x[names.index(k)] = v
    return x


def _tf(A, B, C, D, s):
    return (C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B) + D)[0]


def test_controller_dc_gains_and_order():
    x = _x(log10_k_theta=math.log10(1.7), log10_tau_d_s=math.log10(0.4),
           k_zdot_mrad_per_mps=2.0, k_z_urad_per_m=-30.0)
    A, B, C, D = S.controller_ss(x, (30.0, 70.0))
    assert A.shape == (8, 8) and B.shape == (8, 4) and C.shape == (1, 8) and D.shape == (1, 4)
    dc = _tf(A, B, C, D, 0.0)
    # low-passes and notches all have unit DC gain: the DC gains are the feedback gains
    np.testing.assert_allclose(dc, [1.7, 1.7 * 0.4, -30e-6, 2e-3], rtol=1e-9)


def test_notch_zero_and_lowpass_corner():
    w1, w2 = 31.0, 75.0
    x = _x(notch1_ratio=0.9, notch1_zeta_num=0.0, notch2_zeta_num=0.0,
           log10_lp1_radps=math.log10(12.0), lp1_zeta=0.5, log10_lp2_radps=2.0, lp2_zeta=1.0)
    A, B, C, D = S.controller_ss(x, (w1, w2))
    # a notch with zero numerator damping has a transmission zero at its frequency
    assert abs(_tf(A, B, C, D, 1j * 0.9 * w1)[0]) < 1e-9
    assert abs(_tf(A, B, C, D, 1j * S.START_X[9] * w2)[0]) < 1e-9
    # the response at 12 rad/s: k·LP1(jω_c) (= 1/(2jζ)) times the other sections, by formula
    s = 1j * 12.0
    k = 10 ** S.START_X[0]

    def notch(w, zn, zd):
        return (s * s + 2 * zn * w * s + w * w) / (s * s + 2 * zd * w * s + w * w)

    expected = (k * (1 / (2j * 0.5)) * notch(0.9 * w1, 0.0, S.START_X[8])
                * notch(S.START_X[9] * w2, 0.0, S.START_X[11]) * 1e4 / (s * s + 2 * 100 * s + 1e4))
    assert _tf(A, B, C, D, s)[0] == pytest.approx(expected, rel=1e-9)


def test_design_deviations_cover_the_bending_ranges(uset):
    devs = S.design_deviations(uset)
    fams = [f for _, f, _ in devs]
    assert fams.count("nominal") == 1
    assert fams.count("rigid") == 2 ** 6 + 1
    # mode 1: 8 frequencies × 2 shapes × 4 loop corners; mode 2: 7 × 2 × 2; both: 2^4 × 4
    assert fams.count("bending") == 8 * 2 * 4 + 7 * 2 * 2 + 2 ** 4 * 4
    # the same-sense loop corner of `vega robust`'s worst case is among the mode-1 plants
    assert any(d["thrust"] > 0 and d["actuator"] > 0 and d["delay_s"] < 0
               and d["bending_frequency_1"] == pytest.approx(uset["bending_frequency_1"].lower)
               for label, _, d in devs if label.startswith("mode 1"))
    for mode in (1, 2):
        f = uset[f"bending_frequency_{mode}"]
        values = {round(d[f"bending_frequency_{mode}"], 12) for label, fam, d in devs
                  if fam == "bending" and label.startswith(f"mode {mode}")}
        assert min(values) == pytest.approx(f.lower) and max(values) == pytest.approx(f.upper)
    jyy = [d["jyy"] for label, _, d in devs if "Table 2.3" in label]
    assert jyy == [pytest.approx(4.6e6 / 5.88e6 - 1.0)]


@pytest.fixture(scope="module")
def ds50(context, uset):
    return S.design_set(context, 50.0, uset)


@pytest.mark.slow
def test_cost_radius_is_the_exact_sampled_data_verdict(context, ds50):
    from vega_model.actuator import ActuatorParams
    from vega_loops.margins import total_delay_s

    x = np.array(S.START_X)
    _, detail = S.evaluate(x, ds50, detail=True)
    p = context.parameters(50.0)
    act = ActuatorParams.from_vehicle(context.vehicle)
    A, B, C = plant_loop_ss(p, act, S.INPUT_NAMES)
    model = sampled_data_model(A, B, 0.02, total_delay_s(context.vehicle))
    K = discretise(*S.controller_ss(x, p.omega_radps), 0.02)
    ref = sampled_data_stability(model, C, K, 1.0, nyquist=True)
    assert ref["n_unstable"] == ref["n_unstable_nyquist"] == 0
    # the nominal plant is design plant 0; its radius is below the max over all plants
    assert detail["max_radius"] >= ref["max_abs_eig"] - 1e-12
    assert detail["n_unstable"] == 0


@pytest.mark.slow
def test_a_weak_controller_is_penalised_as_unstable(ds50):
    # k_θ = 0.05 cannot hold the aerodynamically unstable vehicle at max-Q
    cost, detail = S.evaluate(_x(log10_k_theta=math.log10(0.05)), ds50, detail=True)
    assert detail["n_unstable"] > 0 and "nominal" in detail["unstable"]
    assert cost >= 10.0
    good = S.evaluate(np.array(S.START_X), ds50)
    assert good < cost


@pytest.mark.slow
def test_an_unfiltered_bending_mode_is_flagged(ds50):
    # both low-passes at 100 rad/s, no notch depth: the rate gyro sees mode 1 at full gain
    x = _x(log10_lp1_radps=2.0, log10_lp2_radps=2.0, lp1_zeta=1.0, lp2_zeta=1.0,
           notch1_zeta_num=0.6, notch1_zeta_den=0.6, notch2_zeta_num=0.6, notch2_zeta_den=0.6)
    _, detail = S.evaluate(x, ds50, detail=True)
    assert detail["bending_violations"] > 0 or detail["n_unstable"] > 0
    _, good = S.evaluate(np.array(S.START_X), ds50, detail=True)
    assert detail["penalty"] > good["penalty"]


@pytest.mark.slow
def test_short_design_and_export(context, tmp_path):
    from vega_gnc.controller_table import load_controller_table

    design = S.design_flight(context, anchors_s=(46.0, 50.0), grid_step_s=2.0, maxiter=1,
                             popsize=2, workers=0, polish_maxfev=20, progress=lambda _: None,
                             check_between=False)
    np.testing.assert_allclose(design.grid_times_s, [46.0, 48.0, 50.0])
    table = S.write_structured_table(tmp_path / "t.npz", design, context)
    again = load_controller_table(tmp_path / "t.npz")
    assert again.design == "structured" and math.isnan(again.gamma)
    assert again.measurement_sign == 1 and again.input_names == S.INPUT_NAMES
    v46, v50 = (context.parameters(t).v_mps for t in (46.0, 50.0))
    assert table.grid_v_mps[0] == S.V_BELOW_LIFTOFF_MPS
    assert table.grid_v_mps[1] == pytest.approx(v46)
    assert table.grid_v_mps[-2] == pytest.approx(v50)
    assert table.grid_v_mps[-1] == pytest.approx(S.V_BEYOND_BURNOUT * v50)
    # the matrices at a grid point are the realisation of that point's parameters
    A, B, C, D = S.controller_ss(design.x[1], context.parameters(48.0).omega_radps)
    np.testing.assert_allclose(table.A[2], A)
    np.testing.assert_allclose(table.D[2], D)
    np.testing.assert_allclose(table.Dd[2], discretise(A, B, C, D, 0.02)[3])
    # the controller step 4 evaluates between grid points is the one the table flies there
    from vega_loops.margins import flown_controller

    flown, _, clamped = flown_controller(table, context.parameters(47.0).v_mps)
    between = S.flown_between(context, (46.0, design.x[0]), (48.0, design.x[1]), 47.0)
    assert not clamped
    for a, b in zip(flown, between):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)



def test_search_returns_the_point_it_evaluated_inside_the_box():
    """The polish must not leave the box: a cost whose unconstrained minimum lies outside it
    (u0 = 1.5) and whose clipped unconstrained minimum is poor (2.75) against the box optimum
    (u0 = 1, u1 = 0.4: 0.25)."""
    span = S.UPPER - S.LOWER

    def fun(x):
        u = (x - S.LOWER) / span
        return (u[0] - 1.5) ** 2 + 10.0 * (u[0] - u[1] - 0.6) ** 2 + float(np.sum(u[2:] ** 2))

    x0 = S.LOWER.copy()
    x0[0], x0[1] = S.UPPER[0], S.LOWER[1] + 0.4 * span[1]
    x = S._search(fun, (), x0, seed=0, maxiter=3, popsize=2, polish_maxfev=3000)
    assert np.all(x >= S.LOWER) and np.all(x <= S.UPPER)
    assert fun(x) <= fun(x0) + 1e-9 and fun(x) == pytest.approx(0.25, abs=1e-3)


@pytest.mark.slow
def test_tail_cost_is_the_worst_time_plus_a_tenth_of_the_mean(context):
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    sets = [S.design_set(context, t, uset) for t in (90.0, 100.0)]
    x = np.array(S.START_X)
    c = [S.evaluate(x, ds) for ds in sets]
    assert S.tail_cost(x, sets) == pytest.approx(max(c) + 0.05 * (c[0] + c[1]), rel=1e-12)


@pytest.mark.slow
def test_hold_tail_holds_one_controller_and_keeps_the_rest(context):
    """Step 5 on the grid points of a whole table: one controller from the tail-off hold time on,
    every grid point before it untouched."""
    from vega_gnc.controller_table import load_controller_table

    meta = load_controller_table(STRUCTURED_2026_11_27).metadata
    times, xs = meta["grid_times_s"], np.array(meta["parameters_per_grid_time"])
    given = {float(t): (x, None, "given") for t, x in zip(times, xs)}
    done = S.hold_tail(context, given, seed=4001, maxiter=1, popsize=2, polish_maxfev=10,
                       times_s=(90.0, 100.0))
    assert sorted(done) == sorted(given)
    tail = np.array(times) >= S.TAIL_OFF_HOLD_S
    x = np.array([done[float(t)][0] for t in times])
    np.testing.assert_array_equal(x[~tail], xs[~tail])                   # untouched before
    assert np.all(x[tail] == x[tail][0])                                 # one held controller
    assert all(done[float(t)][2].startswith("held from 86 s") for t in np.array(times)[tail])
    assert all(done[float(t)][2] == "given" for t in np.array(times)[~tail])
    # the start (the 86 s parameters) is in the search's population: never worse than it
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    sets = [S.design_set(context, t, uset) for t in (90.0, 100.0)]
    x86 = xs[list(times).index(S.TAIL_OFF_HOLD_S)]
    assert S.tail_cost(x[tail][0], sets) <= S.tail_cost(x86, sets) + 1e-12


@pytest.mark.slow
def test_tail_tuning_counts_the_flown_transition_from_the_left_grid_point(context):
    from vega_gnc.controller_table import load_controller_table
    from vega_model.uncertainty import UncertaintySet

    meta = load_controller_table(STRUCTURED_2026_11_27).metadata
    by = dict(zip(meta["grid_times_s"], meta["parameters_per_grid_time"]))
    x, cost, details = S.tune_tail(context, by[86.0], maxiter=1, popsize=2, polish_maxfev=5,
                                   times_s=(90.0,), left=(84.0, by[84.0]))
    assert sorted(details) == [84.5, 85.0, 85.5, 90.0]
    uset = UncertaintySet.from_vehicle(context.vehicle)
    sets = [S.design_set(context, 90.0, uset)]
    tsets = [S.design_set(context, t, uset) for t in (84.5, 85.0, 85.5)]
    # the transition's loops are those of the controller the runtime flies there
    K = S.flown_between(context, (84.0, np.array(by[84.0])), (86.0, x), 85.0)
    assert details[85.0]["pm_deg"] == S.evaluate_discrete(K, tsets[1], detail=True)[1]["pm_deg"]
    full = S.tail_cost(x, sets, (context, (84.0, np.array(by[84.0])), 86.0, tsets))
    assert cost == pytest.approx(full, rel=1e-12)


@pytest.mark.slow
def test_loader_rules_for_structured_tables(context, tmp_path):
    """NaN γ only in a structured table; a structured table with a γ, an LPV table without
    one and an unknown design are refused in one line."""
    import json

    from vega_gnc.controller_table import ControllerTableError, validate_arrays

    design = S.design_flight(context, anchors_s=(50.0,), grid_step_s=2.0, maxiter=1,
                             popsize=2, workers=0, polish_maxfev=5, progress=lambda _: None)
    S.write_structured_table(tmp_path / "t.npz", design, context)
    with np.load(tmp_path / "t.npz") as f:
        arrays = dict(f)
    assert validate_arrays("t.npz", arrays).design == "structured"
    meta = json.loads(str(arrays["metadata"]))
    with pytest.raises(ControllerTableError, match="'gamma' must be NaN"):
        validate_arrays("t.npz", {**arrays, "gamma": np.array(0.9)})
    lpv = {**arrays, "metadata": np.array(json.dumps({**meta, "design": "lpv"}))}
    with pytest.raises(ControllerTableError, match="'gamma' has non-finite values"):
        validate_arrays("t.npz", lpv)
    odd = {**arrays, "metadata": np.array(json.dumps({**meta, "design": "pid"}))}
    with pytest.raises(ControllerTableError, match="metadata 'design' 'pid'"):
        validate_arrays("t.npz", odd)


@pytest.mark.parametrize("gain, phase_deg, ok", [
    (0.08, -47.0, True), (0.5, -47.0, True),        # 8 dB below / above −1 at the crossing
    (0.3, -47.0, False), (0.15, -47.0, False),      # 3.5 dB above, 2.5 dB below
    (0.3, -20.0, False), (0.4, -10.0, False),       # and a gain crossover with PM 20° / 24°
])
def test_exact_band_criterion_agrees_with_the_margin_tool(gain, phase_deg, ok):
    """band_criterion_misses against margins.extract_margins + bending_ok (the verification's
    own implementation) on a damped resonance L = g·e^{jφ}·ω₀²/(s² + 2ζω₀s + ω₀²)·e^{−sτ}
    whose band holds phase and gain crossovers of known size."""
    from vega_loops.margins import bending_ok, extract_margins

    w0, zeta, tau = 15.0, 0.1, 0.05
    w = np.geomspace(1.0, 60.0, 6000)
    s = 1j * w
    L = (gain * np.exp(1j * math.radians(phase_deg)) * w0 ** 2
         / (s * s + 2 * zeta * w0 * s + w0 ** 2) * np.exp(-s * tau))
    band = (w >= 0.8 * w0) & (w <= 1.2 * w0)
    gm_miss, pm_miss = S.band_criterion_misses(L[None, :], band[None, :])
    row = extract_margins(w, L, (w0, 10 * w0))
    assert bending_ok(row, 1) == ok
    assert (gm_miss[0] == 0.0 and pm_miss[0] == 0.0) == ok
    assert gm_miss[0] == pytest.approx(max(6.0 - row["b1_gm_db"], 0.0), abs=0.02)
    assert pm_miss[0] == pytest.approx(max(30.0 - row["b1_pm_deg"], 0.0), abs=0.2)


def _shipped_points(*times):
    import json

    meta = json.loads(str(np.load(STRUCTURED_2026_11_27)["metadata"]))
    by_time = dict(zip(meta["grid_times_s"], meta["parameters_per_grid_time"]))
    return {t: by_time[t] for t in times}


@pytest.mark.slow
def test_step4_adds_a_point_only_where_it_beats_the_flown_controller(context, uset,
                                                                      monkeypatch):
    """Step 4's guard: between the 44 and 46 s points of the reference table the flown
    controller misses a requirement at 45 s; a tuning that returns a worse controller there
    (k_θ = 0.05: unstable at max-Q) is not added, and the grid stays 44, 46 s. (The anchors'
    tuning returns the reference table's points.)"""
    anchors = _shipped_points(44.0, 46.0)
    ds45 = S.design_set(context, 45.0, uset)
    flown = S.flown_between(context, (44.0, anchors[44.0]), (46.0, anchors[46.0]), 45.0)
    flown_cost, flown_detail = S.evaluate_discrete(flown, ds45, detail=True)
    assert S.misses_requirement(flown_detail)            # step 4 looks at 45 s
    bad = _x(log10_k_theta=math.log10(0.05))
    calls = []

    def tuning(args):
        t_s = args[0]
        calls.append(t_s)
        x = np.array(anchors[t_s], dtype=float) if t_s in anchors else bad
        cost, detail = S.evaluate(x, S.design_set(context, t_s, uset), detail=True)
        return t_s, x, cost, detail

    monkeypatch.setattr(S, "_anchor_task", tuning)
    lines = []
    design = S.design_flight(context, anchors_s=(44.0, 46.0), grid_step_s=2.0, workers=0,
                             progress=lines.append)
    assert calls == [44.0, 46.0, 45.0]
    np.testing.assert_array_equal(design.grid_times_s, [44.0, 46.0])
    assert any(line.startswith("not added") and "t = 45 s" in line for line in lines)
    assert S.evaluate(bad, ds45) > flown_cost
    assert S.added_point_kept(flown_cost - 1e-9, flown_cost)
    assert not S.added_point_kept(flown_cost, flown_cost)
