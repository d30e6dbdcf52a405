"""``vega margins`` (vega_loops.margins) against references independent of the code.

* margin extraction (:func:`extract_margins`): textbook loops with known margins —
  python-control ``stability_margins`` (a different implementation), the roots of the
  characteristic polynomial den + g·num at the claimed gain limits, closed forms for a delayed
  integrator and for the resonance peak of a lightly damped mode;
* the discrete controller's response (:func:`discrete_response`) and the hold
  (:func:`zoh_response`) against hand formulas (a static gain, a first-order filter);
* the sampled-data model (:func:`sampled_data_model`): hand formulas of the modified
  z-transform, and a step-by-step simulation of the held, delayed command;
* stability (:func:`sampled_data_stability`): eigenvalue count and Nyquist count against the
  roots of hand-derived characteristic polynomials, stable and unstable, with open-loop
  unstable plant and controller;
* the flown controller (:func:`flown_controller`): the on-board runtime itself, stepped at
  constant velocities (inside the grid, on a grid point, clamped below and above), gives the
  same commands as the state-space recursion with the interpolated matrices;
* the independent loop assembly against ``verification.loop_margins`` (same continuous
  controller, Padé delay, no hold: the same numbers);
* a dispersed corner perturbs plant, actuator and delay as the simulation applies a
  scenario's deviations (vega_sim.plant_step.parameters_at, vega_sim.assembly), the
  controller staying on the nominal schedule;
* the CLI: bad arguments are one line with exit status 2; a short run writes its files.
"""

import json
import math
from pathlib import Path
from types import SimpleNamespace

import control
import numpy as np
import pytest

from vega_loops import margins as M

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config" / "lpv_controller.npz"
W = np.geomspace(1e-3, 1e3, 40_000)


# ------------------------------------------------------------------- margins, textbook loops
def _stable(num, den, g):
    num = np.concatenate([np.zeros(len(den) - len(num)), num])
    return bool(np.max(np.roots(np.polyadd(den, g * num)).real) < 0.0)


def _conditional_loop():
    """L = k (s + 1)² / (s³ (s/20 + 1)²): phase crossovers at ω² − 19ω + 20 = 0 (1.12 and
    17.88 rad/s), conditionally stable; k puts the gain crossover near 4 rad/s."""
    num = 8.0 * np.polymul([1, 1], [1, 1])
    den = np.polymul([1, 0, 0, 0], np.polymul([1 / 20, 1], [1 / 20, 1]))
    return num, den


def test_conditionally_stable_loop_against_python_control_and_root_locus():
    num, den = _conditional_loop()
    L = np.polyval(num, 1j * W) / np.polyval(den, 1j * W)
    got = M.extract_margins(W, L)
    gm, pm, _, wpc, wgc = control.stability_margins(control.tf(num, den), returnall=True)[:5]
    gm, wpc = np.asarray(gm), np.asarray(wpc)
    low, high = gm < 1, gm > 1
    assert got["w_gm_low_radps"] == pytest.approx(wpc[low][0], rel=1e-4)
    assert got["w_gm_high_radps"] == pytest.approx(wpc[high][0], rel=1e-4)
    assert got["w_gm_low_radps"] == pytest.approx((19 - math.sqrt(281)) / 2, rel=1e-4)
    assert got["gm_low_db"] == pytest.approx(-20 * np.log10(gm[low][0]), abs=2e-3)
    assert got["gm_high_db"] == pytest.approx(20 * np.log10(gm[high][0]), abs=2e-3)
    assert got["pm_deg"] == pytest.approx(np.asarray(pm)[0], abs=2e-3)
    assert got["n_gain_crossovers"] == len(wgc) == 1
    # the meaning of the gain margins: the closed loop is stable exactly between the limits
    g_lo, g_hi = 10 ** (-got["gm_low_db"] / 20), 10 ** (got["gm_high_db"] / 20)
    for g, stable in ((g_lo * 1.001, True), (g_lo * 0.999, False),
                      (g_hi * 0.999, True), (g_hi * 1.001, False), (1.0, True)):
        assert _stable(num, den, g) is stable


def test_delayed_integrator_closed_form():
    """L = k e^{−sτ}/s: PM = 90° − kτ (rad→deg) at ω = k; GM = ω₁₈₀/k at ω₁₈₀ = π/(2τ)."""
    k, tau = 2.0, 0.1
    L = k * np.exp(-1j * W * tau) / (1j * W)
    got = M.extract_margins(W, L)
    assert got["pm_deg"] == pytest.approx(90.0 - math.degrees(k * tau), abs=1e-3)
    assert got["w_pm_radps"] == pytest.approx(k, rel=1e-5)
    assert got["gm_high_db"] == pytest.approx(20 * math.log10(math.pi / (2 * tau) / k), abs=1e-3)
    assert got["gm_low_db"] == math.inf                 # no low-frequency phase crossover
    # a second phase crossover 2π/τ·(…) further up: the smallest margin is the first one
    assert got["w_gm_high_radps"] == pytest.approx(math.pi / (2 * tau), rel=1e-5)


@pytest.mark.parametrize("gain, phase_stabilised", [(0.005, False), (0.1, True)])
def test_bending_peak_and_band_margins(gain, phase_stabilised):
    """A lightly damped mode ω₀ = 30 rad/s, ζ = 0.008, behind an all-pass: the peak of the band
    is gain/(2ζ√(1−ζ²)) (closed form); above −6 dB the band's crossover margins are those
    python-control finds there."""
    w0, z = 30.0, 0.008
    num = np.polymul([gain * w0 ** 2], [-1 / 60, 1])
    den = np.polymul([1, 2 * z * w0, w0 ** 2], [1 / 60, 1])
    L = np.polyval(num, 1j * W) / np.polyval(den, 1j * W)
    got = M.extract_margins(W, L, omega_modes=(w0, 3 * w0))
    peak = 20 * math.log10(gain / (2 * z * math.sqrt(1 - z * z)))
    assert got["b1_peak_db"] == pytest.approx(peak, abs=0.01)
    assert got["b1_w_peak_radps"] == pytest.approx(w0 * math.sqrt(1 - 2 * z * z), rel=1e-3)
    assert got["b1_phase_stabilised"] is phase_stabilised
    gm, pm, _, wpc, wgc = (np.asarray(x) for x in
                           control.stability_margins(control.tf(num, den), returnall=True)[:5])
    band = lambda w: (w >= 0.8 * w0) & (w <= 1.2 * w0)  # noqa: E731
    if np.any(band(wgc)):
        assert got["b1_pm_deg"] == pytest.approx(np.min(np.abs(pm[band(wgc)])), abs=0.05)
    else:
        assert got["b1_pm_deg"] == math.inf
    assert got["b1_gm_db"] == pytest.approx(np.min(np.abs(20 * np.log10(gm[band(wpc)]))), abs=0.01)
    assert got["gm_low_db"] == got["gm_high_db"] == got["pm_deg"] == math.inf   # rigid band


# ------------------------------------------------------------ discrete controller and hold
def test_discrete_response_static_gain_and_first_order_filter():
    T = 0.02
    w = np.array([0.0, 0.3, 3.0, 30.0, 100.0, math.pi / T])
    K = M.discrete_response([[0.5]], [[0.0, 0.0]], [[0.0]], [[2.0, -1.0]], w, T)
    assert np.allclose(K[:, 0, :], [[2.0, -1.0]] * len(w), atol=1e-14)
    a, b, c, d = 0.9, 0.3, -2.0, 0.25
    K = M.discrete_response([[a]], [[b]], [[c]], [[d]], w, T)[:, 0, 0]
    hand = c * b / (np.exp(1j * w * T) - a) + d
    assert np.allclose(K, hand, rtol=1e-12)
    assert K[0] == pytest.approx(c * b / (1 - a) + d)


def test_zoh_response_is_sinc_with_half_sample_delay():
    T = 0.02
    w = np.array([0.0, 1.0, 30.0, 75.0, math.pi / T])
    H = M.zoh_response(w, T)
    x = w * T / 2
    sinc = np.where(x == 0, 1.0, np.sin(x) / np.where(x == 0, 1.0, x))
    assert np.allclose(np.abs(H), sinc, rtol=1e-12)
    assert np.allclose(np.angle(H), -x, atol=1e-12)
    assert abs(H[-1]) == pytest.approx(2 / math.pi)


# ----------------------------------------------------------------------- sampled-data model
def test_sampled_data_model_hand_formulas():
    T, tau = 0.02, 0.039
    theta = tau - T                                          # d = 1, θ = 19 ms
    a = 3.0
    Phi, G0, G1, d = M.sampled_data_model(np.array([[-a]]), np.array([[1.0]]), T, tau)
    assert d == 1
    assert Phi[0, 0] == pytest.approx(math.exp(-a * T))
    assert G0[0, 0] == pytest.approx((1 - math.exp(-a * (T - theta))) / a)
    assert G1[0, 0] == pytest.approx(math.exp(-a * (T - theta)) * (1 - math.exp(-a * theta)) / a)
    Phi, G0, G1, d = M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), T, tau)
    assert (Phi[0, 0], G0[0, 0], G1[0, 0], d) == pytest.approx((1.0, T - theta, theta, 1))


def test_sampled_data_model_matches_a_simulation_of_the_held_delayed_command():
    """Commands computed at kT, applied from kT + 39 ms and held for T (vega_bus.timing), on a
    2-state system integrated exactly at 1 ms: the samples x(kT) equal the discrete model."""
    from scipy.linalg import expm

    A = np.array([[0.0, 1.0], [-40.0, -3.0]])
    B = np.array([[0.0], [2.0]])
    T, tau, h = 0.02, 0.039, 0.001
    model = M.sampled_data_model(A, B, T, tau)
    Phi, G0, G1, d = model
    rng = np.random.default_rng(1)
    u = rng.standard_normal(60)
    aug = np.zeros((3, 3))
    aug[:2, :2], aug[:2, 2:] = A, B
    E = expm(aug * h)
    x = np.zeros(2)
    samples = []
    for k_ms in range(0, 60 * 20):
        if k_ms % 20 == 0:
            samples.append(x.copy())
        j = math.floor((k_ms - 39) / 20)                 # command in force during this ms
        uj = u[j] if j >= 0 else 0.0
        x = E[:2, :2] @ x + E[:2, 2] * uj
    xd = np.zeros(2)
    hist = {}
    for k in range(60):
        assert np.allclose(xd, samples[k], atol=1e-12 * (1 + np.abs(samples[k]).max()))
        ud = u[k - d] if k - d >= 0 else 0.0
        ud1 = u[k - d - 1] if k - d - 1 >= 0 else 0.0
        xd = Phi @ xd + G0[:, 0] * ud + G1[:, 0] * ud1
        hist[k] = xd
    assert np.abs(np.array(samples)).max() > 1e-3      # the check saw a moving state


def _static(k):
    return (np.array([[0.0]]), np.array([[0.0]]), np.array([[0.0]]), np.array([[k]]))


@pytest.mark.parametrize("delay_steps, theta, limit", [(0, 0.0, 2.0), (1, 0.0, 1.0),
                                                       (0, 0.5, 2.0)])
def test_stability_count_integrator_with_delay(delay_steps, theta, limit):
    """Plant 1/s, u = −k y, delay (d + θ/T)·T: the characteristic polynomial by hand,
    z^{d+1}(z − 1) … with roots counted outside the unit circle; stable for 0 < kT < limit."""
    T = 0.02
    tau = (delay_steps + theta) * T
    model = M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), T, tau)
    C = np.array([[1.0]])
    for kT in (0.2, 0.9, 0.99 * limit, 1.01 * limit, 1.5 * limit, 3.0):
        k = kT / T
        # x_{k+1} = x_k + (T−θT) u_{k−d} + θT u_{k−d−1}, u = −k x
        g0, g1 = (1 - theta) * T, theta * T
        poly = np.zeros(delay_steps + 3)
        poly[0], poly[1] = 1.0, -1.0                      # z^{d+2} − z^{d+1}
        poly[-2] += k * g0
        poly[-1] += k * g1
        expected = int(np.sum(np.abs(np.roots(poly)) > 1 + 1e-9))
        got = M.sampled_data_stability(model, C, _static(k), sign=-1.0)
        assert got["n_unstable"] == got["n_unstable_nyquist"] == expected, kT
        assert (expected == 0) is (kT < limit)
        assert got["n_open_unstable"] == 0


def test_stability_count_unstable_plant_and_unstable_controller():
    """Open-loop unstable plant 1/(s − a) (P = 1), static gain: the closed-loop pole is
    e^{aT} − k(e^{aT} − 1)/a. Then an integrator plant with an unstable first-order controller
    K(z) = cb/(z − 1.05) + dd: (z − 1)(z − 1.05) + T(cb + dd(z − 1.05)) by hand."""
    T, a = 0.02, 2.0
    model = M.sampled_data_model(np.array([[a]]), np.array([[1.0]]), T, 0.0)
    C = np.array([[1.0]])
    e = math.exp(a * T)
    for k in (0.5, 1.0, 2.5, 50.0, 120.0, 300.0):
        pole = e - k * (e - 1) / a
        got = M.sampled_data_stability(model, C, _static(k), sign=-1.0)
        assert got["n_open_unstable"] == 1
        assert got["n_unstable"] == got["n_unstable_nyquist"] == int(abs(pole) > 1), k
    model = M.sampled_data_model(np.array([[0.0]]), np.array([[1.0]]), T, 0.0)
    for cb, dd in ((-0.5, 5.0), (2.0, 20.0), (-3.0, 60.0), (0.5, 120.0)):
        K = (np.array([[1.05]]), np.array([[cb]]), np.array([[1.0]]), np.array([[dd]]))
        poly = np.polyadd(np.polymul([1, -1], [1, -1.05]), T * np.array([dd, cb - 1.05 * dd]))
        expected = int(np.sum(np.abs(np.roots(poly)) > 1 + 1e-9))
        got = M.sampled_data_stability(model, C, K, sign=-1.0)
        assert got["n_open_unstable"] == 1
        assert got["n_unstable"] == got["n_unstable_nyquist"] == expected, (cb, dd)


# -------------------------------------------------------------- the flown controller
def _runtime_commands(table, v, inputs):
    from vega_gnc.controller_runtime import ControllerRuntime, Measurement

    rt = ControllerRuntime(table)
    names = {"theta_ins_rad": 0, "theta_dot_ins_radps": 1, "z_ins_m": 2, "z_dot_ins_mps": 3}
    out = []
    for k, y in enumerate(inputs):
        full = [0.0] * 4
        for name, value in zip(table.input_names, y):
            full[names[name]] = float(value)
        cmd = rt.step(Measurement(0.02 * (k + 1), *full, velocity_mps=v))
        out.append(cmd.deflection_cmd_rad)
    return np.array(out)


def _recursion(K, sign, inputs):
    Ad, Bd, Cd, Dd = K
    x = np.zeros(Ad.shape[0])
    out = []
    for y in inputs:
        ys = sign * np.asarray(y)
        out.append((Cd @ x + Dd @ ys).item())
        x = Ad @ x + Bd @ ys
    return np.array(out)


@pytest.mark.parametrize("which", ["shipped", "pd"])
def test_flown_controller_is_what_the_runtime_flies(which, table, tmp_path):
    """The runtime stepped at constant velocity gives the commands of the recursion with
    flown_controller's matrices: shipped table (sign −1, two ρ̇ slices) and the PD fixture
    table (sign +1, no ρ̇ slice); below, inside, on and above the grid."""
    if which == "pd":
        from fixture_tables import write_pd_table

        table = write_pd_table(tmp_path / "pd.npz")
    g = table.grid_v_mps
    rng = np.random.default_rng(7)
    inputs = 1e-4 * rng.standard_normal((40, len(table.input_names)))
    for v in (0.5 * g[0], float(g[3]), 0.3 * g[5] + 0.7 * g[6], 1.5 * g[-1]):
        K, v_sched, clamped = M.flown_controller(table, v)
        assert clamped is not (g[0] <= v <= g[-1])
        assert v_sched == min(max(v, g[0]), g[-1])
        got = _recursion(K, table.measurement_sign, inputs)
        want = _runtime_commands(table, v, inputs)
        assert np.max(np.abs(want)) > 0
        assert np.allclose(got, want, rtol=1e-9, atol=1e-15 * np.max(np.abs(want))), v


# -------------------------------------------------------- the assembly vs loop_margins
@pytest.mark.slow
def test_plant_assembly_agrees_with_verification_loop_margins(table, context):
    """verification.loop_margins (plant_for_simulation: its own actuator and Padé-2 delay in
    the interconnection, continuous controller, no hold) and this module's independent
    assembly (linear_model + linear_actuator_ss) with the same continuous controller and the
    same Padé delay give the same rigid-body margins and bending peaks."""
    from vega_model.actuator import ActuatorParams
    from vega_model.delay import pade_ss

    from vega_lpv.verification import loop_margins

    rate = M.runtime_rate(table)
    fake = SimpleNamespace(rho=table.grid_v_mps,
                           controller=lambda v, r: table.interpolate(v, r, discrete=False))
    for t in (30.0, 60.0):
        ref = loop_margins(fake, context, t, rate).as_dict()
        p = context.parameters(t)
        A, B, C = M.plant_loop_ss(p, ActuatorParams.from_vehicle(context.vehicle),
                                  table.input_names)
        w = M.frequency_grid(p.omega_radps, table.dt_s)
        v = min(max(p.v_mps, table.grid_v_mps[0]), table.grid_v_mps[-1])
        Kc = M.ss_response(*table.interpolate(v, rate, discrete=False), w)[:, 0, :]
        G = M.ss_response(A, B, C, np.zeros((C.shape[0], 1)), w)[:, :, 0]
        pade = M.ss_response(*pade_ss(M.total_delay_s(context.vehicle), 2), w)[:, 0, 0]
        L = -table.measurement_sign * np.sum(Kc * G, axis=1) * pade
        got = M.extract_margins(w, L, p.omega_radps)
        assert got["gm_low_db"] == pytest.approx(-ref["gm_low_db"], abs=0.05)
        assert got["gm_high_db"] == pytest.approx(ref["gm_high_db"], abs=0.05)
        assert got["pm_deg"] == pytest.approx(ref["pm_deg"], abs=0.15)
        assert got["b1_peak_db"] == pytest.approx(ref["bending1_gain_db"], abs=0.1)
        assert got["b2_peak_db"] == pytest.approx(ref["bending2_gain_db"], abs=0.1)


# -------------------------------------------------------------------------- dispersion
def test_dispersed_corner_perturbs_as_the_simulation_does(table, context):
    from vega_model.uncertainty import UncertaintySet
    from vega_sim.assembly import loop_timing
    from vega_sim.plant_step import parameters_at
    from vega_sim.scenario import Scenario

    uset = UncertaintySet.from_vehicle(context.vehicle)
    corners = M.dispersed_corners(uset)
    assert len(corners) == 1 + 2 ** 9 + 2 ** 7 + 1
    assert corners[0] == uset.nominal()
    assert corners[-1] == {**uset.nominal(), "jyy": pytest.approx(4.6e6 / 5.88e6 - 1)}
    for dev in corners[1:-1]:
        for name, value in dev.items():
            assert value == 0.0 or value in (uset[name].lower, uset[name].upper)
    assert [M.corner_family(i) for i in (0, 1, 512, 513, 640, 641)] == [
        "nominal", "rigid", "rigid", "bending", "bending", "offnominal"]
    t = 47.5
    p0 = context.parameters(t)
    for index in (1, 300, 600):
        dev = corners[index]
        p, act, tau = M.corner_plant(context, t, dev)
        assert p == parameters_at(context, 47_500, dev)
        scenario = Scenario(name="corner", description="", t_start_s=0.0, t_end_s=1.0,
                            uncertainty=tuple(sorted(dev.items())))
        assert tau == pytest.approx(loop_timing(scenario, context).total_latency_ms / 1000)
        assert act.wn_radps == pytest.approx(
            context.vehicle["actuator.natural_frequency_radps"] * (1 + dev["actuator"]))
        assert p.v_mps == pytest.approx(p0.v_mps * (1 + dev["velocity"]))
        assert p.f1_hz == pytest.approx(p0.f1_hz * (1 + dev["bending_frequency_1"]))
        row = M.analyse_time(table, context, t, [(index, dev)], nyquist=False)[0]
        # the controller knows only the nominal schedule
        assert row["v_sched_mps"] == pytest.approx(p0.v_mps)
        assert row["v_plant_mps"] == pytest.approx(p.v_mps)
        assert row["delay_s"] == tau


# --------------------------------------------------------------------------------- CLI
@pytest.mark.parametrize("argv, needle", [
    (["--at", "abc"], "--at 'abc'"),
    (["--at", "5:1:1"], "STOP >= START"),
    (["--at", "500"], "outside the flight-condition table"),
    (["--workers", "0"], "--workers"),
    (["--at", "47", "--table", "/nonexistent/table.npz"], "no such file"),
])
def test_cli_bad_arguments_exit_2_one_line(argv, needle, capsys):
    from vega_cli import cli

    assert cli.main(["margins", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vega: error: ") and needle in err
    assert err.count("\n") == 1


@pytest.mark.slow
def test_cli_short_range_writes_files(tmp_path, capsys):
    from vega_cli import cli

    out = tmp_path / "m"
    status = cli.main(["margins", "--table", str(SHIPPED), "--at", "47:48:0.5", "--out",
                       str(out), "--workers", "1"])
    assert status in (0, 1)
    text = capsys.readouterr().out
    assert "nominal plant" in text and "47.5" in text
    rows = (out / "margins.csv").read_text().splitlines()
    assert rows[0].split(",")[:3] == ["t_s", "corner", "v_sched_mps"]
    assert len(rows) == 1 + 3
    summary = json.loads((out / "margins.json").read_text())
    assert summary["times_s"] == {"first": 47.0, "last": 48.0, "n": 3}
    assert set(summary["nominal"]) >= {"gm_low_db", "gm_high_db", "pm_deg", "bending_1",
                                       "bending_2", "stability"}
    assert summary["nominal"]["nyquist_disagreements"] == 0
    assert status == (0 if all(v["pass"] for v in summary["nominal"].values()
                               if isinstance(v, dict) and "pass" in v) else 1)
    for name in ("margins_over_time.png", "nichols_max_q.png"):
        assert (out / name).stat().st_size > 10_000


@pytest.mark.slow
def test_cli_dispersed_one_time(tmp_path, capsys):
    from vega_cli import cli

    out = tmp_path / "d"
    cli.main(["margins", "--table", str(SHIPPED), "--at", "60", "--dispersed", "--out",
              str(out), "--workers", "1"])
    capsys.readouterr()
    summary = json.loads((out / "margins.json").read_text())
    disp = summary["dispersed"]
    assert disp["corners"]["n"] == 642
    fams = disp["families"]
    assert fams["all"]["requirements"]["stability"]["n_loops"] == 642
    assert fams["rigid"]["n_plants_per_time"] == 512
    assert fams["bending"]["n_plants_per_time"] == 128
    assert fams["offnominal"]["n_plants_per_time"] == 1
    rows = (out / "margins.csv").read_text().splitlines()
    assert len(rows) == 1 + 642
    worst = (out / "margins_worst.csv").read_text().splitlines()
    assert len(worst) == 2
    w = fams["rigid"]["requirements"]["pm_deg"]
    assert w["family"] == "rigid" and w["t_s"] == 60.0
    assert set(w["deviations"]) <= set(M.RIGID_CORNER_NAMES)
