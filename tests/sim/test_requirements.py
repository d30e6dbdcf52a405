"""Requirement definitions (thesis Table 3.1, docs/REQUIREMENTS.md) and the array-in metric
computation."""

import hashlib
import math

import numpy as np
import pytest
import yaml

from vega_model.flight_conditions import default_flight_conditions_path
from vega_sim.requirements import (REQUIREMENT_KEYS, default_requirements_path,
                                   envelope_from_trajectory, envelope_table,
                                   evaluate_requirements, load_requirements, q_alpha_flip)

D = np.radians   # degrees → radians


@pytest.fixture(scope="module")
def spec():
    return load_requirements()


def test_shipped_bounds_in_si(spec):
    assert spec.drift_m == 500.0 and spec.drift_rate_mps == 15.0
    assert spec.deflection_rad == pytest.approx(D(6.5), rel=1e-15)
    assert spec.deflection_integral_rad_s == pytest.approx(D(250.0), rel=1e-15)
    thesis = {k: v.value for k, v in spec.thesis.items()}
    assert thesis == pytest.approx({"q_alpha": D(-14554.6), "drift": -0.5002,
                                    "drift_rate": 0.1221, "deflection": D(2.9281),
                                    "deflection_integral": D(0.4985)}, rel=1e-12)
    assert "command" in spec.thesis["deflection"].note
    assert "signed" in spec.thesis["deflection_integral"].note
    assert all(spec.sources[k].startswith("thesis Table 3.1") for k in REQUIREMENT_KEYS)
    assert spec.sources["q_alpha_objective"].startswith("thesis Eq. 4.24")


# Q of the flight-condition table at a few of its rows (t [s], Mach, Q [Pa]), read off the CSV
_ROWS = [(8.0, 0.209240489, 3019.89232), (15.0, 0.479309176, 14411.5926),
         (30.0, 1.09019018, 47404.127), (47.3, 1.9442029, 60178.7656)]


def _flight_conditions():
    """The shipped flight-condition CSV, read as plain text: column name → values."""
    lines = [line for line in default_flight_conditions_path().read_text().splitlines()
             if not line.startswith("#")]
    header = lines[0].split(",")
    rows = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    return {name: rows[:, k] for k, name in enumerate(header)}


def test_envelope_is_four_degrees_times_q_with_a_floor(spec):
    """docs/REQUIREMENTS.md §2.3: 4°·Q_nom(M) for M ≥ 0.31, 4°·Q_nom(0.31) below; hand values."""
    table = _flight_conditions()
    for t, mach, q in _ROWS:
        (i,) = np.flatnonzero(table["t_s"] == t)
        assert (table["mach"][i], table["q_pa"][i]) == (mach, q)
    # above the threshold: 4° × Q at the row's Mach (the table is within 0.5 % of it)
    assert spec.envelope(0.479309176) == pytest.approx(D(4 * 14411.5926), rel=0.005)  # 57 646
    assert spec.envelope(1.09019018) == pytest.approx(D(4 * 47404.127), rel=0.005)    # 189 617
    assert spec.envelope(1.9442029) == pytest.approx(D(4 * 60178.7656), rel=0.005)    # 240 715
    # Q_nom(0.31) between the rows at 10.7 s (M 0.308629195, Q 6388.5421 Pa) and 10.8 s
    # (M 0.31243491, Q 6538.93815 Pa): 6388.5421 + 0.360197 × 150.39605 = 6442.714 Pa
    floor = 4 * 6442.714                                                   # 25 770.86 Pa·deg
    assert spec.envelope(0.31) == pytest.approx(D(floor), abs=D(0.06))
    # below the threshold: the floor, not 4° × Q (at M 0.209, 4° × Q would be 12 080 Pa·deg)
    for mach in (0.0, 0.1, 0.209240489, 0.3, 0.3099):
        assert spec.envelope(mach) == pytest.approx(D(floor), abs=D(0.06))
    assert spec.envelope(0.31) < spec.envelope(0.36)


@pytest.mark.slow
def test_envelope_table_is_what_its_generator_gives(spec):
    """The shipped table, its definition block and its provenance agree with the generator."""
    d = spec.envelope_definition
    assert (math.degrees(d.alpha_max_rad), d.mach_min) == (4.0, 0.31)
    assert math.degrees(d.floor_pa_rad) == pytest.approx(25770.9)
    mach, value = envelope_table(D(4.0), mach_min=0.31)
    assert np.array_equal(mach, spec.envelope_mach)
    assert np.max(np.abs(value - spec.envelope_pa_rad)) <= D(0.05) + 1e-9
    assert spec.envelope(0.0) == pytest.approx(d.floor_pa_rad, abs=D(0.05))
    # within max(0.5 %, 20 Pa·deg) of the definition at every trajectory sample, but the three
    # at 95.4–95.6 s where the Mach number stands still at 5.8634 while Q falls (≤ 1.7 %)
    table = _flight_conditions()
    t, m = table["t_s"], table["mach"]
    t, m = t[t <= 100.0], m[t <= 100.0]
    for alpha, mach_min, table in ((4.0, 0.31, spec.envelope), (3.0, 0.0, spec.objective)):
        exact = envelope_from_trajectory(m, D(alpha), mach_min=mach_min)
        error = np.abs(table(m) - exact)
        tol = np.maximum(0.005 * exact, D(20.0))
        assert np.all((error <= tol) | ((t >= 95.4) & (t <= 95.6)))
        assert np.all(error <= np.maximum(0.017 * exact, D(20.0)))
    sha = hashlib.sha256(default_flight_conditions_path().read_bytes()).hexdigest()
    assert spec.provenance["flight_conditions_sha256"] == sha
    assert spec.provenance["alpha_max_deg"] == 4.0 and spec.provenance["mach_min"] == 0.31
    assert "Rocket-Attitude-Dynamics" in spec.provenance["precedent"]
    # the informational objective: 3°·Q_nom(M) from M = 0, no floor
    tree = yaml.safe_load(default_requirements_path().read_text())
    assert tree["q_alpha_objective"]["provenance"]["flight_conditions_sha256"] == sha
    mach3, value3 = envelope_table(D(3.0))
    assert np.array_equal(mach3, spec.objective_mach)
    assert np.max(np.abs(value3 - spec.objective_pa_rad)) <= D(0.05) + 1e-9
    assert spec.objective(0.0) == 0.0
    assert spec.objective(1.09019018) == pytest.approx(D(3 * 47404.127), rel=0.005)


def test_envelope_interpolation(spec):
    m, e = spec.envelope_mach, spec.envelope_pa_rad
    assert spec.envelope(1.021) == pytest.approx(D(178803.1))
    assert spec.envelope(1.0875) == pytest.approx(D(0.5 * (178803.1 + 197804.4)))
    assert spec.envelope(m[-1] + 1.0) == e[-1]          # end value held
    assert np.allclose(spec.envelope(m), e)


def _synthetic():
    t = np.arange(5.0)
    mach = np.array([0.1, 0.5, 1.0, 1.05, 3.0])
    q_alpha = D(np.array([0.0, 40_000.0, -131_000.0, -137_000.0, -5_000.0]))
    z = np.array([0.0, -3.0, 2.0, 1.0, 0.5])
    z_dot = np.array([0.1, -0.2, 14.9, 0.0, 0.0])
    beta = D(np.array([0.0, 1.0, -2.0, 0.0, 0.0]))
    return t, q_alpha, mach, z, z_dot, t, beta


def test_metrics_on_hand_computed_arrays(spec):
    t, qa, mach, z, zd, tb, beta = _synthetic()
    cmd = D(np.array([0.0, 1.0, -3.0, 0.0, 0.0]))
    report = evaluate_requirements(t, qa, mach, z, zd, tb, beta, beta_cmd_rad=cmd, spec=spec)
    assert report.passed
    # envelope at M [0.1, 0.5, 1.0, 1.05, 3.0]: the floor 25 770.9, then linear between the
    # breakpoints: 48416.3 + 65/97 × 20830.0 = 62 374.55; 151407.4 + 118/139 × 27395.7 =
    # 174 664.18; 178803.1 + 29/133 × 19001.3 = 182 946.24; 218599.1 − 617/869 × 59161.1 =
    # 176 594.04 Pa·deg; margins [25 770.9, 22 374.55, 43 664.18, 45 946.24, 171 594.04]:
    # binding at t = 1 s
    q = report["q_alpha"]
    assert (q.time_s, q.value) == (1.0, qa[1])
    assert q.bound == pytest.approx(D(62374.547)) and q.margin == pytest.approx(D(22374.547))
    # the largest |Qα| is another sample (137 000 Pa·deg at 3 s): shown beside
    assert (q.peak_time_s, q.peak_value) == (3.0, qa[3])
    assert q.peak_bound == pytest.approx(D(182946.241))
    # the informational 3°·Q line (objective table at the same Mach: 2126.70, 46 824.09,
    # 131 068.27, 137 156.48, 132 510.76): binding at 2 s with 68.27 Pa·deg to spare
    (o,) = [x for x in report.informational if x.key == "q_alpha_objective"]
    assert (o.key, o.gating, o.passed, o.time_s) == ("q_alpha_objective", False, True, 2.0)
    assert o.bound == pytest.approx(D(131068.271)) and \
        o.margin == pytest.approx(D(68.2714), abs=D(0.001))
    z_row = report["drift"]
    assert (z_row.value, z_row.bound, z_row.margin, z_row.time_s) == (-3.0, 500.0, 497.0, 1.0)
    zd_row = report["drift_rate"]
    assert (zd_row.value, zd_row.time_s) == (14.9, 2.0)
    assert zd_row.margin == pytest.approx(0.1)
    b = report["deflection"]
    assert (b.value, b.time_s) == (D(-2.0), 2.0) and b.margin == pytest.approx(D(4.5))
    integral = report["deflection_integral"]    # trapezoid of |β|: 0.5 + 1.5 + 1 = 3 °s
    assert integral.value == pytest.approx(D(3.0)) and integral.time_s == 4.0
    assert integral.margin == pytest.approx(D(247.0))
    assert report.command_peak_rad == pytest.approx(D(3.0))
    assert report.command_signed_integral_rad_s == pytest.approx(D(-2.0))
    assert [r.display_unit for r in report.results] == ["Pa*deg", "m", "m/s", "deg", "deg*s"]
    text = report.table()
    for figure in ("-14554.6", "-0.5002", "0.1221", "2.9281", "0.4985", "40000 Pa*deg",
                   "≤ 62374.5 Pa*deg", "137000 Pa*deg at 3.000 s", "< 6.5 deg",
                   "max |β_cmd| = 3 deg", "info: yes", "≤ 131068 Pa*deg",
                   "Qα sensitivity"):
        assert figure in text, figure
    assert " NO " not in text


def test_informational_line_never_gates(spec):
    """The 3°·Q objective is evaluated and printed; it changes neither the verdict nor the
    requirement rows."""
    t, qa, mach, z, zd, tb, beta = _synthetic()
    base = evaluate_requirements(t, qa, mach, z, zd, tb, beta, spec=spec)
    over = qa.copy()
    over[2] = D(-131_300.0)      # objective 131 068.27 at M 1.0: 231.73 over; envelope: 43 364 left
    report = evaluate_requirements(t, over, mach, z, zd, tb, beta, spec=spec)
    (o,) = [x for x in report.informational if x.key == "q_alpha_objective"]
    assert not o.passed and o.margin == pytest.approx(D(-231.729), abs=D(0.001))
    assert report.passed and report["q_alpha"].passed
    assert "info: no" in report.table() and " NO " not in report.table()
    assert [r.key for r in report.results] == list(REQUIREMENT_KEYS)
    assert [(r.key, r.passed) for r in report.results] == [(r.key, r.passed)
                                                            for r in base.results]
    # a failing requirement fails the run whatever the informational line says
    worse = over.copy()
    worse[3] = D(-190_000.0)
    failing = evaluate_requirements(t, worse, mach, z, zd, tb, beta, spec=spec)
    assert not failing.passed and not failing["q_alpha"].passed


def test_file_without_objective_has_no_informational_line(tmp_path, spec):
    tree = yaml.safe_load(default_requirements_path().read_text())
    del tree["q_alpha_objective"], tree["q_alpha_allowable"]
    path = tmp_path / "r.yaml"
    path.write_text(yaml.safe_dump(tree))
    other = load_requirements(path)
    assert other.objective_mach is None and other.objective(1.0) is None
    report = evaluate_requirements(*_synthetic(), spec=other)
    assert report.informational == () and report.passed


def test_excess_text_never_prints_minus_zero(spec):
    """A strict bound reached exactly fails with "reaches its bound", not "by -0"."""
    t, qa, mach, z, zd, tb, beta = _synthetic()
    at_stop = beta.copy()
    at_stop[1] = spec.deflection_rad
    row = evaluate_requirements(t, qa, mach, z, zd, tb, at_stop, spec=spec)["deflection"]
    assert not row.passed and row.margin == 0.0
    assert row.excess_text() == "reaches its bound 6.5 deg (the bound is strict)"
    over = evaluate_requirements(t, qa, mach, z, zd, tb, D(np.full(5, 7.0)),
                                 spec=spec)["deflection"]
    assert over.excess_text() == "exceeds its bound 6.5 deg by 0.5 deg"
    assert evaluate_requirements(t, qa, mach, z, zd, tb, beta,
                                 spec=spec)["deflection"].excess_text() == ""


def test_q_alpha_flip_hand_computed(spec):
    """The envelope parameters at which the verdict flips (docs/REQUIREMENTS.md §4)."""
    t = np.array([0.0, 1.0, 2.0, 3.0])
    mach = np.array([0.2, 0.31, 0.5, 1.05])
    qa = D(np.array([30_000.0, -20_000.0, 70_000.0, -137_000.0]))
    # envelope: floor 25 770.9 (M 0.2), 25 770.9 (M 0.31), 62 374.55 (M 0.5), 182 946.24 (1.05)
    # at M ≥ 0.31, |Qα|/envelope = 0.776069, 1.122253, 0.748854 → α = 4° × 1.122253 = 4.48901°
    # below M 0.31: max |Qα| = 30 000 Pa·deg (t = 0); tied: 4° × 30000/25770.9 = 4.65641°
    f = q_alpha_flip(t, qa, mach, spec=spec)
    assert math.degrees(f.alpha_flip_rad) == pytest.approx(4.48901, abs=2e-5)
    assert (f.alpha_flip_time_s, f.alpha_flip_mach) == (2.0, 0.5)
    assert math.degrees(f.floor_flip_pa_rad) == pytest.approx(30_000.0)
    assert f.floor_flip_time_s == 0.0
    assert math.degrees(f.alpha_flip_tied_rad) == pytest.approx(4.65642, abs=2e-5)
    # raising the threshold: at 0.31 and 0.5 the sample at M 0.5 still exceeds 4°·Q; at 1.05
    # everything below is within the floor 182 946 and the sample at 1.05 within its bound
    assert f.mach_min_flip == 1.05
    assert not f.passed and not evaluate_requirements(
        t, qa, mach, np.zeros(4), np.zeros(4), t, np.zeros(4), spec=spec)["q_alpha"].passed
    assert "α_allow ≥ 4.489°" in f.text() and "Mach threshold ≥ 1.050" in f.text()


@pytest.mark.parametrize("alpha_deg, floor, passes", [
    (4.49, 30_000.0, True), (4.488, 30_000.0, False), (4.49, 29_999.0, False)])
def test_q_alpha_flip_is_where_the_verdict_flips(tmp_path, spec, alpha_deg, floor, passes):
    """Scaling the table above M 0.31 by α/4 and setting the floor flips the verdict exactly at
    the computed values."""
    t = np.array([0.0, 1.0, 2.0, 3.0])
    mach = np.array([0.2, 0.31, 0.5, 1.05])
    qa = D(np.array([30_000.0, -20_000.0, 70_000.0, -137_000.0]))
    tree = yaml.safe_load(default_requirements_path().read_text())
    env = tree["q_alpha_envelope"]
    # F below 0.31 (a breakpoint just below it keeps the segment flat), α/4 × table from 0.31
    scaled = [v * alpha_deg / 4.0 for m, v in zip(env["mach"], env["value"]) if m >= 0.31]
    env["mach"] = [0.0, 0.3099999] + [m for m in env["mach"] if m >= 0.31]
    env["value"] = [floor, floor] + scaled
    path = tmp_path / "r.yaml"
    path.write_text(yaml.safe_dump(tree))
    other = load_requirements(path)
    report = evaluate_requirements(t, qa, mach, np.zeros(4), np.zeros(4), t, np.zeros(4),
                                   spec=other)
    assert report["q_alpha"].passed is passes
    f = q_alpha_flip(t, qa, mach, spec=spec)
    assert (math.degrees(f.alpha_flip_rad) <= alpha_deg
            and math.degrees(f.floor_flip_pa_rad) <= floor) is passes


def test_q_alpha_flip_agrees_with_the_verdict(spec):
    """On random histories, "meets the flip values" is the Qα verdict of the shipped file."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(1, 30))
        mach = np.sort(rng.uniform(0.0, 6.0, n))
        qa = spec.envelope(mach) * rng.uniform(-1.1, 1.1, n)
        t = np.arange(n, dtype=float)
        f = q_alpha_flip(t, qa, mach, spec=spec)
        ok = evaluate_requirements(t, qa, mach, np.zeros(n), np.zeros(n), t, np.zeros(n),
                                   spec=spec)["q_alpha"].passed
        assert f.passed is ok
        assert (f.mach_min_flip == 0.31) is ok


def test_violations_and_boundaries(spec):
    t, qa, mach, z, zd, tb, beta = _synthetic()
    qa_over = qa.copy()
    qa_over[3] = D(-183_000.0)                      # 53.76 Pa·deg over 182 946.24 at M 1.05
    report = evaluate_requirements(t, qa_over, mach, z, zd, tb, beta, spec=spec)
    assert not report.passed and not report["q_alpha"].passed
    assert report["q_alpha"].margin == pytest.approx(D(-53.759), abs=D(0.001))
    assert " NO " in report.table() and report.command_peak_rad is None
    # a load exactly on the envelope is not a violation (≤): at M = 0, the floor
    on = spec.envelope(0.0)
    zero = evaluate_requirements([0.0, 1.0], [on, -on], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0],
                                 [0.0, 1.0], [0.0, 0.0], spec=spec)
    assert zero.passed and zero["q_alpha"].margin == 0.0
    # the 3°·Q objective is 0 at M = 0: zero load is on it, a floor-sized load far over it
    (o,) = [x for x in zero.informational if x.key == "q_alpha_objective"]
    assert not o.passed and o.bound == 0.0 and zero.passed
    # the other bounds are strict (<)
    on_bound = z.copy()
    on_bound[4] = -500.0
    assert not evaluate_requirements(t, qa, mach, on_bound, zd, tb, beta,
                                     spec=spec)["drift"].passed
    beta_stop = beta.copy()
    beta_stop[1] = spec.deflection_rad
    assert not evaluate_requirements(t, qa, mach, z, zd, tb, beta_stop,
                                     spec=spec)["deflection"].passed
    big = np.full(5, D(70.0))                       # ∫ = 280 °s over 4 s
    row = evaluate_requirements(t, qa, mach, z, zd, tb, big, spec=spec)["deflection_integral"]
    assert not row.passed and row.margin == pytest.approx(D(-30.0))
    diverged = z.copy()
    diverged[2] = np.nan
    row = evaluate_requirements(t, qa, mach, diverged, zd, tb, beta, spec=spec)["drift"]
    assert not row.passed and math.isnan(row.value) and row.time_s == 2.0


def test_bad_arrays(spec):
    t, qa, mach, z, zd, tb, beta = _synthetic()
    with pytest.raises(ValueError, match="z_m has 4 samples, expected 5"):
        evaluate_requirements(t, qa, mach, z[:4], zd, tb, beta, spec=spec)
    with pytest.raises(ValueError, match="beta_t_s must be a non-empty 1-D array"):
        evaluate_requirements(t, qa, mach, z, zd, [], [], spec=spec)


@pytest.mark.parametrize("old, new, message", [
    ("schema_version: 1", "schema_version: 1\nextra: 2", "field 'extra': unknown key"),
    ("drift:\n  value: 500.0\n  unit: m", "drift:\n  value: 500.0\n  unit: deg",
     "field 'drift.unit'"),
    ("drift:\n  value: 500.0", "drift:\n  value: '500'", "field 'drift.value'"),
    ("drift:\n  value: 500.0", "drift:\n  value: -1.0", "field 'drift.value': must be > 0"),
    ("  unit: m/s\n  source: \"thesis Table 3.1 (lateral velocity",
     "  unit: m/s\n  limit: 3\n  source: \"thesis Table 3.1 (lateral velocity",
     "field 'drift_rate.limit': unknown key"),
    ("  mach: [0, 0.31, 0.365,", "  mach: [0, 0.365, 0.31,", "field 'q_alpha_envelope.mach'"),
    ("  mach: [0, 0.31, 0.365,", "  mach: [0, 0.365,", "mach and value differ in length"),
    ("    alpha_max_deg: 4.0\n    mach_min", "    alpha_max_deg: 0\n    mach_min",
     "field 'q_alpha_envelope.definition.alpha_max_deg': must be a finite number > 0"),
    ("    floor_pa_deg: 25770.9", "    floor_pa_deg: 25770.9\n    floor: 1",
     "field 'q_alpha_envelope.definition.floor': unknown key"),
    ("  mach: [0, 0.019, 0.038,", "  mach: [0, 0.038, 0.019,",
     "field 'q_alpha_objective.mach'"),
    ("q_alpha_objective:\n", "q_alpha_objective:\n  gating: true\n",
     "field 'q_alpha_objective.gating': unknown key"),
    ("  q_alpha:\n    value: -14554.6", "  q_alpha:\n    valu: -14554.6",
     "field 'thesis_table_5_1.q_alpha.valu': unknown key"),
    ("  drift_rate:\n    value: 0.1221", "  drift_rte:\n    value: 0.1221",
     "field 'thesis_table_5_1.drift_rte': unknown key"),
])
def test_config_errors_name_the_field(tmp_path, old, new, message):
    text = default_requirements_path().read_text()
    assert old in text, old
    path = tmp_path / "requirements.yaml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(ValueError) as info:
        load_requirements(path)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert str(info.value).startswith(str(path))


def test_missing_section(tmp_path):
    text = default_requirements_path().read_text()
    path = tmp_path / "r.yaml"
    path.write_text(text.replace("deflection_integral:\n", "deflection_integrals:\n", 1))
    with pytest.raises(ValueError, match="field 'deflection_integrals': unknown key"):
        load_requirements(path)
    with pytest.raises(ValueError, match="cannot read requirements"):
        load_requirements(tmp_path / "none.yaml")
