"""Loop margins of the synthesis report (``verification.loop_margins``) on loops with KNOWN margins.

``loop_margins`` breaks the loop at the actuator input: L(jω) = −K(jω) P_yu(jω), with P_yu the
last input (u) to the last four outputs (y) of ``plant_for_simulation`` and K the controller
the synthesis result gives at the clamped velocity. Here both are replaced by textbook
systems (``plant_for_simulation`` is monkeypatched; the result and the context are minimal
objects following what ``loop_margins`` reads), so that L is a transfer function whose margins
are known independently of the code under test:

* hand-derived closed forms (phase crossovers of k(s+a)²/(s³(s/p+1)²) solve
  ω² − (p − a)ω + ap = 0; gain crossovers are the roots of a polynomial);
* the characteristic polynomial den + g·num of the loop scaled by g, whose roots say for
  which g the closed loop is stable — the very meaning of the low and high gain margins;
* python-control ``stability_margins`` (a different implementation);
* the transfer function evaluated from its polynomials (``np.polyval``), not from the
  state-space matrices the code under test uses.

The synthesis report (pipeline.run_synthesis → ``rep.margins``) stores exactly
``loop_margins(...).as_dict()``; the dB conversion is checked too.
"""

import math
from types import SimpleNamespace

import control
import numpy as np
import pytest
from scipy.optimize import brentq

from vega_lpv import verification
from vega_lpv.verification import loop_margins

DEFAULT_W = np.logspace(-3, 3.3, 6000)          # loop_margins' default grid
DENSE_W = np.logspace(-1, 2.2, 80_000)            # relative spacing 9.2e-5
# Relative spacing of the default grid: loop_margins reads the sample left of a crossing, so a
# quantity with log-slope σ is off by at most σ·STEP (σ ≤ 3 on these loops away from resonances).
STEP = 10 ** (6.3 / 5999) - 1.0                  # 0.24 %

# y = COL · G(s) u, K(s) = lead(s) · ROW: L = −K P = −(ROW·COL) lead G = lead G.
COL = np.array([1.0, 0.5, -1.0, 2.0])
ROW = np.array([-0.25, -0.5, 0.25, -0.125])
assert ROW @ COL == -1.0


# ----------------------------------------------------------------------------- loop building
def _poly(*factors):
    out = np.array([1.0])
    for f in factors:
        out = np.polymul(out, np.asarray(f, dtype=float))
    return out


def _bending(w0, zeta_num, zeta_den):
    """Lightly damped pole pair with a better damped zero pair at the same frequency: a
    resonance peak of ≈ ζ_num/ζ_den at ω0 (a bending mode as the loop sees it)."""
    return [1.0, 2 * zeta_num * w0, w0 ** 2], [1.0, 2 * zeta_den * w0, w0 ** 2]


class Loop:
    """Plant G = num_g/den_g (SISO) and controller lead = num_k/den_k as polynomials."""

    def __init__(self, num_g, den_g, num_k, den_k, omega=(50.0, 100.0)):
        self.num_g, self.den_g = np.asarray(num_g, float), np.asarray(den_g, float)
        self.num_k, self.den_k = np.asarray(num_k, float), np.asarray(den_k, float)
        self.num = np.polymul(self.num_g, self.num_k)
        self.den = np.polymul(self.den_g, self.den_k)
        self.omega = tuple(omega)

    def L(self, w):
        """L(jω) from the polynomials (independent of any state-space realisation)."""
        s = 1j * np.asarray(w, dtype=float)
        return np.polyval(self.num, s) / np.polyval(self.den, s)

    def closed_loop_stable(self, g):
        """Roots of den + g·num (unity negative feedback around g·L) all in the open LHP."""
        num = np.concatenate([np.zeros(self.den.size - self.num.size), self.num])
        return bool(np.max(np.roots(self.den + g * num).real) < 0.0)

    def tf(self):
        return control.tf(self.num, self.den)

    def is_lower_limit(self, g, rel=1e-3):
        """Stable just above gain factor g, unstable just below."""
        return self.closed_loop_stable(g * (1 + rel)) and not self.closed_loop_stable(g * (1 - rel))

    def is_upper_limit(self, g, rel=1e-3):
        """Stable just below gain factor g, unstable just above."""
        return self.closed_loop_stable(g * (1 - rel)) and not self.closed_loop_stable(g * (1 + rel))


def _generalized(loop, seed=0):
    """A plant object with 3 exogenous inputs before u and 2 performance outputs before y
    (random, must be ignored), and y = COL · G u; the controller K = lead · ROW."""
    A, b, c, d = (np.asarray(m, float)
                  for m in control.ssdata(control.tf2ss(loop.num_g, loop.den_g)))
    n = A.shape[0]
    rng = np.random.default_rng(seed)
    B = np.hstack([rng.standard_normal((n, 3)), b])
    C = np.vstack([rng.standard_normal((2, n)), np.outer(COL, c)])
    D = np.zeros((6, 4))
    D[:, :3] = rng.standard_normal((6, 3))
    D[:2, 3] = rng.standard_normal(2)
    D[2:, 3] = COL * d.item()
    plant = SimpleNamespace(A=A, B=B, C=C, D=D)
    Ak, bk, ck, dk = (np.asarray(m, float)
                      for m in control.ssdata(control.tf2ss(loop.num_k, loop.den_k)))
    K = (Ak, bk @ ROW[None, :], ck, dk.item() * ROW[None, :])
    return plant, K


class FakeResult:
    """What loop_margins reads from a synthesis result: the grid ``rho`` and ``controller``."""

    def __init__(self, K, rho=(100.0, 1000.0)):
        self.rho = np.array(rho, dtype=float)
        self.K = K
        self.calls = []

    def controller(self, rho, rho_dot):
        self.calls.append((rho, rho_dot))
        return self.K


def _margins(monkeypatch, loop, v_mps=500.0, rate=20.0, rho=(100.0, 1000.0), **kw):
    plant, K = _generalized(loop)
    calls = []

    def fake_plant(t_s, context):
        calls.append((t_s, context))
        return plant

    monkeypatch.setattr(verification, "plant_for_simulation", fake_plant)
    params = SimpleNamespace(v_mps=v_mps, omega_radps=loop.omega)
    context = SimpleNamespace(parameters=lambda t: params)
    result = FakeResult(K, rho)
    m = loop_margins(result, context, 40.0, rate, **kw)
    assert calls == [(40.0, context)]
    return m, result


# ----------------------------------------------------------------------------- references
FINE_W = np.logspace(-3, 3.3, 400_000)


def _crossings(loop, w=FINE_W):
    """Independent reference: phase crossovers (Im L = 0, Re L < 0) with |L| there, and gain
    crossovers (|L| = 1) with the phase margin 180° − |∠L|, refined by brentq."""
    Lw = loop.L(w)
    phase, gain = [], []
    for k in np.nonzero(np.sign(Lw.imag[:-1]) != np.sign(Lw.imag[1:]))[0]:
        if Lw.real[k] < 0:
            wp = brentq(lambda x: loop.L(x).imag, w[k], w[k + 1], xtol=1e-14, rtol=1e-14)
            phase.append((wp, abs(loop.L(wp))))
    logmag = np.log(np.abs(Lw))
    for k in np.nonzero(np.sign(logmag[:-1]) != np.sign(logmag[1:]))[0]:
        wc = brentq(lambda x: np.log(abs(loop.L(x))), w[k], w[k + 1], xtol=1e-14, rtol=1e-14)
        gain.append((wc, 180.0 - abs(math.degrees(np.angle(loop.L(wc))))))
    return phase, gain


def _conditional_loop(k=4.0, a=1.0, p=30.0, omega=(50.0, 100.0), bending=()):
    """L = k (s+a)² / (s³ (s/p+1)²) · Π bending: a triple integrator (an unstable rigid body's
    phase) with a double lead — conditionally stable like the launcher's loop."""
    num_g, den_g = _poly(*[b[0] for b in bending]), _poly([1, 0, 0, 0], *[b[1] for b in bending])
    num_k = k * _poly([1, a], [1, a])
    den_k = _poly([1 / p, 1], [1 / p, 1])
    return Loop(num_g, den_g, num_k, den_k, omega)


K_GAIN, A_ZERO, P_POLE = 4.0, 1.0, 30.0


def _hand_conditional():
    """Hand derivation for L = k(s+a)²/(s³(s/p+1)²), k = 4, a = 1, p = 30.

    ∠L = −270° + 2 atan(ω/a) − 2 atan(ω/p) = −180°  ⇔  atan(ω/a) − atan(ω/p) = 45°
    ⇔ ω(1/a − 1/p) = 1 + ω²/(ap)  ⇔  ω² − (p − a) ω + ap = 0.
    |L| = 1 ⇔ k(ω² + a²) = ω³(1 + ω²/p²) ⇔ ω⁵/p² + ω³ − kω² − k a² = 0.
    """
    k, a, p = K_GAIN, A_ZERO, P_POLE
    disc = math.sqrt((p - a) ** 2 - 4 * a * p)
    w_low, w_high = ((p - a) - disc) / 2, ((p - a) + disc) / 2

    def mag(w):
        return k * (w * w + a * a) / (w ** 3 * (1 + w * w / p ** 2))

    roots = np.roots([1 / p ** 2, 0, 1, -k, 0, -k * a * a])
    wc = float(max(r.real for r in roots if abs(r.imag) < 1e-9 and r.real > 0))
    pm = 180.0 - 270.0 + 2 * math.degrees(math.atan(wc / a)) - 2 * math.degrees(math.atan(wc / p))
    return dict(w_low=w_low, w_high=w_high, gm_low=1 / mag(w_low), gm_high=1 / mag(w_high),
                wc=wc, pm=pm)


# ----------------------------------------------------------------------------- tests
def test_hand_reference_agrees_with_python_control_and_closed_loop_roots():
    """The references themselves: hand formulas = python-control = the root locus."""
    hand = _hand_conditional()
    loop = _conditional_loop()
    gm, pm, _, wpc, wgc, _ = control.stability_margins(loop.tf(), returnall=True)
    assert sorted(wpc) == pytest.approx([hand["w_low"], hand["w_high"]], rel=1e-6)
    assert sorted(gm) == pytest.approx([hand["gm_low"], hand["gm_high"]], rel=1e-6)
    assert list(wgc) == pytest.approx([hand["wc"]], rel=1e-6)
    assert list(pm) == pytest.approx([hand["pm"]], abs=1e-6)
    # the meaning: stable exactly for gains between the two margins
    g_lo, g_hi = hand["gm_low"], hand["gm_high"]
    assert g_lo == pytest.approx(0.14407, rel=1e-4) and g_hi == pytest.approx(13.0141, rel=1e-4)
    assert hand["pm"] == pytest.approx(47.158, abs=1e-3)
    assert hand["wc"] == pytest.approx(4.15243, rel=1e-5)
    assert loop.closed_loop_stable(1.0)
    assert loop.is_lower_limit(g_lo) and loop.is_upper_limit(g_hi)


@pytest.mark.slow
def test_conditionally_stable_loop_default_grid(monkeypatch):
    """The report's call (default grid): every number against the hand derivation."""
    hand = _hand_conditional()
    m, _ = _margins(monkeypatch, _conditional_loop())
    # gain margins are factors: the reduction (< 1) and the increase (> 1), not swapped
    assert m.gm_low == pytest.approx(hand["gm_low"], rel=3 * STEP)
    assert m.gm_high == pytest.approx(hand["gm_high"], rel=3 * STEP)
    # phase margin is the distance of ∠L from −180° at the crossover (47.2°, not 180° − PM)
    assert m.pm_deg == pytest.approx(hand["pm"], abs=0.3)
    assert m.crossover_radps == pytest.approx(hand["wc"], rel=2 * STEP)
    d = m.as_dict()
    assert d["gm_low_db"] == pytest.approx(20 * math.log10(hand["gm_low"]), abs=0.1)
    assert d["gm_high_db"] == pytest.approx(20 * math.log10(hand["gm_high"]), abs=0.1)
    assert d["gm_low_db"] == pytest.approx(-16.83, abs=0.1)       # by hand: 1/|L(j1.0743)|
    assert d["gm_high_db"] == pytest.approx(22.29, abs=0.1)        # by hand: 1/|L(j27.93)|
    assert d["pm_deg"] == m.pm_deg and d["crossover_radps"] == m.crossover_radps
    assert d["t_s"] == 40.0


@pytest.mark.slow
def test_conditionally_stable_loop_dense_grid_is_tight(monkeypatch):
    """With a dense frequency grid the sampling error vanishes: 5e-4 relative (5 grid steps)."""
    hand = _hand_conditional()
    m, _ = _margins(monkeypatch, _conditional_loop(), w_radps=DENSE_W)
    assert m.gm_low == pytest.approx(hand["gm_low"], rel=5e-4)
    assert m.gm_high == pytest.approx(hand["gm_high"], rel=5e-4)
    assert m.pm_deg == pytest.approx(hand["pm"], abs=1e-3)
    assert m.crossover_radps == pytest.approx(hand["wc"], rel=5e-4)


@pytest.mark.slow
def test_margins_mean_what_they_say_for_the_closed_loop(monkeypatch):
    """Scaling the loop by the reported factors puts the closed loop on the stability boundary:
    just inside both margins stable, just outside unstable (roots of den + g·num)."""
    loop = _conditional_loop()
    m, _ = _margins(monkeypatch, loop, w_radps=DENSE_W)
    assert loop.is_lower_limit(m.gm_low) and loop.is_upper_limit(m.gm_high)


@pytest.mark.slow
def test_open_loop_stable_textbook_loop(monkeypatch):
    """L = 2/(s(s+1)(s+2)): phase −180° at ω = √2 where |L| = 2/6, so GM = 3 (9.54 dB) and no
    lower limit; |L| = 1 at x = ω² root of x³ + 5x² + 4x − 4 = 0; PM = 180° − 90° − atan ω −
    atan(ω/2) (Ogata's example: 32.6°)."""
    loop = Loop([2.0], _poly([1, 0], [1, 1], [1, 2]), [1.0], [1.0])
    x = max(r.real for r in np.roots([1, 5, 4, -4]) if abs(r.imag) < 1e-12)
    wc = math.sqrt(x)
    pm = 90.0 - math.degrees(math.atan(wc)) - math.degrees(math.atan(wc / 2))
    assert pm == pytest.approx(32.613, abs=1e-3)
    m, _ = _margins(monkeypatch, loop)
    assert m.gm_high == pytest.approx(3.0, rel=3 * STEP)
    assert m.as_dict()["gm_high_db"] == pytest.approx(20 * math.log10(3.0), abs=0.05)
    assert math.isnan(m.gm_low)                       # no gain reduction limit
    assert m.pm_deg == pytest.approx(pm, abs=0.2)
    assert m.crossover_radps == pytest.approx(wc, rel=2 * STEP)
    dense, _ = _margins(monkeypatch, loop, w_radps=DENSE_W)
    assert dense.gm_high == pytest.approx(3.0, rel=5e-4)
    assert dense.pm_deg == pytest.approx(pm, abs=5e-3)


@pytest.mark.slow
def test_bending_peaks_are_the_maximum_in_each_window(monkeypatch):
    """Two resonances (ω1 = 150, ω2 = 400 rad/s, peaks of different height): the reported
    gain is the MAXIMUM of |L| within ±20 % of each bending frequency of the parameters,
    in mode order — the window's minimum is 20+ dB lower."""
    b1, b2 = _bending(150.0, 0.05, 0.005), _bending(400.0, 0.02, 0.004)
    loop = _conditional_loop(omega=(150.0, 400.0), bending=(b1, b2))
    m, _ = _margins(monkeypatch, loop)
    mag_db = 20 * np.log10(np.abs(loop.L(DEFAULT_W)))
    expected, lowest = [], []
    for w0 in (150.0, 400.0):
        window = (DEFAULT_W > 0.8 * w0) & (DEFAULT_W < 1.2 * w0)
        expected.append(mag_db[window].max())
        lowest.append(mag_db[window].min())
    assert m.bending_gain_db == pytest.approx(tuple(expected), abs=1e-6)
    assert min(e - lo for e, lo in zip(expected, lowest)) > 15.0
    # the continuous peak (hand: |L_rigid(jω_i)| · ζ_num/ζ_den) is what the grid sampled
    rigid = _conditional_loop()
    for got, w0, ratio in zip(m.bending_gain_db, (150.0, 400.0), (10.0, 5.0)):
        hand_db = 20 * math.log10(abs(rigid.L(w0)) * ratio)
        assert got == pytest.approx(hand_db, abs=0.5)
    assert m.bending_gain_db[0] == pytest.approx(-39.8, abs=0.5)   # the two modes not swapped
    assert m.bending_gain_db[1] == pytest.approx(-71.3, abs=0.5)
    d = m.as_dict()
    assert (d["bending1_gain_db"], d["bending2_gain_db"]) == m.bending_gain_db
    # the resonances do not disturb the rigid-body margins (references from the full loop)
    phase, gain = _crossings(loop)
    assert [w for w, _ in phase] == pytest.approx([1.0734, 28.536], rel=1e-3)
    assert m.gm_low == pytest.approx(1 / phase[0][1], rel=3 * STEP)
    assert m.gm_high == pytest.approx(1 / phase[1][1], rel=3 * STEP)
    assert m.pm_deg == pytest.approx(gain[0][1], abs=0.3)


@pytest.mark.slow
def test_phase_margin_is_the_smallest_over_all_gain_crossovers(monkeypatch):
    """A resonance at 12 rad/s that rises above 0 dB (a phase-stabilised mode) adds gain and
    phase crossovers. Closed loop stable (roots). The reported PM is the smallest distance
    from −180° over ALL gain crossovers (15.9° at the last of three, not 54.0° at the first),
    GM_high the smallest increase over the phase crossovers with |L| < 1 (1.497 at 12.8 rad/s,
    not the last one), GM_low the largest reduction limit with |L| > 1."""
    loop = _conditional_loop(omega=(12.0, 100.0), bending=(_bending(12.0, 0.2, 0.05),))
    phase, gain = _crossings(loop)
    assert [w for w, _ in gain] == pytest.approx([4.19516, 11.57667, 12.31774], rel=1e-5)
    assert [p for _, p in gain] == pytest.approx([54.035, 63.437, 15.920], abs=1e-3)
    assert [w for w, _ in phase] == pytest.approx([1.04426, 12.83287, 14.94375, 21.57200],
                                                  rel=1e-5)
    pm_ref, wc_ref = min((abs(p), w) for w, p in gain)
    gm_high_ref = min(1 / g for _, g in phase if g < 1)
    gm_low_ref = max(1 / g for _, g in phase if g > 1)
    # python-control agrees on every crossover and margin
    gm, pm, _, wpc, wgc, _ = control.stability_margins(loop.tf(), returnall=True)
    assert sorted(wgc) == pytest.approx([w for w, _ in gain], rel=1e-5)
    assert sorted(wpc) == pytest.approx([w for w, _ in phase], rel=1e-5)
    assert min(np.abs(pm)) == pytest.approx(pm_ref, abs=1e-4)
    assert sorted(gm)[:2] == pytest.approx([gm_low_ref, gm_high_ref], rel=1e-5)
    # and the root locus: stable between the two margins only
    assert loop.closed_loop_stable(1.0)
    assert loop.is_lower_limit(gm_low_ref) and loop.is_upper_limit(gm_high_ref)
    m, _ = _margins(monkeypatch, loop, w_radps=DENSE_W)
    assert m.pm_deg == pytest.approx(pm_ref, abs=0.05)
    assert m.crossover_radps == pytest.approx(wc_ref, rel=1e-4)
    assert m.gm_high == pytest.approx(gm_high_ref, rel=1e-3)
    assert m.gm_low == pytest.approx(gm_low_ref, rel=1e-3)
    assert m.bending_gain_db[0] > 0.0                 # the mode is above 0 dB (not gain-stabilised)


@pytest.mark.slow
def test_low_gain_margin_is_the_nearest_reduction_limit(monkeypatch):
    """A lightly damped low-frequency mode (1.6 rad/s, below the crossover) makes ∠L cross
    −180° three times with |L| > 1. Reducing the gain destabilises the loop first at the
    largest 1/|L| of these (0.602; roots: stable at 1.001×, unstable at 0.999×), so that is
    GM_low — not the smallest (0.179, the bound of a second, disjoint stable range)."""
    loop = _conditional_loop(omega=(20.0, 100.0), bending=(_bending(1.6, 0.02, 0.05),))
    phase, _ = _crossings(loop)
    reductions = sorted(1 / g for _, g in phase if g > 1)
    assert reductions == pytest.approx([0.17947, 0.26882, 0.60152], rel=1e-4)
    nearest = reductions[-1]
    assert loop.closed_loop_stable(1.0)
    assert loop.is_lower_limit(nearest)
    gm, *_ = control.stability_margins(loop.tf(), returnall=True)
    assert sorted(gm)[:3] == pytest.approx(reductions, rel=1e-5)
    m, _ = _margins(monkeypatch, loop, w_radps=DENSE_W)
    # |L| has a log-slope ≈ 1/(2ζ) = 25 near the mode: 25 grid steps of 9.2e-5 → 0.5 %
    assert m.gm_low == pytest.approx(nearest, rel=5e-3)
    assert m.gm_high == pytest.approx(1 / phase[-1][1], rel=1e-3)
    assert loop.is_lower_limit(m.gm_low, rel=0.01)


@pytest.mark.slow
def test_bending_window_is_plus_minus_20_percent_of_the_parameter_frequency(monkeypatch):
    """The model's bending frequencies are uncertain (Table 2.3: −20/+15 %, −25/+20 %): the
    peak is searched within ±20 % of the frequency the parameters give. Resonances at 1.15×
    and 0.85× the parameter frequencies are found (hand: |L_rigid(jω)|·ζ_num/ζ_den); the
    maximum over the window equals the analytic maximum over the same samples."""
    b1, b2 = _bending(150.0, 0.05, 0.005), _bending(400.0, 0.02, 0.004)
    params = (150.0 / 1.15, 400.0 / 0.85)
    loop = _conditional_loop(omega=params, bending=(b1, b2))
    m, _ = _margins(monkeypatch, loop)
    mag_db = 20 * np.log10(np.abs(loop.L(DEFAULT_W)))
    expected = [mag_db[(DEFAULT_W > 0.8 * w0) & (DEFAULT_W < 1.2 * w0)].max() for w0 in params]
    assert m.bending_gain_db == pytest.approx(tuple(expected), abs=1e-6)
    rigid = _conditional_loop()
    for got, w0, ratio in zip(m.bending_gain_db, (150.0, 400.0), (10.0, 5.0)):
        assert got == pytest.approx(20 * math.log10(abs(rigid.L(w0)) * ratio), abs=0.5)


@pytest.mark.slow
def test_controller_scheduled_at_the_clamped_velocity_and_given_rate(monkeypatch):
    """K is taken at v(t) clamped to the synthesis grid and at the requested ρ̇ slice."""
    loop = _conditional_loop()
    _, inside = _margins(monkeypatch, loop, v_mps=512.5, rate=7.25)
    assert inside.calls == [(512.5, 7.25)]
    _, above = _margins(monkeypatch, loop, v_mps=1500.0, rate=0.0)
    assert above.calls == [(1000.0, 0.0)]
    _, below = _margins(monkeypatch, loop, v_mps=20.0, rate=35.8)
    assert below.calls == [(100.0, 35.8)]


# ----------------------------------------------------------------------------- the real loop
@pytest.fixture(scope="module")
def pd_table(tmp_path_factory):
    from fixture_tables import write_pd_table

    return write_pd_table(tmp_path_factory.mktemp("pd") / "pd.npz")


@pytest.mark.slow
@pytest.mark.parametrize("t_s", [20.0, 40.0, 80.0])
def test_real_plant_margins_match_python_control(pd_table, t_s):
    """The launcher's own loop (plant_for_simulation: rigid body, bending, actuator, delay)
    closed by the fixture PD controller: loop_margins against python-control's
    stability_margins on L = −K·P_yu built from the exported plant matrices (the crossing
    at ω = 0 that python-control lists is below loop_margins' grid), and the meaning of
    the margins checked on the closed-loop eigenvalues."""
    from vega_lpv.interconnection import plant_for_simulation
    from vega_model.parameters import default_context

    ctx = default_context()
    p = ctx.parameters(t_s)
    Ak, Bk, Ck, Dk = pd_table.interpolate(p.v_mps, discrete=False)
    # the table's sign is +1 (u = K_pd y_INS) while the plant measures y = −y_INS: K = −K_pd
    K = (Ak, -Bk, Ck, -Dk)
    result = FakeResult(K, rho=(0.0, 1e4))
    m = loop_margins(result, ctx, t_s, 20.0)
    plant = plant_for_simulation(t_s, ctx)
    P = control.ss(plant.A, plant.B[:, -1:], plant.C[-4:], plant.D[-4:, -1:])
    L = -(control.ss(*K) * P)
    gm, pm, _, wpc, wgc, _ = control.stability_margins(L, returnall=True)
    gm, wpc = np.asarray(gm), np.asarray(wpc)
    seen = wpc > 1e-3
    gm_low_ref = gm[seen & (gm < 1)].max()
    gm_high_ref = gm[seen & (gm > 1)].min()
    i = int(np.argmin(np.abs(pm)))
    assert m.gm_low == pytest.approx(gm_low_ref, rel=0.01)
    assert m.gm_high == pytest.approx(gm_high_ref, rel=0.01)
    assert m.pm_deg == pytest.approx(abs(pm[i]), abs=0.3)
    assert m.crossover_radps == pytest.approx(wgc[i], rel=0.01)
    window_db = []
    for w0 in p.omega_radps:
        w = DEFAULT_W[(DEFAULT_W > 0.8 * w0) & (DEFAULT_W < 1.2 * w0)]
        resp = np.asarray(control.frequency_response(L, w).complex).ravel()
        window_db.append(float(20 * np.log10(np.abs(resp)).max()))
    assert m.bending_gain_db == pytest.approx(tuple(window_db), abs=1e-6)

    def stable(g):
        return np.linalg.eigvals(control.feedback(g * L, 1).A).real.max() < 0.0

    assert stable(1.0)
    assert stable(1.01 * m.gm_low) and not stable(0.99 * m.gm_low)
    assert stable(0.99 * m.gm_high) and not stable(1.01 * m.gm_high)
